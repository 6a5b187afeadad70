"""The pieces every on-policy and off-policy session shares: one learning step on an
episode, the record of an iteration, the settling test, and the divergence check."""

from __future__ import annotations

import numpy as np

from ..core import Array, theta_sizes
from ..errors import ConvergenceError
from ..learn import (
    IterationRecord,
    Trajectory,
    interval_moments,
    policy_step,
    solutions_of_output_equation,
)
from ._drive import Drive
from ._knowledge import known_flux_form
from ._results import TuningIteration
from ._settings import TuningSettings

__all__ = [
    "DIVERGED_CURRENT",
    "NOISE_FLOOR_FACTOR",
    "checked",
    "iteration_record",
    "known_form",
    "learning_step",
    "relative_change",
    "settled",
]


def relative_change(new: Array, old: Array | None) -> float:
    """``||new - old|| / ||new||`` (inf without an old value)."""
    if old is None:
        return float("inf")
    return float(np.linalg.norm(new - old)) / max(float(np.linalg.norm(new)), 1e-300)


def _unknowns(episode: Trajectory) -> int:
    """Unknowns of the continuous data equation of this episode."""
    n, m, q = episode.n, episode.m, episode.q
    return sum(theta_sizes(n, m, q))


#: Currents beyond this (A) mean the applied policy does not stabilize the sampled loop.
DIVERGED_CURRENT = 1e6


def checked(episode: Trajectory, K: Array, settings: TuningSettings) -> Trajectory:
    """Raise a clear error if an episode's currents diverged (the policy is unstable)."""
    peak = float(np.max(np.abs(episode.x)))
    if peak > DIVERGED_CURRENT:
        gain = np.array2string(K, precision=4, separator=", ", max_line_width=200)
        raise ConvergenceError(
            f"the currents diverged (|i| reached {peak:.3g} A in {episode.duration * 1e3:g} ms) "
            f"under the feedback K = {gain} V/A "
            f"applied every {settings.input_hold} sample(s) of {settings.h:g} s: it does "
            "not stabilize the sampled loop; choose a smaller K0 (e.g. about L_s times the "
            "wanted bandwidth in rad/s) or input_hold = 1"
        )
    return episode


def learning_step(
    episode: Trajectory,
    K: Array,
    settings: TuningSettings,
    X: Array,
    *,
    allow_deficient: tuple[str, ...] = (),
    known: dict[str, Array] | None = None,
    iteration: int,
) -> IterationRecord:
    """One policy-iteration step on an episode's data: evaluate ``K`` (= K_j), improve it.

    Checks first that the episode did not diverge (:func:`checked`).
    """
    checked(episode, K, settings)
    moments = interval_moments(episode, settings.regression_interval(_unknowns(episode)))
    return policy_step(
        moments,
        K,
        settings.Q,
        settings.R,
        X=X,
        allow_deficient=allow_deficient,
        known=known,
        iteration=iteration,
    )


def iteration_record(
    record: IterationRecord,
    *,
    step: str,
    K_applied: Array,
    U_applied: Array,
    U: Array,
    previous_theta: Array | None,
    data_seconds: float,
) -> TuningIteration:
    """The :class:`TuningIteration` of a learning step, with what was applied."""
    return TuningIteration(
        iteration=record.iteration,
        step=step,
        K_applied=K_applied,
        U_applied=U_applied,
        theta=record.theta,
        P=record.P,
        K=record.K,
        U=U,
        rank=record.regression.rank,
        unknowns=record.regression.unknowns,
        change=relative_change(record.theta, previous_theta),
        data_seconds=data_seconds,
    )


#: A change that stops shrinking counts as settled when it is below this many epsilon_1.
NOISE_FLOOR_FACTOR = 100.0


def settled(
    change: float, previous_change: float, threshold: float, settings: TuningSettings
) -> bool:
    """Whether Theta has settled: it changed by less than ``threshold``, or it stopped
    shrinking below ``NOISE_FLOOR_FACTOR`` epsilon_1. Policy iteration converges
    quadratically, and each on-policy episode brings its own data error; once the
    changes stop shrinking they measure only that error, which more episodes of the same
    kind do not reduce."""
    if change < threshold:
        return True
    return change >= previous_change and change < NOISE_FLOOR_FACTOR * settings.feedback_tolerance


def known_form(drive: Drive, settings: TuningSettings, phi_pm: float) -> tuple[Array, Array]:
    """``(X, w)`` of the known-flux form at the session's operating point."""
    C, _, F, w = known_flux_form(drive.pole_pairs, settings.speed, settings.torque, phi_pm)
    X, _ = solutions_of_output_equation(C, F)
    return X, w
