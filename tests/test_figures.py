"""The reproduction's figures: every controller drawn and told apart, units, honest Fig. 5.

The figures are checked as matplotlib ``Figure`` objects (:func:`figures` writes
nothing): their axes, legends and lines, and, once drawn, where their texts land.
"""

from __future__ import annotations

import io
import re
from itertools import combinations
from typing import Any

import numpy as np
import pytest
from matplotlib.figure import Figure
from matplotlib.transforms import Bbox

from selftune.report import Reproduction
from selftune.report._figure_data import (
    ALGORITHM_KEYS,
    CONTROLLERS,
    LABELS,
    iteration_series,
    optimal_value,
    torque_steps,
)
from selftune.report._figures import STYLES, figures, save_figure

#: An axis label ends with its unit in parentheses.
UNIT = re.compile(r"\((A|V|N m|ms|V\$\^2\$ s|[^()]*dimensionless)\)$")


@pytest.fixture(scope="module")
def drawn(reproduction: Reproduction) -> dict[str, Figure]:
    return figures(reproduction)


def legend_texts(figure: Figure) -> list[str]:
    return [text.get_text() for legend in figure.legends for text in legend.get_texts()]


def drawn_lines(figure: Figure) -> dict[str, Any]:
    """Label -> line, for the visible lines with finite data in the figure's panels."""
    lines = {}
    for axes in figure.axes:
        for line in axes.get_lines():
            y = np.asarray(line.get_ydata(), dtype=float)
            if line.get_visible() and y.size and np.all(np.isfinite(y)):
                lines[str(line.get_label())] = line
    return lines


def test_the_five_figures_are_the_outputs(drawn: dict[str, Figure]) -> None:
    assert list(drawn) == ["fig1", "fig2", "fig3", "fig4", "fig5"]
    for stem, figure in drawn.items():
        assert isinstance(figure, Figure)
        assert figure.get_suptitle().startswith(f"Fig. {stem[-1]} "), stem


def test_every_axis_has_a_label_with_a_unit_and_every_panel_a_title(
    drawn: dict[str, Figure],
) -> None:
    for stem, figure in drawn.items():
        for axes in figure.axes:
            assert UNIT.search(axes.get_ylabel()), (stem, axes.get_ylabel())
            assert axes.get_title(), stem
        bottom = figure.axes[-1]
        assert UNIT.search(bottom.get_xlabel()), (stem, bottom.get_xlabel())
    assert "(N m)" in drawn["fig1"].axes[0].get_ylabel()  # the torque plot
    assert "dimensionless" in drawn["fig4"].axes[0].get_ylabel()


def test_every_controller_in_a_legend_is_drawn(drawn: dict[str, Figure]) -> None:
    for stem, figure in drawn.items():
        texts, lines = legend_texts(figure), drawn_lines(figure)
        assert texts, stem
        for text in texts:
            assert text in lines, (stem, text)
    for stem in ("fig1", "fig2", "fig3"):
        texts = legend_texts(drawn[stem])
        for name in CONTROLLERS:
            assert any(text.startswith(LABELS[name]) for text in texts), (stem, name)
    for stem in ("fig4", "fig5"):
        texts = legend_texts(drawn[stem])
        for key in ALGORITHM_KEYS:
            assert any(text.startswith(LABELS[key]) for text in texts), (stem, key)


def test_coinciding_curves_stay_visible() -> None:
    """Distinct colours and markers; the LQR a wide band underneath; the curves that
    share a dash pattern have different phases and nested marker sizes."""
    styles = list(STYLES.values())
    assert len({style.colour for style in styles}) == len(styles)
    lqr = STYLES["lqr"]
    assert all(lqr.width > 2 * style.width for style in styles if style is not lqr)
    assert lqr.alpha < 1
    for first, second in combinations(styles, 2):
        assert first.dashes != second.dashes
        if first.marker == second.marker and first.marker:
            assert abs(first.size - second.size) > 3  # nested, both visible
    sizes = sorted(STYLES[key].size for key in ("1", "2", "3"))
    assert sizes[0] < sizes[1] < sizes[2]


def test_the_lqr_is_drawn_under_the_others(drawn: dict[str, Figure]) -> None:
    for stem in ("fig1", "fig2", "fig3"):
        lines = drawn_lines(drawn[stem])
        band = next(line for label, line in lines.items() if label.startswith(LABELS["lqr"]))
        others = [line for label, line in lines.items() if not label.startswith(LABELS["lqr"])]
        assert all(band.get_zorder() < line.get_zorder() for line in others)


