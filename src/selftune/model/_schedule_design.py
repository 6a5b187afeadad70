"""The optimal digital controller designed over speed and checked between the grid speeds.

At a held speed the current loop's plant is ``A(omega) = A_0 + omega A_1``: the optimal
digital law (:func:`~selftune.model.solve_digital_regulation`, with the drive's delay and
integral action) changes with the speed. A firmware stores that law at a grid of
electrical speeds ``omega_e = p speed`` and interpolates ``K``, ``K_i``, ``U`` and ``X``
entrywise, linearly between the two neighbours of the speed it runs at
(:class:`~selftune.model.SpeedSchedule`, :meth:`~selftune.model.SpeedSchedule.law_at`).

:func:`design_schedule` designs the pointwise optimum at each grid speed, then checks the
interpolated schedule on a fine grid (:data:`FINE_POINTS` speeds strictly between each
pair of neighbours) against the pointwise optimum at each fine speed:

- the excess cost: the cost of the interpolated feedback ``[K, K_i]`` on the sampled loop
  at that speed over the optimum's, minus 1, for the worst initial state of the loop
  (``zeta_0' P zeta_0`` over ``zeta_0' P* zeta_0``, the largest eigenvalue of
  ``P*^-1 P``: every torque step included), at most :data:`EXCESS`; the loop's value
  ``P`` is :meth:`~selftune.loop.SampledLoop.values`;
- the stability margin: the interpolated loop's distance ``1 - rho`` from instability
  (rho its spectral radius) at least :data:`MARGIN_FRACTION` of the optimum's;
- the feedforward: ``U`` and ``X`` within :data:`FEEDFORWARD_ERROR` of the optimum's
  (relative, Frobenius norm): with integral action an error only moves the integrator's
  steady state, without it the current's.

Where an interval fails, its midpoint is added to the grid and its two halves are checked
again, up to :data:`MAX_POINTS` grid points (then :class:`~selftune.errors.UnsolvableError`
names the interval). Speeds are rad/s: the motor's methods take the mechanical speed, the
schedule is over the electrical speed. The motor is any object with ``p``,
``regulation_problem(speed)`` and ``sampled_plant(speed, h, hold)``
(:class:`ScheduledMotor`), whatever its number q of reference channels.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from itertools import pairwise
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike

from ..core import Array, ControlLaw, positive_finite, positive_integer
from ..errors import InputError, UnsolvableError
from ..loop import Hold, SampledLoop
from ._digital import solve_digital_regulation
from ._optimum import ModelBasedSolution
from ._problem import RegulationProblem
from ._schedule import SpeedSchedule

__all__ = [
    "COVERED_ROUNDING",
    "EXCESS",
    "FEEDFORWARD_ERROR",
    "FINE_POINTS",
    "MARGIN_FRACTION",
    "MAX_POINTS",
    "ScheduleCheck",
    "ScheduleDesign",
    "ScheduledMotor",
    "bandwidth",
    "check_covered",
    "design_schedule",
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


class ScheduledMotor(Protocol):
    """What a schedule needs of a motor (:class:`~selftune.model.SPMSM` has it)."""

    @property
    def p(self) -> int:
        """Pole pairs: the electrical speed is ``p`` times the mechanical."""
        ...

    def regulation_problem(self, speed: float) -> RegulationProblem:
        """The regulation problem at a held speed.

        Parameters
        ----------
        speed : float
            Mechanical speed, rad/s.
        """
        ...

    def sampled_plant(self, speed: float, h: float, hold: str = ...) -> tuple[Array, Array, Array]:
        """``(Ad, Bd, Ed)`` of :meth:`regulation_problem` sampled exactly.

        Parameters
        ----------
        speed : float
            Mechanical speed, rad/s.
        h : float
            Sampling period, s.
        hold : {"rotor", "stationary"}
            What the drive holds over a sample.
        """
        ...


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


@dataclass(frozen=True, eq=False)
class ScheduleCheck:
    """The interpolated schedule against the pointwise optimum on the fine grid.

    Attributes
    ----------
    electrical_speed : ndarray, shape (k,)
        The fine speeds, rad/s (electrical), between the grid speeds.
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

    electrical_speed: Array
    excess: Array
    radius: Array
    optimal_radius: Array
    feedforward_error: Array
    optima: tuple[ModelBasedSolution, ...] = field(repr=False)
    limit: float = EXCESS

    @property
    def passed(self) -> Array:
        """Whether each fine speed meets :attr:`limit`, :data:`MARGIN_FRACTION` and
        :data:`FEEDFORWARD_ERROR`."""
        return np.asarray(
            (self.excess <= self.limit)
            & (1.0 - self.radius >= MARGIN_FRACTION * (1.0 - self.optimal_radius))
            & (self.feedforward_error <= FEEDFORWARD_ERROR)
        )

    @property
    def worst(self) -> int:
        """The index of the fine speed with the largest excess cost."""
        return int(np.argmax(self.excess))


