"""The fleet's picture: the spread of the identified parameters, the drives that stand
out of their group, the refusals by cause (``summary.md`` and ``fleet.png``/``.svg``).

A drive stands out when one of its identified parameters lies more than
:data:`OUTLIER_Z` robust standard deviations from its group's median: the robust z
``(x - median) / sqrt((1.4826 MAD)^2 + se^2)``, median and MAD (median absolute
deviation) over the group's learned drives, 1.4826 MAD being the standard deviation of
normally spread values, and ``se`` the drive's own standard error of the parameter (an
estimate its log pins down poorly is not a finding). One drive in a group cannot move
the median or the MAD much, so a hot winding (R_s up 30%), a loose connection or
another motor shows against the group's own spread (which the parameters' manufacturing
spread and the estimates' errors make). A group of fewer than :data:`MIN_GROUP` learned
drives is not judged.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "MIN_GROUP",
    "OUTLIER_Z",
    "PARAMETERS",
    "FleetSummary",
    "Outlier",
    "RefusalCause",
    "robust_z",
    "summarize",
    "summary_markdown",
    "write_figure",
]

#: Robust standard deviations from the group's median beyond which a drive is named.
OUTLIER_Z = 4.0

#: Fewest learned drives of a group for its median and spread to judge a drive.
MIN_GROUP = 5

#: 1 / Phi^-1(3/4): the MAD of normally spread values times this is their std.
_MAD_TO_SD = 1.4826

#: The parameters judged: column, name, unit.
PARAMETERS: tuple[tuple[str, str, str], ...] = (
    ("R_s_ohm", "R_s", "ohm"),
    ("L_s_H", "L_s", "H"),
    ("phi_pm_Wb", "phi_pm", "Wb"),
    ("dead_time_V", "dead-time voltage", "V"),
)

#: Each parameter's standard error's column.
_ERRORS = {"R_s_ohm": "R_s_se_ohm", "L_s_H": "L_s_se_H", "phi_pm_Wb": "phi_pm_se_Wb",
           "dead_time_V": "dead_time_se_V"}  # fmt: skip


@dataclass(frozen=True)
class Outlier:
    """A drive whose parameter stands out of its group.

    Attributes
    ----------
    drive, group, path : str
        The drive, its group and its log.
    parameter : str
        The parameter (a column of the table, unit in the name).
    value, median : float
        Its value and the group's median, in the parameter's unit.
    z : float
        The robust z (see the module).
    """

    drive: str
    group: str
    path: str
    parameter: str
    value: float
    median: float
    z: float


@dataclass(frozen=True)
class RefusalCause:
    """The logs refused (or failed) for one cause.

    Attributes
    ----------
    cause : str
        The error's class (``TooLittleData``, ``DataFileError``, ...).
    count : int
        Logs.
    drives : tuple of str
        Their drive ids.
    example : str
        One of their messages.
    """

    cause: str
    count: int
    drives: tuple[str, ...]
    example: str


@dataclass(frozen=True)
class FleetSummary:
    """What ``summary.md`` says.

    Attributes
    ----------
    logs_count, learned_count : int
        Rows of the table, and those learned.
    groups_count : int
        Groups.
    spread : tuple of (str, float, float, float, int)
        Per parameter: column, the 5th, 50th and 95th percentile of the drives' relative
        deviation from their group's median, and the drives with a value.
    outliers : tuple of Outlier
        The drives that stand out, largest ``|z|`` first.
    refusals : tuple of RefusalCause
        The logs not learned, by cause, the most common first.
    deviations : dict
        Per parameter column, the relative deviations (for the figure).
    """

    logs_count: int
    learned_count: int
    groups_count: int
    spread: tuple[tuple[str, float, float, float, int], ...]
    outliers: tuple[Outlier, ...]
    refusals: tuple[RefusalCause, ...]
    deviations: dict[str, np.ndarray]


def robust_z(
    values: np.ndarray, standard_errors: np.ndarray | None = None
) -> tuple[np.ndarray, float]:
    """The robust z of each value, and the median (NaN values are left out of both).

    Parameters
    ----------
    values : ndarray
        A group's values.
    standard_errors : ndarray, optional
        Each value's own standard error (NaN or absent: none).

    Returns
    -------
    (ndarray, float)
        ``(x - median) / sqrt((1.4826 MAD)^2 + se^2)`` (NaN where the value is, or all
        if the scale is 0) and the median.
    """
    finite = values[np.isfinite(values)]
    if finite.size == 0:
        return np.full(values.shape, math.nan), math.nan
    median = float(np.median(finite))
    spread = _MAD_TO_SD * float(np.median(np.abs(finite - median)))
    own = np.zeros(values.shape) if standard_errors is None else np.nan_to_num(standard_errors)
    scale = np.sqrt(spread**2 + own**2)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(scale > 0.0, (values - median) / scale, math.nan), median


def summarize(columns: dict[str, list[Any]]) -> FleetSummary:
    """The summary of a fleet's table.

    Parameters
    ----------
    columns : dict
        The table's columns ``path``, ``drive``, ``group``, ``verdict``, ``error`` and
        those of :data:`PARAMETERS`.
    """
    verdicts = columns["verdict"]
    learned = np.array([verdict == "learned" for verdict in verdicts], dtype=bool)
    groups = np.array(columns["group"], dtype=object)
    outliers: list[Outlier] = []
    spread = []
    deviations: dict[str, np.ndarray] = {}
    for column, _, _ in PARAMETERS:
        values = np.array([math.nan if v is None else v for v in columns[column]], dtype=float)
        errors = np.array(
            [math.nan if v is None else v for v in columns.get(_ERRORS[column], [None] * len(
                values))], dtype=float,
        )  # fmt: skip
        relative = np.full(values.shape, math.nan)
        for group in sorted(set(groups[learned])):
            members = np.flatnonzero(learned & (groups == group))
            z, median = robust_z(values[members], errors[members])
            if np.isfinite(median) and median != 0.0:
                relative[members] = values[members] / median - 1.0
            if np.count_nonzero(np.isfinite(values[members])) < MIN_GROUP:
                continue
            for index, score in zip(members, z, strict=True):
                if np.isfinite(score) and abs(score) > OUTLIER_Z:
                    outliers.append(Outlier(
                        columns["drive"][index], group, columns["path"][index], column,
                        float(values[index]), median, float(score),
                    ))  # fmt: skip
        found = relative[np.isfinite(relative)]
        deviations[column] = found
        if found.size:
            low, middle, high = (float(p) for p in np.percentile(found, [5, 50, 95]))
            spread.append((column, low, middle, high, int(found.size)))
    causes: dict[str, list[int]] = {}
    for row, verdict in enumerate(verdicts):
        if verdict != "learned":
            causes.setdefault(verdict, []).append(row)
    counts = Counter({cause: len(rows) for cause, rows in causes.items()})
    refusals = tuple(
        RefusalCause(
            cause,
            count,
            tuple(columns["drive"][i] for i in causes[cause]),
            columns["error"][causes[cause][0]],
        )
        for cause, count in sorted(counts.items(), key=lambda item: (-item[1], item[0]))
    )
    return FleetSummary(
        logs_count=len(verdicts),
        learned_count=int(np.count_nonzero(learned)),
        groups_count=len(set(groups)),
        spread=tuple(spread),
        outliers=tuple(sorted(outliers, key=lambda o: (-abs(o.z), o.drive, o.parameter))),
        refusals=refusals,
        deviations=deviations,
    )


def _names(drives: Sequence[str], limit: int = 10) -> str:
    shown = ", ".join(drives[:limit])
    return shown + (f" and {len(drives) - limit} more" if len(drives) > limit else "")


def summary_markdown(summary: FleetSummary, figure: str = "fleet.png") -> str:
    """``summary.md``.

    Parameters
    ----------
    summary : FleetSummary
        The fleet's summary.
    figure : str
        The figure's file name, linked.
    """
    titles = {column: f"{name} ({unit})" for column, name, unit in PARAMETERS}
    lines = [
        "# selftune fleet",
        "",
        f"{summary.logs_count} logs of {summary.groups_count} groups: {summary.learned_count}"
        f" learned, {summary.logs_count - summary.learned_count} refused or failed.",
        "",
        f"![the fleet]({figure})",
        "",
        "## Spread of the identified parameters",
        "",
        "Each drive's deviation from its group's median, percent (learned drives with the"
        ' parameter identified: identify-then-design with `structure = "spmsm"`; the'
        " dead-time voltage with `dead_time = true`).",
        "",
        "| parameter | drives | 5th percentile | median | 95th percentile |",
        "|---|---:|---:|---:|---:|",
    ]
    lines += [
        f"| {titles[column]} | {count} | {100 * low:+.2f}% | {100 * middle:+.2f}% |"
        f" {100 * high:+.2f}% |"
        for column, low, middle, high, count in summary.spread
    ]
    if not summary.spread:
        lines.append("| (none identified) | 0 | | | |")
    lines += [
        "",
        f"## Drives that stand out (more than {OUTLIER_Z:g} robust standard deviations from"
        " their group's median)",
        "",
        f"Robust z = (x - median) / sqrt((1.4826 MAD)^2 + se^2) over the group's learned"
        " drives (se: the drive's own standard error of the parameter); groups of"
        f" fewer than {MIN_GROUP} are not judged.",
        "",
    ]
    if summary.outliers:
        lines += [
            "| drive | group | parameter | value | group median | z |",
            "|---|---|---|---:|---:|---:|",
        ]
        lines += [
            f"| {o.drive} | {o.group} | {titles[o.parameter]} | {o.value:.4g} | {o.median:.4g} |"
            f" {o.z:+.1f} |"
            for o in summary.outliers
        ]
    else:
        lines.append("None.")
    lines += ["", "## Logs not learned, by cause", ""]
    if summary.refusals:
        lines += ["| cause | logs | drives | for example |", "|---|---:|---|---|"]
        lines += [
            f"| {r.cause} | {r.count} | {_names(r.drives)} | {r.example.replace('|', '/')} |"
            for r in summary.refusals
        ]
    else:
        lines.append("None.")
    return "\n".join(lines) + "\n"


def write_figure(summary: FleetSummary, stem: str | Path) -> list[Path]:
    """The fleet's figure: each parameter's deviations from the group medians (the drives
    that stand out marked), and the logs not learned by cause; ``stem.png`` and
    ``stem.svg``.

    Parameters
    ----------
    summary : FleetSummary
        The fleet's summary.
    stem : str or Path
        The files' path without the suffix.
    """
    from matplotlib.figure import Figure

    from ..report._figures import save_figure

    figure = Figure(figsize=(11, 4.2), layout="constrained")
    spread, causes = figure.subplots(1, 2, width_ratios=[2, 1])
    for place, (column, _, _) in enumerate(PARAMETERS):
        values = 100 * summary.deviations.get(column, np.zeros(0))
        jitter = np.random.default_rng(place).uniform(-0.15, 0.15, values.size)
        spread.plot(place + jitter, values, ".", color="0.55", markersize=3)
        marked = [o for o in summary.outliers if o.parameter == column]
        for outlier in marked:
            deviation = 100 * (outlier.value / outlier.median - 1.0)
            spread.plot(place, deviation, "o", color="tab:red", markersize=6)
            spread.annotate(outlier.drive, (place, deviation), fontsize=7,
                            xytext=(5, 0), textcoords="offset points")  # fmt: skip
    spread.set_xticks(range(len(PARAMETERS)), [name for _, name, _ in PARAMETERS])
    spread.set_ylabel("deviation from the group's median, %")
    spread.set_title(f"identified parameters ({summary.learned_count} drives)")
    spread.grid(alpha=0.3)
    names = [r.cause for r in summary.refusals] or ["(none)"]
    counts = [r.count for r in summary.refusals] or [0]
    causes.barh(range(len(names)), counts, color="tab:orange")
    causes.set_yticks(range(len(names)), names, fontsize=8)
    causes.invert_yaxis()
    causes.set_xlabel("logs")
    causes.set_title(f"not learned ({summary.logs_count - summary.learned_count} logs)")
    return save_figure(figure, stem)
