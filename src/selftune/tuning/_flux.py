"""Algorithm 3's first step: the magnet flux, told apart from the inverter's voltage error.

The back-EMF ``w_e phi_pm`` acts on the q axis as a constant voltage. At one speed and
one current direction, an inverter's dead-time voltage (about ``-(4/pi) v`` along the
current, ``v = t_d f_sw V_dc``) is a constant voltage too, and the two are confounded:
the paper's no-load step, and any fit of a single operating point, then finds the flux
a few per cent off. Here they are told apart by the experiment and the model:

- the torque reference steps through :data:`~._knowledge.STEP_LEVELS` (positive and
  negative): the dead-time voltage follows the current's sign, the back-EMF does not;
- the exact discrete model of the log is fitted by output error
  (:func:`selftune.learn.gather_evidence`), with the dead time as an input of its own
  (the phase currents' signs, ``settings.dead_time``); with ``w_1 = w_e phi_guess`` the
  assumed back-EMF, the model's ``Bd^-1 Ed`` column of ``w_1`` is ``phi_pm / phi_guess``
  times that of a motor whose back-EMF is the assumed one (:func:`_hold_factor`), so
  ``phi_pm = phi_guess |(Bd^-1 Ed)_1| / hold factor``, with a standard error from the
  fit's covariance. The factor is 1 for a dq hold (then ``Bd^-1 Ed = B^-1 D``); a PWM
  inverter holds its voltage in the stationary frame while the back-EMF is constant in
  dq, and then it is about ``sin(w_e h / 2) / (w_e h / 2)``: ignored, the flux came out
  ``(w_e h)^2 / 24`` low (0.26% at 2,500 rad/s and 10 kHz, fifty standard errors).

The controller of the step is K0 with the assumed back-EMF fed forward (``u_q += w_1``),
so that the currents follow the steps; nothing else of the guess is used.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core import Array, ControlLaw
from ..errors import ConvergenceError, ExcitationError, InputError
from ..learn import (
    LearningOptions,
    OutputErrorFit,
    SpmsmStructure,
    dead_time_voltage,
    gather_evidence,
)
from ..sim import held, uniform
from ._drive import Drive
from ._episodes import checked, known_form
from ._knowledge import STEP_DWELL, STEP_LEVELS, reference_perturbation
from ._learning import learning_options, learning_problem
from ._offpolicy import BACK_EMF_FEEDFORWARD
from ._settings import TuningSettings

__all__ = ["FLUX_PRECISION", "FluxEstimate", "identify_flux"]

#: The largest relative standard error of the identified flux accepted (a tenth of the
#: 0.5% a torque loop can live with, as the flux scales the torque reference).
FLUX_PRECISION = 0.0025


@dataclass(frozen=True)
class FluxEstimate:
    """The identified magnet flux and the inverter's voltage error.

    Attributes
    ----------
    phi_pm : float
        Magnet flux linkage, Wb.
    standard_error : float
        Its standard error, Wb.
    dead_time_voltage : float or None
        ``v = t_d f_sw V_dc`` per phase, V (None unless modelled).
    seconds : float
        Motor data used, s.
    """

    phi_pm: float
    standard_error: float
    dead_time_voltage: float | None
    seconds: float

    def as_dict(self) -> dict[str, float]:
        """``{"phi_pm", "phi_pm_se"}`` (Wb) and ``"dead_time_voltage"`` (V) if modelled."""
        values = {"phi_pm": self.phi_pm, "phi_pm_se": self.standard_error}
        if self.dead_time_voltage is not None:
            values["dead_time_voltage"] = self.dead_time_voltage
        return values


def _ratio(fit: OutputErrorFit, parameters: Array) -> float:
    """``|(Bd^-1 Ed)_1|``: the back-EMF per unit of the assumed one."""
    _, Bd, Ed = fit.matrices(parameters)
    return float(np.linalg.norm(np.linalg.solve(Bd, Ed[:, 0])))


def _hold_factor(fit: OutputErrorFit, electrical_speed: float, drive: Drive) -> float:
    """``|(Bd^-1 Ed)_1|`` of a surface PMSM with the fit's R_s and L_s whose back-EMF is
    the assumed one (``kappa = 1``), on the drive's hold (:class:`~selftune.learn.
    SpmsmStructure`): what the ratio of the true motor is, per unit of ``phi_pm /
    phi_guess``. It depends on ``w_e h`` and hardly on R_s and L_s (to second order in
    ``R_s h / L_s``), so their rough values from the unstructured fit do."""
    structure = SpmsmStructure(electrical_speed, fit.model.h, hold=drive.loop.hold)
    R_s, L_s = structure.initial(fit.model)[:2]
    _, Bd, Ed = structure(np.array([R_s, L_s, 1.0]))
    return float(np.linalg.norm(np.linalg.solve(Bd, Ed[:, 0])))


def _ratio_and_error(fit: OutputErrorFit) -> tuple[float, float, float]:
    """The ratio, its standard error (delta method) and the q component's sign."""
    theta = fit.parameters
    base = _ratio(fit, theta)
    deviations = np.sqrt(np.maximum(np.diag(fit.parameter_covariance), 0.0))
    gradient = np.zeros_like(theta)
    for index in range(theta.shape[0]):
        step = max(deviations[index], 1e-9 * max(abs(float(theta[index])), 1e-12))
        shifted = theta.copy()
        shifted[index] += step
        gradient[index] = (_ratio(fit, shifted) - base) / step
    variance = float(gradient @ fit.parameter_covariance @ gradient)
    _, Bd, Ed = fit.matrices(theta)
    q_part = -float(np.linalg.solve(Bd, Ed[:, 0])[1])
    return base, float(np.sqrt(max(variance, 0.0))), q_part


def identify_flux(drive: Drive, settings: TuningSettings, phi_guess: float) -> FluxEstimate:
    """Identify the magnet flux from one stepping episode (see the module docstring).

    Parameters
    ----------
    drive : Drive
        The drive.
    settings : TuningSettings
        Operating point, K0, exploration, ``flux_length`` and ``dead_time``.
    phi_guess : float
        A rough flux (e.g. the nameplate's), Wb.

    Returns
    -------
    FluxEstimate

    Raises
    ------
    ExcitationError
        If the flux's standard error exceeds :data:`FLUX_PRECISION` (the message says how
        much longer the step should be).
    ConsistencyError
        If the model cannot explain the log (e.g. dead time not modelled).
    ConvergenceError
        If the identified flux is not physical, or the plant is unstable.
    """
    cycle = len(STEP_LEVELS) * STEP_DWELL
    if settings.flux_length < cycle * (1.0 - 1e-9):
        raise InputError(
            f"flux_length: {settings.flux_length:g} s is shorter than one cycle of the "
            f"torque steps ({cycle:g} s): the current would not reverse, and the dead-time "
            "voltage could not be told from the back-EMF"
        )
    X, w = known_form(drive, settings, phi_guess)

    def stepping(t: Array) -> Array:
        return w + reference_perturbation(t, "steps", settings.torque)

    samples = max(2, round(settings.flux_length / settings.h))
    episode = drive.run(
        ControlLaw.regulator(settings.K0, X, BACK_EMF_FEEDFORWARD),
        held(stepping),
        num_samples=samples,
        exploration=uniform(settings.exploration),
        seed=settings.seed + 7919,
        assumed_flux=phi_guess,
    )
    checked(episode, settings.K0, settings)
    options: LearningOptions = learning_options(drive, settings, target="digital")
    evidence = gather_evidence([episode], learning_problem(drive, settings, phi_guess), options)
    if evidence.fit is None:
        raise ConvergenceError(
            "Algorithm 3, flux step: the identified plant is not stable, so its back-EMF "
            "cannot be read off an output-error model; check the speed and K0"
        )
    ratio, error, q_part = _ratio_and_error(evidence.fit)
    factor = _hold_factor(evidence.fit, drive.pole_pairs * settings.speed, drive)
    phi_pm, phi_se = phi_guess * ratio / factor, phi_guess * error / factor
    if not (np.isfinite(phi_pm) and q_part > 0.0):
        raise ConvergenceError(
            f"Algorithm 3, flux step: the back-EMF the data show is not physical "
            f"({phi_pm:.4g} Wb, on the wrong axis or of the wrong sign); check the speed, "
            "the pole pairs and the sign of the logged voltages"
        )
    if phi_se > FLUX_PRECISION * phi_pm:
        needed = episode.duration * (phi_se / (FLUX_PRECISION * phi_pm)) ** 2
        raise ExcitationError(
            f"Algorithm 3, flux step: the flux's standard error is {phi_se / phi_pm:.2%} "
            f"(at most {FLUX_PRECISION:.2%}) from {episode.duration:.3g} s; about "
            f"{needed:.2g} s (flux_length) or more exploration would do"
        )
    return FluxEstimate(phi_pm, phi_se, dead_time_voltage(evidence), float(episode.duration))