@dataclass(frozen=True, eq=False)
class _Design:
    """What every pointwise optimum of one schedule shares."""

    motor: ScheduledMotor
    Q: Array
    R: Array
    h: float
    input_delay: int
    integral_weight: Array | None
    hold: Hold

    def optimum(self, electrical_speed: float) -> ModelBasedSolution:
        """The digital optimum at ``electrical_speed`` (rad/s)."""
        speed = electrical_speed / self.motor.p
        return solve_digital_regulation(
            self.motor.regulation_problem(speed), self.Q, self.R, self.h,
            input_delay=self.input_delay, integral_weight=self.integral_weight,
            plant=self.motor.sampled_plant(speed, self.h, self.hold),
        )  # fmt: skip


@dataclass(frozen=True, eq=False)
class ScheduleDesign:
    """A designed schedule: the grid's optima, the schedule and its check.

    Attributes
    ----------
    schedule : SpeedSchedule
        The laws a drive interpolates.
    optima : tuple of ModelBasedSolution
        The pointwise optimum at each grid speed (``schedule.laws`` are their laws).
    check : ScheduleCheck
        The fine grid's check of the final grid.
    added : tuple of float
        The electrical speeds the refinement added, rad/s.
    loop : SampledLoop
        The sampled loop (period, delay, integrator and its weight) of every optimum.
    hold : str
        What the drive holds over a sample.
    """

    schedule: SpeedSchedule
    optima: tuple[ModelBasedSolution, ...]
    check: ScheduleCheck
    added: tuple[float, ...]
    loop: SampledLoop
    hold: str
    _design: _Design = field(repr=False)

    def pointwise_optimum(self, electrical_speed: float) -> ModelBasedSolution:
        """The digital optimum of this schedule's loop at one electrical speed (rad/s), as
        at the grid's speeds (e.g. a single-speed controller at an operating point).

        Parameters
        ----------
        electrical_speed : float
            rad/s (electrical), anywhere the motor's model holds.
        """
        return self._design.optimum(electrical_speed)

    def excess_of(self, law: ControlLaw | SpeedSchedule) -> Array:
        """The excess cost of one fixed ``law`` (e.g. one designed at a single speed), or
        of another schedule interpolated at each speed (e.g. one designed on an identified
        motor, judged on this design's true one), at each speed of the check's fine grid
        (:func:`worst_excess`; ``inf`` where it does not stabilize the loop).

        Parameters
        ----------
        law : ControlLaw or SpeedSchedule
            The law or the schedule (the loop's delay and integrator).
        """
        optima = self.check.optima
        plants = [optimum.sampled_plant[:2] for optimum in optima]
        weights = self.loop.weights(optima[0].Q, optima[0].R, "digital")
        laws: ControlLaw | list[ControlLaw] = law if isinstance(law, ControlLaw) else [
            law.law_at(float(speed)) for speed in self.check.electrical_speed
        ]  # fmt: skip
        values, _ = self.loop.values(plants, laws, weights)
        return worst_excess(values, np.array([optimum.P for optimum in optima]))


def _relative(error: Array, reference: Array) -> Array:
    """Frobenius norms of ``error`` over those of ``reference`` (stacks)."""
    scale = np.linalg.norm(reference, axis=(-2, -1))
    return np.asarray(np.linalg.norm(error, axis=(-2, -1)) / np.maximum(scale, 1e-300))


