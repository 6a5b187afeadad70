"""What a session hands the learners: the problem a drive engineer knows, the options the
drive and the settings imply, and the result read back as a :class:`TuningResult`.

Every session learns through :func:`selftune.learn.learn_controller` (off-policy, and
Algorithm 3's second step on a realistic drive) or has its on-policy result judged by
:func:`selftune.learn.assess` on all its episodes, so that every result carries the same
verdict: alignment of the log with the drive's delay, measurement noise, consistency,
standard errors and a stability margin; or an error that says why the data do not
support a controller.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TypeVar

import numpy as np

from ..core import Array, pack_theta, unpack_theta
from ..errors import InputError, TooLittleData
from ..learn import (
    IterationRecord,
    LearnedController,
    LearningOptions,
    LearningProblem,
    Trajectory,
    aligned_trajectory,
    feedforward,
    stated_shift,
)
from ..sim import DriveSettings
from ._drive import Drive
from ._episodes import iteration_record
from ._knowledge import known_flux_form
from ._results import TuningIteration, TuningResult
from ._settings import Target, TuningSettings

__all__ = [
    "LONGER_BATCHES",
    "LONGEST_BATCH_FACTOR",
    "aligned",
    "check_drive",
    "from_learned",
    "learned_at_length",
    "learning_options",
    "learning_problem",
    "longer_batch",
    "pulse_bus",
]

#: What a batch's learning returns (:func:`learned_at_length`).
Learned = TypeVar("Learned")

#: The relative agreement of the drive's sampling period with the settings' required.
SAMPLING_AGREEMENT = 1e-9


def check_drive(drive: Drive, settings: TuningSettings) -> None:
    """Raise unless the drive and the settings describe the same loop.

    Raises
    ------
    InputError
        If the sampling periods differ, or the settings ask for what the drive cannot do
        (the digital target or integral action on a controller updated every
        ``input_hold > 1`` samples).
    """
    h = drive.loop.h
    if abs(h - settings.h) > SAMPLING_AGREEMENT * settings.h:
        raise InputError(
            f"h: the settings say {settings.h:g} s but the drive samples every {h:g} s"
        )
    if settings.input_hold != 1 and (settings.target == "digital" or settings.integral_action):
        what = "the digital target" if settings.target == "digital" else "integral action"
        raise InputError(
            f"input_hold: {what} is the controller of a loop that updates every sample; "
            f"set input_hold = 1 (got {settings.input_hold})"
        )


def learning_problem(drive: Drive, settings: TuningSettings, phi_pm: float) -> LearningProblem:
    """The known-flux problem (C = I, E = 0, F from p and the flux) with the settings' cost,
    K0 and integral action.

    Parameters
    ----------
    drive : Drive
        The drive (for its pole pairs).
    settings : TuningSettings
        Operating point, cost (``Q_i`` too), K0, integral action.
    phi_pm : float
        The flux the controller assumes, Wb.
    """
    C, _, F, _ = known_flux_form(drive.pole_pairs, settings.speed, settings.torque, phi_pm)
    return LearningProblem(
        settings.Q, settings.R, C=C, F=F, integral_action=settings.integral_action,
        integral_weight=settings.Q_i,
    )  # fmt: skip


#: When the learner finds a batch too short for its noise (TooLittleData), the tuner runs
#: a longer batch of the length it asks for (with a quarter more, :func:`longer_batch`),
#: at most :data:`LONGER_BATCHES` times and up to this many times the batch it planned;
#: beyond, the refusal stands. (The length it names assumes the errors fall as 1/sqrt(T);
#: a part that does not, such as the dead-time model's sensitivity, can need a second one.)
LONGEST_BATCH_FACTOR = 10.0

#: How many longer batches a tuner runs on TooLittleData (see LONGEST_BATCH_FACTOR).
LONGER_BATCHES = 2


def learned_at_length(
    learn: Callable[[int], Learned], planned: int, h: float
) -> tuple[Learned, int, tuple[str, ...]]:
    """``learn(samples)`` of the batch planned, run again as long as a TooLittleData
    refusal asks (:func:`longer_batch`, at most :data:`LONGER_BATCHES` times; beyond, the
    refusal stands).

    Parameters
    ----------
    learn : callable
        ``samples -> result``: runs a batch of that many samples and learns from it.
    planned : int
        The samples first planned.
    h : float
        Sampling period, s.

    Returns
    -------
    result
        What ``learn`` returned.
    samples : int
        The samples of the batch it learned from.
    notes : tuple of str
        A line for each longer batch run, and why.
    """
    notes: tuple[str, ...] = ()
    samples = planned
    for batch_number in range(1, LONGER_BATCHES + 2):
        try:
            return learn(samples), samples, notes
        except TooLittleData as refusal:
            longer = longer_batch(refusal, samples, planned, h)
            if batch_number > LONGER_BATCHES or longer is None:
                raise
            K_se, U_se = refusal.relative_se
            notes += (
                f"the {samples * h:.3g} s batch was too short for its noise (standard errors "
                f"of K {K_se:.2%}, of U {U_se:.2%}); a {longer * h:.3g} s batch was run, as "
                "the learner asked",
            )
            samples = longer
    raise AssertionError("unreachable: the last batch returns or raises")


def longer_batch(refusal: TooLittleData, samples: int, planned: int, h: float) -> int | None:
    """The samples of the longer batch a TooLittleData refusal asks for: a quarter more
    than the length it names; None where that is not longer than the batch refused or
    beyond :data:`LONGEST_BATCH_FACTOR` times the one planned (the refusal stands).

    Parameters
    ----------
    refusal : TooLittleData
        The learner's refusal (its ``needed_seconds``).
    samples : int
        The refused batch's samples.
    planned : int
        The samples of the batch first planned.
    h : float
        Sampling period, s.
    """
    longer = int(np.ceil(1.25 * refusal.needed_seconds / h))
    return longer if samples < longer <= LONGEST_BATCH_FACTOR * planned else None


def learning_options(
    drive: Drive, settings: TuningSettings, *, target: Target | None = None
) -> LearningOptions:
    """The options of the drive's alignment and the settings' target and dead time.

    Parameters
    ----------
    drive : Drive
        Its computation delay and what its log holds.
    settings : TuningSettings
        Target, dead-time model, iterations, regression interval.
    target : str, optional
        Overrides ``settings.target``.
    """
    return LearningOptions(
        target=settings.target if target is None else target,
        method="adp",
        input_delay=drive.loop.input_delay,
        logged_input=drive.logged_input,
        interval=settings.regression_interval(),
        max_iterations=settings.policy_iterations,
        dead_time=settings.dead_time,
        electrical_speed=drive.pole_pairs * settings.speed,
        voltage_hold=drive.loop.hold,
    )


def pulse_bus(drive: DriveSettings) -> float | None:
    """The DC bus, V, that the learner reads the dead time's pulses from
    (:attr:`~selftune.learn.LearningOptions.dc_voltage`): the drive's where its carrier
    PWM has a dead time, else None (an average PWM's voltage is not late, and without
    dead time no pulse is short).

    Parameters
    ----------
    drive : DriveSettings
        The drive.
    """
    return drive.dc_voltage if drive.pwm == "carrier" and drive.dead_time > 0.0 else None


def aligned(episode: Trajectory, drive: Drive) -> Trajectory:
    """The episode with row k of ``u`` the voltage applied during sample k (a drive that
    logs commanded voltages is read with its delay)."""
    shift = stated_shift(drive.logged_input, drive.loop.input_delay)
    return episode if not shift else aligned_trajectory(episode, shift)


def from_learned(
    algorithm: str,
    learned: LearnedController,
    w: Array,
    seconds: float,
    settings: TuningSettings,
    identified: dict[str, float] | None = None,
) -> TuningResult:
    """A :class:`TuningResult` of a controller learned off-policy from ``seconds`` of data."""
    history = _history(learned.history, learned, settings, seconds)
    theta = None
    if learned.target == "continuous" and history:
        # Theta of the problem stated: without the dead-time channels' rows of M
        P, K, M = _unpacked(history[-1].theta, history[-1].K)
        theta = pack_theta(P, K, M[: learned.law.U.shape[1]])
    assert learned.B is not None  # learn_controller estimates it
    return TuningResult(
        algorithm=algorithm,
        law=learned.law,
        P=learned.P,
        B=learned.B,
        w=w,
        history=history,
        data_seconds=seconds,
        feedforward_learned=True,
        quality=learned.verdict,
        target=learned.target,
        theta=theta,
        identified={} if identified is None else identified,
        learned=learned,
    )


def _history(
    records: Sequence[IterationRecord],
    learned: LearnedController,
    settings: TuningSettings,
    seconds: float,
) -> tuple[TuningIteration, ...]:
    """The policy-iteration steps as iterations, with the policy each step improved on.

    For the continuous target each step's feedforward follows from its Theta; the digital
    learner computes U once, from the last step, so every step carries the final U."""
    if not records:  # designed from the model (policy iteration failed on the batch)
        return ()
    history: list[TuningIteration] = []
    previous_theta: Array | None = None
    m = learned.law.U.shape[0]
    K_applied = np.zeros((m, records[0].K.shape[1]))
    K_applied[:, : settings.K0.shape[1]] = settings.K0
    U_applied = np.zeros_like(learned.law.U)
    for record in records:
        if learned.target == "continuous" and learned.law.K_i is None:
            # Theta's exogenous block has a row per channel the learner saw: the reference's
            # and, with the dead-time model, the currents' signs after them (U drops those)
            P, K_next, M = _unpacked(record.theta, record.K)
            U = feedforward(P, K_next, M, settings.R)[:, : learned.law.U.shape[1]]
        else:
            U = learned.law.U
        history.append(
            iteration_record(
                record,
                step="off-policy",
                K_applied=K_applied,
                U_applied=U_applied,
                U=U,
                previous_theta=previous_theta,
                data_seconds=seconds,
            )
        )
        previous_theta = record.theta
        K_applied, U_applied = record.K, U
    return tuple(history)


def _unpacked(theta: Array, K: Array) -> tuple[Array, Array, Array]:
    """``(P, K, M)`` of a Theta with as many exogenous channels as it holds: the
    reference's and, with the dead-time model, the currents' signs after them."""
    m, n = K.shape
    return unpack_theta(theta, n, m, (theta.size - n * (n + 1) // 2 - m * n) // n)
