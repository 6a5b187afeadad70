"""What ``selftune tune`` prints and writes for an interior PM motor: the identified motor,
the MTPA references, the law, its verdict, the true torque, and the law against the
model-based digital optimum of the same loop (evaluation only)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core import cost_document, matrix_block
from ..model import IPMSM, ModelBasedSolution, solve_digital_regulation
from ..sim import DriveSettings
from ..tuning import TuningSettings
from ..tuning._interior import InteriorCommissioning
from ._digital_evaluation import feedback_excess_cost, true_motor
from ._evaluate import block_error
from ._tune_report import drive_text

__all__ = ["InteriorEvaluation", "evaluate_interior", "interior_document", "interior_lines"]


@dataclass(frozen=True)
class InteriorEvaluation:
    """A commissioned interior motor against the truth (evaluation only).

    Attributes
    ----------
    optimum : ModelBasedSolution
        The digital optimum of the true (heated) motor's sampled loop, same cost.
    K_error, K_i_error : float
        ``||K - K*|| / ||K*||`` and the same of K_i (NaN without integral action).
    excess_cost : float
        The learned feedback's cost over the optimum's for the torque step, minus 1.
    parameter_errors : dict of str to float
        Each identified parameter's relative error against the true (heated) motor.
    """

    optimum: ModelBasedSolution
    K_error: float
    K_i_error: float
    excess_cost: float
    parameter_errors: dict[str, float]


#: The identified parameters and their units.
_PARAMETERS = (("R_s", "ohm"), ("L_d", "H"), ("L_q", "H"), ("phi_pm", "Wb"))


def evaluate_interior(
    result: InteriorCommissioning, motor: IPMSM, settings: TuningSettings, drive: DriveSettings
) -> InteriorEvaluation:
    """``result`` against the true motor's digital optimum (same hold, delay and cost).

    Parameters
    ----------
    result : InteriorCommissioning
        The commissioning.
    motor : IPMSM
        The true motor (nameplate values; the drive heats it).
    settings : TuningSettings
        Operating point and cost.
    drive : DriveSettings
        The drive.
    """
    truth = true_motor(motor, drive)
    law = result.learned.law
    optimum = solve_digital_regulation(
        truth.regulation_problem(settings.speed), settings.Q, settings.R, settings.h,
        input_delay=law.history, integral_weight=result.integral_weight,
        plant=truth.sampled_plant(settings.speed, settings.h, drive.voltage_hold),
    )  # fmt: skip
    w = truth.exogenous(settings.speed, settings.torque)
    errors = {
        name: float(getattr(result.motor, name) / getattr(truth, name) - 1.0)
        for name, _ in _PARAMETERS
    }
    return InteriorEvaluation(
        optimum=optimum,
        K_error=block_error(law.K, optimum.law.K),
        K_i_error=block_error(law.K_i, optimum.law.K_i),
        excess_cost=feedback_excess_cost(optimum, law, w),
        parameter_errors=errors,
    )


def interior_lines(
    source: str,
    result: InteriorCommissioning,
    evaluation: InteriorEvaluation,
    drive: DriveSettings,
) -> list[str]:
    """The report ``selftune tune`` prints for an interior motor.

    Parameters
    ----------
    source : str
        The motor file's name.
    result : InteriorCommissioning
        The commissioning.
    evaluation : InteriorEvaluation
        Its comparison with the truth.
    drive : DriveSettings
        The drive it ran on.
    """
    law = result.learned.law
    servo = " with integral action" if law.K_i is not None else ""
    lines = [
        f"Interior PM motor commissioned on {source}, {drive_text(drive)}: digital "
        f"controller{servo}, identify-then-design from {result.data_seconds * 1e3:.3g} ms "
        "of motor data",
        *(f"  note: {note}" for note in result.notes),
        "",
    ]
    i_d, i_q = result.references
    lines += [
        f"MTPA of the identified motor at T* = {result.torque:g} N m: i_d* = {i_d:.5g} A, "
        f"i_q* = {i_q:.5g} A",
        "",
        "the controller (w = [p speed phi_assumed, i_d*, i_q*]; K's columns: "
        + ", ".join(law.state)
        + "):",
        f"  {law.equations()}",
        *matrix_block("K", law.K, ["u_d", "u_q"], list(law.state[: law.K.shape[1]])),
    ]
    if law.K_i is not None:
        lines += matrix_block("K_i", law.K_i, ["u_d", "u_q"], ["z_d", "z_q"])
    lines += matrix_block("U", law.U, ["u_d", "u_q"], ["w1", "i_d*", "i_q*"])
    lines += ["", *result.learned.verdict.lines()]
    errors = ", ".join(
        f"{name} {evaluation.parameter_errors[name]:+.3%}" for name, _ in _PARAMETERS
    )
    lines += [f"  the identified motor against the truth (only to compare): {errors}", ""]
    lines.append(
        f"on the simulated drive at the MTPA references: true torque {result.true_torque:.6g}"
        f" N m, error {result.true_torque / result.torque - 1.0:+.3%}"
    )
    integral = ""
    if law.K_i is not None:
        integral = f", ||K_i - K_i*|| / ||K_i*|| = {evaluation.K_i_error:.2e}"
    lines.append(
        f"against the model-based optimum of the same loop: ||K - K*|| / ||K*|| = "
        f"{evaluation.K_error:.2e}{integral}, excess cost {evaluation.excess_cost:.2e}"
    )
    return lines


def interior_document(
    motor: IPMSM,
    settings: TuningSettings,
    result: InteriorCommissioning,
    evaluation: InteriorEvaluation,
    drive: DriveSettings,
) -> dict[str, Any]:
    """The JSON ``selftune tune --json`` writes for an interior motor: the law in the
    ``control_law`` form, the identified motor, the MTPA references, the torque, the whole
    cost (Q, R, Q_i), h and the delay.

    Parameters
    ----------
    motor : IPMSM
        The true motor (nameplate values).
    settings : TuningSettings
        The settings.
    result : InteriorCommissioning
        The commissioning.
    evaluation : InteriorEvaluation
        Its comparison with the truth.
    drive : DriveSettings
        The drive.
    """
    law = result.learned.law
    identified: dict[str, float] = {}
    for name, _ in _PARAMETERS:
        identified[name] = float(getattr(result.motor, name))
        identified[f"{name}_se"] = result.standard_errors[name]
    return {
        "method": "identify",
        "structure": "ipmsm",
        "target": "digital",
        "integral_action": law.K_i is not None,
        "control_law": law.document(),
        "reference": {
            "w": ["p speed phi_assumed (V)", "i_d* (A)", "i_q* (A)"],
            "rule": "MTPA of the identified motor",
            "torque": result.torque,
            "i_d": float(result.references[0]),
            "i_q": float(result.references[1]),
        },
        "identified": identified,
        "quality": result.learned.verdict,
        "data_seconds": result.data_seconds,
        "true_torque": result.true_torque,
        "steady_torque_error": result.true_torque / result.torque - 1.0,
        "model_based": evaluation.optimum.law.document(),
        "K_relative_error": evaluation.K_error,
        "K_i_relative_error": evaluation.K_i_error,
        "excess_cost": evaluation.excess_cost,
        "parameter_relative_errors": evaluation.parameter_errors,
        "motor": motor,
        "drive": {"settings": drive},
        "settings": settings,
        "cost": cost_document(settings.Q, settings.R, result.integral_weight),
        "h": settings.h,
        "input_delay": law.history,
        "notes": list(result.notes),
        "speed_electrical": float(motor.p * settings.speed),
        "w": np.concatenate([[motor.p * settings.speed * motor.phi_pm], result.references]),
    }
