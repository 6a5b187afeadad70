"""The reproduction's Figs. 1-5, drawn from a :class:`~selftune.report.Reproduction`.

Every controller is drawn where it applies: the LQR (the model-based optimum), the
initial controller, Algorithms 1, 2 and 3 and the off-policy variant (the default of
``selftune tune``); Algorithm 3's controller acts on its identified flux. The numbers
come from :mod:`._figure_data` (evaluation only: nothing is learned here).

- Fig. 1: the torque step on the true motor: torque ``T = 1.5 p phi_pm i_q`` (N m) with
  its reference, and ``i_d`` (A, equal to the error ``e_d`` since ``i_d* = 0``);
- Fig. 2: ``i_q`` with its reference ``i_q*``, and the error ``e_q = i_q - i_q*`` (A);
- Fig. 3: the feedback part ``-K xbar`` of the voltage, ``xbar = x - X w`` (V);
- Fig. 4: ``||Theta_j - Theta*|| / ||Theta*||`` after each iteration (dimensionless);
- Fig. 5: the learned cost-to-go of each iteration's feedback against its true value,
  both from rest about the true operating point (V^2 s), and the steady torque error
  of the controller applied in the iteration (N m), which that cost does not include.

Line styles: the paper's colours (green LQR, blue initial, cyan Alg. 1, red Alg. 2),
with purple Alg. 3 and orange off-policy. The LQR is a wide translucent band under the
others; the curves that coincide with it (Algs. 2, 3, off-policy) share one dash
pattern with shifted phases, so that their dashes alternate on the band, and their
markers are staggered in time; in the iteration figures coinciding markers are nested
(large hollow circle, hollow diamond, small filled triangle).

The figures are :class:`matplotlib.figure.Figure` objects with an Agg canvas attached
(no pyplot, no global backend switch, nothing to close); :func:`figures` returns them,
:func:`save_figure` writes one as PNG and SVG.
"""

from __future__ import annotations

import os
import textwrap
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib import rc_context
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from ..core import Array, atomic_path
from ._figure_data import (
    ALGORITHM_KEYS,
    LABELS,
    algorithm_label,
    coincidence_note,
    iteration_series,
    largest_mismatch,
    offset_text,
    optimal_value,
    steady_torque_offset,
    torque_steps,
    weight_text,
)

if TYPE_CHECKING:
    from ._reproduce import Reproduction

__all__ = [
    "STYLES",
    "Style",
    "figure_cost",
    "figure_feedback",
    "figure_q_current",
    "figure_theta_error",
    "figure_torque",
    "figures",
    "save_all",
    "save_figure",
]


@dataclass(frozen=True)
class Style:
    """How one controller is drawn.

    Attributes
    ----------
    colour : str
        Line and marker colour.
    dashes : str or tuple
        Matplotlib line style; ``(offset, (on, off))`` is a dash pattern with a phase.
    width : float
        Line width, pt.
    marker : str
        Marker, "" for none.
    size : float
        Marker size in the iteration figures, pt (nested sizes keep coinciding markers
        visible; 0.7 of it in the time plots).
    filled : bool
        Filled or hollow marker.
    alpha : float
        Opacity.
    """

    colour: str
    dashes: str | tuple[float, tuple[float, float]]
    width: float
    marker: str
    size: float
    filled: bool = False
    alpha: float = 1.0


#: How each controller is drawn (the paper's colour code, extended to Alg. 3, off-policy).
STYLES: dict[str, Style] = {
    "lqr": Style("#2ca02c", "-", 6.0, "", 0.0, alpha=0.45),
    "initial": Style("#1f3fd0", (0, (7.0, 3.0)), 1.5, "o", 5.0),
    "1": Style("#009a9a", (0, (2.0, 2.0)), 1.7, "D", 7.5),
    "2": Style("#d62728", (0, (4.0, 8.0)), 1.8, "o", 11.0),
    "3": Style("#8e2fb8", (4, (4.0, 8.0)), 1.8, "v", 5.0, filled=True),
    "offpolicy": Style("#ff7f0e", (8, (4.0, 8.0)), 1.8, "s", 8.0),
}

