"""selftune: self-tuning optimal torque control of PMSM drives by adaptive dynamic programming.

The library learns the optimal feedback and feedforward of a linear plant from sampled
data (no model needed), the paper's continuous-time controller or the optimum of the
sampled loop a drive runs (:func:`learn_controller`, with a verdict on every result),
and computes the model-based optimum to compare against.

The packages follow the data flow (each uses only those listed before it, and ``learn``
never uses ``model``; an import contract checks both)::

    errors, core   exceptions; validation rules, thresholds, generic numerics  [neutral]
    model          the motor, the linear problem, the model-based optimum     [the truth]
    learn          Trajectory, file formats, the data equation, the learners  [the method]
    sim            signals, the exact simulator, simulated drives
    config         MOTOR.toml and CONFIG.toml
    tuning         the paper's Algorithms 1-3 and off-policy on a drive
    report         evaluation against the truth, the paper's reproduction, figures
    bench          the benchmarks, one module per study
    commands, cli  what each command does; argument parsing
"""

from __future__ import annotations

from .config import LearnConfig, MotorConfig, load_learn_config, load_motor_config
from .errors import (
    CoarseTimeResolution,
    ConfigurationMismatch,
    ConsistencyError,
    ConvergenceError,
    DataFileError,
    ExcitationError,
    InputError,
    MisalignedLog,
    ModelMissesEffect,
    NotExciting,
    NotStabilizing,
    NumericalFailure,
    PolicyIterationFailure,
    Refusal,
    SamplingJitter,
    SelftuneError,
    TooLittleData,
    TooShort,
    UnsolvableError,
)
from .learn import (
    LearnedController,
    LearningOptions,
    LearningProblem,
    Trajectory,
    learn_controller,
    learn_lqr,
    learn_output_regulation,
    learn_regulator,
    load_trajectory,
    save_trajectory,
)
from .model import (
    SPMSM,
    ModelBasedSolution,
    RegulationProblem,
    lqr,
    policy_value,
    solve_digital_regulation,
    solve_optimal_regulation,
)
from .sim import simulate, simulate_batch

__version__ = "0.1.0"

__all__ = [
    "SPMSM",
    "CoarseTimeResolution",
    "ConfigurationMismatch",
    "ConsistencyError",
    "ConvergenceError",
    "DataFileError",
    "ExcitationError",
    "InputError",
    "LearnConfig",
    "LearnedController",
    "LearningOptions",
    "LearningProblem",
    "MisalignedLog",
    "ModelBasedSolution",
    "ModelMissesEffect",
    "MotorConfig",
    "NotExciting",
    "NotStabilizing",
    "NumericalFailure",
    "PolicyIterationFailure",
    "Refusal",
    "RegulationProblem",
    "SamplingJitter",
    "SelftuneError",
    "TooLittleData",
    "TooShort",
    "Trajectory",
    "UnsolvableError",
    "__version__",
    "learn_controller",
    "learn_lqr",
    "learn_output_regulation",
    "learn_regulator",
    "load_learn_config",
    "load_motor_config",
    "load_trajectory",
    "lqr",
    "policy_value",
    "save_trajectory",
    "simulate",
    "simulate_batch",
    "solve_digital_regulation",
    "solve_optimal_regulation",
]
