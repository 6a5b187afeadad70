"""The method: learning optimal controllers from sampled data, without the model.

The learners take :class:`Trajectory` samples (from a simulator, or a drive's log read
by :func:`load_trajectory`, or in its own columns and frame by :func:`load_log`) and the
known part of the problem (C, E, F, the cost weights and a stabilizing K0); they never
see A, B or D. Nothing here imports
:mod:`selftune.model` or :mod:`selftune.tuning`; an import contract checks that.

The flow, one subpackage a stage::

    data/       Trajectory, CSV, NPZ and MAT files, a drive's own       the logs
                columns and phase frame (LogFormat)
    evidence/   exact discrete model, alignment, dead time,             what the logs say
                output-error fit and noise, consistency tests
    learners/   moments and regression of the data equation, one        the method
                policy-iteration driver, continuous ADP (plain,
                regulator, servo), discrete-time ADP, identify-then-design
    verdict/    standard errors, stability margin over the plants       how good it is
                the data allow, refusals
    online/     the model of a running drive from moments with          while it runs
                forgetting, a surface PMSM's parameters, a change test
    _pipeline   learn_controller and assess: the stages in order
    _speeds     a log over several held speeds: each learned at its own, one motor

:class:`LearningProblem` (what is known: C, E, F, Q, R, integral action) and
:class:`LearningOptions` (what to learn and how) are the inputs of every stage;
:class:`LearnedController` is every learner's result. Every learner takes the data, the
problem, K0 and the options, in that order. For a drive's log, :func:`learn_controller`
runs the evidence, the learner of the options' target and method, and the verdict;
:func:`assess` gives the same verdict to a controller learned elsewhere.
"""

from __future__ import annotations

from ._pi import PIEquivalent, pi_control_law, pi_equivalent, pi_equivalent_or_reason
from ._pipeline import aligned_trajectory, assess, learn_controller
from ._problem import LearningOptions, LearningProblem, Method, Target
from ._result import DiscountStage, Formulation, JudgedPlants, LearnedController
from ._speeds import (
    SpeedsLearned,
    combined_estimate,
    learn_over_speeds,
    speed_segments,
    top_part,
)
from .data._frames import LogColumn, LogFormat, load_log
from .data._io import (
    CsvHeader,
    load_csv,
    load_npz,
    load_trajectory,
    read_csv_chunks,
    save_csv,
    save_npz,
    save_trajectory,
)
from .data._trajectory import Trajectory, as_trajectories
from .evidence._alignment import (
    CANDIDATE_SHIFTS,
    Alignment,
    LoggedInput,
    aligned_transitions,
    applied_inputs,
    check_alignment,
    sampling_period,
    stated_shift,
)
from .evidence._dead_time import direction_signs, phase_signs
from .evidence._discrete_model import DiscreteModel, Transitions, fit_discrete_model
from .evidence._evidence import ConsistencyTest, Evidence, gather_evidence
from .evidence._incremental_structure import IncrementalStructure
from .evidence._output_error import (
    IpmsmStructure,
    OutputErrorFit,
    SpmsmStructure,
    fit_output_error,
    simulated_trajectories,
)
from .learners._continuous import (
    learn_lqr,
    learn_output_regulation,
    learn_regulator,
    solutions_of_output_equation,
)
from .learners._digital import (
    DigitalTransitions,
    digital_transitions,
    learn_digital_adp,
    steady_state_map,
)
from .learners._identify import design_continuous, design_digital
from .learners._moments import IntervalMoments, WKind, interval_moments
from .learners._policy_iteration import (
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
from .learners._regression import (
    BLOCK_ADVICE,
    Regression,
    RegressionSolution,
    regression,
    solve_regression,
)
from .learners._servo import learn_servo, servo_from_moments
from .verdict._quality import TOO_LITTLE_DATA, MotorEstimate, Quality, closed_loop_radius
from .verdict._verdict import dead_time_voltage

__all__ = [
    "BLOCK_ADVICE",
    "CANDIDATE_SHIFTS",
    "MAX_TOLERANCE",
    "TOO_LITTLE_DATA",
    "Alignment",
    "ConsistencyTest",
    "CsvHeader",
    "DigitalTransitions",
    "DiscountStage",
    "DiscreteModel",
    "Evidence",
    "Formulation",
    "IncrementalStructure",
    "IntervalMoments",
    "IpmsmStructure",
    "IterationRecord",
    "JudgedPlants",
    "LearnedController",
    "LearningOptions",
    "LearningProblem",
    "LogColumn",
    "LogFormat",
    "LoggedInput",
    "Method",
    "MotorEstimate",
    "OutputErrorFit",
    "PIEquivalent",
    "PolicyIterationFacts",
    "Quality",
    "Regression",
    "RegressionSolution",
    "SpeedsLearned",
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
    "combined_estimate",
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
    "learn_over_speeds",
    "learn_regulator",
    "learn_servo",
    "load_csv",
    "load_log",
    "load_npz",
    "load_trajectory",
    "not_converged",
    "phase_signs",
    "pi_control_law",
    "pi_equivalent",
    "pi_equivalent_or_reason",
    "policy_iteration",
    "policy_step",
    "read_csv_chunks",
    "regression",
    "sampling_period",
    "save_csv",
    "save_npz",
    "save_trajectory",
    "servo_from_moments",
    "simulated_trajectories",
    "solutions_of_output_equation",
    "solve_regression",
    "speed_segments",
    "stated_shift",
    "steady_state_map",
    "top_part",
]
