"""A saturating motor's law scheduled over speed and current together.

A saturating motor's incremental inductances move with its current (its
:class:`~selftune.model.CurrentSchedule`), and every motor's sampled plant moves with its
speed (its :class:`~selftune.model.SpeedSchedule`); a drive that runs over both needs the
law at both. :class:`SpeedCurrentSchedule` stores it on a grid of electrical speeds times
q-axis current references and interpolates each matrix bilinearly: linearly in ``i_q*``
between the two neighbouring grid currents of the laws each neighbouring grid speed has
there, then linearly in ``omega_e`` (what a firmware does with a two-dimensional table).

:func:`design_speed_current_schedule` designs the pointwise digital optimum at every grid
point and checks the interpolated law against the pointwise optimum, by the rules of the
one-dimensional schedules (:mod:`._refine`: the excess cost for the worst initial state
at most 1%, the stability margin at least 90% of the optimum's, the feedforward within
1%), on lines through every cell of the grid, :data:`~._refine.FINE_POINTS` points
strictly inside each of its sides:

- along each grid current, between neighbouring grid speeds (a failure there bisects the
  speed interval);
- along each grid speed, between neighbouring grid currents (bisects the current
  interval);
- along the middle current of each current interval, between neighbouring grid speeds:
  the inside of the cell, where both interpolations act (bisects the current interval:
  along the grid currents the speed interpolation passed).

Bilinear interpolation on a cell is linear along each of those lines, so each is one
interval of a one-dimensional schedule, judged by :func:`~._refine.check_interval`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial
from itertools import pairwise

import numpy as np
from numpy.typing import ArrayLike

from ..core import Array, ControlLaw, finite_float, positive_finite, positive_integer
from ..errors import UnsolvableError
from ._digital import solve_digital_regulation
from ._optimum import ModelBasedSolution
from ._problem import RegulationProblem
from ._refine import (
    EXCESS,
    FINE_POINTS,
    MAX_POINTS,
    CheckRules,
    ScheduleCheck,
    check_grid,
    check_interval,
)
from ._schedule import CurrentSchedule, GainSchedule, SpeedSchedule, same_structure

__all__ = [
    "SpeedCurrentCheck",
    "SpeedCurrentDesign",
    "SpeedCurrentSchedule",
    "design_speed_current_schedule",
]


@dataclass(frozen=True, init=False, eq=False)
class SpeedCurrentSchedule:
    """Control laws on a grid of electrical speeds times q-axis current references,
    interpolated bilinearly (see the module).

    Parameters
    ----------
    electrical_speed : array_like, shape (s,)
        The speeds, rad/s (electrical), strictly increasing, at least two.
    current : array_like, shape (c,)
        The ``i_q*`` grid, A, strictly increasing, at least two.
    laws : sequence of sequence of ControlLaw
        ``laws[i][j]``: the law at ``current[i]`` and ``electrical_speed[j]``; all of
        one structure, ``C``, ``F`` and ``h``.

    Raises
    ------
    InputError
        If a grid is not strictly increasing finite numbers with at least two points, or
        the laws do not fit the grids or each other.
    """

    electrical_speed: Array
    current: Array
    rows: tuple[SpeedSchedule, ...] = field(repr=False)

    def __init__(
        self, electrical_speed: ArrayLike, current: ArrayLike, laws: Sequence[Sequence[ControlLaw]]
    ) -> None:
        rows = tuple(SpeedSchedule(electrical_speed, row) for row in laws)
        first_column = CurrentSchedule(current, [row.laws[0] for row in rows])  # the grid's checks
        same_structure([law for row in rows for law in row.laws])
        object.__setattr__(self, "electrical_speed", rows[0].grid)
        object.__setattr__(self, "current", first_column.grid)
        object.__setattr__(self, "rows", rows)

    @property
    def covered(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """The speeds (rad/s, electrical) and the currents (A) the schedule covers."""
        return self.rows[0].covered, (float(self.current[0]), float(self.current[-1]))

    @property
    def first_law(self) -> ControlLaw:
        """The law at the first point of both grids (its structure is every law's)."""
        return self.rows[0].first_law

    def law(self, index: int, speed_index: int) -> ControlLaw:
        """The grid's law at ``current[index]`` and ``electrical_speed[speed_index]``.

        Parameters
        ----------
        index : int
            The grid current's index.
        speed_index : int
            The grid speed's index.
        """
        return self.rows[index].laws[speed_index]

    def column(self, electrical_speed: float) -> CurrentSchedule:
        """The schedule over ``i_q*`` the firmware runs at one speed: each grid
        current's law interpolated to it over speed.

        Parameters
        ----------
        electrical_speed : float
            rad/s (electrical), within the covered speeds.
        """
        return CurrentSchedule(self.current, [row.law_at(electrical_speed) for row in self.rows])

    def law_at(self, electrical_speed: float, current: float) -> ControlLaw:
        """The law the firmware runs at a speed and a current: bilinear between the four
        grid laws about them (the grid's own law on a grid point).

        Parameters
        ----------
        electrical_speed : float
            rad/s (electrical), within the covered speeds.
        current : float
            ``i_q*``, A, within the covered currents.

        Raises
        ------
        InputError
            If either is outside the grid (naming it and the covered range).
        """
        at = finite_float(current, "current")
        return self.column(electrical_speed).law_at(at)

    def table(self, name: str) -> Array:
        """One matrix over the grid, shape ``(c, s, rows, columns)`` (current first).

        Parameters
        ----------
        name : {"K", "K_i", "U", "X"}
            The matrix.
        """
        return np.array([row.table(name) for row in self.rows])

    def document(self) -> dict[str, object]:
        """The schedule for a JSON result: ``electrical_speed`` (rad/s) and ``current``
        (A, ``i_q*``), and ``K``, ``K_i`` (null without integral action), ``U``, ``X``
        indexed ``[current][speed]`` in the convention of
        :meth:`~selftune.core.ControlLaw.document`, with what every entry shares."""
        first = self.rows[0].document()
        integral = self.first_law.K_i is not None
        return {
            "electrical_speed": self.electrical_speed,
            "current": self.current,
            "K": self.table("K"),
            "K_i": self.table("K_i") if integral else None,
            "U": self.table("U"),
            "X": self.table("X"),
            **{key: first[key] for key in ("history", "C", "F", "h", "state")},
            "equations": self.first_law.equations() + "; each matrix bilinear in "
            "omega_e and i_q* between the neighbouring speeds of electrical_speed and "
            "currents of current, indexed [current][speed]",
        }


@dataclass(frozen=True, eq=False)
class SpeedCurrentCheck(CheckRules):
    """The interpolated schedule against the pointwise optimum at the fine points of the
    lines through its cells (see the module).

    Attributes
    ----------
    electrical_speed, current : ndarray, shape (k,)
        Each fine point, rad/s (electrical) and A.
    excess : ndarray, shape (k,)
        The interpolated law's excess cost over the optimum (worst initial state).
    radius, optimal_radius : ndarray, shape (k,)
        The interpolated loop's spectral radius, and the optimum's.
    feedforward_error : ndarray, shape (k,)
        The larger relative error of the interpolated ``U`` and ``X``.
    limit : float
        The largest excess cost allowed.
    """

    electrical_speed: Array
    current: Array
    excess: Array
    radius: Array
    optimal_radius: Array
    feedforward_error: Array
    limit: float = EXCESS


@dataclass(frozen=True, eq=False)
class SpeedCurrentDesign:
    """A designed schedule over speed and current: the schedule, its check and the grid
    points the refinement added.

    Attributes
    ----------
    schedule : SpeedCurrentSchedule
        The laws a drive interpolates.
    check : SpeedCurrentCheck
        The fine points' check.
    added_speeds, added_currents : tuple of float
        The speeds (rad/s, electrical) and currents (A) the refinement added.
    """

    schedule: SpeedCurrentSchedule
    check: SpeedCurrentCheck
    added_speeds: tuple[float, ...]
    added_currents: tuple[float, ...]


#: The regulation problem and its exact sampled plant at ``(i_q*, omega_e)``.
PlantAt = Callable[[float, float], tuple[RegulationProblem, tuple[Array, Array, Array]]]

#: A line through the cells: what it runs along (``"speed"``, at a fixed current;
#: ``"current"``, at a fixed speed), that fixed value, and the grid (``"speed"`` or
#: ``"current"``) and interval a failure on it bisects.
_Line = tuple[str, float, str, tuple[float, float]]


def design_speed_current_schedule(
    plant: PlantAt,
    currents: ArrayLike,
    electrical_speeds: ArrayLike,
    Q: ArrayLike,
    R: ArrayLike,
    h: float,
    *,
    input_delay: int = 1,
    integral_weight: ArrayLike | None = None,
    excess: float = EXCESS,
    fine_points: int = FINE_POINTS,
    max_points: int = MAX_POINTS,
) -> SpeedCurrentDesign:
    """The digital optimum on a grid of currents times speeds, interpolated bilinearly,
    checked on lines through every cell and refined by bisection where the check fails
    (see the module).

    Parameters
    ----------
    plant : callable
        ``(i_q* (A), omega_e (rad/s)) -> (problem, (Ad, Bd, Ed))``: the regulation
        problem and its exact sampled plant there.
    currents : array_like, shape (c,)
        The initial ``i_q*`` grid, A, strictly increasing (at least two).
    electrical_speeds : array_like, shape (s,)
        The initial speed grid, rad/s (electrical), strictly increasing (at least two).
    Q, R : array_like
        The continuous weights of the digital cost.
    h : float
        Sampling period, s.
    input_delay : int, optional
        d, the computation delay in samples (default 1).
    integral_weight : array_like, optional
        ``Q_i``: the optimal servo controller; None (default): no integral action.
    excess, fine_points, max_points : optional
        As :func:`~selftune.model.design_schedule` (``max_points`` for each grid).

    Returns
    -------
    SpeedCurrentDesign

    Raises
    ------
    InputError
        If a grid is not strictly increasing finite numbers (at least two).
    UnsolvableError
        If a pointwise optimum does not exist, or a grid would need more than
        ``max_points`` points (naming the interval that still fails and why).
    """
    grids = {
        "current": check_grid(currents, "currents", "currents (A)"),
        "speed": check_grid(electrical_speeds, "electrical_speeds", "speeds (rad/s)"),
    }
    points = positive_integer(fine_points, "fine_points")
    allowed = positive_finite(excess, "excess")
    limit = positive_integer(max_points, "max_points", minimum=2)
    weights = np.asarray(Q, float), np.asarray(R, float)
    servo = None if integral_weight is None else np.asarray(integral_weight, float)
    optima: dict[tuple[float, float], ModelBasedSolution] = {}

    def optimum(current: float, speed: float) -> ModelBasedSolution:
        if (current, speed) not in optima:
            problem, sampled = plant(current, speed)
            optima[current, speed] = solve_digital_regulation(
                problem, *weights, h, input_delay=input_delay, integral_weight=servo,
                plant=sampled,
            )  # fmt: skip
        return optima[current, speed]

    checks: dict[tuple[object, ...], tuple[_Line, ScheduleCheck]] = {}
    added: dict[str, list[float]] = {"current": [], "speed": []}
    while True:
        lines = _lines(grids, optimum, points, allowed, checks)
        failing = next((line for line, check in lines if not np.all(check.passed)), None)
        if failing is None:
            break
        _, _, axis, (low, high) = failing
        if len(grids[axis]) >= limit:
            check = next(check for line, check in lines if line == failing)
            raise _too_many(axis, (low, high), check, limit)
        middle = 0.5 * (low + high)
        grids[axis] = sorted([*grids[axis], middle])
        added[axis].append(middle)
    schedule = SpeedCurrentSchedule(
        grids["speed"], grids["current"],
        [[optimum(c, s).law for s in grids["speed"]] for c in grids["current"]],
    )  # fmt: skip
    return SpeedCurrentDesign(
        schedule, _joined(lines, allowed), tuple(added["speed"]), tuple(added["current"])
    )


def _lines(
    grids: dict[str, list[float]],
    optimum: Callable[[float, float], ModelBasedSolution],
    points: int,
    allowed: float,
    checks: dict[tuple[object, ...], tuple[_Line, ScheduleCheck]],
) -> list[tuple[_Line, ScheduleCheck]]:
    """The checks of every line through the grid's cells (cached: a line's check depends
    only on its ends' laws), each with the interval a failure on it bisects: along a grid
    current, the speed interval; along a grid speed or inside a cell, the current's."""
    speeds, currents = grids["speed"], grids["current"]
    found = []

    def judged(line: _Line, interval: tuple[float, float], laws: list[ControlLaw]) -> None:
        along, fixed, _, _ = line
        key = (*line, interval)
        if key not in checks:
            schedule: GainSchedule
            if along == "speed":
                at, schedule = partial(_at_current, optimum, fixed), SpeedSchedule(interval, laws)
            else:
                at, schedule = partial(_at_speed, optimum, fixed), CurrentSchedule(interval, laws)
            checks[key] = (line, check_interval(at, schedule, interval, points, allowed))
        found.append(checks[key])

    for current in currents:  # along each grid current
        for interval in pairwise(speeds):
            laws = [optimum(current, speed).law for speed in interval]
            judged(("speed", current, "speed", interval), interval, laws)
    for speed in speeds:  # along each grid speed
        for interval in pairwise(currents):
            laws = [optimum(current, speed).law for current in interval]
            judged(("current", speed, "current", interval), interval, laws)
    for cell in pairwise(currents):  # inside each cell: along its middle current
        middle = 0.5 * (cell[0] + cell[1])
        for interval in pairwise(speeds):
            laws = [  # each end's laws interpolated in the current, as bilinearly
                CurrentSchedule(cell, [optimum(current, speed).law for current in cell])
                .law_at(middle)
                for speed in interval
            ]  # fmt: skip
            judged(("speed", middle, "current", cell), interval, laws)
    return found


def _at_current(
    optimum: Callable[[float, float], ModelBasedSolution], current: float, speed: float
) -> ModelBasedSolution:
    """The optimum at ``(current, speed)``: a line along speed at one current."""
    return optimum(current, speed)


def _at_speed(
    optimum: Callable[[float, float], ModelBasedSolution], speed: float, current: float
) -> ModelBasedSolution:
    """The optimum at ``(current, speed)``: a line along current at one speed."""
    return optimum(current, speed)


def _joined(lines: list[tuple[_Line, ScheduleCheck]], allowed: float) -> SpeedCurrentCheck:
    """The lines' checks as one, each fine point with its speed and current."""
    speeds, currents = [], []
    for (along, fixed, _, _), check in lines:
        at = np.full(check.points.size, fixed)
        speeds.append(check.points if along == "speed" else at)
        currents.append(at if along == "speed" else check.points)
    metrics = {
        name: np.concatenate([getattr(check, name) for _, check in lines])
        for name in ("excess", "radius", "optimal_radius", "feedforward_error")
    }
    return SpeedCurrentCheck(
        np.concatenate(speeds), np.concatenate(currents), **metrics, limit=allowed
    )


def _too_many(
    axis: str, interval: tuple[float, float], check: ScheduleCheck, limit: int
) -> UnsolvableError:
    """The refusal when a grid would need more than ``limit`` points."""
    low, high = interval
    unit, what = ("rad/s (electrical)", "speeds") if axis == "speed" else ("A (i_q*)", "currents")
    return UnsolvableError(
        f"{what}: the schedule over speed and current needs more than max_points = {limit} "
        f"{what}: between {low:g} and {high:g} {unit} the interpolated law still has "
        f"{check.shortfall()}"
    )
