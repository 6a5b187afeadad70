"""A schedule's figure: gains, bandwidth and excess cost against its variable.

:func:`figure_schedule` draws a :class:`~selftune.model.ScheduleDesign` in four panels
over the electrical speed ``omega_e`` (rad/s), or a saturating motor's
:class:`~selftune.model.CurrentScheduleDesign` over the q-axis current reference ``i_q*``
(A), the single law beside it then the one learned at rated current:

- the state feedback ``K`` (its entries on ``i_d``, ``i_q``, V/A), the grid's laws as
  markers and the interpolated schedule (:meth:`~selftune.model.SpeedSchedule.law_at`)
  as lines;
- the integral gain ``K_i`` (V/(A s)), likewise (a law without one: the panel says so);
- the closed loop's dominant-pole bandwidth ``-ln(rho) / h`` (rad/s) of the interpolated
  schedule and of the pointwise optimum, at the check's fine speeds;
- the excess cost over the pointwise optimum (worst initial state, dimensionless, log
  scale) of the schedule and of the single-speed controller, with the limit.

:func:`figure_speed_current` draws a schedule over speed and current the same way
against speed, one line per grid current.

The figure is a :class:`matplotlib.figure.Figure` with an Agg canvas (no pyplot), as
the reproduction's (:mod:`._figures`); :func:`~selftune.report.save_figure` writes it.
"""

from __future__ import annotations

from itertools import product
from typing import Protocol

import numpy as np
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..core import Array
from ..loop import SampledLoop
from ..model import (
    CurrentScheduleDesign,
    ScheduleCheck,
    ScheduleDesign,
    SpeedCurrentDesign,
    SpeedSchedule,
    bandwidth,
)

__all__ = ["figure_schedule", "figure_speed_current"]

#: The entries of K and K_i drawn: (row, column, label), as ``u_row`` on ``x_column``.
_ENTRIES = ((0, 0, "d on d"), (0, 1, "d on q"), (1, 0, "q on d"), (1, 1, "q on q"))

#: Colours of the entries, the schedule, the optimum and the single-speed controller.
_COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd")
_SCHEDULE, _OPTIMUM, _SINGLE = "#1f77b4", "#2ca02c", "#ff7f0e"


def _panels() -> tuple[Figure, list[Axes]]:
    """A figure of four panels, one above the other, sharing their abscissa."""
    figure = Figure(figsize=(7.0, 9.0), layout="constrained")
    FigureCanvasAgg(figure)
    axes = list(figure.subplots(4, 1, sharex=True, squeeze=False)[:, 0])
    for panel in axes:
        panel.grid(True, alpha=0.3)
    return figure, axes


class DrawnSchedule(Protocol):
    """What :func:`figure_schedule` draws of a schedule that is not a designed one (a
    law learned at each held speed): the schedule, its check, its loop and hold."""

    @property
    def schedule(self) -> SpeedSchedule:
        """The laws at the grid speeds."""
        ...

    @property
    def check(self) -> ScheduleCheck:
        """The check at the fine speeds."""
        ...

    @property
    def loop(self) -> SampledLoop:
        """The sampled loop."""
        ...

    @property
    def hold(self) -> str:
        """What the drive holds over a sample."""
        ...


