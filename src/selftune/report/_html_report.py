"""The report of a learned controller as one self-contained HTML page and its figures
(``selftune learn --report DIR``, ``selftune tune --report DIR`` without ``--online``).

The page holds the verdict in one sentence on top, the controller's numbers with their
standard errors, the six figures of :mod:`._learn_figures` embedded as PNG (base64
``data:`` URLs, each with alt text and a caption) and the printed report; it loads
nothing and runs no script. The same PNGs are written beside it. A law scheduled over
speed adds the schedule's figure (:func:`~._schedule_figure.figure_schedule`), embedded
and written as :data:`SCHEDULE_FILES`. The set is written as
one (:func:`~selftune.core._atomic.output_directory`): into a new or empty directory, or
over a previous report.
"""

from __future__ import annotations

import base64
import html
import io
from collections.abc import Sequence
from pathlib import Path

from matplotlib.figure import Figure

from ..core import Array, labels
from ..core._atomic import output_directory, write_text
from ..learn import LearnedController
from ._learn_figures import FIGURE_STEMS, LearnFigureData, learn_figure_data, learn_figures

__all__ = [
    "LEARN_REPORT_FILES",
    "LEARN_REPORT_NAMES",
    "REPORT_PAGE",
    "SCHEDULE_FILES",
    "report_files",
    "report_page",
    "verdict_sentence",
    "write_learn_report",
]

#: The page's file name.
REPORT_PAGE = "report.html"

#: The files of a learned controller's report: the page and one PNG per figure.
LEARN_REPORT_FILES = (REPORT_PAGE, *(f"{stem}.png" for stem in FIGURE_STEMS))

#: The speed schedule's figure, beside them when the law is scheduled over speed (and
#: what ``selftune solve --report DIR`` writes).
SCHEDULE_FILES = ("schedule.png", "schedule.svg")

#: Every file a learned controller's report directory may hold (a previous report's).
LEARN_REPORT_NAMES = (*LEARN_REPORT_FILES, *SCHEDULE_FILES)

#: What each figure shows: its title (the alt text) and how to read it (the caption).
_CAPTIONS = {
    "currents": (
        "Measured against model-predicted states",
        "The logged states and the fitted model's prediction of them from the logged "
        "inputs: the model the verdict and the standard errors rest on.",
    ),
    "autocorrelation": (
        "Autocorrelation of the model's errors",
        "Inside the grey band (95% of a white series) the errors are white noise: the "
        "model explains the data. Bars far outside say it misses an effect.",
    ),
    "alignment": (
        "Alignment scan: residual against the shift of the logged inputs",
        "The one-step residual for each assumed delay between a logged voltage and its "
        "effect; the shift used is circled in orange, and should be the lowest.",
    ),
    "step": (
        "Predicted step response with the band over the plants the data allow",
        "The learned controller on the fitted model (orange) and the least-to-largest "
        "response over the plants drawn from the model's uncertainty (blue band).",
    ),
    "poles": (
        "Closed-loop poles with the stability margin",
        "The poles of the learned sampled loop; the dashed red circle has radius 1 - "
        "margin, the margin the verdict states.",
    ),
    "spectrum": (
        "Spectrum of the model's errors",
        "Flat at the dashed level for white noise; peaks are what the model misses.",
    ),
    "schedule": (
        "The speed schedule against electrical speed",
        "Its gains K and K_i interpolated between the grid's laws (dots), the closed "
        "loop's dominant-pole bandwidth beside the pointwise optimum's, and the excess "
        "cost over the pointwise optimum of the schedule and of the single-speed law, "
        "with the limit the design checked.",
    ),
}

_STYLE = """
body { font-family: sans-serif; max-width: 60em; margin: 2em auto; padding: 0 1em;
       color: #222; line-height: 1.4; }
p.verdict { font-size: 1.2em; font-weight: bold; border-left: 4px solid #2ca02c;
            padding-left: 0.6em; }
table { border-collapse: collapse; margin: 0.5em 0 1.5em; }
th, td { border: 1px solid #ccc; padding: 0.2em 0.6em; text-align: right; }
th { background: #f4f4f4; }
figure { margin: 1.5em 0; }
figure img { max-width: 100%; }
figcaption { font-size: 0.95em; color: #444; }
pre { background: #f8f8f8; padding: 0.8em; overflow-x: auto; font-size: 0.85em; }
"""


def verdict_sentence(learned: LearnedController, data: LearnFigureData) -> str:
    """The verdict in one sentence: the standard errors as the printout states them and
    the stability margin on the fitted model and on the plants the data allow.

    Parameters
    ----------
    learned : LearnedController
        The judged result.
    data : LearnFigureData
        Its figures' numbers (the poles on the plausible plants).
    """
    quality = learned.verdict
    plants = (
        f"at least {data.least_margin:.3g} on all {data.plants} plants the data allow"
        if data.plants
        else "no other plants drawn (no output-error model)"
    )
    return (
        f"The data support this {learned.target} controller: {quality.errors_text()}; "
        f"its loop is stable with a margin of {quality.stability_margin:.3g} on the fitted "
        f"model, {plants}."
    )


