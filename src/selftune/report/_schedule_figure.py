"""The speed schedule's figure: gains, bandwidth and excess cost against electrical speed.

:func:`figure_schedule` draws a :class:`~selftune.model.ScheduleDesign` in four panels
over the electrical speed ``omega_e`` (rad/s):

- the state feedback ``K`` (its entries on ``i_d``, ``i_q``, V/A), the grid's laws as
  markers and the interpolated schedule (:meth:`~selftune.model.SpeedSchedule.law_at`)
  as lines;
- the integral gain ``K_i`` (V/(A s)), likewise (a law without one: the panel says so);
- the closed loop's dominant-pole bandwidth ``-ln(rho) / h`` (rad/s) of the interpolated
  schedule and of the pointwise optimum, at the check's fine speeds;
- the excess cost over the pointwise optimum (worst initial state, dimensionless, log
  scale) of the schedule and of the single-speed controller, with the limit.

The figure is a :class:`matplotlib.figure.Figure` with an Agg canvas (no pyplot), as
the reproduction's (:mod:`._figures`); :func:`~selftune.report.save_figure` writes it.
"""

from __future__ import annotations

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..core import Array
from ..model import ScheduleDesign, bandwidth

__all__ = ["figure_schedule"]

#: The entries of K and K_i drawn: (row, column, label), as ``u_row`` on ``x_column``.
_ENTRIES = ((0, 0, "d on d"), (0, 1, "d on q"), (1, 0, "q on d"), (1, 1, "q on q"))

#: Colours of the entries, the schedule, the optimum and the single-speed controller.
_COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd")
_SCHEDULE, _OPTIMUM, _SINGLE = "#1f77b4", "#2ca02c", "#ff7f0e"


def figure_schedule(
    design: ScheduleDesign, single_excess: Array, single_speed: float | None = None
) -> Figure:
    """The schedule's gains, bandwidth and excess cost against electrical speed.

    Parameters
    ----------
    design : ScheduleDesign
        The designed schedule and its check.
    single_excess : ndarray
        The single-speed controller's excess cost at the check's fine speeds
        (:meth:`~selftune.model.ScheduleDesign.excess_of`).
    single_speed : float, optional
        The electrical speed it was designed at, rad/s (marked where inside the range).

    Returns
    -------
    Figure
    """
    schedule, check = design.schedule, design.check
    grid = schedule.electrical_speed
    speeds = np.unique(np.concatenate([grid, check.electrical_speed]))
    laws = [schedule.law_at(float(speed)) for speed in speeds]
    figure = Figure(figsize=(7.0, 9.0), layout="constrained")
    FigureCanvasAgg(figure)
    axes = list(figure.subplots(4, 1, sharex=True, squeeze=False)[:, 0])
    for panel in axes:
        panel.grid(True, alpha=0.3)
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
    h = design.loop.h
    rate.plot(check.electrical_speed, bandwidth(check.radius, h), color=_SCHEDULE,
              label="interpolated schedule")  # fmt: skip
    rate.plot(check.electrical_speed, bandwidth(check.optimal_radius, h), "--",
              color=_OPTIMUM, label="pointwise optimum")  # fmt: skip
    rate.set_ylabel("bandwidth $-\\ln\\rho/h$ (rad/s)")
    rate.legend(loc="best", fontsize="small")
    floor = 1e-12
    excess.semilogy(check.electrical_speed, np.maximum(check.excess, floor), color=_SCHEDULE,
                    label="interpolated schedule")  # fmt: skip
    excess.semilogy(check.electrical_speed, np.maximum(single_excess, floor), color=_SINGLE,
                    label="single-speed controller")  # fmt: skip
    excess.axhline(check.limit, color="black", linewidth=0.9, label=f"limit {check.limit:g}")
    if single_speed is not None and grid[0] <= single_speed <= grid[-1]:
        excess.axvline(single_speed, color=_SINGLE, linestyle=":", linewidth=0.9)
    excess.set_ylabel("excess cost (worst state)")
    excess.set_xlabel("electrical speed $\\omega_e$ (rad/s)")
    excess.legend(loc="best", fontsize="small")
    for speed in grid:
        for panel in axes:
            panel.axvline(speed, color="grey", linewidth=0.5, alpha=0.5)
    figure.suptitle(
        f"Speed schedule: {grid.size} grid speeds, h = {h:g} s, delay "
        f"{design.loop.input_delay}, {design.hold} hold",
        fontsize="medium",
    )
    return figure
