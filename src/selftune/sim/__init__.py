"""Simulation: exact sampled-data simulation of LTI plants, signals, and simulated drives.

- :func:`simulate`, :func:`simulate_batch`: the plant ``x' = A x + B u + D w`` under a
  sampled linear policy with exploration, exact by the matrix exponential
  (:mod:`._simulator`), vectorized over batches of plants;
- exogenous signals (:mod:`._signals`): :func:`constant`, :func:`steps`, :func:`held`,
  :func:`exosystem`;
- exploration (:mod:`._exploration`): :func:`uniform`, :func:`prbs`, :func:`sum_of_sines`;
- :class:`SimulatedDrive`: the ideal drive the self-tuning sessions run on.
"""

from __future__ import annotations

from ..core import Discretization, discretize
from ._checks import Seed
from ._drive import SimulatedDrive
from ._exploration import (
    BinaryExploration,
    Exploration,
    SinusoidalExploration,
    UniformExploration,
    prbs,
    sum_of_sines,
    uniform,
)
from ._signals import (
    ConstantSignal,
    ExogenousSignal,
    Exosystem,
    HeldSignal,
    StepSignal,
    constant,
    exosystem,
    held,
    steps,
)
from ._simulator import TrajectoryBatch, simulate, simulate_batch

__all__ = [
    "BinaryExploration",
    "ConstantSignal",
    "Discretization",
    "ExogenousSignal",
    "Exosystem",
    "Exploration",
    "HeldSignal",
    "Seed",
    "SimulatedDrive",
    "SinusoidalExploration",
    "StepSignal",
    "TrajectoryBatch",
    "UniformExploration",
    "constant",
    "discretize",
    "exosystem",
    "held",
    "prbs",
    "simulate",
    "simulate_batch",
    "steps",
    "sum_of_sines",
    "uniform",
]
