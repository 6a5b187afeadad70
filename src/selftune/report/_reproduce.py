"""The paper's Section V, regenerated: Algorithms 1-3 and off-policy on the paper's motor.

:func:`reproduce` runs every algorithm with the paper's settings (PAPER_NOTES.md
section 6) on :meth:`SPMSM.paper`, compares each with the model-based optimum, and
simulates the torque step under the LQR, the initial and every algorithm's controller
(the paper's Figs. 1-3 show the LQR, the initial, Algorithm 1 and 2; the figures here
show all). :func:`report` renders the table the command
prints; :func:`results_document` every printed number as JSON; :func:`write_outputs`
writes ``results.json`` and the five figures (:mod:`._figures`).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from ..core import Array, finite_or_null, fixed, scientific, to_jsonable, write_json
from ..core._atomic import output_directory
from ..learn import Trajectory
from ..model import SPMSM, ModelBasedSolution
from ..tuning import AlgorithmName, TuningResult, TuningSettings, run_algorithm
from ._documents import history_document, regulator_document
from ._evaluate import TuningEvaluation, closed_loop_response, evaluate

__all__ = [
    "ALGORITHM_LABELS",
    "Reproduction",
    "report",
    "reproduce",
    "results_document",
    "write_outputs",
]

#: The label of each algorithm (:data:`selftune.tuning.ALGORITHMS`) in tables and figures.
ALGORITHM_LABELS: Mapping[AlgorithmName, str] = MappingProxyType(
    {"1": "Alg. 1", "2": "Alg. 2", "3": "Alg. 3", "offpolicy": "off-policy"}
)

#: Length of the simulated torque step of Figs. 1-3, s.
RESPONSE_DURATION = 0.01


@dataclass(frozen=True)
class Reproduction:
    """Everything the reproduction computed (the CLI, the figures and the JSON read it).

    Attributes
    ----------
    motor : SPMSM
    settings : TuningSettings
    optimum : ModelBasedSolution
        The model-based optimum (the truth).
    results : dict of str to TuningResult
        Keyed ``"1"``, ``"2"``, ``"3"``, ``"offpolicy"``.
    evaluations : dict of str to TuningEvaluation
        The same keys.
    responses : dict of str to Trajectory
        Torque steps from rest under ``"lqr"``, ``"initial"`` and every algorithm's
        controller (Algorithm 3's with its identified flux).
    wall_seconds : float
        How long the learning and the simulations took.
    """

    motor: SPMSM
    settings: TuningSettings
    optimum: ModelBasedSolution
    results: dict[str, TuningResult]
    evaluations: dict[str, TuningEvaluation]
    responses: dict[str, Trajectory]
    wall_seconds: float

    def controller(self, name: str) -> tuple[Array, Array, Array, Array]:
        """``(K, X, U, w)`` of a response's controller.

        Parameters
        ----------
        name : str
            ``"lqr"`` (the optimum), ``"initial"`` (K0, no feedforward), or an algorithm's key.
        """
        w_true = self.motor.exogenous(self.settings.speed, self.settings.torque)
        if name == "lqr":
            return self.optimum.K, self.optimum.X, self.optimum.U, w_true
        if name == "initial":
            return self.settings.K0, self.optimum.X, np.zeros((2, 2)), w_true
        result = self.results[name]
        return result.K, result.X, result.U, result.w


def reproduce(
    seed: int = 0,
    *,
    motor: SPMSM | None = None,
    settings: TuningSettings | None = None,
    step: Callable[[str], None] | None = None,
) -> Reproduction:
    """Run the paper's Section V.

    Parameters
    ----------
    seed : int
        Seed of the exploration signals.
    motor : SPMSM, optional
        Default :meth:`SPMSM.paper`.
    settings : TuningSettings, optional
        Default :meth:`TuningSettings.paper` (with ``seed``).
    step : callable, optional
        Called with a short description before each stage (for progress display).
    """
    motor = SPMSM.paper() if motor is None else motor
    settings = replace(TuningSettings.paper() if settings is None else settings, seed=seed)
    announce = step or (lambda _: None)
    start = time.perf_counter()
    results: dict[str, TuningResult] = {}
    evaluations: dict[str, TuningEvaluation] = {}
    for key, label in ALGORITHM_LABELS.items():
        announce(f"{label}: learning")
        results[key] = run_algorithm(key, motor, settings)
        evaluations[key] = evaluate(results[key], motor, settings)
    optimum = evaluations["2"].optimum
    assert isinstance(optimum, ModelBasedSolution), "the paper's algorithms are continuous"
    announce("torque steps")
    partial = Reproduction(motor, settings, optimum, results, evaluations, {}, 0.0)
    responses = {}
    for name in ("lqr", "initial", "1", "2", "3", "offpolicy"):
        K, X, U, w = partial.controller(name)
        responses[name] = closed_loop_response(motor, settings, K, X, U, w, RESPONSE_DURATION)
    return replace(partial, responses=responses, wall_seconds=time.perf_counter() - start)


def _theta(result: TuningResult) -> Array:
    """The result's Theta (the paper's algorithms always learn the continuous one)."""
    assert result.theta is not None, "the reproduction learns the continuous target"
    return result.theta


def _cell(value: float, width: int) -> str:
    """A table cell: four decimals, ``0`` for a zero, ``-`` for a non-finite value."""
    text = fixed(value)
    return f"{'0' if text == '0.0000' else text:>{width}}"


def _rank_text(result: TuningResult) -> str:
    """``"9 of 11"``, or ``"9/11+4/4"`` when a feedforward step solved the rest (eq. 13)."""
    text = f"{result.rank}/{result.unknowns}"
    feedforward = [item for item in result.history if item.step == "feedforward"]
    if feedforward:
        text += f"+{feedforward[-1].rank}/{feedforward[-1].unknowns}"
    return text


THETA_LABELS = (
    "P_11",
    "P_22",
    "2 P_12",
    "K_11",
    "K_21",
    "K_12",
    "K_22",
    "M_11",
    "M_21",
    "M_12",
    "M_22",
)


def report(reproduction: Reproduction) -> str:
    """The table ``selftune reproduce`` prints: Theta* against each algorithm's Theta.

    Parameters
    ----------
    reproduction : Reproduction
        What :func:`reproduce` computed.
    """
    results, evaluations = reproduction.results, reproduction.evaluations
    keys = list(ALGORITHM_LABELS)
    labels = "".join(f"{label:>12}" for label in ALGORITHM_LABELS.values())
    header = f"{'':>16}{'Theta*':>10}" + labels
    lines = [
        "Self-tuning torque control (Wang 2022, Sec. V) on the paper's motor:",
        f"  R_s = {reproduction.motor.R_s} ohm, L_s = {reproduction.motor.L_s} H, "
        f"phi_pm = {reproduction.motor.phi_pm} Wb, p = {reproduction.motor.p}; "
        f"{reproduction.settings.speed:g} rad/s, T* = {reproduction.settings.torque:g} N m, "
        "Q = 1e3 I, R = I",
        f"  h = {reproduction.settings.h * 1e6:g} us, episodes of "
        f"{reproduction.settings.episode_length * 1e3:g} ms, exploration "
        f"+-{reproduction.settings.exploration:g} V, seed {reproduction.settings.seed}",
        "",
        "Theta = [vecs(P); vec(K); vec(M)], M = (D + A X*)' P",
        header,
    ]
    for index, label in enumerate(THETA_LABELS):
        row = f"{label:>16}{_cell(reproduction.optimum.theta[index], 10)}"
        row += "".join(f"{_cell(_theta(results[key])[index], 12)}" for key in keys)
        lines.append(row)
    lines.append("")

    def summary(label: str, values: list[str]) -> None:
        lines.append(f"{label:>26}" + "".join(f"{value:>12}" for value in values))

    summary(
        "||Theta-Theta*||/||Theta*||",
        [scientific(evaluations[k].final_theta_error, 12) for k in keys],
    )
    summary("||K - K*|| / ||K*||", [scientific(evaluations[k].K_error, 12) for k in keys])
    summary("||U - U*|| / ||U*||", [scientific(evaluations[k].U_error, 12) for k in keys])
    summary("regression rank", [_rank_text(results[k]) for k in keys])
    summary("iterations", [str(1 + results[k].history[-1].iteration) for k in keys])
    summary("motor data, ms", [f"{results[k].data_seconds * 1e3:.1f}" for k in keys])
    identified = results["3"].identified
    motor = reproduction.motor
    summary("identified phi_pm, Wb", ["-", "-", f"{identified['phi_pm']:.8f}", "-"])
    summary(
        "  relative error",
        ["-", "-", scientific(identified["phi_pm"] / motor.phi_pm - 1, 12), "-"],
    )
    summary("  standard error, Wb", ["-", "-", scientific(identified["phi_pm_se"], 12), "-"])
    lines.append("")
    lines.append(
        f"K* = {reproduction.optimum.K[0, 0]:.4f} I,  U* = "
        f"[[{reproduction.optimum.U[0, 0]:.4f}, {reproduction.optimum.U[0, 1]:.4f}], "
        f"[{reproduction.optimum.U[1, 0]:.4f}, {reproduction.optimum.U[1, 1]:.4f}]]; true "
        f"phi_pm = {reproduction.motor.phi_pm} Wb"
    )
    for key, label in ALGORITHM_LABELS.items():
        for note in results[key].notes:
            lines.append(f"{label}: {note}")
    return "\n".join(lines)


def results_document(reproduction: Reproduction) -> dict[str, Any]:
    """Every number the command prints (and the histories), as JSON-ready data.

    Non-finite numbers (e.g. Theta error of Algorithm 3's no-load step, which has other
    unknowns) become ``null``.

    Parameters
    ----------
    reproduction : Reproduction
        What :func:`reproduce` computed.
    """

    settings = reproduction.settings
    optimum = reproduction.optimum
    w = reproduction.motor.exogenous(settings.speed, settings.torque)
    document: dict[str, Any] = {
        "motor": reproduction.motor,
        "settings": settings,
        "model_based": {
            **regulator_document(optimum),
            "x_e": optimum.X @ w,
            "u_e": optimum.U @ w,
        },
        "algorithms": {},
        "wall_seconds": reproduction.wall_seconds,
    }
    for key in ALGORITHM_LABELS:
        result, evaluation = reproduction.results[key], reproduction.evaluations[key]
        document["algorithms"][key] = {
            **regulator_document(result),
            "theta_error": evaluation.final_theta_error * float(np.linalg.norm(optimum.theta)),
            "theta_relative_error": evaluation.final_theta_error,
            "K_relative_error": evaluation.K_error,
            "U_relative_error": evaluation.U_error,
            "rank": result.rank,
            "unknowns": result.unknowns,
            "iterations": 1 + result.history[-1].iteration,
            "data_seconds": result.data_seconds,
            "quality": result.quality,
            "feedforward_learned": result.feedforward_learned,
            "identified": result.identified,
            "notes": list(result.notes),
            "history": history_document(result, evaluation),
        }
    return finite_or_null(to_jsonable(document))


def write_outputs(reproduction: Reproduction, out: str | os.PathLike[str]) -> list[Path]:
    """Write ``results.json`` and fig1..fig5 (PNG and SVG) into ``out``; return the paths.

    The files are written as one set (:func:`~selftune.core._atomic.output_directory`):
    into a temporary directory beside ``out``, then put in place together, so a failure
    or an interrupt leaves ``out`` as it was, and an earlier set there is replaced as a
    whole (no stale figure of another run stays).

    Parameters
    ----------
    reproduction : Reproduction
        What :func:`reproduce` computed.
    out : str or os.PathLike
        Output directory: absent (created, with its parents), empty, or holding only an
        earlier output of this function.
    """
    from ._figures import save_all

    directory = Path(out)
    with output_directory(out, (), "selftune reproduce output") as temporary:
        paths = save_all(reproduction, temporary)
        write_json(temporary / "results.json", results_document(reproduction))
    return [directory / path.name for path in [*paths, temporary / "results.json"]]