def test_the_torque_steps_include_off_policy_and_algorithm_3(
    reproduction: Reproduction,
) -> None:
    steps = torque_steps(reproduction)
    assert tuple(steps) == CONTROLLERS
    reference = reproduction.settings.torque
    for name in ("lqr", "2", "3", "offpolicy"):
        torque = reproduction.motor.torque(steps[name].x[-1, 1])
        assert torque == pytest.approx(reference, rel=1e-2), name  # 10 ms: nearly settled
    lqr = steps["lqr"].x
    for name in ("3", "offpolicy"):
        assert steps[name].x.shape == lqr.shape
        np.testing.assert_allclose(steps[name].x, lqr, atol=1e-4)
    assert reproduction.motor.torque(steps["1"].x[-1, 1]) < 0.97 * reference


def test_fig5_never_shows_an_iteration_below_the_optimum(reproduction: Reproduction) -> None:
    best = optimal_value(reproduction)
    for key in ALGORITHM_KEYS:
        series = iteration_series(reproduction, key)
        assert np.all(series.true_value >= best * (1 - 1e-9)), key
        np.testing.assert_allclose(series.learned_value, series.true_value, rtol=1e-5)
        assert series.true_value[-1] == pytest.approx(best, rel=1e-6)
        assert np.all(np.diff(series.true_value) <= 1e-9 * best), key  # Kleinman: monotone
        assert series.iteration[0] == 1 and np.all(np.diff(series.iteration) == 1)
    # the torque error shows what the cost-to-go does not: Alg. 1's missing feedforward
    assert abs(iteration_series(reproduction, "1").torque_offset[-1]) > 0.1
    for key in ("2", "3", "offpolicy"):
        assert abs(iteration_series(reproduction, key).torque_offset[-1]) < 1e-3, key


def test_fig4_has_every_algorithm_and_its_error_is_relative(
    reproduction: Reproduction, drawn: dict[str, Figure]
) -> None:
    for key in ALGORITHM_KEYS:
        series = iteration_series(reproduction, key)
        finite = series.theta_error[np.isfinite(series.theta_error)]
        assert finite.size and np.all(finite < 1.0), key
    assert iteration_series(reproduction, "1").theta_error[-1] > 0.1  # rank 9 of 11
    for key in ("2", "3", "offpolicy"):
        assert iteration_series(reproduction, key).theta_error[-1] < 1e-5, key
    assert drawn["fig4"].axes[0].get_yscale() == "log"


def _boxes(figure: Figure) -> dict[str, Bbox]:
    figure.canvas.draw()
    renderer = figure.canvas.get_renderer()  # type: ignore[attr-defined]
    boxes = {
        f"axes {index}": axes.get_tightbbox(renderer) for index, axes in enumerate(figure.axes)
    }
    boxes["suptitle"] = figure._suptitle.get_window_extent(renderer)  # type: ignore[union-attr]
    for index, legend in enumerate(figure.legends):
        boxes[f"legend {index}"] = legend.get_window_extent(renderer)
    return boxes


def test_no_text_overlaps_or_leaves_the_figure(drawn: dict[str, Figure]) -> None:
    for stem, figure in drawn.items():
        boxes = _boxes(figure)
        page = figure.bbox.padded(1.0)
        for name, box in boxes.items():
            assert page.x0 <= box.x0 and box.x1 <= page.x1, (stem, name)
            assert page.y0 <= box.y0 and box.y1 <= page.y1, (stem, name)
        for (first, one), (second, other) in combinations(boxes.items(), 2):
            overlap = Bbox.intersection(one.padded(-1.0), other.padded(-1.0))
            assert overlap is None or overlap.width <= 0 or overlap.height <= 0, (
                stem,
                first,
                second,
            )


def test_texts_are_readable_in_print(drawn: dict[str, Figure]) -> None:
    for stem, figure in drawn.items():
        assert figure.get_figwidth() <= 7.5, stem
        for axes in figure.axes:
            texts = [axes.title, axes.xaxis.label, axes.yaxis.label, *axes.get_yticklabels()]
            assert all(text.get_fontsize() >= 8.5 for text in texts), stem  # type: ignore[operator]
        for legend in figure.legends:
            assert all(text.get_fontsize() >= 8.5 for text in legend.get_texts()), stem


def test_a_figure_is_saved_as_png_and_svg(drawn: dict[str, Figure], tmp_path: Any) -> None:
    paths = save_figure(drawn["fig1"], tmp_path / "fig1")
    assert [path.name for path in paths] == ["fig1.png", "fig1.svg"]
    assert paths[0].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "<svg" in paths[1].read_text()[:500]
    buffer = io.BytesIO()
    drawn["fig5"].savefig(buffer, format="png")
    assert buffer.tell() > 10_000
