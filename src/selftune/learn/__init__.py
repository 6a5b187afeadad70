"""The method: learning optimal controllers from sampled data, without the model.

The learners take :class:`Trajectory` samples (from a simulator, or a drive's log read
by :func:`load_trajectory`) and the known part of the problem (C, E, F, the cost weights
and a stabilizing K0); they never see A, B or D. Nothing here imports
:mod:`selftune.model` or :mod:`selftune.tuning`; an import contract checks that.

The data flow: :class:`Trajectory` -> :func:`interval_moments` (the quadrature of the
data equation, :mod:`._moments`) -> :func:`regression` and :func:`solve_regression`
(the rows and their excitation check, :mod:`._regression`) -> :func:`policy_step` and
:func:`policy_iteration` (:mod:`._policy_iteration`) -> :func:`learn_lqr` and
:func:`learn_regulator` (:mod:`._continuous`), :func:`learn_servo` (integral action,
:mod:`._servo`), the discrete-time learner :func:`learn_digital_adp` (:mod:`._digital`).
Every learner takes the data, the :class:`LearningProblem`, K0 and the
:class:`LearningOptions`, in that order, and returns a :class:`LearnedController`.

For a drive's log, :func:`learn_controller` runs them all behind one pipeline: the
evidence of the log (alignment, output-error model, consistency, :mod:`._evidence`),
the learner of the options' target and method, and the verdict (:class:`Quality`,
:mod:`._quality`); :func:`assess` gives the same verdict to a controller learned
elsewhere.
"""

from __future__ import annotations

from ._alignment import (
    CANDIDATE_SHIFTS,
    Alignment,
    LoggedInput,
    aligned_transitions,
    applied_inputs,
    check_alignment,
    sampling_period,
    stated_shift,
)
from ._continuous import (
    learn_lqr,
    learn_output_regulation,
    learn_regulator,
    solutions_of_output_equation,
)
from ._dead_time import direction_signs, phase_signs
from ._digital import (
    DigitalTransitions,
    digital_transitions,
    learn_digital_adp,
    steady_state_map,
)
from ._discrete_model import DiscreteModel, Transitions, fit_discrete_model
from ._evidence import ConsistencyTest, Evidence, gather_evidence
from ._identify import design_continuous, design_digital
from ._io import load_csv, load_npz, load_trajectory, save_csv, save_npz, save_trajectory
from ._learner import aligned_trajectory, assess, learn_controller
from ._moments import IntervalMoments, WKind, interval_moments
from ._output_error import OutputErrorFit, SpmsmStructure, fit_output_error, simulated_trajectories
from ._policy_iteration import (
    MAX_TOLERANCE,
    IterationRecord,
    PolicyIterationFacts,
    check_iteration_settings,
    estimated_B,
    feedforward,
    not_converged,
    policy_iteration,
    policy_step,
)
from ._problem import LearningOptions, LearningProblem, Method, Target
from ._quality import TOO_LITTLE_DATA, Quality, closed_loop_radius
from ._regression import (
    BLOCK_ADVICE,
    Regression,
    RegressionSolution,
    regression,
    solve_regression,
)
from ._result import DiscountStage, Formulation, LearnedController
from ._servo import learn_servo, servo_from_moments
from ._trajectory import Trajectory, as_trajectories
from ._verdict import dead_time_voltage

__all__ = [
    "BLOCK_ADVICE",
    "CANDIDATE_SHIFTS",
    "MAX_TOLERANCE",
    "TOO_LITTLE_DATA",
    "Alignment",
    "ConsistencyTest",
    "DigitalTransitions",
    "DiscountStage",
    "DiscreteModel",
    "Evidence",
    "Formulation",
    "IntervalMoments",
    "IterationRecord",
    "LearnedController",
    "LearningOptions",
    "LearningProblem",
    "LoggedInput",
    "Method",
    "OutputErrorFit",
    "PolicyIterationFacts",
    "Quality",
    "Regression",
    "RegressionSolution",
    "SpmsmStructure",
    "Target",
    "Trajectory",
    "Transitions",
    "WKind",
    "aligned_trajectory",
    "aligned_transitions",
    "applied_inputs",
    "as_trajectories",
    "assess",
    "check_alignment",
    "check_iteration_settings",
    "closed_loop_radius",
    "dead_time_voltage",
    "design_continuous",
    "design_digital",
    "digital_transitions",
    "direction_signs",
    "estimated_B",
    "feedforward",
    "fit_discrete_model",
    "fit_output_error",
    "gather_evidence",
    "interval_moments",
    "learn_controller",
    "learn_digital_adp",
    "learn_lqr",
    "learn_output_regulation",
    "learn_regulator",
    "learn_servo",
    "load_csv",
    "load_npz",
    "load_trajectory",
    "not_converged",
    "phase_signs",
    "policy_iteration",
    "policy_step",
    "regression",
    "sampling_period",
    "save_csv",
    "save_npz",
    "save_trajectory",
    "servo_from_moments",
    "simulated_trajectories",
    "solutions_of_output_equation",
    "solve_regression",
    "stated_shift",
    "steady_state_map",
]
