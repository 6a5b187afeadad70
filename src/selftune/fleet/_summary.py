"""The fleet's picture: the spread of the identified parameters, the drives that stand
out of their group, the refusals by cause (``summary.md`` and ``fleet.png``/``.svg``).

The rule (:func:`robust_z`, :func:`outlier_threshold`): a drive stands out when one of
its identified parameters has a robust z beyond its group's threshold,

    z = (x - median) / sqrt(s^2 + se^2),

median and s over the group's learned drives, ``se`` the drive's own standard error of
the parameter (an estimate its log pins down poorly is not a finding). ``s`` is Tukey's
biweight midvariance's standard deviation (c = 9 MADs around the median; Mosteller and
Tukey 1977): a drive more than 9 MADs out weighs nothing in it, so a hot winding (R_s
up 30%), a loose connection or another motor shows against the group's own spread (the
manufacturing spread and the estimates' errors together), and it is far less noisy
than the 1.4826 MAD on small groups. The z is scale-free: the group's values are
judged relative to their own spread, so a +-5% spread scales with the parameter without
taking logarithms (within +-5% the logarithm would change a deviation by <3%, and it
would shrink a +30% unit's z by 13%).

The threshold is a stated false-alarm rate, not a fixed z: :data:`FALSE_ALARM_RATE`
(0.1%) per group, family-wise over its drives and the four :data:`PARAMETERS`
(Bonferroni: 0.025% per parameter). ``outlier_threshold(n)`` is the 99.975th percentile
of the largest ``|z|`` of ``n`` ordinary drives (``se = 0``), the larger of normally and
uniformly spread values, simulated once (400,000 groups per size and spread):

==========  ======  =====  =====  =====  =====  =====  =====  =====
n drives    5       8      10     12     15     20     30     50
normal      216.3   30.6   15.9   11.6   8.4    6.43   5.67   5.09
uniform     234.6   26.6   14.9   9.5    6.8    4.20   3.05   2.65
threshold   234.7   30.7   15.9   11.7   8.5    6.73   5.91   5.40
==========  ======  =====  =====  =====  =====  =====  =====  =====

Below 20 drives the threshold is that simulation's table (:data:`_THRESHOLDS`, rounded
up, and made non-increasing in n: a group of 6 takes the 62.5 of a group of 7, 57.2
simulated); from 20 drives on it is the Bonferroni quantile of Student's t with
0.7 (n - 1) degrees of freedom (the scale's efficiency, 86% asymptotically, shrunk to
stay above every simulated size from 20 to 500: 5.13 at 100 against 5.02, 5.12 at 500
against 5.12, where the t's tail is nearly the normal's, 5.03). A drive's own se only
shrinks its ``|z|``, so the rate holds with the standard errors too. Measured on
224,000 fresh groups of 5 to 60 drives (tests/test_fleet_outliers.py): 0.06% of the
normally spread groups named a drive, 0.012% of the uniform ones, none of the uniform
ones estimated with errors and their standard errors. 0.1% per group: a fleet of 20
groups of ordinary drives names one in at most 2% of fleets.

Uniform (not normal) spread matters little below 10 drives, where a small estimate of
the spread is what crosses a threshold, and lowers the largest z much above 15 (a
uniform spread has no tail: 2.65 against 5.09 at 50 drives): the threshold takes the
larger, the normal's, because the estimates' errors are normal and the manufacturing
spread is not known to be uniform. A spread with heavier tails than the normal's would
raise the rate.

What a group of n drives can name (a +30% R_s among +-5% uniform units whose R_s se
is 1.2%, the median of bench section 12's realistic drive; simulated, 10,000 groups
each): 0% at 8 drives, 0.5% at 10, 6% at 12, 44% at 15, 85% at 20, 97% at 30, 99.8%
at 50. A group of 8 knows its spread too poorly for +30%: it names R_s x2 in 14% of
groups, R_s x3 (another motor, a loose connection) in 99%. The scale is the biweight
because it names the most on small groups of the 50%-breakdown scales tried (at a 1%
rate, +30% in a group of 12: biweight 87%, Qn 83%, Sn 64%, MAD 40%) and takes O(n)
time and memory (Qn needs the n^2 / 2 differences). The rule before, a fixed 4 robust
standard deviations over the 1.4826 MAD, named an ordinary drive in 23% (uniform) to
33% (normal) of groups of 8, and in 11% of normally spread groups of 50. A group of
fewer than :data:`MIN_GROUP` learned drives is not judged.
"""

from __future__ import annotations

import math
import warnings
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

__all__ = [
    "FALSE_ALARM_RATE",
    "MIN_GROUP",
    "PARAMETERS",
    "SUMMARY_COLUMNS",
    "FleetSummary",
    "Outlier",
    "RefusalCause",
    "outlier_threshold",
    "robust_z",
    "summarize",
    "summary_markdown",
    "write_figure",
]

#: The chance that a group of ordinary drives names one of them (any parameter).
FALSE_ALARM_RATE = 1e-3

#: Fewest learned drives of a group for its median and spread to judge a drive.
MIN_GROUP = 5

#: The biweight's tuning constant, MADs: a value this far from the median weighs nothing.
_BIWEIGHT_C = 9.0

#: The thresholds of groups of MIN_GROUP to 19 drives (simulated: see the module).
_THRESHOLDS = (234.7, 62.5, 62.5, 30.7, 27.4, 15.9, 15.4, 11.7, 10.8, 9.2, 8.5, 7.7, 7.5,
               7.2, 7.1)  # fmt: skip

