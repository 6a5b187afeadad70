"""The model side: the motor, the linear regulation problem and its model-based optimum.

This is the truth the learners are judged by. Nothing in :mod:`selftune.learn` may
import it (an import contract checks that); the learners see only sampled data.

- :class:`SPMSM`: the surface-mounted PMSM and its torque-control forms (eq. 8, 15);
  :class:`IPMSM`: the interior PMSM (``L_d != L_q``) with MTPA current references;
  :data:`Motor`: either;
- :class:`RegulationProblem`: ``x' = A x + B u + D w, w' = E w, e = C x + F w`` and its
  regulator equations;
- :func:`solve_optimal_regulation`: the optimal ``K*, P*, X*, U*`` (with
  ``integral_weight``, the optimal servo controller: ``K_i`` too), a
  :class:`ModelBasedSolution` of the continuous loop;
- :func:`solve_digital_regulation`: the optimal digital controller of the sampled loop
  with a computation delay (:mod:`._digital`), with integral action if asked;
- :func:`design_schedule`: that optimum on a grid of speeds, as a :class:`SpeedSchedule`
  a drive interpolates linearly, checked between the grid speeds (:mod:`._schedule_design`);
- :func:`design_current_schedule`: a saturating motor's optimum on a grid of q-axis
  current references, as a :class:`CurrentSchedule`, by the same refinement;
- :func:`design_speed_current_schedule`: that optimum on a grid of speeds times
  currents, as a :class:`SpeedCurrentSchedule` interpolated bilinearly, by the same rules
  (:mod:`._speed_current`).
"""

from __future__ import annotations

from ..core import lqr, policy_value
from ._current_schedule import CurrentScheduleDesign, design_current_schedule
from ._digital import DigitalCost, solve_digital_regulation
from ._ipmsm import IPMSM, motor_from_parameters
from ._motor import SPMSM
from ._optimum import ModelBasedSolution, solve_optimal_regulation
from ._problem import RegulationProblem
from ._refine import excess_over
from ._schedule import CurrentSchedule, GainSchedule, SpeedSchedule
from ._schedule_design import (
    EXCESS,
    FINE_POINTS,
    ScheduleCheck,
    ScheduleDesign,
    ScheduledMotor,
    bandwidth,
    check_covered,
    design_schedule,
    worst_excess,
)
from ._speed_current import (
    SpeedCurrentCheck,
    SpeedCurrentDesign,
    SpeedCurrentSchedule,
    design_speed_current_schedule,
)

#: A PMSM of either kind: the surface motor (the paper's) or the interior one.
Motor = SPMSM | IPMSM

__all__ = [
    "EXCESS",
    "FINE_POINTS",
    "IPMSM",
    "SPMSM",
    "CurrentSchedule",
    "CurrentScheduleDesign",
    "DigitalCost",
    "GainSchedule",
    "ModelBasedSolution",
    "Motor",
    "RegulationProblem",
    "ScheduleCheck",
    "ScheduleDesign",
    "ScheduledMotor",
    "SpeedCurrentCheck",
    "SpeedCurrentDesign",
    "SpeedCurrentSchedule",
    "SpeedSchedule",
    "bandwidth",
    "check_covered",
    "design_current_schedule",
    "design_schedule",
    "design_speed_current_schedule",
    "excess_over",
    "lqr",
    "motor_from_parameters",
    "policy_value",
    "solve_digital_regulation",
    "solve_optimal_regulation",
    "worst_excess",
]
