"""A saturating motor's law scheduled over its q-axis current reference.

A saturating motor's incremental inductances move with its current, so its digital
optimum does too: :func:`design_current_schedule` designs it at a grid of ``i_q*``
(A), interpolates ``K``, ``K_i``, ``U``, ``X`` linearly between them
(:class:`~selftune.model.CurrentSchedule`) and checks and refines the grid by the speed
schedule's rules (:func:`~._refine.refine_grid`). The plant at a current is the
caller's (e.g. identified incremental models interpolated between the currents they were
learned at: :func:`selftune.tuning.commission_over_current`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..core import Array, positive_finite, positive_integer
from ._digital import solve_digital_regulation
from ._optimum import ModelBasedSolution
from ._problem import RegulationProblem
from ._refine import EXCESS, FINE_POINTS, MAX_POINTS, ScheduleCheck, check_grid, refine_grid
from ._schedule import CurrentSchedule

__all__ = ["CurrentScheduleDesign", "PlantAt", "design_current_schedule"]


@dataclass(frozen=True, eq=False)
class CurrentScheduleDesign:
    """A designed current schedule: the grid's optima, the schedule and its check.

    Attributes
    ----------
    schedule : CurrentSchedule
        The laws a drive interpolates over ``i_q*``.
    optima : tuple of ModelBasedSolution
        The pointwise optimum at each grid current.
    check : ScheduleCheck
        The fine grid's check (its points are currents, A).
    added : tuple of float
        The currents the refinement added, A.
    """

    schedule: CurrentSchedule
    optima: tuple[ModelBasedSolution, ...]
    check: ScheduleCheck
    added: tuple[float, ...]


#: The regulation problem and its exact sampled plant ``(Ad, Bd, Ed)`` at one current.
PlantAt = Callable[[float], tuple[RegulationProblem, tuple[Array, Array, Array]]]


def design_current_schedule(
    plant: PlantAt,
    currents: ArrayLike,
    Q: ArrayLike,
    R: ArrayLike,
    h: float,
    *,
    input_delay: int = 1,
    integral_weight: ArrayLike | None = None,
    excess: float = EXCESS,
    fine_points: int = FINE_POINTS,
    max_points: int = MAX_POINTS,
) -> CurrentScheduleDesign:
    """The digital optimum designed on a grid of q-axis current references, interpolated
    and checked on a fine grid between them, refined by bisection where the check fails
    (:func:`refine_grid`, the speed schedule's rules; see the module docstring).

    A saturating motor's incremental model moves with its current; ``plant`` gives it at
    any current of the grid's range (e.g. the models identified at the grid's currents,
    interpolated between them), and the check judges the interpolated law against that
    model's pointwise optimum.

    Parameters
    ----------
    plant : callable
        ``i_q* (A) -> (problem, (Ad, Bd, Ed))``: the regulation problem and its exact
        sampled plant at that current.
    currents : array_like, shape (g,)
        The initial grid of ``i_q*``, A, strictly increasing (at least two).
    Q, R : array_like
        The continuous weights of the digital cost.
    h : float
        Sampling period, s.
    input_delay : int, optional
        d, the computation delay in samples (default 1).
    integral_weight : array_like, optional
        ``Q_i``: the optimal servo controller; None (default): no integral action.
    excess, fine_points, max_points : optional
        As :func:`design_schedule`.

    Returns
    -------
    CurrentScheduleDesign

    Raises
    ------
    InputError
        If the currents are not strictly increasing finite numbers (at least two).
    UnsolvableError
        If a pointwise optimum does not exist, or the grid would need more than
        ``max_points`` currents.
    """
    grid = check_grid(currents, "currents", "currents (A)")
    weights = np.asarray(Q, float), np.asarray(R, float)
    servo = None if integral_weight is None else np.asarray(integral_weight, float)

    def optimum(current: float) -> ModelBasedSolution:
        problem, sampled = plant(current)
        return solve_digital_regulation(
            problem, *weights, h, input_delay=input_delay, integral_weight=servo,
            plant=sampled,
        )  # fmt: skip

    refined = refine_grid(
        optimum, grid, CurrentSchedule, name="currents",
        points=positive_integer(fine_points, "fine_points"),
        excess=positive_finite(excess, "excess"),
        max_points=positive_integer(max_points, "max_points", minimum=2),
    )  # fmt: skip
    assert isinstance(refined.schedule, CurrentSchedule)
    return CurrentScheduleDesign(refined.schedule, refined.optima, refined.check, refined.added)
