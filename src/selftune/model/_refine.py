"""A gain schedule's refinement over any scheduling variable: the pointwise optima on a
grid, the interpolated law checked against them on a fine grid between the grid's
points, and the grid bisected where the check fails.

The rules (the excess cost for the worst initial state at most :data:`EXCESS`, the
stability margin at least :data:`MARGIN_FRACTION` of the optimum's, the feedforward
within :data:`FEEDFORWARD_ERROR`, at most :data:`MAX_POINTS` grid points) are the speed
schedule's (:mod:`._schedule_design`, where they are told in full); the current schedule
(:mod:`._current_schedule`) uses the same ones through :func:`refine_grid`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from itertools import pairwise
from typing import Protocol

import numpy as np

from ..core import Array, ControlLaw
from ..errors import InputError, UnsolvableError
from ..loop import SampledLoop
from ._optimum import ModelBasedSolution
from ._schedule import GainSchedule

__all__ = [
    "EXCESS",
    "FEEDFORWARD_ERROR",
    "FINE_POINTS",
    "MARGIN_FRACTION",
    "MAX_POINTS",
    "CheckRules",
    "PointOptimum",
    "RefinedGrid",
    "ScheduleCheck",
    "check_grid",
    "check_interval",
    "excess_over",
    "joined_checks",
    "refine_grid",
    "worst_excess",
]

#: The largest excess cost of the interpolated schedule over the pointwise digital
#: optimum at any speed of the fine grid (0.01: 1%).
EXCESS = 0.01

#: Speeds checked strictly between each pair of neighbouring grid speeds.
FINE_POINTS = 50

#: The stability margin: the interpolated loop's ``1 - rho`` (rho its spectral radius)
#: at least this share of the pointwise optimum's.
MARGIN_FRACTION = 0.9

#: The largest relative error (Frobenius norm) of the interpolated ``U`` and ``X``.
FEEDFORWARD_ERROR = 0.01

#: The most grid speeds a schedule may need before the design gives up.
MAX_POINTS = 65


class PointOptimum(Protocol):
    """What the check reads of a pointwise optimum (a
    :class:`~selftune.model.ModelBasedSolution`, or an optimum designed on an identified
    sampled plant): its loop, continuous weights, sampled plant, value and law."""

    @property
    def loop(self) -> SampledLoop:
        """The sampled loop (period, delay, integral action)."""
        ...

    @property
    def Q(self) -> Array:
        """The state weight."""
        ...

    @property
    def R(self) -> Array:
        """The input weight."""
        ...

    @property
    def P(self) -> Array:
        """The optimal value over the loop's state."""
        ...

    @property
    def law(self) -> ControlLaw:
        """The optimal law."""
        ...

    @property
    def sampled_plant(self) -> tuple[Array, Array, Array]:
        """``(Ad, Bd, Ed)``."""
        ...

    @property
    def U(self) -> Array:
        """The law's feedforward."""
        ...

    @property
    def X(self) -> Array:
        """The law's steady-state map."""
        ...


def check_grid(values: object, name: str, what: str) -> list[float]:
    """A schedule's initial grid as floats, or an error naming ``name``: at least two
    finite values, strictly increasing.

    Parameters
    ----------
    values : array_like
        The grid.
    name : str
        The argument it came from.
    what : str
        What its values are, with their unit (``"currents (A)"``).

    Raises
    ------
    InputError
        Naming ``name``.
    """
    grid = np.asarray(values, dtype=float)
    if grid.ndim != 1 or grid.size < 2 or not np.all(np.isfinite(grid)):
        raise InputError(f"{name}: needs at least two finite {what}, got {values!r}")
    if not np.all(np.diff(grid) > 0.0):
        raise InputError(f"{name}: must increase strictly, got {grid.tolist()}")
    return [float(value) for value in grid]


def worst_excess(P: Array, P_optimal: Array) -> Array:
    """The excess cost of a loop's value ``P`` over the optimum's ``P*`` for the worst
    initial state: ``max_zeta zeta' P zeta / zeta' P* zeta - 1``, the largest eigenvalue
    of ``P*^-1 P`` minus 1 (``inf`` where ``P`` is).

    Parameters
    ----------
    P : ndarray, shape (..., nz, nz)
        The values of a law (from :meth:`~selftune.loop.SampledLoop.values`).
    P_optimal : ndarray, shape (..., nz, nz)
        The optimal values, positive definite.

    Returns
    -------
    ndarray, shape (...)
    """
    P_, optimal = np.asarray(P, dtype=float), np.asarray(P_optimal, dtype=float)
    finite = np.all(np.isfinite(P_), axis=(-2, -1))
    lower = np.linalg.cholesky(0.5 * (optimal + np.swapaxes(optimal, -1, -2)))
    safe = np.where(finite[..., None, None], P_, optimal)
    half = np.linalg.solve(lower, safe)
    whitened = np.linalg.solve(lower, np.swapaxes(half, -1, -2))
    largest = np.linalg.eigvalsh(0.5 * (whitened + np.swapaxes(whitened, -1, -2)))[..., -1]
    return np.asarray(np.where(finite, largest - 1.0, np.inf), dtype=float)


