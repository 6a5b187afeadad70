"""The off-policy variant: one batch of motor data, reused for every policy-iteration step."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..core import Array, ControlLaw
from ..errors import TooLittleData
from ..learn import LearnedController, learn_controller
from ..sim import held, uniform
from ._drive import Drive
from ._episodes import checked, known_form
from ._knowledge import reference_perturbation
from ._learning import check_drive, from_learned, learning_options, learning_problem
from ._results import TuningResult
from ._settings import TuningSettings

__all__ = ["BACK_EMF_FEEDFORWARD", "LONGER_BATCHES", "LONGEST_BATCH_FACTOR", "offpolicy"]

#: When the learner finds the batch too short for its noise (TooLittleData), the session
#: runs a longer batch of the length it asks for (with a quarter more), at most
#: :data:`LONGER_BATCHES` times and up to this many times ``episode_length``; beyond, the
#: refusal stands. (The length it names assumes the errors fall as 1/sqrt(T); a part that
#: does not, such as the dead-time model's sensitivity, can need a second one.)
LONGEST_BATCH_FACTOR = 10.0

#: How many longer batches a session runs on TooLittleData (see LONGEST_BATCH_FACTOR).
LONGER_BATCHES = 2

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

    notes: tuple[str, ...] = ()
    samples = settings.samples_per_episode
    for batch_number in range(1, LONGER_BATCHES + 2):
        try:
            learned, seconds = learned_from(samples)
            break
        except TooLittleData as refusal:
            longer = int(np.ceil(1.25 * refusal.needed_seconds / settings.h))
            cap = LONGEST_BATCH_FACTOR * settings.samples_per_episode
            if batch_number > LONGER_BATCHES or not samples < longer <= cap:
                raise
            K_se, U_se = refusal.relative_se
            notes += (
                f"the {samples * settings.h:.3g} s batch was too short for its noise "
                f"(standard errors of K {K_se:.2%}, of U {U_se:.2%}); a "
                f"{longer * settings.h:.3g} s batch was run, as the learner asked",
            )
            samples = longer
    result = from_learned(algorithm, learned, w, seconds, settings, identified)
    return replace(result, notes=(*result.notes, *notes))
