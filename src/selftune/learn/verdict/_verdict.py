"""The verdict's numbers: the target's optimum on the fitted model, its standard errors,
and the quality of a learned law (see :mod:`._quality` for what they mean and
:func:`~._learner.learn_controller` for where they are used)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from ...core import Array, ControlLaw
from .._problem import LearningOptions, LearningProblem
from ..evidence._discrete_model import DiscreteModel
from ..evidence._evidence import INFLATION_LIMIT, Evidence
from ..learners._identify import design_continuous, design_digital
from ._quality import (
    PLAUSIBLE_MODELS,
    BlockErrors,
    MotorEstimate,
    Quality,
    block_errors,
    closed_loop_radii,
    closed_loop_radius,
    relative_size,
    standard_errors,
)

__all__ = [
    "ROUNDING_FLOOR",
    "ModelErrors",
    "dead_time_voltage",
    "design_target",
    "model_errors",
    "plausible_models",
    "plausible_plants",
    "relative_size",
    "verdict",
    "without_extra",
]

#: The smallest standard error stated, relative to the largest entry: the learners are
#: exact to about this on noise-free data, not better.
ROUNDING_FLOOR = 1e-10


def without_extra(law: ControlLaw, q: int) -> ControlLaw:
    """The law without the feedforward of the appended direction channels."""
    if law.X.shape[1] == q:
        return law
    return ControlLaw(
        law.K, law.X[:, :q], law.U[:, :q], history=law.history, K_i=law.K_i,
        C=law.C, F=None if law.F is None else law.F[:, :q], h=law.h,
    )  # fmt: skip


def design_target(
    model: DiscreteModel, problem: LearningProblem, options: LearningOptions
) -> tuple[ControlLaw, Array, Array]:
    """The optimum of the options' target on a model (identify-then-design)."""
    if options.target == "digital":
        design = design_digital(model, problem, options.input_delay)
    else:
        design = design_continuous(model, problem)
    assert design.B is not None  # identify-then-design estimates it
    return design.law, design.P, design.B


def _outputs(law: ControlLaw, P: Array) -> tuple[Array, Array, Array]:
    K = law.K if law.K_i is None else np.hstack([law.K, law.K_i])
    return K, law.U, P


@dataclass(frozen=True)
class ModelErrors:
    """The target's optimum on the fitted model and its standard errors, known before any
    learner runs. ``K`` is ``[K, K_i]``; its first ``feedback_width`` columns are the
    law's K (the currents' and the delayed voltages' feedback)."""

    K: Array
    U: Array
    P: Array
    K_se: Array
    U_se: Array
    P_se: Array
    notes: tuple[str, ...]
    feedback_width: int
    optimum_radius: float

    @property
    def relative(self) -> BlockErrors:
        """The relative standard errors of K, K_i and U."""
        return block_errors((self.K_se, self.K), (self.U_se, self.U), self.feedback_width)


def model_errors(
    evidence: Evidence, problems: tuple[LearningProblem, int], options: LearningOptions
) -> ModelErrors:
    """Standard errors of the target's optimum from the output-error model's covariance."""
    problem, q = problems
    fit = evidence.fit
    model = evidence.model

    def design(candidate: DiscreteModel) -> tuple[Array, Array, Array]:
        learned, P, _ = design_target(candidate, problem, options)
        return _outputs(without_extra(learned, q), P)

    optimum, P, _ = design_target(model, problem, options)
    K, U, P = _outputs(without_extra(optimum, q), P)
    width = optimum.K.shape[1]
    radius = closed_loop_radius(model, optimum, options.input_delay)
    if fit is None:
        assert model.covariance is not None
        note = (
            "the plant is not stable, so no output-error model: the least-squares model and "
            "its standard errors are used, which measurement noise on the states biases"
        )
        errors = standard_errors(
            design, model.matrices, model.parameters, model.covariance, model.h
        )
        return ModelErrors(
            K, U, P, *errors, notes=(note,), feedback_width=width, optimum_radius=radius
        )
    K_se, U_se, P_se = standard_errors(
        design, fit.matrices, fit.parameters, fit.parameter_covariance, model.h
    )
    return ModelErrors(
        K, U, P, K_se, U_se, P_se, notes=(), feedback_width=width, optimum_radius=radius
    )


