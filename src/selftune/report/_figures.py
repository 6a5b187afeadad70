"""The paper's Figs. 1-5, drawn from a :class:`~selftune.report.Reproduction`.

Colours and line styles are the paper's: green solid the LQR (model-based optimum),
blue dashed the initial controller, cyan dashed Algorithm 1, red dashed Algorithm 2.

- Fig. 1: ``i_d`` and the error ``e_d = i_d`` during the torque step;
- Fig. 2: ``i_q`` and ``e_q = i_q - i_q*``;
- Fig. 3: the feedback part ``-K xbar`` of the control, ``xbar = x - X w``;
- Fig. 4: ``||Theta_j - Theta*||`` over iterations (Algorithm 1 stalls, rank 9 of 11);
- Fig. 5: true and learned cost-to-go from ``x(0) = 0`` over iterations.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from ..core import Array, atomic_path

if TYPE_CHECKING:
    from ._reproduce import Reproduction

__all__ = [
    "STYLES",
    "figure_cost",
    "figure_current",
    "figure_feedback",
    "figure_theta_error",
    "save_all",
    "save_figure",
]

#: Line style of each controller: label, colour, line style (the paper's colour code).
STYLES: dict[str, tuple[str, str, str]] = {
    "lqr": ("LQR (model-based)", "green", "-"),
    "initial": ("initial control", "blue", "--"),
    "1": ("Alg. 1", "cyan", "--"),
    "2": ("Alg. 2", "red", "--"),
}


def _plot(axes: Axes, t: Array, y: Array, name: str) -> None:
    label, colour, style = STYLES[name]
    axes.plot(t * 1e3, y, color=colour, linestyle=style, label=label, linewidth=1.4)


def figure_current(reproduction: Reproduction, axis: int) -> Figure:
    """Fig. 1 (``axis=0``, d) or Fig. 2 (``axis=1``, q): the current and its error."""
    name = "d" if axis == 0 else "q"
    x_e = reproduction.optimum.X @ reproduction.motor.exogenous(
        reproduction.settings.speed, reproduction.settings.torque
    )
    figure, (upper, lower) = plt.subplots(2, 1, sharex=True, figsize=(6.4, 5.2))
    for key, response in reproduction.responses.items():
        _plot(upper, response.t, response.x[:, axis], key)
        _plot(lower, response.t, response.x[:, axis] - x_e[axis], key)
    upper.set_ylabel(f"$i_{name}$ (A)")
    lower.set_ylabel(f"$e_{name}$ (A)")
    lower.set_xlabel("time (ms)")
    upper.set_title(
        f"{name}-axis current during the torque step 0 -> {reproduction.settings.torque:g} N m"
    )
    upper.legend(loc="best", fontsize=8)
    for axes in (upper, lower):
        axes.grid(True, alpha=0.3)
    figure.tight_layout()
    return figure


def figure_feedback(reproduction: Reproduction) -> Figure:
    """Fig. 3: the feedback part ``-K (x - X w)`` of each controller (V)."""
    figure, axes_pair = plt.subplots(2, 1, sharex=True, figsize=(6.4, 5.2))
    for key, response in reproduction.responses.items():
        K, X, _, w = reproduction.controller(key)
        feedback = -(response.x - X @ w) @ K.T
        for index, axes in enumerate(axes_pair):
            _plot(axes, response.t, feedback[:, index], key)
    axes_pair[0].set_ylabel("$-(K\\bar{x})_d$ (V)")
    axes_pair[1].set_ylabel("$-(K\\bar{x})_q$ (V)")
    axes_pair[1].set_xlabel("time (ms)")
    axes_pair[0].set_title("feedback part of the control, $\\bar{x} = x - X w$")
    axes_pair[0].legend(loc="best", fontsize=8)
    for axes in axes_pair:
        axes.grid(True, alpha=0.3)
    figure.tight_layout()
    return figure


def _per_iteration(values: Array, iterations: list[int], pick: str) -> tuple[Array, Array]:
    """One value per iteration: the ``"last"`` or ``"first"`` record of each."""
    chosen: dict[int, float] = {}
    for iteration, value in zip(iterations, values, strict=True):
        if pick == "last" or iteration not in chosen:
            chosen[iteration] = float(value)
    keys = sorted(chosen)
    return np.array(keys, dtype=float) + 1.0, np.array([chosen[k] for k in keys])


def figure_theta_error(reproduction: Reproduction) -> Figure:
    """Fig. 4: ``||Theta_j - Theta*||`` after each iteration (log scale)."""
    figure, axes = plt.subplots(figsize=(6.4, 4.0))
    for key in ("1", "2"):
        result, evaluation = reproduction.results[key], reproduction.evaluations[key]
        iterations = [item.iteration for item in result.history]
        x, y = _per_iteration(evaluation.theta_error, iterations, "last")
        label, colour, style = STYLES[key]
        axes.semilogy(x, y, color=colour, linestyle=style, marker="o", label=label)
    axes.set_xlabel("iteration j")
    axes.set_ylabel("$\\|\\Theta_j - \\Theta^*\\|_2$")
    axes.set_title("parameter error: Alg. 1 stalls at rank 9 of 11, Alg. 2 converges")
    axes.grid(True, which="both", alpha=0.3)
    axes.legend(fontsize=8)
    figure.tight_layout()
    return figure


def figure_cost(reproduction: Reproduction) -> Figure:
    """Fig. 5: true and learned cost-to-go from ``x(0) = 0``, Alg. 1 above, Alg. 2 below."""
    figure, axes_pair = plt.subplots(2, 1, sharex=True, figsize=(6.4, 5.2))
    for axes, key in zip(axes_pair, ("1", "2"), strict=True):
        result, evaluation = reproduction.results[key], reproduction.evaluations[key]
        iterations = [item.iteration for item in result.history]
        x, true = _per_iteration(evaluation.true_cost, iterations, "first")
        _, learned = _per_iteration(evaluation.learned_cost, iterations, "first")
        colour = STYLES[key][1]
        axes.plot(x, true, color="black", marker="s", label="true cost of $(K_j, U_j)$")
        axes.plot(
            x,
            learned,
            color=colour,
            linestyle="--",
            marker="o",
            label="learned $\\bar{x}(0)^T P_j \\bar{x}(0)$",
        )
        axes.set_ylabel("cost-to-go")
        axes.set_title(STYLES[key][0], fontsize=10)
        axes.grid(True, alpha=0.3)
        axes.legend(fontsize=8)
    axes_pair[1].set_xlabel("iteration j")
    figure.tight_layout()
    return figure


def save_figure(figure: Figure, stem: str | os.PathLike[str]) -> list[Path]:
    """Save ``figure`` as ``stem.png`` and ``stem.svg``, each atomically; close it."""
    paths = []
    try:
        for suffix, options in ((".png", {"dpi": 150}), (".svg", {})):
            path = Path(f"{os.fspath(stem)}{suffix}")
            with atomic_path(path, suffix=suffix) as temporary:
                figure.savefig(temporary, format=suffix[1:], **options)  # type: ignore[arg-type]
            paths.append(path)
    finally:
        plt.close(figure)
    return paths


def _figures(reproduction: Reproduction) -> Iterator[tuple[str, Figure]]:
    yield "fig1", figure_current(reproduction, 0)
    yield "fig2", figure_current(reproduction, 1)
    yield "fig3", figure_feedback(reproduction)
    yield "fig4", figure_theta_error(reproduction)
    yield "fig5", figure_cost(reproduction)


def save_all(reproduction: Reproduction, directory: Path) -> list[Path]:
    """Write fig1..fig5 as PNG and SVG into ``directory``."""
    paths: list[Path] = []
    for stem, figure in _figures(reproduction):
        paths += save_figure(figure, directory / stem)
    return paths