def bandwidth(radius: ArrayLike, h: float) -> Array:
    """The dominant-pole bandwidth of a sampled loop, ``-ln(rho) / h``, rad/s: the rate
    of its slowest mode (0 where rho >= 1, the loop unstable).

    Parameters
    ----------
    radius : array_like
        Spectral radii rho of the closed loop.
    h : float
        Sampling period, s.
    """
    radii = np.asarray(radius, dtype=float)
    with np.errstate(divide="ignore"):
        rates = -np.log(np.clip(radii, 1e-300, 1.0)) / h
    return np.asarray(np.where(radii < 1.0, rates, 0.0))


def _check_interval(
    design: _Design, schedule: SpeedSchedule, low: float, high: float, points: int, limit: float
) -> ScheduleCheck:
    """The check at ``points`` speeds strictly between ``low`` and ``high``."""
    speeds = np.linspace(low, high, points + 2)[1:-1]
    optima = tuple(design.optimum(float(speed)) for speed in speeds)
    laws = [schedule.law_at(float(speed)) for speed in speeds]
    loop = optima[0].loop
    plants = [optimum.sampled_plant[:2] for optimum in optima]
    weights = loop.weights(design.Q, design.R, "digital")
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
        electrical_speed=speeds,
        excess=excess,
        radius=np.asarray(radii, dtype=float),
        optimal_radius=optimal_radii,
        feedforward_error=feedforward,
        optima=optima,
        limit=limit,
    )


def _joined(checks: Sequence[ScheduleCheck]) -> ScheduleCheck:
    """The checks of consecutive intervals as one."""
    arrays = {
        name: np.concatenate([getattr(check, name) for check in checks])
        for name in (
            "electrical_speed", "excess", "radius", "optimal_radius", "feedforward_error",
        )
    }  # fmt: skip
    return ScheduleCheck(
        **arrays,
        optima=tuple(optimum for check in checks for optimum in check.optima),
        limit=checks[0].limit,
    )


def _grid(speeds: ArrayLike, p: int) -> Array:
    """The mechanical speeds as the electrical grid, validated."""
    values = np.asarray(speeds, dtype=float)
    if values.ndim != 1 or values.size < 2 or not np.all(np.isfinite(values)):
        raise InputError(f"speeds: needs at least two finite speeds (rad/s), got {speeds!r}")
    if not np.all(np.diff(values) > 0.0):
        raise InputError(f"speeds: must increase strictly, got {values.tolist()}")
    return p * values


#: How far (relative to the larger end) a speed may stray outside the covered range and
#: count as covered: the range is read off logged angles, to their rounding.
COVERED_ROUNDING = 1e-6


def check_covered(electrical_speeds: Sequence[float], covered: tuple[float, float]) -> None:
    """Refuse speeds outside the range the identification data cover, naming them.

    Parameters
    ----------
    electrical_speeds : sequence of float
        The speeds asked for, rad/s (electrical).
    covered : (float, float)
        The lowest and highest electrical speed of the data, rad/s.

    Raises
    ------
    InputError
        Naming every speed outside ``covered`` (beyond :data:`COVERED_ROUNDING`) and the
        range.
    """
    low, high = (float(value) for value in covered)
    slack = COVERED_ROUNDING * max(abs(low), abs(high))
    outside = [speed for speed in electrical_speeds if not low - slack <= speed <= high + slack]
    if outside:
        listed = ", ".join(f"{speed:g}" for speed in outside)
        raise InputError(
            f"speeds: {listed} rad/s (electrical) outside the speeds the data cover, "
            f"{low:g} to {high:g} rad/s (electrical): the identified motor is not known "
            "there; log those speeds or narrow the schedule"
        )


