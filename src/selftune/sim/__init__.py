"""Simulation: exact sampled-data simulation of LTI plants, signals, and simulated drives.

- :func:`simulate`, :func:`simulate_batch`: the plant ``x' = A x + B u + D w`` under a
  sampled linear policy with exploration, exact by the matrix exponential
  (:mod:`._simulator`), vectorized over batches of plants;
- exogenous signals (:mod:`._signals`): :func:`constant`, :func:`steps`, :func:`held`,
  :func:`exosystem`;
- exploration (:mod:`._exploration`): :func:`uniform`, :func:`prbs`, :func:`sum_of_sines`;
- :func:`simulate_loop`: the ideal digital loop of a :class:`~selftune.core.ControlLaw`
  with a computation delay, exact (:mod:`._loop`);
- :class:`SimulatedDrive`: the ideal drive the self-tuning sessions run on;
- :class:`RealisticDrive`: a drive that behaves like hardware (computation delay, PWM,
  dead time, noise, ADC, voltage limit, temperature; :mod:`._realistic`);
  :meth:`RealisticDrive.start` keeps it running chunk by chunk (:class:`DriveSession`,
  :class:`DriveChunk`), its motor heating or failing along a :class:`ParameterProfile`
  (:mod:`._session`, :mod:`._profile`); with magnetic saturation, :class:`SaturationModel`
  or a :class:`FluxMap` (:mod:`._saturation`); :func:`run_speed_profile` runs it while
  the speed changes (a ramp or a staircase, :func:`ramp_speeds`; :mod:`._ramp`);
- :class:`GemDrive`: gym-electric-motor's PMSM environment as a drive (the ``gem`` extra;
  :mod:`._gem`), so a gym-electric-motor current loop is tuned by the same sessions.
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
from ._gem import GEM_ENVIRONMENT, GEM_SOLVERS, GemDrive
from ._loop import LoopLogs, simulate_loop
from ._profile import ParameterFactors, ParameterProfile
from ._ramp import ramp_speeds, run_speed_profile
from ._realistic import DriveRecord, DriveSettings, RealisticDrive, run_drive_batch
from ._saturation import FluxMap, Saturation, SaturationModel
from ._session import DriveChunk, DriveSession
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
    "GEM_ENVIRONMENT",
    "GEM_SOLVERS",
    "BinaryExploration",
    "ConstantSignal",
    "Discretization",
    "DriveChunk",
    "DriveRecord",
    "DriveSession",
    "DriveSettings",
    "ExogenousSignal",
    "Exosystem",
    "Exploration",
    "FluxMap",
    "GemDrive",
    "HeldSignal",
    "LoopLogs",
    "ParameterFactors",
    "ParameterProfile",
    "RealisticDrive",
    "Saturation",
    "SaturationModel",
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
    "ramp_speeds",
    "run_drive_batch",
    "run_speed_profile",
    "simulate",
    "simulate_batch",
    "simulate_loop",
    "steps",
    "sum_of_sines",
    "uniform",
]
