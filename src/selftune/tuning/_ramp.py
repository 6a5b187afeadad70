"""Commissioning over a speed range: the staircase experiment, the motor learned from it,
and the range of speeds the data cover.

At a held speed the current loop's plant is ``A(omega) = A_0 + omega A_1``: R_s, the
inductances and the flux do not depend on the speed, so the affine-in-speed plant is the
identified motor, and a speed schedule is designed on it
(:func:`~selftune.model.design_schedule`) only within the speeds the data cover.

The experiment (:func:`commission_ramp`) runs the drive over a staircase of speeds from
a low to a high one (:func:`~selftune.sim.ramp_speeds`, the speed held within each
sample, the angle integrating it: :func:`~selftune.sim.run_speed_profile`), under the
gentle K0 with the back-EMF and the references' cross-coupling fed forward at each held
speed (:func:`~._interior.decoupling_feedforward`: under K0 alone the back-EMF drove the
top speed's currents to a median of 1.5-4.8 and peaks of 1.4-8.4 times the rated current
on the ramp bench's nine motors), with the current steps of the interior commissioning
(:func:`~._interior.current_steps`; a surface motor's torque reference through the same
levels), ``w_1 = p speed phi_assumed`` following the speed. The log is learned part by
part, each held speed with the motor's structure (``"ipmsm"`` or ``"spmsm"``) at its own
speed, and the parts' parameters combined (:func:`selftune.learn.learn_over_speeds`,
which also says why one fit over a linear ramp is not done).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..core import Array, ControlLaw
from ..learn import LearnedController, LearningProblem, Trajectory, learn_over_speeds, top_part
from ..model import IPMSM, Motor
from ..sim import DriveSettings, RealisticDrive, held, ramp_speeds, run_speed_profile, uniform
from ._interior import check_current_range, current_steps, decoupling_feedforward, motor_of
from ._knowledge import STEP_DWELL, STEP_LEVELS
from ._learning import learning_options, pulse_bus
from ._resistance import check_against_nameplate
from ._settings import TuningSettings

__all__ = [
    "RAMP_LEVELS",
    "RAMP_SECONDS",
    "RampCommissioning",
    "commission_ramp",
]

#: The experiment's length, s, and its held speeds: what the ramp bench measures
#: (docs/schedule.md). Four held speeds of 0.25 s refused 3 of 20 drawn motors there
#: that two of 0.5 s learned, and learned 1 that two refused.
RAMP_SECONDS = 1.0
RAMP_LEVELS = 2


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
    segments : tuple of (float, LearnedController)
        Each held speed (electrical, rad/s) and the law learned there, with its verdict
        and identified motor (``quality.motor``).
    data_seconds : float
        Length of the log, s.
    integral_weight : ndarray or None
        The integral weight the learner used (None without integral action).
    record_speeds : ndarray, shape (N,)
        The mechanical speed held over each sample of the experiment, rad/s.
    log : Trajectory
        The experiment's log (with its angle column).
    standstill : bool
        Whether a held speed was standstill: covered, not learned
        (:class:`~selftune.learn.SpeedsLearned`).
    """

    motor: Motor
    standard_errors: dict[str, float]
    covered: tuple[float, float]
    segments: tuple[tuple[float, LearnedController], ...]
    data_seconds: float
    integral_weight: Array | None
    record_speeds: Array
    log: Trajectory
    standstill: bool = False

    @property
    def top(self) -> tuple[float, LearnedController]:
        """The segment at the highest speed in magnitude: its electrical speed (rad/s) and
        its law (:func:`~selftune.learn.top_part`)."""
        return top_part(self.segments)


def commission_ramp(
    motor: Motor,
    settings: TuningSettings,
    drive: DriveSettings,
    speeds: tuple[float, float],
    *,
    seconds: float = RAMP_SECONDS,
    levels: int = RAMP_LEVELS,
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
    ModelMissesEffect
        When the combined motor's R_s is far from the nameplate's
        (:func:`~._resistance.check_against_nameplate`).
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

    def law(speed: float) -> ControlLaw:  # K0, the feedforward following the speed
        return ControlLaw.regulator(settings.K0, -F, decoupling_feedforward(motor, motor.p * speed))

    record = run_speed_profile(
        motor, profile, h, drive, law, held(reference), exploration=uniform(settings.exploration),
        seed=seed,
    )  # fmt: skip
    check_current_range(
        record, drive, abs(scale),
        f"the ramp from {speeds[0]:g} to {speeds[1]:g} rad/s",
    )  # fmt: skip
    log = record.trajectory
    problem = LearningProblem(
        settings.Q, settings.R, C=np.eye(2), F=F, integral_action=settings.integral_action,
        integral_weight=settings.Q_i,
    )  # fmt: skip
    plant = RealisticDrive(motor, float(profile[-1]), h, drive)
    base = replace(
        learning_options(plant, settings), method="identify",
        structure="ipmsm" if interior else "spmsm", dc_voltage=pulse_bus(drive),
    )  # fmt: skip
    learned = learn_over_speeds(log, problem, settings.K0, base)
    assert learned.motor is not None  # identify-then-design combines the parts' motors
    found, errors = motor_of(learned.motor, motor.p)
    check_against_nameplate(
        found.R_s, found.L_d, found.L_q, motor.R_s, h,
        (drive.dead_time_voltage(h), motor.R_s * abs(scale)),
    )  # fmt: skip
    return RampCommissioning(
        motor=found, standard_errors=errors,
        covered=learned.covered, segments=learned.parts,
        data_seconds=count * h,
        integral_weight=problem.integral_weight if settings.integral_action else None,
        record_speeds=profile, log=log, standstill=learned.standstill,
    )  # fmt: skip
