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

import importlib
from typing import TYPE_CHECKING, Any

from .errors import (
    CoarseTimeResolution,
    ConfigurationMismatch,
    ConsistencyError,
    ConvergenceError,
    CurrentOverrange,
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

if TYPE_CHECKING:
    from .config import LearnConfig, MotorConfig, load_learn_config, load_motor_config
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
    "CurrentOverrange",
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

# The rest of the public names, imported when first used rather than with the package
# (numpy and scipy take about a second): ``selftune.cli`` is then quick to import, and a
# Ctrl-C during a command's imports reaches the command line's own handling (one line,
# exit code 130) rather than ending in a traceback.
_LAZY: dict[str, str] = {
    "LearnConfig": "config",
    "MotorConfig": "config",
    "load_learn_config": "config",
    "load_motor_config": "config",
    "LearnedController": "learn",
    "LearningOptions": "learn",
    "LearningProblem": "learn",
    "Trajectory": "learn",
    "learn_controller": "learn",
    "learn_lqr": "learn",
    "learn_output_regulation": "learn",
    "learn_regulator": "learn",
    "load_trajectory": "learn",
    "save_trajectory": "learn",
    "SPMSM": "model",
    "ModelBasedSolution": "model",
    "RegulationProblem": "model",
    "lqr": "model",
    "policy_value": "model",
    "solve_digital_regulation": "model",
    "solve_optimal_regulation": "model",
    "simulate": "sim",
    "simulate_batch": "sim",
}

# The subpackages ``import selftune`` has always made available as attributes.
_SUBPACKAGES = ("config", "core", "learn", "loop", "model", "sim")


def __getattr__(name: str) -> Any:
    """A public name (or subpackage) of selftune, imported on first use (PEP 562).

    Parameters
    ----------
    name : str
        The attribute asked for.
    """
    if name in _SUBPACKAGES:
        return importlib.import_module(f"{__name__}.{name}")
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    """The module's names, the public ones not yet imported included."""
    return sorted(set(globals()) | set(__all__))