class CheckRules:
    """The rules every schedule's check applies at its fine points, for a check that has
    ``excess``, ``radius``, ``optimal_radius``, ``feedforward_error`` (arrays) and
    ``limit`` (:class:`ScheduleCheck`, :class:`~._speed_current.SpeedCurrentCheck`)."""

    excess: Array
    radius: Array
    optimal_radius: Array
    feedforward_error: Array
    limit: float

    @property
    def passed(self) -> Array:
        """Whether each fine point meets :attr:`limit`, :data:`MARGIN_FRACTION` and
        :data:`FEEDFORWARD_ERROR`."""
        return np.asarray(
            (self.excess <= self.limit)
            & (1.0 - self.radius >= MARGIN_FRACTION * (1.0 - self.optimal_radius))
            & (self.feedforward_error <= FEEDFORWARD_ERROR)
        )

    @property
    def worst(self) -> int:
        """The index of the fine point with the largest excess cost."""
        return int(np.argmax(self.excess))

    def shortfall(self) -> str:
        """What the check found against its rules, in words: the largest excess, the
        smallest share of the optimum's margin and the largest feedforward error, each with
        its limit (a refusal's text)."""
        margin = (1.0 - self.radius) / (1.0 - self.optimal_radius)
        return (
            f"an excess cost up to {np.max(self.excess):.3g} (limit {self.limit:g}), "
            f"1 - rho down to {np.min(margin):.3g} of the optimum's (limit "
            f"{MARGIN_FRACTION:g}) and a feedforward error up to "
            f"{np.max(self.feedforward_error):.3g} (limit {FEEDFORWARD_ERROR:g})"
        )


@dataclass(frozen=True, eq=False)
class ScheduleCheck(CheckRules):
    """The interpolated schedule against the pointwise optimum on the fine grid.

    Attributes
    ----------
    points : ndarray, shape (k,)
        The fine grid between the grid's points: electrical speeds, rad/s (a
        :class:`SpeedSchedule`'s, also :attr:`electrical_speed`), or q-axis currents, A
        (a :class:`~selftune.model.CurrentSchedule`'s).
    excess : ndarray, shape (k,)
        The interpolated law's excess cost over the optimum (:func:`worst_excess`).
    radius : ndarray, shape (k,)
        The interpolated loop's spectral radius rho.
    optimal_radius : ndarray, shape (k,)
        The optimum's.
    feedforward_error : ndarray, shape (k,)
        The larger relative error of the interpolated ``U`` and ``X``.
    optima : tuple of ModelBasedSolution
        The pointwise optimum at each fine speed.
    limit : float
        The largest excess cost allowed (:data:`EXCESS` by default).
    """

    points: Array
    excess: Array
    radius: Array
    optimal_radius: Array
    feedforward_error: Array
    optima: tuple[PointOptimum, ...] = field(repr=False)
    limit: float = EXCESS

    @property
    def electrical_speed(self) -> Array:
        """The fine speeds of a speed schedule's check, rad/s (electrical): :attr:`points`."""
        return self.points


def excess_over(optima: Sequence[PointOptimum], laws: ControlLaw | list[ControlLaw]) -> Array:
    """The excess cost (:func:`worst_excess`) of ``laws`` (one for all, or one each) on
    the plants of ``optima`` (pointwise optima of one loop) over those optima.

    Parameters
    ----------
    optima : sequence of ModelBasedSolution
        The pointwise optima: their sampled plants, loop, weights and values.
    laws : ControlLaw or list of ControlLaw
        The law judged at every optimum's plant, or one law each.

    Returns
    -------
    ndarray, shape (len(optima),)
        ``inf`` where a law does not stabilize its plant.
    """
    loop = optima[0].loop
    plants = [optimum.sampled_plant[:2] for optimum in optima]
    weights = loop.weights(optima[0].Q, optima[0].R, "digital")
    values, _ = loop.values(plants, laws, weights)
    return worst_excess(values, np.array([optimum.P for optimum in optima]))


def _relative(error: Array, reference: Array) -> Array:
    """Frobenius norms of ``error`` over those of ``reference`` (stacks)."""
    scale = np.linalg.norm(reference, axis=(-2, -1))
    return np.asarray(np.linalg.norm(error, axis=(-2, -1)) / np.maximum(scale, 1e-300))