def figure_schedule(
    design: ScheduleDesign | CurrentScheduleDesign | DrawnSchedule,
    single_excess: Array,
    single_speed: float | None = None,
    single_label: str | None = None,
) -> Figure:
    """The schedule's gains, bandwidth and excess cost against its variable: electrical
    speed (a :class:`~selftune.model.ScheduleDesign`) or the q-axis current reference (a
    :class:`~selftune.model.CurrentScheduleDesign`).

    Parameters
    ----------
    design : ScheduleDesign or CurrentScheduleDesign
        The designed schedule and its check.
    single_excess : ndarray
        The single law's excess cost at the check's fine points
        (:meth:`~selftune.model.ScheduleDesign.excess_of`, or
        :func:`~selftune.model.excess_over` of the check's optima).
    single_speed : float, optional
        Where the single law was designed (rad/s electrical, or A of ``i_q*``; marked
        where inside the range).
    single_label : str, optional
        The single law's legend (default: "single-speed controller" over speed, "one law
        (rated current)" over current).

    Returns
    -------
    Figure
    """
    schedule, check = design.schedule, design.check
    over_speed = isinstance(schedule, SpeedSchedule)
    grid = schedule.grid
    speeds = np.unique(np.concatenate([grid, check.points]))
    laws = [schedule.law_at(float(speed)) for speed in speeds]
    figure, axes = _panels()
    gains, integral, rate, excess = axes
    for (row, column, label), colour in zip(_ENTRIES, _COLOURS, strict=True):
        gains.plot(speeds, [law.K[row, column] for law in laws], color=colour,
                   label=f"$K$ {label}")  # fmt: skip
        gains.plot(grid, schedule.table("K")[:, row, column], "o", color=colour)
        if schedule.laws[0].K_i is not None:
            integral.plot(speeds, [law.K_i[row, column] for law in laws if law.K_i is not None],
                          color=colour, label=f"$K_i$ {label}")  # fmt: skip
            integral.plot(grid, schedule.table("K_i")[:, row, column], "o", color=colour)
    gains.set_ylabel("$K$ (V/A)")
    gains.legend(loc="best", fontsize="small", title="lines: interpolated; dots: grid")
    integral.set_ylabel("$K_i$ (V/(A s))")
    if schedule.laws[0].K_i is None:
        integral.text(0.5, 0.5, "no integral action", transform=integral.transAxes,
                      ha="center", va="center")  # fmt: skip
    else:
        integral.legend(loc="best", fontsize="small")
    h = design.loop.h if not isinstance(design, CurrentScheduleDesign) else schedule.laws[0].h
    assert h is not None  # a current schedule's laws are servo laws, with their h
    rate.plot(check.points, bandwidth(check.radius, h), color=_SCHEDULE,
              label="interpolated schedule")  # fmt: skip
    rate.plot(check.points, bandwidth(check.optimal_radius, h), "--",
              color=_OPTIMUM, label="pointwise optimum")  # fmt: skip
    rate.set_ylabel("bandwidth $-\\ln\\rho/h$ (rad/s)")
    rate.legend(loc="best", fontsize="small")
    floor = 1e-12
    single = single_label or (
        "single-speed controller" if over_speed else "one law (rated current)"
    )
    excess.semilogy(check.points, np.maximum(check.excess, floor), color=_SCHEDULE,
                    label="interpolated schedule")  # fmt: skip
    excess.semilogy(check.points, np.maximum(single_excess, floor), color=_SINGLE,
                    label=single)  # fmt: skip
    excess.axhline(check.limit, color="black", linewidth=0.9, label=f"limit {check.limit:g}")
    if single_speed is not None and grid[0] <= single_speed <= grid[-1]:
        excess.axvline(single_speed, color=_SINGLE, linestyle=":", linewidth=0.9)
    excess.set_ylabel("excess cost (worst state)")
    excess.set_xlabel(
        "electrical speed $\\omega_e$ (rad/s)"
        if over_speed
        else "q-axis current reference $i_q^*$ (A)"
    )
    excess.legend(loc="best", fontsize="small")
    for point in grid:
        for panel in axes:
            panel.axvline(point, color="grey", linewidth=0.5, alpha=0.5)
    loop = (
        f"delay {design.loop.input_delay}, {design.hold} hold"
        if not isinstance(design, CurrentScheduleDesign)
        else f"{schedule.laws[0].history} past voltage(s) fed back"
    )
    figure.suptitle(
        f"{'Speed' if over_speed else 'Current'} schedule: {grid.size} grid {schedule.points}, "
        f"h = {h:g} s, {loop}",
        fontsize="medium",
    )
    return figure