#: Text sizes for print: the figures are 7 inches wide and readable at that width.
_PRINT: dict[Any, Any] = {
    "font.size": 10.0,
    "axes.titlesize": 10.0,
    "axes.labelsize": 10.0,
    "legend.fontsize": 9.0,
    "legend.title_fontsize": 9.0,
    "xtick.labelsize": 9.0,
    "ytick.labelsize": 9.0,
    "figure.titlesize": 11.5,
}

#: Markers per curve in the time plots.
_MARKERS_PER_CURVE = 8

#: Characters per line of a caption (a legend's title).
_CAPTION_WIDTH = 105

_TIME = "time $t$ (ms)"
_ITERATION = "iteration $j$ (count, dimensionless)"


def _new_figure(rows: int, height: float) -> tuple[Figure, list[Axes]]:
    """A 7-inch-wide figure with ``rows`` panels sharing x, rendered by Agg."""
    figure = Figure(figsize=(7.0, height), layout="constrained")
    FigureCanvasAgg(figure)
    axes = list(figure.subplots(rows, 1, sharex=True, squeeze=False)[:, 0])
    for panel in axes:
        panel.grid(True, alpha=0.3)
    return figure, axes


def _line_options(name: str) -> dict[str, Any]:
    style = STYLES[name]
    return {
        "color": style.colour,
        "linestyle": style.dashes,
        "linewidth": style.width,
        "alpha": style.alpha,
        "marker": style.marker or None,
        "markersize": style.size,
        "markerfacecolor": style.colour if style.filled else "none",
        "markeredgecolor": style.colour,
        "markeredgewidth": 1.3,
        "zorder": 1 if name == "lqr" else 2,
    }


