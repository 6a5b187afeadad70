"""The method: learning optimal controllers from sampled data, without the model.

The learners take :class:`Trajectory` samples (from a simulator, or a drive's log read
by :func:`load_trajectory`) and the known part of the problem (C, E, F, the cost weights
and a stabilizing K0); they never see A, B or D. Nothing here imports
:mod:`selftune.model` or :mod:`selftune.tuning`; an import contract checks that.

The data flow: :class:`Trajectory` -> :func:`interval_moments` (the quadrature of the
data equation, :mod:`._moments`) -> :func:`regression` and :func:`solve_regression`
(the rows and their excitation check, :mod:`._regression`) -> :func:`policy_step` and
:func:`policy_iteration` (:mod:`._policy_iteration`) -> :func:`learn_lqr` and
:func:`learn_output_regulation` (:mod:`._continuous`).
"""

from __future__ import annotations

from ._continuous import (
    LearnedSolution,
    LQRLearningResult,
    learn_lqr,
    learn_output_regulation,
    solutions_of_output_equation,
)
from ._io import load_csv, load_npz, load_trajectory, save_csv, save_npz, save_trajectory
from ._moments import IntervalMoments, WKind, interval_moments
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
from ._regression import (
    BLOCK_ADVICE,
    Regression,
    RegressionSolution,
    regression,
    solve_regression,
)
from ._trajectory import Trajectory, as_trajectories

__all__ = [
    "BLOCK_ADVICE",
    "MAX_TOLERANCE",
    "IntervalMoments",
    "IterationRecord",
    "LQRLearningResult",
    "LearnedSolution",
    "PolicyIterationFacts",
    "Regression",
    "RegressionSolution",
    "Trajectory",
    "WKind",
    "as_trajectories",
    "check_iteration_settings",
    "estimated_B",
    "feedforward",
    "interval_moments",
    "learn_lqr",
    "learn_output_regulation",
    "load_csv",
    "load_npz",
    "load_trajectory",
    "not_converged",
    "policy_iteration",
    "policy_step",
    "regression",
    "save_csv",
    "save_npz",
    "save_trajectory",
    "solutions_of_output_equation",
    "solve_regression",
]