def _floored(se: Array, value: Array) -> Array:
    """Standard errors no smaller than the rounding floor of the block's size."""
    return np.maximum(se, ROUNDING_FLOOR * float(np.max(np.abs(value), initial=0.0)))


def verdict(
    law: ControlLaw, errors: ModelErrors, evidence: Evidence, options: LearningOptions
) -> tuple[Quality, Array, list[DiscreteModel]]:
    """The quality of ``law``, the spectral radii of its loop on plausible models, and
    those models (the fitted one first)."""
    model = evidence.model
    notes = list(errors.notes)
    exact = evidence.consistency.exact  # rounding only: no test of the errors applies
    fit = evidence.fit
    if evidence.sign_correction is not None:
        steps = (
            ""
            if evidence.adc_step is None
            else f" (their phase currents rounded to the ADC's {evidence.adc_step:.3g} A steps "
            "the log shows)"
        )
        notes.append(
            "the dead-time model's bias from the currents' signs near zero (where the noise "
            f"decides them) was measured on simulations of the fitted model{steps} and "
            "removed; the standard errors include the correction's own size"
        )
    if evidence.next_sample_signs:
        unheld = (
            ""
            if evidence.pulse_shift is not None
            else "; on a carrier PWM inverter its standard errors leave out the shift its "
            "pulses leave unless the DC bus is given ([learning] dc_voltage, V)"
        )
        notes.append(
            "the dead-time model took the phase signs of "
            f"{evidence.next_sample_signs} samples as the next sample shows them (near zero "
            "current the noise decides the measured ones), and the parameters are that "
            f"fit's{unheld}"
        )
    if (
        evidence.sign_correction is None and fit is not None
        and fit.correlation_inflation > INFLATION_LIMIT and not exact
    ):  # fmt: skip
        notes.append(
            f"the model misses part of the data: its output errors are correlated in time "
            f"({fit.correlation_inflation:.3g} times the variance white noise "
            "gives); the standard errors include that, a bias it may cause they cannot show"
        )
    K_learned = _outputs(law, errors.P)[0]
    K_se, U_se = errors.K_se, errors.U_se
    if options.method == "adp" and options.target == "continuous":
        # the continuous data equation's quadrature error: no noise explains it
        K_se = np.sqrt(K_se**2 + (K_learned - errors.K) ** 2)
        U_se = np.sqrt(U_se**2 + (law.U - errors.U) ** 2)
        notes.append(
            "the standard errors include the O(h^2) quadrature error of the continuous data "
            "equation, measured against the continuous optimum of the fitted model"
        )
    # rounding: no learner is exact beyond about 1e-10 of each block's size
    width = law.K.shape[1]
    K_se = np.hstack([_floored(K_se[:, :width], K_learned[:, :width]),
                      _floored(K_se[:, width:], K_learned[:, width:])])  # fmt: skip
    U_se = _floored(U_se, law.U)
    models = plausible_plants(evidence)
    radii = closed_loop_radii(models, law, options.input_delay)
    relative = block_errors((K_se, K_learned), (U_se, law.U), width)
    alignment = evidence.alignment
    quality = Quality(
        shift=alignment.shift,
        detected_shift=alignment.detected_shift,
        alignment_ratio=alignment.ratio,
        noise_rms=evidence.model_noise,
        residual_rms=model.residual_rms,
        consistency_statistic=evidence.consistency.statistic,
        consistency_threshold=evidence.consistency.threshold,
        consistency_exact=evidence.consistency.exact,
        noise_handling=options.noise if options.method == "adp" else "output error",
        K_se=K_se,
        U_se=U_se,
        P_se=errors.P_se if options.method == "identify" else np.full_like(errors.P, np.nan),
        K_relative_se=relative.K,
        K_i_relative_se=relative.K_i,
        U_relative_se=relative.U,
        stability_margin=1.0 - float(radii[0]),
        voltage_error=dead_time_voltage(evidence),
        log_precision=evidence.precision,
        notes=tuple(notes),
        motor=motor_estimate(evidence),
    )
    return quality, radii, models


