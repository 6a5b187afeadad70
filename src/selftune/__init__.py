"""selftune: self-tuning optimal torque control of PMSM drives by adaptive dynamic programming.

The library learns the optimal feedback and feedforward of a linear plant from sampled
data (no model needed), and computes the model-based optimum to compare against.
"""

from __future__ import annotations

from .errors import (
    ConvergenceError,
    DataFileError,
    ExcitationError,
    InputError,
    SelftuneError,
    UnsolvableError,
)
from .motor import SPMSM
from .regulation import (
    ModelBasedSolution,
    RegulationProblem,
    lqr,
    policy_value,
    solve_optimal_regulation,
)

__version__ = "0.1.0"

__all__ = [
    "SPMSM",
    "ConvergenceError",
    "DataFileError",
    "ExcitationError",
    "InputError",
    "ModelBasedSolution",
    "RegulationProblem",
    "SelftuneError",
    "UnsolvableError",
    "__version__",
    "lqr",
    "policy_value",
    "solve_optimal_regulation",
]