def _matrix_table(name: str, value: Array, se: Array, rows: Sequence[str],
                  columns: Sequence[str]) -> str:  # fmt: skip
    """One matrix as an HTML table of ``value +- standard error`` entries."""
    head = "".join(f"<th>{html.escape(column)}</th>" for column in columns)
    body = []
    for row, values, errors in zip(rows, value, se, strict=True):
        cells = "".join(
            f"<td>{entry:.6g} &plusmn; {error:.2g}</td>"
            for entry, error in zip(values, errors, strict=True)
        )
        body.append(f"<tr><th>{html.escape(row)}</th>{cells}</tr>")
    return (
        f"<table><caption>{html.escape(name)}</caption><tr><th></th>{head}</tr>"
        + "".join(body)
        + "</table>"
    )


def _numbers(learned: LearnedController) -> str:
    """The tables of K, K_i and U with their standard errors."""
    law, quality = learned.law, learned.verdict
    inputs = labels("u", law.m)
    width = law.K.shape[1]
    parts = [_matrix_table("K", law.K, quality.K_se[:, :width], inputs, law.state[:width])]
    if law.K_i is not None:
        integrators = labels("z", law.K_i.shape[1])
        parts.append(_matrix_table("K_i", law.K_i, quality.K_se[:, width:], inputs, integrators))
    if law.U.size:
        parts.append(_matrix_table("U", law.U, quality.U_se, inputs, labels("w", law.q)))
    return "\n".join(parts)


def _png(figure: Figure) -> bytes:
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=110)
    return buffer.getvalue()


def report_page(
    title: str, sentence: str, numbers: str, figures: dict[str, bytes], lines: Sequence[str]
) -> str:
    """The self-contained HTML page.

    Parameters
    ----------
    title : str
        What was learned from what (the page's heading).
    sentence : str
        The verdict in one sentence.
    numbers : str
        The HTML tables of the controller's numbers.
    figures : dict of str to bytes
        Each figure's PNG by its stem (:data:`~._learn_figures.FIGURE_STEMS`).
    lines : sequence of str
        The printed report.
    """
    blocks = []
    for stem, png in figures.items():
        heading, caption = _CAPTIONS[stem]
        encoded = base64.b64encode(png).decode("ascii")
        blocks.append(
            f'<figure id="{stem}"><img src="data:image/png;base64,{encoded}" '
            f'alt="{html.escape(heading)}">'
            f"<figcaption><b>{html.escape(heading)}.</b> {html.escape(caption)} "
            f"(<code>{stem}.png</code>)</figcaption></figure>"
        )
    return "\n".join(
        [
            "<!DOCTYPE html>",
            '<html lang="en"><head><meta charset="utf-8">',
            f"<title>{html.escape(title)}</title><style>{_STYLE}</style></head><body>",
            f"<h1>{html.escape(title)}</h1>",
            f'<p class="verdict" id="verdict">{html.escape(sentence)}</p>',
            "<h2>The controller</h2>",
            numbers,
            "<h2>Figures</h2>",
            *blocks,
            "<h2>The printed report</h2>",
            f"<pre>{html.escape(chr(10).join(lines))}</pre>",
            "</body></html>",
            "",
        ]
    )


def write_learn_report(
    learned: LearnedController,
    title: str,
    lines: Sequence[str],
    out: str,
    step: tuple[Array, Array] | None = None,
    schedule: Figure | None = None,
) -> list[Path]:
    """Write :data:`LEARN_REPORT_FILES` (and :data:`SCHEDULE_FILES` with ``schedule``)
    into ``out`` as one set.

    Parameters
    ----------
    learned : LearnedController
        The judged result, with its evidence.
    title : str
        The page's heading (what was learned from what).
    lines : sequence of str
        The printed report, shown at the page's end.
    out : str
        The directory: absent, empty or a previous report.
    step : (ndarray, ndarray), optional
        The reference before and after the step response's step (default: read off the
        logs, :func:`~._learn_figures.logged_step`).
    schedule : Figure, optional
        The speed schedule's figure (:func:`~._schedule_figure.figure_schedule`), when
        the law is scheduled over speed.

    Returns
    -------
    list of Path
        The files written.
    """
    data = learn_figure_data(learned, step)
    figures = learn_figures(data)
    if schedule is not None:
        figures["schedule"] = schedule
    pngs = {stem: _png(figure) for stem, figure in figures.items()}
    page = report_page(title, verdict_sentence(learned, data), _numbers(learned), pngs, lines)
    names = report_files(schedule is not None)
    with output_directory(out, LEARN_REPORT_NAMES, "learn report") as temporary:
        for stem, png in pngs.items():  # the PNGs the page embeds
            (temporary / f"{stem}.png").write_bytes(png)
        if schedule is not None:
            schedule.savefig(temporary / "schedule.svg", format="svg")
        write_text(temporary / REPORT_PAGE, page)
    return [Path(out) / name for name in names]


def report_files(scheduled: bool) -> tuple[str, ...]:
    """The files of a learned controller's report, with the schedule's or without.

    Parameters
    ----------
    scheduled : bool
        Whether the law is scheduled over speed (its figure is in the report).
    """
    return LEARN_REPORT_FILES + (SCHEDULE_FILES if scheduled else ())