#: Degrees of freedom of the scale per drive beyond the first (from 20 drives on).
_EFFICIENCY = 0.7

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

#: The table's columns :func:`summarize` reads.
SUMMARY_COLUMNS = (
    *("path", "drive", "group", "verdict", "error"),
    *(name for column, _, _ in PARAMETERS for name in (column, _ERRORS[column])),
)


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
    group_sizes : tuple of (str, int)
        Each group's learned drives, by group.
    """

    logs_count: int
    learned_count: int
    groups_count: int
    spread: tuple[tuple[str, float, float, float, int], ...]
    outliers: tuple[Outlier, ...]
    refusals: tuple[RefusalCause, ...]
    deviations: dict[str, np.ndarray]
    group_sizes: tuple[tuple[str, int], ...] = ()


def robust_z(
    values: np.ndarray, standard_errors: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The robust z of each value, and the median, of a group (or of groups, along the last
    axis); NaN values are left out of both.

    Parameters
    ----------
    values : ndarray
        A group's values (or groups', one a row).
    standard_errors : ndarray, optional
        Each value's own standard error (NaN or absent: none).

    Returns
    -------
    (ndarray, ndarray)
        ``(x - median) / sqrt(s^2 + se^2)``, ``s`` the biweight midvariance's standard
        deviation (see the module; NaN where the value is, or all if the scale is 0), and
        the median (a 0-d array for one group; NaN for a group without a value).
    """
    x = np.asarray(values, dtype=float)
    finite = np.isfinite(x)
    count = np.count_nonzero(finite, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a group without a value
        median = np.asarray(np.median(x, axis=-1) if finite.all() else np.nanmedian(x, axis=-1))
        deviation = x - median[..., None]
        mad = np.nanmedian(np.abs(deviation), axis=-1)[..., None]
        u = np.where(finite, deviation / (_BIWEIGHT_C * mad), math.inf)
        inside = np.abs(u) < 1.0
        w = np.where(inside, 1.0 - u**2, 0.0)
        top = np.sum(np.where(inside, deviation**2 * w**4, 0.0), axis=-1)
        bottom = np.abs(np.sum(np.where(inside, w * (1.0 - 5.0 * u**2), 0.0), axis=-1))
        spread = np.where(mad[..., 0] > 0.0, np.sqrt(count * top) / bottom, 0.0)
        own = np.zeros(x.shape) if standard_errors is None else np.nan_to_num(standard_errors)
        scale = np.sqrt(spread[..., None] ** 2 + own**2)
        z = np.where(scale > 0.0, deviation / scale, math.nan)
    return z, median


def outlier_threshold(count: int) -> float:
    """The ``|z|`` beyond which a drive of a group of ``count`` learned drives is named:
    :data:`FALSE_ALARM_RATE` for the group over its drives and :data:`PARAMETERS` (see
    the module; infinite below :data:`MIN_GROUP`).

    Parameters
    ----------
    count : int
        The group's drives with a value of the parameter.
    """
    if count < MIN_GROUP:
        return math.inf
    if count < MIN_GROUP + len(_THRESHOLDS):
        return _THRESHOLDS[count - MIN_GROUP]
    level = 1.0 - FALSE_ALARM_RATE / (2 * len(PARAMETERS) * count)
    return float(stats.t.ppf(level, _EFFICIENCY * (count - 1)))


def summarize(columns: dict[str, list[Any]]) -> FleetSummary:
    """The summary of a fleet's table.

    Parameters
    ----------
    columns : dict
        The table's :data:`SUMMARY_COLUMNS`: ``path``, ``drive``, ``group``,
        ``verdict``, ``error``, those of :data:`PARAMETERS` and their standard errors.
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
            [math.nan if v is None else v for v in columns[_ERRORS[column]]], dtype=float
        )
        relative = np.full(values.shape, math.nan)
        for group in sorted(set(groups[learned])):
            members = np.flatnonzero(learned & (groups == group))
            z, center = robust_z(values[members], errors[members])
            median = float(center)
            if np.isfinite(median) and median != 0.0:
                relative[members] = values[members] / median - 1.0
            threshold = outlier_threshold(int(np.count_nonzero(np.isfinite(values[members]))))
            for index, score in zip(members, z, strict=True):
                if np.isfinite(score) and abs(score) > threshold:
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
        group_sizes=tuple(
            (group, int(np.count_nonzero(learned & (groups == group))))
            for group in sorted(set(groups[learned]))
        ),
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
        "## Drives that stand out (a false alarm in at most"
        f" {100 * FALSE_ALARM_RATE:g}% of groups of ordinary drives)",
        "",
        "Robust z = (x - median) / sqrt(s^2 + se^2) over the group's learned drives (s:"
        " the biweight midvariance's standard deviation, a drive more than 9 MADs from the"
        " median left out; se: the drive's own standard error of the parameter). A drive is"
        " named when |z| of one of its four parameters exceeds its group's threshold, which"
        f" depends on the group's size n so that a group of ordinary drives (normally or"
        f" uniformly spread) names one in at most {100 * FALSE_ALARM_RATE:g}% of cases: "
        + ", ".join(f"{outlier_threshold(n):.3g} at {n} drives" for n in (8, 20, 50))
        + f"; groups of fewer than {MIN_GROUP} are not judged. Here: "
        + (
            _names(
                [
                    f"{group} ({n} drives) {outlier_threshold(n):.3g}"
                    for group, n in summary.group_sizes
                ],
                limit=5,
            )
            or "no group"
        )
        + ".",
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
