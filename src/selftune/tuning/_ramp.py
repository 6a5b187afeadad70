"""Commissioning over a speed range: learn the motor from a log whose speed changes, and
the range of speeds the data cover.

At a held speed the current loop's plant is ``A(omega) = A_0 + omega A_1``: R_s, the
inductances and the flux do not depend on the speed, so the affine-in-speed plant is the
identified motor, and a speed schedule is designed on it
(:func:`~selftune.model.design_schedule`) only within the speeds the data cover.

The experiment (:func:`commission_ramp`) runs the drive over a staircase of speeds from a
low to a high one (:func:`~selftune.sim.ramp_speeds`, the speed held within each sample,
the angle integrating it: :func:`~selftune.sim.run_speed_profile`), under the gentle K0
with the current steps of the interior commissioning (:func:`~._interior.current_steps`;
a surface motor's torque reference through the same levels), ``w_1 = p speed
phi_assumed`` following the speed. The log is cut where its angle column's speed changes
(:func:`speed_segments`); each segment is a log at a held speed, fitted by the structured
identification at its own speed (``structure = "ipmsm"`` or ``"spmsm"``, the learner's
verdict on each); the segments' parameters, which the physics says are one motor's, are
combined by their inverse variances. The data cover the segments' lowest to highest
electrical speed.

Not done: one fit over a log whose speed changes every sample (a linear ramp). The
output-error fit simulates one time-invariant sampled plant over a log; a speed per
sample needs a plant per sample, in its simulation, its sensitivities, its bootstrap and
the structure's and the verdict's checks. A linear ramp's log is refused here, saying so.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from itertools import pairwise
from typing import Any

import numpy as np

from ..core import Array, ControlLaw
from ..errors import InputError, SelftuneError
from ..learn import LearnedController, LearningProblem, Trajectory, learn_controller
from ..model import IPMSM, Motor
from ..sim import DriveSettings, RealisticDrive, held, ramp_speeds, run_speed_profile, uniform
from ._interior import current_steps, identified_motor
from ._knowledge import STEP_DWELL, STEP_LEVELS
from ._learning import learning_options
from ._settings import TuningSettings

__all__ = [
    "MIN_SEGMENT",
    "SPEED_STEP",
    "RampCommissioning",
    "commission_ramp",
    "speed_segments",
]

#: A change of the angle column's speed between samples larger than this share of the
#: log's largest speed starts a new segment (the angle's rounding is about 1e-12 of it).
SPEED_STEP = 1e-6

#: The shortest segment of a held speed the learner fits, s: four current steps.
MIN_SEGMENT = 4 * STEP_DWELL


def speed_segments(log: Trajectory, h: float) -> list[tuple[int, int, float]]:
    """The log cut where the speed of its angle column changes.

    Parameters
    ----------
    log : Trajectory
        A log with an angle column (the electrical rotor angle, rad).
    h : float
        Sampling period, s.

    Returns
    -------
    list of (first, last, electrical speed)
        Samples ``first .. last - 1`` at one speed (over ``[t_first, t_last)``) and that
        speed, rad/s (the mean of the angle's steps over h).

    Raises
    ------
    InputError
        Without an angle column, or when a segment is shorter than :data:`MIN_SEGMENT`
        (a speed that changes every sample: a linear ramp, which this learner cannot fit).
    """
    if log.angle is None:
        raise InputError("angle: a log over several speeds needs its angle column theta")
    steps = np.angle(np.exp(1j * np.diff(log.angle))) / h  # the speed over each sample
    largest = max(float(np.max(np.abs(steps))), 1e-300)
    cuts = np.flatnonzero(np.abs(np.diff(steps)) > SPEED_STEP * largest) + 1
    bounds = [0, *cuts.tolist(), steps.size]
    shortest = min(b - a for a, b in pairwise(bounds)) * h
    if shortest < MIN_SEGMENT:
        raise InputError(
            f"angle: the speed holds for as little as {shortest:.3g} s (at least "
            f"{MIN_SEGMENT:g} s a speed is needed): the identification fits one plant at a "
            "held speed per segment and cannot fit a speed that changes every sample; log "
            "a staircase of held speeds"
        )
    return [(a, b, float(np.mean(steps[a:b]))) for a, b in pairwise(bounds)]


def _segment(log: Trajectory, first: int, last: int) -> Trajectory:
    """Rows ``first .. last - 1`` of the log: row ``last`` starts the next speed's sample,
    and its reference is that speed's (``w_1 = p speed phi_assumed``; kept, it moved the
    flux read off the segment's mean ``w_1`` by 0.4% at 5% and 100% of a speed)."""
    assert log.w is not None and log.angle is not None
    rows = slice(first, last)
    return Trajectory(
        t=log.t[rows], x=log.x[rows], u=log.u[first : last - 1], w=log.w[rows],
        angle=log.angle[rows],
    )  # fmt: skip


def _combined(motors: list[tuple[Motor, dict[str, float]]]) -> tuple[Motor, dict[str, float]]:
    """The segments' motors combined by inverse variances, parameter by parameter."""
    first, names = motors[0][0], list(motors[0][1])
    values, errors = {}, {}
    for name in names:
        estimates = np.array([getattr(motor, name) for motor, _ in motors])
        weights = np.array([1.0 / max(se[name], 1e-300) ** 2 for _, se in motors])
        values[name] = float(np.sum(weights * estimates) / np.sum(weights))
        errors[name] = float(1.0 / np.sqrt(np.sum(weights)))
    changed: dict[str, Any] = values
    return replace(first, **changed), errors


@dataclass(frozen=True)
class RampCommissioning:
    """A motor identified from a log over several speeds (SI units).

    Attributes
    ----------
    motor : SPMSM or IPMSM
        The identified motor (the segments' parameters combined; the nameplate's p).
    standard_errors : dict of str to float
        The combined parameters' standard errors.
    covered : (float, float)
        The lowest and highest electrical speed of the data, rad/s.
    segments : tuple of (float, SPMSM or IPMSM, LearnedController)
        Each held speed's electrical speed (rad/s), identified motor and learned law.
    data_seconds : float
        Length of the log, s.
    integral_weight : ndarray or None
        The integral weight the learner used (None without integral action).
    record_speeds : ndarray, shape (N,)
        The mechanical speed held over each sample of the experiment, rad/s.
    """

    motor: Motor
    standard_errors: dict[str, float]
    covered: tuple[float, float]
    segments: tuple[tuple[float, Motor, LearnedController], ...]
    data_seconds: float
    integral_weight: Array | None
    record_speeds: Array


def commission_ramp(
    motor: Motor,
    settings: TuningSettings,
    drive: DriveSettings,
    speeds: tuple[float, float],
    *,
    seconds: float = 1.0,
    levels: int = 4,
    seed: int = 0,
) -> RampCommissioning:
    """Run the staircase experiment and identify the motor (see the module docstring).

    Parameters
    ----------
    motor : SPMSM or IPMSM
        The true motor (its nameplate flux and pole pairs are what the engineer knows).
    settings : TuningSettings
        T* (N m), cost, K0, exploration, integral action (its speed is not used).
    drive : DriveSettings
        The drive.
    speeds : (float, float)
        The lowest and highest mechanical speed of the staircase, rad/s.
    seconds : float
        Length of the experiment, s.
    levels : int
        Held speeds of the staircase.
    seed : int
        Seed of the exploration and the noise.

    Raises
    ------
    SelftuneError
        The learner's refusal of a segment, naming its speed.
    """
    h = settings.h
    count = round(seconds / h)
    profile = ramp_speeds(speeds[0], speeds[1], count, levels)
    interior = isinstance(motor, IPMSM)
    F = motor.regulation_problem(float(profile[0])).F
    scale = 2.0 * settings.torque / (3.0 * motor.p * motor.phi_pm)
    levels_array = np.asarray(STEP_LEVELS)

    def reference(t: Array) -> Array:
        rows = np.minimum(np.round(t / h).astype(int), count - 1)
        back_emf = motor.p * profile[rows] * motor.phi_pm  # w_1, the nameplate flux
        if interior:
            d, q = current_steps(t, scale)
            return np.column_stack([back_emf, d, q])
        torque = levels_array[np.floor(t / STEP_DWELL).astype(int) % levels_array.size]
        return np.column_stack([back_emf, torque * settings.torque])

    law = ControlLaw.regulator(settings.K0, -F, np.zeros((2, F.shape[1])))
    record = run_speed_profile(
        motor, profile, h, drive, law, held(reference), exploration=uniform(settings.exploration),
        seed=seed,
    )  # fmt: skip
    log = record.trajectory
    problem = LearningProblem(
        settings.Q, settings.R, C=np.eye(2), F=F, integral_action=settings.integral_action,
        integral_weight=settings.Q_i,
    )  # fmt: skip
    plant = RealisticDrive(motor, float(profile[-1]), h, drive)
    base = replace(
        learning_options(plant, settings), method="identify",
        structure="ipmsm" if interior else "spmsm",
    )  # fmt: skip
    segments = []
    for first, last, speed in speed_segments(log, h):
        options = replace(base, electrical_speed=speed)
        try:
            learned = learn_controller(_segment(log, first, last), problem, settings.K0, options)
        except SelftuneError as error:  # said at the segment's speed
            raise error.retold(f"at {speed:g} rad/s (electrical): {error}") from None
        identified, _ = identified_motor(learned, motor.p)
        segments.append((speed, identified, learned))
    combined = _combined([identified_motor(learned, motor.p) for _, _, learned in segments])
    electrical = [speed for speed, _, _ in segments]
    return RampCommissioning(
        motor=combined[0], standard_errors=combined[1],
        covered=(min(electrical), max(electrical)), segments=tuple(segments),
        data_seconds=count * h,
        integral_weight=problem.integral_weight if settings.integral_action else None,
        record_speeds=profile,
    )  # fmt: skip