def design_schedule(
    motor: ScheduledMotor,
    speeds: ArrayLike,
    Q: ArrayLike,
    R: ArrayLike,
    h: float,
    *,
    input_delay: int = 1,
    integral_weight: ArrayLike | None = None,
    hold: Hold = "rotor",
    excess: float = EXCESS,
    fine_points: int = FINE_POINTS,
    max_points: int = MAX_POINTS,
    covered: tuple[float, float] | None = None,
) -> ScheduleDesign:
    """The digital optimum designed on a speed grid, interpolated and checked (see the
    module docstring); the grid refined by bisection where the check fails.

    Parameters
    ----------
    motor : ScheduledMotor
        The motor (e.g. :class:`~selftune.model.SPMSM`).
    speeds : array_like, shape (g,)
        The initial grid of mechanical speeds, rad/s, strictly increasing (at least two:
        ``[min, max]`` lets the refinement choose the rest).
    Q, R : array_like
        The continuous weights of the digital cost (as :func:`solve_digital_regulation`).
    h : float
        Sampling period, s.
    input_delay : int, optional
        d, the computation delay in samples (default 1).
    integral_weight : array_like, optional
        ``Q_i``: the optimal servo controller; None (default): no integral action.
    hold : {"rotor", "stationary"}, optional
        What the drive holds over a sample (``motor.sampled_plant``'s ``hold``).
    excess : float, optional
        The largest excess cost allowed at a fine speed (default :data:`EXCESS`, 1%).
    fine_points : int, optional
        Speeds checked between each pair of grid speeds (default :data:`FINE_POINTS`).
    max_points : int, optional
        The most grid speeds the refinement may reach (default :data:`MAX_POINTS`).
    covered : (float, float), optional
        The electrical speeds (rad/s, lowest and highest) the data the motor was
        identified from cover: a grid speed outside them is refused
        (:func:`check_covered`); None: no such limit (a motor known otherwise).

    Returns
    -------
    ScheduleDesign

    Raises
    ------
    InputError
        If the speeds are not strictly increasing finite numbers (at least two), lie
        outside ``covered`` (naming them), or an argument of
        :func:`solve_digital_regulation` is not as it requires.
    UnsolvableError
        If a pointwise optimum does not exist, or the grid would need more than
        ``max_points`` speeds (naming the interval that still fails and why).
    """
    grid = [float(speed) for speed in _grid(speeds, motor.p)]
    if covered is not None:
        check_covered(grid, covered)
    points = positive_integer(fine_points, "fine_points")
    allowed = positive_finite(excess, "excess")
    limit = positive_integer(max_points, "max_points", minimum=2)
    if len(grid) > limit:
        raise InputError(f"speeds: {len(grid)} speeds, more than max_points = {limit}")
    design = _Design(
        motor, np.asarray(Q, float), np.asarray(R, float), h, input_delay,
        None if integral_weight is None else np.asarray(integral_weight, float), hold,
    )  # fmt: skip
    optima = {speed: design.optimum(speed) for speed in grid}
    checks: dict[tuple[float, float], ScheduleCheck] = {}
    added: list[float] = []
    while True:
        schedule = SpeedSchedule(grid, [optima[speed].law for speed in grid])
        failing = None
        for low, high in pairwise(grid):
            if (low, high) not in checks:
                checks[(low, high)] = _check_interval(design, schedule, low, high, points, allowed)
            if failing is None and not np.all(checks[(low, high)].passed):
                failing = (low, high)
        if failing is None:
            break
        low, high = failing
        check = checks.pop(failing)
        if len(grid) >= limit:
            margin = (1.0 - check.radius) / (1.0 - check.optimal_radius)
            raise UnsolvableError(
                f"speeds: the schedule needs more than max_points = {limit} speeds: between "
                f"{low:g} and {high:g} rad/s (electrical) the interpolated law still has an "
                f"excess cost up to {np.max(check.excess):.3g} (limit {allowed:g}), 1 - rho "
                f"down to {np.min(margin):.3g} of the optimum's (limit {MARGIN_FRACTION:g}) "
                f"and a feedforward error up to {np.max(check.feedforward_error):.3g} "
                f"(limit {FEEDFORWARD_ERROR:g})"
            )
        middle = 0.5 * (low + high)
        optima[middle] = design.optimum(middle)
        grid = sorted([*grid, middle])
        added.append(middle)
    intervals = pairwise(grid)
    return ScheduleDesign(
        schedule=schedule,
        optima=tuple(optima[speed] for speed in grid),
        check=_joined([checks[interval] for interval in intervals]),
        added=tuple(added),
        loop=optima[grid[0]].loop,
        hold=hold,
        _design=design,
    )
