"""The neutral layer: validation rules, numerical thresholds and generic numerical tools.

Everything in selftune may use this package; it uses nothing of selftune but
:mod:`selftune.errors`. It holds the one home of each input rule and threshold
(:mod:`._validation`), the vectorization conventions of the paper (:mod:`._vectorize`),
atomic file output (:mod:`._atomic`), the generic LQR and Lyapunov solvers
(:mod:`._linalg`), their discrete-time counterparts with the delay and integrator
augmentations (:mod:`._dlinalg`), exact zero-order-hold discretization
(:mod:`._discretize`), the Clarke and Park transforms (:mod:`._phases`) and the paper's
settings (:mod:`._paper`).
"""

from __future__ import annotations

from ._atomic import atomic_path, finite_or_null, to_jsonable, write_json, write_text
from ._control_law import ControlLaw, WithLaw, state_names
from ._discretize import Discretization, augmented, discretize, expm_stack, rotating_hold
from ._dlinalg import (
    continuous_from_discrete,
    delay_augmented,
    dlqr,
    dpolicy_value,
    dpolicy_values,
    integrator_augmented,
    sampled_data_weights,
)
from ._linalg import (
    check_detectable,
    check_plant,
    check_stabilizable,
    format_eigenvalue,
    lqr,
    minimize_weighted_norm,
    policy_value,
    regulator_equations,
    solve_regulator,
    unique_eigenvalues,
)
from ._paper import (
    PAPER_EPISODE_LENGTH,
    PAPER_EXPLORATION,
    PAPER_MOTOR,
    PAPER_SAMPLING,
    PAPER_SPEED,
    PAPER_TABLE_MOTOR,
    PAPER_TORQUE,
    paper_K0,
    paper_Q,
    paper_R,
)
from ._text import compact, fixed, labels, matrix_block, scientific, vector
from ._validation import (
    DEFINITENESS_TOLERANCE,
    RANK_TOLERANCE,
    Array,
    as_matrix,
    as_vector,
    check_positive_definite,
    check_positive_semidefinite,
    check_symmetric,
    check_weights,
    finite_float,
    first_non_increasing,
    is_positive_definite,
    numerical_rank,
    positive_finite,
    positive_integer,
    symmetric_tolerance,
)
from ._vectorize import (
    pack_theta,
    theta_sizes,
    unpack_theta,
    unvec,
    unvecs,
    vec,
    vecs,
    vecs_hat,
    vecs_hat_from_outer,
)

__all__ = [
    "DEFINITENESS_TOLERANCE",
    "PAPER_EPISODE_LENGTH",
    "PAPER_EXPLORATION",
    "PAPER_MOTOR",
    "PAPER_SAMPLING",
    "PAPER_SPEED",
    "PAPER_TABLE_MOTOR",
    "PAPER_TORQUE",
    "RANK_TOLERANCE",
    "Array",
    "ControlLaw",
    "Discretization",
    "WithLaw",
    "as_matrix",
    "as_vector",
    "atomic_path",
    "augmented",
    "check_detectable",
    "check_plant",
    "check_positive_definite",
    "check_positive_semidefinite",
    "check_stabilizable",
    "check_symmetric",
    "check_weights",
    "compact",
    "continuous_from_discrete",
    "delay_augmented",
    "discretize",
    "dlqr",
    "dpolicy_value",
    "dpolicy_values",
    "expm_stack",
    "finite_float",
    "finite_or_null",
    "first_non_increasing",
    "fixed",
    "format_eigenvalue",
    "integrator_augmented",
    "is_positive_definite",
    "labels",
    "lqr",
    "matrix_block",
    "minimize_weighted_norm",
    "numerical_rank",
    "pack_theta",
    "paper_K0",
    "paper_Q",
    "paper_R",
    "policy_value",
    "positive_finite",
    "positive_integer",
    "regulator_equations",
    "rotating_hold",
    "sampled_data_weights",
    "scientific",
    "solve_regulator",
    "state_names",
    "symmetric_tolerance",
    "theta_sizes",
    "to_jsonable",
    "unique_eigenvalues",
    "unpack_theta",
    "unvec",
    "unvecs",
    "vec",
    "vecs",
    "vecs_hat",
    "vecs_hat_from_outer",
    "vector",
    "write_json",
    "write_text",
]