def plausible_plants(evidence: Evidence) -> list[DiscreteModel]:
    """The plants the verdict judges a learned loop on: the fitted model, then
    :func:`plausible_models` from the output-error fit's covariance (the fitted model
    alone without a fit).

    Parameters
    ----------
    evidence : Evidence
        The logs' evidence.
    """
    fit = evidence.fit
    if fit is None:
        return [evidence.model]
    return plausible_models(evidence.model, fit.matrices, fit.parameters, fit.parameter_covariance)


def plausible_models(
    model: DiscreteModel,
    matrices: Callable[[Array], tuple[Array, Array, Array]],
    parameters: Array,
    covariance: Array,
    stacked: Callable[[Array], tuple[Array, Array, Array]] | None = None,
) -> list[DiscreteModel]:
    """The model, then :data:`PLAUSIBLE_MODELS` models drawn from its parameters'
    uncertainty (a fixed seed: a verdict is reproducible).

    Parameters
    ----------
    model : DiscreteModel
        The fitted model (its h and statistics are kept by the draws).
    matrices : callable
        The parameters' map to ``(Ad, Bd, Ed)``.
    parameters : ndarray, shape (p,)
        The fitted parameters.
    covariance : ndarray, shape (p, p)
        Their covariance.
    stacked : callable, optional
        The same map for a stack of parameters (rows) at once, to stacks of matrices
        (:meth:`~selftune.learn.SpmsmStructure.stack`); default: ``matrices`` draw by draw.
    """
    rng = np.random.default_rng(0)
    draws = rng.multivariate_normal(parameters, covariance, size=PLAUSIBLE_MODELS, method="svd")
    drawn = (
        zip(*stacked(draws), strict=True)
        if stacked is not None
        else (matrices(theta) for theta in draws)
    )
    return [model] + [replace(model, Ad=Ad, Bd=Bd, Ed=Ed) for Ad, Bd, Ed in drawn]


def motor_estimate(evidence: Evidence) -> MotorEstimate | None:
    """The structured fit's R_s, L_s, flux (and dead-time voltage) with their standard
    errors; None without a structured fit.

    The fit's third parameter is the back-EMF ratio ``kappa``; the flux is ``kappa w_1 /
    w_e`` with ``w_1 = p speed phi_assumed`` the logs' first reference channel (its mean:
    the speed is held) and ``w_e`` the structure's electrical speed.

    Parameters
    ----------
    evidence : Evidence
        The logs' evidence.
    """
    fit = evidence.fit
    if fit is None or fit.structure is None:
        return None
    se = np.sqrt(np.maximum(np.diag(fit.parameter_covariance), 0.0))
    names = fit.structure.names(fit.structure.dead_time)
    values = dict(zip(names, fit.parameters.tolist(), strict=True))
    errors = dict(zip(names, se.tolist(), strict=True))
    back_emf = np.concatenate([e.w[:, 0] for e in evidence.episodes if e.w is not None])
    flux = float(np.mean(back_emf)) / fit.structure.electrical_speed
    return MotorEstimate(
        R_s=values["R_s"], R_s_se=errors["R_s"], L_s=values.get("L_s"), L_s_se=errors.get("L_s"),
        phi_pm=values["kappa"] * flux, phi_pm_se=errors["kappa"] * abs(flux),
        v=values.get("v"), v_se=errors.get("v"),
        L_d=values.get("L_d"), L_d_se=errors.get("L_d"), L_q=values.get("L_q"),
        L_q_se=errors.get("L_q"), L_dq=values.get("L_dq"), L_dq_se=errors.get("L_dq"),
        phi_q=None if "kappa_q" not in values else values["kappa_q"] * flux,
        phi_q_se=None if "kappa_q" not in errors else errors["kappa_q"] * abs(flux),
    )  # fmt: skip


def dead_time_voltage(evidence: Evidence) -> float | None:
    """The dead-time voltage ``v = t_d f_sw V_dc`` per phase, V, of the fitted model (the
    gain of the phase signs' channels is ``-v Bd``); None unless modelled.

    Parameters
    ----------
    evidence : Evidence
        The logs' evidence (with ``dead_time``).
    """
    if not evidence.extra:
        return None
    model = evidence.model
    gain = model.Ed[:, model.Ed.shape[1] - evidence.extra :]
    return -float(np.trace(np.linalg.solve(model.Bd, gain))) / evidence.extra
