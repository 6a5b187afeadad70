"""The off-policy variant: one batch of motor data, reused for every policy-iteration step."""

from __future__ import annotations

import numpy as np

from ..core import Array, unpack_theta
from ..learn import IterationRecord, feedforward, learn_output_regulation
from ..sim import held, uniform
from ._drive import Drive
from ._episodes import checked, iteration_record, known_form
from ._knowledge import known_flux_form, reference_perturbation
from ._results import TuningIteration, TuningResult
from ._settings import TuningSettings

__all__ = ["offpolicy"]


def offpolicy(drive: Drive, settings: TuningSettings, phi_pm: float) -> TuningResult:
    """The off-policy variant: one batch of ``episode_length`` seconds, reused throughout.

    The batch is run once under ``K0`` with exploration on the inputs and the perturbed
    reference together; :func:`~selftune.learn.learn_output_regulation` (customized)
    then iterates on it (at least 50 steps allowed) to its 1e-9 relative tolerance.

    Parameters
    ----------
    drive : Drive
        The drive (e.g. :class:`selftune.sim.SimulatedDrive`).
    settings : TuningSettings
        The session's settings.
    phi_pm : float
        The known magnet flux, Wb.

    Returns
    -------
    TuningResult
    """
    X, w = known_form(drive, settings, phi_pm)
    C, E, F, _ = known_flux_form(drive.pole_pairs, settings.speed, settings.torque, phi_pm)
    kind = settings.perturbation

    def perturbed(t: Array) -> Array:
        return w + reference_perturbation(t, kind)

    batch = drive.run(
        settings.K0,
        X,
        np.zeros((2, 2)),
        held(perturbed),
        num_samples=settings.samples_per_episode,
        exploration=uniform(settings.exploration),
        seed=settings.seed,
        assumed_flux=phi_pm,
    )
    checked(batch, settings.K0, settings)
    learned = learn_output_regulation(
        batch,
        C,
        E,
        F,
        settings.Q,
        settings.R,
        settings.K0,
        interval=settings.regression_interval(),
        max_iterations=max(settings.max_iterations, 50),
        method="customized",
    )
    return TuningResult(
        algorithm="offpolicy",
        K=learned.K,
        P=learned.P,
        X=learned.X,
        U=learned.U,
        theta=learned.theta,
        B=learned.B,
        w=w,
        history=_history(learned.history, settings, batch.duration),
        data_seconds=batch.duration,
        converged=learned.converged,
        feedforward_learned=True,
    )


def _history(
    records: tuple[IterationRecord, ...], settings: TuningSettings, seconds: float
) -> tuple[TuningIteration, ...]:
    """The policy-iteration steps as iterations, with the policy each step improved on."""
    history: list[TuningIteration] = []
    previous_theta: Array | None = None
    K_applied = settings.K0
    U_applied = np.zeros((2, 2))
    for record in records:
        P, K_next, M = unpack_theta(record.theta, 2, 2, 2)
        U = feedforward(P, K_next, M, settings.R)
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
        K_applied, U_applied = K_next, U
    return tuple(history)
