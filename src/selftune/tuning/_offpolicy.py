"""The off-policy variant: one batch of motor data, reused for every policy-iteration step."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..core import Array, ControlLaw
from ..learn import LearnedController, learn_controller
from ..sim import held, uniform
from ._drive import Drive
from ._episodes import checked, known_form
from ._knowledge import reference_perturbation
from ._learning import (
    LONGER_BATCHES,
    LONGEST_BATCH_FACTOR,
    check_drive,
    from_learned,
    learned_at_length,
    learning_options,
    learning_problem,
)
from ._results import TuningResult
from ._settings import TuningSettings

__all__ = ["BACK_EMF_FEEDFORWARD", "LONGER_BATCHES", "LONGEST_BATCH_FACTOR", "offpolicy"]

#: The feedforward of the batch's controller: ``u_q += w_1``, the assumed back-EMF.
BACK_EMF_FEEDFORWARD = np.array([[0.0, 0.0], [1.0, 0.0]])
BACK_EMF_FEEDFORWARD.setflags(write=False)


def offpolicy(
    drive: Drive,
    settings: TuningSettings,
    phi_pm: float,
    *,
    identified: dict[str, float] | None = None,
    algorithm: str = "offpolicy",
) -> TuningResult:
    """The off-policy variant: one batch of ``episode_length`` seconds, reused throughout.

    The batch is run once under ``K0`` with the assumed back-EMF fed forward
    (``u_q += w_1``, what a drive with a known flux does; without it a low-resistance
    motor's currents are driven far by the back-EMF), with exploration on the inputs and
    the perturbed reference together; :func:`~selftune.learn.learn_controller` then learns the
    controller of ``settings.target`` from it (with integral action if asked), with its
    verdict: the log's alignment with the drive's delay, noise handled by output error,
    the consistency test, standard errors and a stability margin.

    Parameters
    ----------
    drive : Drive
        The drive (e.g. :class:`selftune.sim.SimulatedDrive`).
    settings : TuningSettings
        The session's settings.
    phi_pm : float
        The magnet flux the controller assumes (known, or identified), Wb.
    identified : dict, optional
        What an earlier step identified (Algorithm 3), kept in the result.
    algorithm : str
        The result's algorithm name.

    Returns
    -------
    TuningResult

    Raises
    ------
    ConsistencyError, ExcitationError, ConvergenceError
        When the data do not support a controller (the message says why).
    """
    check_drive(drive, settings)
    X, w = known_form(drive, settings, phi_pm)
    kind = settings.perturbation

    def perturbed(t: Array) -> Array:
        return w + reference_perturbation(t, kind, settings.torque)

    def learned_from(samples: int) -> tuple[LearnedController, float]:
        batch = drive.run(
            ControlLaw.regulator(settings.K0, X, BACK_EMF_FEEDFORWARD),
            held(perturbed),
            num_samples=samples,
            exploration=uniform(settings.exploration),
            seed=settings.seed,
            assumed_flux=phi_pm,
        )
        checked(batch, settings.K0, settings)
        problem = learning_problem(drive, settings, phi_pm)
        options = learning_options(drive, settings)
        return learn_controller(batch, problem, settings.K0, options), batch.duration

    (learned, seconds), _, notes = learned_at_length(
        learned_from, settings.samples_per_episode, settings.h
    )
    result = from_learned(algorithm, learned, w, seconds, settings, identified)
    return replace(result, notes=(*result.notes, *notes))