def figure_speed_current(
    design: SpeedCurrentDesign,
    judged_speeds: Array,
    schedule_excess: Array,
    alone_excess: Array,
) -> Figure:
    """A schedule over speed and current against speed, one colour per grid current:
    ``K`` and ``K_i`` (their ``d on d`` entries solid, ``q on q`` dashed; the grid's
    laws as dots), the interpolated loop's bandwidth and the pointwise optimum's along
    each grid current, and the excess cost: the design's check along each grid current
    (over the identified models' optimum), and, over the true motor's optimum, the
    largest over the judged currents of the schedule and of the schedule over ``i_q*``
    alone (designed at one speed).

    Parameters
    ----------
    design : SpeedCurrentDesign
        The schedule and its check.
    judged_speeds : ndarray, shape (S,)
        The speeds judged against the true motor, rad/s (electrical).
    schedule_excess, alone_excess : ndarray, shape (S, N)
        The excess over the true optimum at those speeds and N currents, of the schedule
        and of the one over ``i_q*`` alone.

    Returns
    -------
    Figure
    """
    schedule, check = design.schedule, design.check
    speeds = np.unique(np.concatenate([schedule.electrical_speed, check.electrical_speed]))
    first = schedule.first_law
    h = first.h
    assert h is not None  # the laws are servo laws, with their h
    figure, axes = _panels()
    gains, integral, rate, excess = axes
    colours = colormaps["viridis"](np.linspace(0.0, 0.9, schedule.current.size))
    floor = 1e-12
    for index, (current, colour) in enumerate(zip(schedule.current, colours, strict=True)):
        row = schedule.rows[index]
        laws = [row.law_at(float(speed)) for speed in speeds]
        label = f"$i_q^*$ = {current:.3g} A"
        for (entry, style), (panel, name) in product(
            (((0, 0), "-"), ((1, 1), "--")), ((gains, "K"), (integral, "K_i"))
        ):
            if name == "K_i" and first.K_i is None:
                continue
            values = [getattr(law, name)[entry] for law in laws]
            panel.plot(speeds, values, style, color=colour,
                       label=label if entry == (0, 0) else None)  # fmt: skip
            panel.plot(schedule.electrical_speed, row.table(name)[:, entry[0], entry[1]], "o",
                       color=colour, markersize=3)  # fmt: skip
        along = np.flatnonzero(check.current == current)
        order = along[np.argsort(check.electrical_speed[along])]
        rate.plot(check.electrical_speed[order], bandwidth(check.radius[order], h),
                  color=colour, label=label)  # fmt: skip
        rate.plot(check.electrical_speed[order], bandwidth(check.optimal_radius[order], h),
                  ":", color=colour)  # fmt: skip
        excess.semilogy(check.electrical_speed[order], np.maximum(check.excess[order], floor),
                        color=colour, linewidth=0.8)  # fmt: skip
    gains.set_ylabel("$K$ (V/A)")
    gains.legend(loc="best", fontsize="small", title="solid: d on d; dashed: q on q")
    integral.set_ylabel("$K_i$ (V/(A s))")
    if first.K_i is None:
        integral.text(0.5, 0.5, "no integral action", transform=integral.transAxes,
                      ha="center", va="center")  # fmt: skip
    rate.set_ylabel("bandwidth $-\\ln\\rho/h$ (rad/s)")
    rate.legend(loc="best", fontsize="small", title="solid: interpolated; dotted: optimum")
    excess.semilogy(judged_speeds, np.maximum(np.max(schedule_excess, axis=1), floor),
                    color="black", label="schedule, true motor (worst current)")  # fmt: skip
    excess.semilogy(judged_speeds, np.maximum(np.max(alone_excess, axis=1), floor),
                    color=_SINGLE, label="schedule over $i_q^*$ alone, true motor")  # fmt: skip
    excess.axhline(check.limit, color="grey", linewidth=0.9, label=f"limit {check.limit:g}")
    excess.set_ylabel("excess cost (worst state)")
    excess.set_xlabel("electrical speed $\\omega_e$ (rad/s)")
    excess.legend(loc="best", fontsize="small", title="thin: check along each grid current")
    for point in schedule.electrical_speed:
        for panel in axes:
            panel.axvline(point, color="grey", linewidth=0.5, alpha=0.5)
    figure.suptitle(
        f"Speed and current schedule: {schedule.electrical_speed.size} speeds x "
        f"{schedule.current.size} currents, h = {h:g} s, {first.history} past voltage(s) fed "
        "back",
        fontsize="medium",
    )
    return figure
