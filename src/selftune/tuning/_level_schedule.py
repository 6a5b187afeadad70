"""The schedule designed on a saturating motor's levels: the digital optimum at each
level's identified incremental model, interpolated linearly in ``i_q*`` between them
(:func:`level_plants`), scheduled over ``i_q*`` (:func:`schedule_over_levels`) or over
speed and ``i_q*`` together (:func:`schedule_over_speed_and_levels`). The levels are
:mod:`._saturation`'s, commissioned or learned from logs (``selftune learn``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from ..core import Array
from ..learn import IncrementalStructure
from ..model import (
    CurrentScheduleDesign,
    RegulationProblem,
    SpeedCurrentDesign,
    design_current_schedule,
    design_speed_current_schedule,
)
from ..model._speed_current import PlantAt
from ._interior import CURRENT_REFERENCE_F

__all__ = ["by_current", "level_plants", "schedule_over_levels", "schedule_over_speed_and_levels"]


def by_current(currents: Array, thetas: Array) -> tuple[Array, Array]:
    """The levels' ``i_q*`` (A) and parameters in rising ``i_q*``, as a schedule's grid
    and an interpolation need (a negative torque's levels, by rising share, fall).

    Parameters
    ----------
    currents : ndarray, shape (g,)
        The levels' ``i_q*``, A, distinct.
    thetas : ndarray, shape (g, 6)
        Their identified parameters, row by row.
    """
    current, theta = np.asarray(currents, dtype=float), np.asarray(thetas, dtype=float)
    order = np.argsort(current)
    return current[order], theta[order]


def level_plants(currents: Array, thetas: Array, structure: IncrementalStructure) -> PlantAt:
    """The plant at a current and an electrical speed from the levels' identified models,
    interpolated linearly in ``i_q*`` between them (the structure's model at that speed).

    Parameters
    ----------
    currents : ndarray, shape (g,)
        The levels' ``i_q*``, A, distinct, in any order (:func:`by_current`).
    thetas : ndarray, shape (g, 6)
        Their identified parameters (:func:`~._saturation.incremental_parameters`).
    structure : IncrementalStructure
        The structure (sampling period, hold), without the dead-time channels.
    """
    currents, thetas = by_current(currents, thetas)

    def plant(current: float, speed: float) -> tuple[RegulationProblem, tuple[Array, Array, Array]]:
        theta = np.array([np.interp(current, currents, column) for column in thetas.T])
        at = replace(structure, electrical_speed=speed)
        A, B, D = at.continuous(theta)
        problem = RegulationProblem(
            A=A, B=B, C=np.eye(2), D=D, E=np.zeros((3, 3)), F=CURRENT_REFERENCE_F
        )
        return problem, at(theta)

    return plant


def schedule_over_levels(
    currents: Array, thetas: Array, structure: IncrementalStructure, Q: Array, R: Array,
    *, input_delay: int, integral_weight: Array | None,
) -> CurrentScheduleDesign:  # fmt: skip
    """The digital optimum scheduled over ``i_q*`` on the levels' identified models,
    interpolated linearly in ``i_q*`` between them (:func:`level_plants`,
    :func:`~selftune.model.design_current_schedule`).

    Parameters
    ----------
    currents : ndarray, shape (g,)
        The levels' ``i_q*``, A, distinct, in any order (the grid is them rising,
        :func:`by_current`).
    thetas : ndarray, shape (g, 6)
        Their identified parameters (:func:`~._saturation.incremental_parameters`).
    structure : IncrementalStructure
        The structure at the levels' electrical speed, sampling period and hold, without
        the dead-time channels (the law's plant).
    Q, R : ndarray
        The continuous weights of the digital cost.
    input_delay : int
        The loop's delay, samples.
    integral_weight : ndarray or None
        ``Q_i`` (None: no integral action).
    """
    currents, thetas = by_current(currents, thetas)
    plants = level_plants(currents, thetas, structure)

    def plant(current: float) -> tuple[RegulationProblem, tuple[Array, Array, Array]]:
        return plants(current, structure.electrical_speed)

    return design_current_schedule(
        plant, currents, Q, R, structure.h, input_delay=input_delay,
        integral_weight=integral_weight,
    )  # fmt: skip


def schedule_over_speed_and_levels(
    currents: Array, thetas: Array, structure: IncrementalStructure, Q: Array, R: Array,
    electrical_speeds: Sequence[float], *, input_delay: int, integral_weight: Array | None,
) -> SpeedCurrentDesign:  # fmt: skip
    """The digital optimum scheduled over speed and ``i_q*`` together on the levels'
    identified models (:func:`level_plants`; the incremental structure's model at each
    speed), :func:`~selftune.model.design_speed_current_schedule` from the levels'
    currents times ``electrical_speeds``.

    Parameters
    ----------
    currents, thetas, structure, Q, R, input_delay, integral_weight
        As :func:`schedule_over_levels`.
    electrical_speeds : sequence of float
        The initial speed grid, rad/s (electrical), strictly increasing.
    """
    currents, thetas = by_current(currents, thetas)
    return design_speed_current_schedule(
        level_plants(currents, thetas, structure), currents, electrical_speeds, Q, R,
        structure.h, input_delay=input_delay, integral_weight=integral_weight,
    )  # fmt: skip
