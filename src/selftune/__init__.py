"""selftune: self-tuning optimal torque control of PMSM drives by adaptive dynamic programming.

The library learns the optimal feedback and feedforward of a linear plant from sampled
data (no model needed), and computes the model-based optimum to compare against.

The data flow, one module per arrow::

    motor (SPMSM)  ->  regulation problem (A..F)  ->  model-based optimum   [the truth]
    simulate -> Trajectory (io: CSV/NPZ) -> data_equation -> learning      [the method]
    torque: the paper's Algorithms 1-3 and off-policy on a drive
"""

from __future__ import annotations

from .config import LearnConfig, MotorConfig, load_learn_config, load_motor_config
from .errors import (
    ConvergenceError,
    DataFileError,
    ExcitationError,
    InputError,
    SelftuneError,
    UnsolvableError,
)
from .io import load_trajectory, save_trajectory
from .learning import (
    LearnedSolution,
    LQRLearningResult,
    learn_lqr,
    learn_output_regulation,
)
from .motor import SPMSM
from .regulation import (
    ModelBasedSolution,
    RegulationProblem,
    lqr,
    policy_value,
    solve_optimal_regulation,
)
from .simulate import simulate, simulate_batch
from .trajectory import Trajectory

__version__ = "0.1.0"

__all__ = [
    "SPMSM",
    "ConvergenceError",
    "DataFileError",
    "ExcitationError",
    "InputError",
    "LQRLearningResult",
    "LearnConfig",
    "LearnedSolution",
    "ModelBasedSolution",
    "MotorConfig",
    "RegulationProblem",
    "SelftuneError",
    "Trajectory",
    "UnsolvableError",
    "__version__",
    "learn_lqr",
    "learn_output_regulation",
    "load_learn_config",
    "load_motor_config",
    "load_trajectory",
    "lqr",
    "policy_value",
    "save_trajectory",
    "simulate",
    "simulate_batch",
    "solve_optimal_regulation",
]
