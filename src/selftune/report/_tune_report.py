"""What ``selftune tune`` prints and writes: the controller a drive can run, how good the
data say it is, and what it does on the simulated drive (evaluation only).

Every number comes from the typed results (:class:`~selftune.tuning.TuningResult`, its
:class:`~selftune.learn.Quality`, :class:`TuningEvaluation`); nothing is recomputed here.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..core import cost_document, matrix_block
from ..learn import LearningProblem, PIEquivalent, pi_equivalent_or_reason
from ..model import SPMSM
from ..sim import DriveSettings
from ..tuning import TuningResult, TuningSettings
from ._documents import history_document
from ._drive_check import steady_torque_error
from ._evaluate import TuningEvaluation, learner_integral_weight

__all__ = [
    "HOT_RESISTANCE",
    "TorqueCheck",
    "drive_text",
    "torque_check",
    "tune_document",
    "tune_lines",
    "tuned_pi",
]

#: The resistance after tuning against which the torque error is checked again: +40%,
#: a winding about 100 K hotter (copper +0.39 %/K).
HOT_RESISTANCE = 1.4

_NAMES = {"1": "Algorithm 1", "2": "Algorithm 2", "3": "Algorithm 3", "offpolicy": "Off-policy"}


@dataclass(frozen=True)
class TorqueCheck:
    """The learned controller on the simulated drive (evaluation only).

    Attributes
    ----------
    steady_error : float
        ``(mean torque - T*) / T*`` in steady state, at the tuning temperature.
    hot_error : float
        The same after R_s rose by :data:`HOT_RESISTANCE` without re-tuning.
    """

    steady_error: float
    hot_error: float


def torque_check(
    motor: SPMSM, settings: TuningSettings, result: TuningResult, drive: DriveSettings | None
) -> TorqueCheck:
    """Run the learned controller on the simulated drive: steady torque error, cold and
    with R_s +40% (:func:`~._drive_check.steady_torque_error`).

    Parameters
    ----------
    motor : SPMSM
        The motor (nameplate values).
    settings : TuningSettings
        Speed, torque and sampling period.
    result : TuningResult
        The session's result (its law and its ``w``).
    drive : DriveSettings or None
        The drive it was tuned on (None: the ideal drive).
    """
    arguments = (motor, settings.speed, settings.h, result.law, result.w)
    return TorqueCheck(
        steady_error=steady_torque_error(*arguments, settings=drive, seed=settings.seed),
        hot_error=steady_torque_error(
            *arguments, settings=drive, resistance_factor=HOT_RESISTANCE, seed=settings.seed
        ),
    )


def drive_text(drive: DriveSettings | None) -> str:
    """The simulated drive in a few words.

    Parameters
    ----------
    drive : DriveSettings or None
        The drive (None: the ideal one).
    """
    if drive is None:
        return "the ideal drive (exact dq model, no delay)"
    parts = [f"{drive.input_delay}-sample delay", f"{drive.pwm} PWM"]
    if drive.dead_time:
        parts.append(f"{drive.dead_time * 1e6:g} us dead time")
    if drive.current_noise:
        parts.append(f"{drive.current_noise * 1e3:g} mA noise")
    if drive.adc_bits is not None:
        parts.append(f"{drive.adc_bits}-bit ADC")
    if drive.temperature_rise:
        parts.append(f"{drive.temperature_rise:g} K warmer")
    return "a realistic drive (" + ", ".join(parts) + ")"


def tuned_pi(
    motor: SPMSM, settings: TuningSettings, result: TuningResult
) -> tuple[PIEquivalent | None, str]:
    """The PI equivalent of a session's law on the plants it estimated
    (:func:`~selftune.learn.pi_equivalent_or_reason`), for the cost the session's learner
    optimized (the settings' Q, R and the learner's Q_i).

    Parameters
    ----------
    motor : SPMSM
        The motor (nameplate values: F of the integral weight's problem).
    settings : TuningSettings
        The session's cost.
    result : TuningResult
        The session's result.
    """
    law = result.law
    problem = LearningProblem(
        settings.Q, settings.R, C=law.C, F=law.F, integral_action=law.K_i is not None,
        integral_weight=learner_integral_weight(motor, settings) if law.K_i is not None else None,
    )  # fmt: skip
    if result.target == "digital":
        return pi_equivalent_or_reason(law, problem, result.judged, "digital")
    return pi_equivalent_or_reason(law, problem, result.judged, "continuous")


def tune_lines(
    source: str,
    result: TuningResult,
    evaluation: TuningEvaluation,
    torque: TorqueCheck,
    drive: DriveSettings | None,
    pi: tuple[PIEquivalent | None, str] | None = None,
) -> list[str]:
    """The report ``selftune tune`` prints.

    Parameters
    ----------
    source : str
        The motor file's name.
    result : TuningResult
        The session's result.
    evaluation : TuningEvaluation
        Its comparison with the model-based optimum.
    torque : TorqueCheck
        Its steady torque on the simulated drive.
    drive : DriveSettings or None
        The drive it was tuned on.
    pi : (PIEquivalent or None, str), optional
        Its PI equivalent, or why there is none (:func:`tuned_pi`); appended.
    """
    law = result.law
    target = "digital" if result.target == "digital" else "continuous (the paper's)"
    servo = " with integral action" if law.K_i is not None else ""
    lines = [
        f"{_NAMES[result.algorithm]} on {source}, {drive_text(drive)}: {target} "
        f"controller{servo}, from {result.data_seconds * 1e3:.3g} ms of motor data",
        "",
        "the controller (K's columns: " + ", ".join(law.state) + "):",
        f"  {law.equations()}",
        *matrix_block("K", law.K, ["u_d", "u_q"], list(law.state[: law.K.shape[1]])),
    ]
    if law.K_i is not None:
        lines += matrix_block("K_i", law.K_i, ["u_d", "u_q"], ["z_d", "z_q"])
    lines += matrix_block("U", law.U, ["u_d", "u_q"], ["w1", "w2"])
    lines += ["", *result.quality.lines(), ""]
    lines.append(
        f"on the simulated drive: steady torque error {torque.steady_error:+.3%}; after R_s "
        f"+{HOT_RESISTANCE - 1:.0%} without re-tuning {torque.hot_error:+.3%}"
    )
    integral = ""
    if result.law.K_i is not None:
        integral = f", ||K_i - K_i*|| / ||K_i*|| = {evaluation.K_i_error:.2e}"
    lines.append(
        f"against the model-based optimum of the same loop: ||K - K*|| / ||K*|| = "
        f"{evaluation.K_error:.2e}{integral}, ||U - U*|| / ||U*|| = "
        f"{evaluation.U_error:.2e}, excess cost {evaluation.excess_cost:.2e}"
    )
    if result.identified:
        identified = result.identified
        lines.append(
            f"identified phi_pm = {identified['phi_pm']:.6g} +- {identified['phi_pm_se']:.2g} Wb"
            + (
                f", dead-time voltage {identified['dead_time_voltage']:.3g} V per phase"
                if "dead_time_voltage" in identified
                else ""
            )
        )
    lines += list(result.notes)
    if pi is not None:
        lines += ["", *(pi[0].lines(["u_d", "u_q"], ["i_d", "i_q"]) if pi[0] else [])]
        lines += [] if pi[0] else [f"no PI equivalent: {pi[1]}"]
    return lines


def tune_document(
    motor: SPMSM,
    settings: TuningSettings,
    result: TuningResult,
    evaluation: TuningEvaluation,
    torque: TorqueCheck,
    pi: PIEquivalent | None = None,
) -> dict[str, Any]:
    """The JSON ``selftune tune --json`` writes (every number of the report and more),
    with the whole cost the controller optimized (``cost``: Q, R and Q_i; ``h``;
    ``input_delay``) and its PI equivalent (null without one).

    Parameters
    ----------
    motor : SPMSM
        The motor (nameplate values).
    settings : TuningSettings
        The session's settings.
    result : TuningResult
        The session's result.
    evaluation : TuningEvaluation
        Its comparison with the model-based optimum.
    torque : TorqueCheck
        Its steady torque on the simulated drive.
    pi : PIEquivalent, optional
        Its PI equivalent (:func:`tuned_pi`).
    """
    optimum = evaluation.optimum
    best = optimum.law
    weight = learner_integral_weight(motor, settings) if result.law.K_i is not None else None
    return {
        "algorithm": result.algorithm,
        "target": result.target,
        "integral_action": result.law.K_i is not None,
        "control_law": result.law.document(),
        "learned": {"P": result.P, "B": result.B, "theta": result.theta, "w": result.w},
        "quality": result.quality,
        "identified": result.identified,
        "data_seconds": result.data_seconds,
        "model_based": best.document(),
        "K_relative_error": evaluation.K_error,
        "K_i_relative_error": evaluation.K_i_error,
        "U_relative_error": evaluation.U_error,
        "theta_relative_error": evaluation.final_theta_error,
        "excess_cost": evaluation.excess_cost,
        "steady_torque_error": torque.steady_error,
        "steady_torque_error_hot": torque.hot_error,
        "hot_resistance_factor": HOT_RESISTANCE,
        "motor": motor,
        "settings": settings,
        "notes": list(result.notes),
        "history": history_document(result, evaluation),
        "cost": cost_document(settings.Q, settings.R, weight),
        "h": settings.h,
        "input_delay": result.law.history,
        "pi_equivalent": None if pi is None else pi.document(),
    }
