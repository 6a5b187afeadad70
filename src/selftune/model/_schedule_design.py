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

The refinement is :func:`refine_grid`, over any scheduling variable: the speed here,
and a saturating motor's q-axis current reference in :func:`design_current_schedule`
(the plant at a current given by the caller, e.g. identified incremental models
interpolated between the currents they were learned at).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike

from ..core import Array, ControlLaw, positive_finite, positive_integer
from ..errors import InputError
from ..loop import Hold, SampledLoop
from ._digital import solve_digital_regulation
from ._optimum import ModelBasedSolution
from ._problem import RegulationProblem
from ._refine import (
    EXCESS,
    FEEDFORWARD_ERROR,
    FINE_POINTS,
    MARGIN_FRACTION,
    MAX_POINTS,
    ScheduleCheck,
    excess_over,
    refine_grid,
    worst_excess,
)
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
        laws: ControlLaw | list[ControlLaw] = law if isinstance(law, ControlLaw) else [
            law.law_at(float(speed)) for speed in self.check.electrical_speed
        ]  # fmt: skip
        return excess_over(self.check.optima, laws)


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


def _grid(speeds: ArrayLike, p: int) -> Array:
    """The mechanical speeds as the electrical grid, validated."""
    values = np.asarray(speeds, dtype=float)
    if values.ndim != 1 or values.size < 2 or not np.all(np.isfinite(values)):
        raise InputError(f"speeds: needs at least two finite speeds (rad/s), got {speeds!r}")
    if not np.all(np.diff(values) > 0.0):
        raise InputError(f"speeds: must increase strictly, got {values.tolist()}")
    return p * values


#: How far (relative to the larger end) a speed may stray outside the covered range and
#: count as covered: the range is read off logged angles, to their resolution (an
#: encoder's count over a held part: 1,024 counts a turn on 20 pole pairs read a 40 ms
#: part's speed to 3 rad/s, 0.15% of 2,000 rad/s; a 16,384-count one on 9 pole pairs
#: read a 0.5 s part's to 4e-5 of it). The plant is affine in speed, so the schedule's
#: ends that far out are the data's.
COVERED_ROUNDING = 2e-3


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
    refined = refine_grid(
        design.optimum, grid, SpeedSchedule, name="speeds", points=points, excess=allowed,
        max_points=limit,
    )  # fmt: skip
    assert isinstance(refined.schedule, SpeedSchedule)
    return ScheduleDesign(
        schedule=refined.schedule,
        optima=refined.optima,
        check=refined.check,
        added=refined.added,
        loop=refined.optima[0].loop,
        hold=hold,
        _design=design,
    )