def _plot_time(axes: Axes, t: Array, y: Array, name: str, label: str | None = None) -> None:
    """One controller's curve against time in ms, its markers staggered."""
    spacing = max(1, t.size // _MARKERS_PER_CURVE)
    start = spacing * list(STYLES).index(name) // len(STYLES)
    options = _line_options(name)
    options["markersize"] *= 0.7
    label = LABELS[name] if label is None else label
    axes.plot(t * 1e3, y, label=label, markevery=(start, spacing), **options)


def _reference(axes: Axes, t: Array, value: float, label: str) -> None:
    """A constant reference, thin black."""
    axes.plot(t * 1e3, np.full(t.shape, value), color="black", linewidth=0.9, label=label)


def _wrap(text: str) -> str:
    """``text`` in lines of :data:`_CAPTION_WIDTH` characters, never inside ``$..$``."""
    parts = text.split("$")
    kept = "$".join(part.replace(" ", "\u00a0") if odd else part for odd, part in _odd(parts))
    lines = textwrap.wrap(kept, _CAPTION_WIDTH, break_long_words=False, break_on_hyphens=False)
    return "\n".join(line.replace("\u00a0", " ") for line in lines)


def _odd(parts: list[str]) -> Iterator[tuple[bool, str]]:
    return ((index % 2 == 1, part) for index, part in enumerate(parts))


def _legend(figure: Figure, axes: Axes, caption: str, columns: int = 2) -> None:
    """The legend of ``axes``' lines below the panels, with ``caption`` as its title."""
    handles, labels = axes.get_legend_handles_labels()
    figure.legend(
        handles,
        labels,
        loc="outside lower center",
        ncol=columns,
        title=_wrap(caption),
        frameon=False,
    )


def _step(reproduction: Reproduction) -> str:
    settings = reproduction.settings
    return f"Torque step 0 \u2192 {settings.torque:g} N m at {settings.speed:g} rad/s from rest"


def figure_torque(reproduction: Reproduction) -> Figure:
    """Fig. 1: the torque (N m) with its reference, and ``i_d`` (A), of every controller.

    The torque is the true motor's, ``1.5 p phi_pm i_q`` with the true flux; each legend
    entry gives the controller's steady torque error.

    Parameters
    ----------
    reproduction : Reproduction
        What :func:`~selftune.report.reproduce` computed.
    """
    motor = reproduction.motor
    responses = torque_steps(reproduction)
    torques = {name: motor.torque(response.x[:, 1]) for name, response in responses.items()}
    with rc_context(_PRINT):
        figure, (upper, lower) = _new_figure(2, 6.8)
        for name, response in responses.items():
            offset = steady_torque_offset(reproduction, *reproduction.controller(name))
            label = f"{LABELS[name]}: steady error {offset_text(offset)} N m"
            _plot_time(upper, response.t, torques[name], name, label)
            _plot_time(lower, response.t, response.x[:, 0], name, label)
        _reference(upper, responses["lqr"].t, reproduction.settings.torque, "reference $T^*$")
        upper.set_ylabel("torque $T$ (N m)")
        upper.set_title(
            "torque $T = 1.5\\,p\\,\\varphi_\\mathrm{pm}\\,i_q$ of the true motor "
            f"($\\varphi_\\mathrm{{pm}}$ = {motor.phi_pm:g} Wb) and its reference $T^*$"
        )
        lower.set_ylabel("d-axis current $i_d$ (A)")
        lower.set_title("d-axis current $i_d$ (equal to its error $e_d$: the reference is 0)")
        lower.set_xlabel(_TIME)
        figure.suptitle(f"Fig. 1  {_step(reproduction)}: torque and d-axis current")
        _legend(figure, upper, coincidence_note(torques, "N m"))
    return figure


def figure_q_current(reproduction: Reproduction) -> Figure:
    """Fig. 2: ``i_q`` with its reference ``i_q*``, and ``e_q = i_q - i_q*`` (A).

    Parameters
    ----------
    reproduction : Reproduction
        What :func:`~selftune.report.reproduce` computed.
    """
    reference = float(reproduction.motor.current_reference(reproduction.settings.torque)[1])
    responses = torque_steps(reproduction)
    with rc_context(_PRINT):
        figure, (upper, lower) = _new_figure(2, 6.6)
        for name, response in responses.items():
            _plot_time(upper, response.t, response.x[:, 1], name)
            _plot_time(lower, response.t, response.x[:, 1] - reference, name)
        _reference(upper, responses["lqr"].t, reference, "reference $i_q^*$")
        upper.set_ylabel("q-axis current $i_q$ (A)")
        upper.set_title(f"q-axis current $i_q$ and its reference $i_q^*$ = {reference:.3f} A")
        lower.set_ylabel("error $e_q = i_q - i_q^*$ (A)")
        lower.set_title("q-axis current error (a steady error means a wrong feedforward $U$)")
        lower.set_xlabel(_TIME)
        figure.suptitle(f"Fig. 2  {_step(reproduction)}: q-axis current")
        currents = {name: response.x[:, 1] for name, response in responses.items()}
        _legend(figure, upper, coincidence_note(currents, "A"), columns=3)
    return figure


def figure_feedback(reproduction: Reproduction) -> Figure:
    """Fig. 3: the feedback part ``-K (x - X w)`` of each controller's voltage (V).

    Parameters
    ----------
    reproduction : Reproduction
        What :func:`~selftune.report.reproduce` computed.
    """
    responses = torque_steps(reproduction)
    feedback: dict[str, Array] = {}
    for name, response in responses.items():
        K, X, _, w = reproduction.controller(name)
        feedback[name] = -(response.x - X @ w) @ K.T
    with rc_context(_PRINT):
        figure, axes_pair = _new_figure(2, 6.6)
        for name, response in responses.items():
            for index, axes in enumerate(axes_pair):
                _plot_time(axes, response.t, feedback[name][:, index], name)
        for axes, axis in zip(axes_pair, "dq", strict=True):
            axes.set_ylabel(f"$-(K\\bar{{x}})_{axis}$ (V)")
            axes.set_title(
                f"{axis}-axis feedback voltage (0 in steady state only with the right $U$)"
            )
        axes_pair[1].set_xlabel(_TIME)
        figure.suptitle(
            f"Fig. 3  {_step(reproduction)}: feedback part of the voltage,\n"
            "$-K\\bar{x}$ with $\\bar{x} = x - Xw$ (each controller's own $X$ and $w$)"
        )
        voltages = {name: values[:, 1] for name, values in feedback.items()}
        _legend(figure, axes_pair[0], coincidence_note(voltages, "V (q axis)"), columns=3)
    return figure


def _plot_iterations(axes: Axes, x: Array, y: Array, key: str, label: str | None) -> None:
    finite = np.isfinite(y)
    axes.plot(x[finite], y[finite], label=label, **_line_options(key))


def _iteration_axis(axes: Axes) -> None:
    axes.xaxis.set_major_locator(MaxNLocator(integer=True))
    axes.set_xlabel(_ITERATION)


def figure_theta_error(reproduction: Reproduction) -> Figure:
    """Fig. 4: ``||Theta_j - Theta*|| / ||Theta*||`` after each iteration (log scale).

    Parameters
    ----------
    reproduction : Reproduction
        What :func:`~selftune.report.reproduce` computed.
    """
    with rc_context(_PRINT):
        figure, (axes,) = _new_figure(1, 5.0)
        for key in ALGORITHM_KEYS:
            series = iteration_series(reproduction, key)
            label = algorithm_label(reproduction, key)
            _plot_iterations(axes, series.iteration, series.theta_error, key, label)
        axes.set_yscale("log")
        axes.grid(True, which="minor", alpha=0.12)
        axes.set_ylabel("$\\|\\Theta_j - \\Theta^*\\|\\,/\\,\\|\\Theta^*\\|$ (dimensionless)")
        axes.set_title("at the end of iteration $j$ (after its feedforward step, if it has one)")
        _iteration_axis(axes)
        figure.suptitle("Fig. 4  Relative error of the learned parameters $\\Theta$")
        caption = (
            "\u0398 = [vecs(P); vec(K); vec((D + AX*)'P)], against the model-based \u0398*. "
            "Coinciding points are nested: Alg. 2 large circle, Alg. 1 diamond, Alg. 3 small "
            "filled triangle."
        )
        _legend(figure, axes, caption)
    return figure


def figure_cost(reproduction: Reproduction) -> Figure:
    """Fig. 5: learned against true value of each iteration's feedback; steady torque error.

    Upper panel: the learned cost-to-go ``x_bar(0)' P_j x_bar(0)`` of the feedback
    ``K_j`` applied in iteration j (coloured markers) and its true value
    ``x_bar0' P_{K_j} x_bar0`` on the true motor (black), with the optimum's
    ``x_bar0' P* x_bar0``: the cost (5) of the torque step from rest about the true
    operating point, with the true feedforward. Lower panel: the steady torque error of
    the whole controller ``(K_j, U_j)`` applied, which that value does not include (with
    ``U_j != U*`` the cost (5) about the true operating point is unbounded).

    Parameters
    ----------
    reproduction : Reproduction
        What :func:`~selftune.report.reproduce` computed.
    """
    best = optimal_value(reproduction)
    settings = reproduction.settings
    series = {key: iteration_series(reproduction, key) for key in ALGORITHM_KEYS}
    with rc_context(_PRINT):
        figure, (upper, lower) = _new_figure(2, 7.6)
        for key, values in series.items():
            label = algorithm_label(reproduction, key)
            _plot_iterations(upper, values.iteration, values.learned_value, key, label)
            _plot_iterations(lower, values.iteration, values.torque_offset, key, None)
        true_label: str | None = "true value of $K_j$ (black, one line per algorithm)"
        for values in series.values():
            finite = np.isfinite(values.true_value)
            x, y = values.iteration[finite], values.true_value[finite]
            upper.plot(x, y, "k-+", linewidth=0.8, markersize=8, zorder=3, label=true_label)
            true_label = None
        span = np.array([0.6, max(int(values.iteration[-1]) for values in series.values()) + 0.4])
        optimum = _line_options("lqr") | {"marker": None}
        label = f"optimum $\\bar{{x}}_0^\\top P^* \\bar{{x}}_0$ = {best:.2f} V$^2$ s (LQR)"
        upper.plot(span, [best, best], label=label, **optimum)
        lower.plot(span, [0.0, 0.0], **optimum)
        upper.set_xlim(*span)
        upper.set_ylabel("cost-to-go (V$^2$ s)")
        upper.set_title(
            "value of the feedback $K_j$ of iteration $j$: learned "
            "$\\bar{x}(0)^\\top P_j\\,\\bar{x}(0)$ (markers) and true (black)"
        )
        lower.set_ylabel("steady torque error (N m)")
        lower.set_title(
            f"steady torque error of the controller $(K_j, U_j)$ of iteration $j$ on the true "
            f"motor ($T^*$ = {settings.torque:g} N m)"
        )
        _iteration_axis(lower)
        figure.suptitle("Fig. 5  Cost and steady torque error of each iteration's controller")
        lowest = min(float(np.nanmin(values.true_value)) for values in series.values())
        below = "none is" if lowest >= best * (1.0 - 1e-9) else "some are"
        caption = (
            "Cost-to-go: the cost (5) of the torque step from rest about the true operating "
            "point, $\\bar{x}(0) = -X^*w$, with $Q$ = "
            f"{weight_text(settings.Q)} V$^2$/A$^2$, $R$ = {weight_text(settings.R)} "
            "(dimensionless), under the feedback $K_j$ with the true feedforward $U^*$: "
            "what $P_j$ estimates. Largest |learned \u2212 true| / true: "
            f"{largest_mismatch(reproduction):.1e}; of the true values, {below} below the "
            "optimum. A controller whose own $U_j \\neq U^*$ also keeps the steady torque "
            "error of the lower panel, and its cost (5) about the true operating point grows "
            "without bound."
        )
        _legend(figure, upper, caption)
    return figure


def save_figure(figure: Figure, stem: str | os.PathLike[str]) -> list[Path]:
    """Save ``figure`` as ``stem.png`` (150 dpi) and ``stem.svg``, each atomically.

    Parameters
    ----------
    figure : Figure
        The figure.
    stem : str or os.PathLike
        The path without its suffix.
    """
    paths = []
    for suffix, options in ((".png", {"dpi": 150}), (".svg", {})):
        path = Path(f"{os.fspath(stem)}{suffix}")
        with atomic_path(path, suffix=suffix) as temporary:
            figure.savefig(temporary, format=suffix[1:], **options)  # type: ignore[arg-type]
        paths.append(path)
    return paths


def _figures(reproduction: Reproduction) -> Iterator[tuple[str, Figure]]:
    yield "fig1", figure_torque(reproduction)
    yield "fig2", figure_q_current(reproduction)
    yield "fig3", figure_feedback(reproduction)
    yield "fig4", figure_theta_error(reproduction)
    yield "fig5", figure_cost(reproduction)


def figures(reproduction: Reproduction) -> dict[str, Figure]:
    """Figs. 1-5 by their file stems (``"fig1"`` ..), without writing anything.

    Parameters
    ----------
    reproduction : Reproduction
        What :func:`~selftune.report.reproduce` computed.
    """
    return dict(_figures(reproduction))


def save_all(reproduction: Reproduction, directory: Path) -> list[Path]:
    """Write fig1..fig5 as PNG and SVG into ``directory``.

    Parameters
    ----------
    reproduction : Reproduction
        What :func:`~selftune.report.reproduce` computed.
    directory : Path
        An existing directory.
    """
    paths: list[Path] = []
    for stem, figure in _figures(reproduction):
        paths += save_figure(figure, directory / stem)
    return paths