def check_interval(
    optimum: Callable[[float], PointOptimum],
    schedule: GainSchedule,
    interval: tuple[float, float],
    points: int,
    limit: float,
) -> ScheduleCheck:
    """The check of ``schedule`` against ``optimum`` at ``points`` points strictly between
    the interval's ends (of the schedule's variable; the one check of every schedule).

    Parameters
    ----------
    optimum : callable
        The digital optimum at one value of the variable.
    schedule : GainSchedule
        The interpolated laws (covering the interval).
    interval : (float, float)
        The two grid points.
    points : int
        How many points strictly between them.
    limit : float
        The largest excess cost allowed.
    """
    low, high = interval
    speeds = np.linspace(low, high, points + 2)[1:-1]
    optima = tuple(optimum(float(speed)) for speed in speeds)
    laws = [schedule.law_at(float(speed)) for speed in speeds]
    loop = optima[0].loop
    plants = [optimum.sampled_plant[:2] for optimum in optima]
    weights = loop.weights(optima[0].Q, optima[0].R, "digital")
    values, radii = loop.values(plants, laws, weights)
    excess = worst_excess(values, np.array([optimum.P for optimum in optima]))
    pairs = zip(plants, optima, strict=True)
    optimal_radii = np.array([loop.spectral_radius(plant, optimum.law) for plant, optimum in pairs])
    feedforward = np.maximum(
        _relative(
            np.array([law.U for law in laws]) - np.array([o.U for o in optima]),
            np.array([o.U for o in optima]),
        ),
        _relative(
            np.array([law.X for law in laws]) - np.array([o.X for o in optima]),
            np.array([o.X for o in optima]),
        ),
    )
    return ScheduleCheck(
        points=speeds,
        excess=excess,
        radius=np.asarray(radii, dtype=float),
        optimal_radius=optimal_radii,
        feedforward_error=feedforward,
        optima=optima,
        limit=limit,
    )


def joined_checks(checks: Sequence[ScheduleCheck]) -> ScheduleCheck:
    """The checks of consecutive intervals as one."""
    arrays = {
        name: np.concatenate([getattr(check, name) for check in checks])
        for name in (
            "points", "excess", "radius", "optimal_radius", "feedforward_error",
        )
    }  # fmt: skip
    return ScheduleCheck(
        **arrays,
        optima=tuple(optimum for check in checks for optimum in check.optima),
        limit=checks[0].limit,
    )


@dataclass(frozen=True, eq=False)
class RefinedGrid:
    """What :func:`refine_grid` found: the final grid's schedule, its optima and check.

    Attributes
    ----------
    schedule : GainSchedule
        The laws a drive interpolates.
    optima : tuple of ModelBasedSolution
        The pointwise optimum at each grid point (``schedule.laws`` are their laws).
    check : ScheduleCheck
        The fine grid's check of the final grid.
    added : tuple of float
        The points the refinement added.
    """

    schedule: GainSchedule
    optima: tuple[ModelBasedSolution, ...]
    check: ScheduleCheck
    added: tuple[float, ...]


def refine_grid(
    optimum: Callable[[float], ModelBasedSolution],
    grid: Sequence[float],
    kind: type[GainSchedule],
    *,
    name: str,
    points: int,
    excess: float,
    max_points: int,
) -> RefinedGrid:
    """The schedule of the pointwise optima on a grid of a scheduling variable, checked
    on a fine grid between its points and refined by bisection where the check fails (the
    module docstring's rules), whatever the variable: the one refinement of
    :func:`design_schedule` (speed) and :func:`design_current_schedule` (current).

    Parameters
    ----------
    optimum : callable
        The digital optimum at one value of the variable.
    grid : sequence of float
        The initial grid, strictly increasing (validated by the caller).
    kind : type of GainSchedule
        The schedule built (its variable's names and unit are the messages').
    name : str
        The argument the grid came from (the refusal names it).
    points : int
        Points checked between each pair of grid points.
    excess : float
        The largest excess cost allowed at a fine point.
    max_points : int
        The most grid points the refinement may reach.

    Raises
    ------
    UnsolvableError
        If the grid would need more than ``max_points`` points (naming the interval that
        still fails and why).
    """
    values = [float(value) for value in grid]
    optima = {value: optimum(value) for value in values}
    checks: dict[tuple[float, float], ScheduleCheck] = {}
    added: list[float] = []
    while True:
        schedule = kind(values, [optima[value].law for value in values])
        failing = None
        for interval in pairwise(values):
            if interval not in checks:
                checks[interval] = check_interval(optimum, schedule, interval, points, excess)
            if failing is None and not np.all(checks[interval].passed):
                failing = interval
        if failing is None:
            break
        low, high = failing
        check = checks.pop(failing)
        if len(values) >= max_points:
            raise UnsolvableError(
                f"{name}: the schedule needs more than max_points = {max_points} {kind.points}: "
                f"between {low:g} and {high:g} {kind.unit}{kind.frame} the interpolated law "
                f"still has {check.shortfall()}"
            )
        middle = 0.5 * (low + high)
        optima[middle] = optimum(middle)
        values = sorted([*values, middle])
        added.append(middle)
    return RefinedGrid(
        schedule=schedule,
        optima=tuple(optima[value] for value in values),
        check=joined_checks([checks[interval] for interval in pairwise(values)]),
        added=tuple(added),
    )
