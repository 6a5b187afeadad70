"""The paper's settings (Wang 2022, Sec. V, reconciled in PAPER_NOTES.md): their one home.

The motor, the operating point, the cost weights and the learning experiment that
reproduce every number the paper prints. The motor model (:meth:`SPMSM.paper`), the
motor file's defaults (:mod:`selftune.config`), the self-tuning settings
(:class:`~selftune.tuning.TuningSettings`) and the reproduction all read them here.
"""

from __future__ import annotations

from types import MappingProxyType

import numpy as np

from ._validation import Array

__all__ = [
    "PAPER_EPISODE_LENGTH",
    "PAPER_EXPLORATION",
    "PAPER_MOTOR",
    "PAPER_SAMPLING",
    "PAPER_SPEED",
    "PAPER_TABLE_MOTOR",
    "PAPER_TORQUE",
    "paper_K0",
    "paper_Q",
    "paper_R",
]

#: The reconciled motor (erratum 1): R_s ohm, L_s H, phi_pm Wb, p pole pairs, J kg m^2.
PAPER_MOTOR = MappingProxyType({"R_s": 0.439, "L_s": 0.0601, "phi_pm": 0.46, "p": 2, "J": 0.0163})

#: Table II as printed (does not reproduce the paper's results).
PAPER_TABLE_MOTOR = MappingProxyType(
    {"R_s": 0.439, "L_s": 0.0615, "phi_pm": 0.5, "p": 2, "J": 0.0163}
)

#: Mechanical speed held by the load machine, rad/s.
PAPER_SPEED = 10.0

#: Torque reference T*, N m.
PAPER_TORQUE = 10.0

#: Sampling period, s (10 us).
PAPER_SAMPLING = 1e-5

#: Length of each learning episode, s (5 ms).
PAPER_EPISODE_LENGTH = 5e-3

#: Amplitude of the uniform exploration on each input, V.
PAPER_EXPLORATION = 1.0


def paper_Q() -> Array:
    """The state weight ``Q = 1e3 I`` (erratum 1: the text's 1e4 does not reproduce)."""
    return 1e3 * np.eye(2)


def paper_R() -> Array:
    """The input weight ``R = I``."""
    return np.eye(2)


def paper_K0() -> Array:
    """The initial stabilizing feedback ``K0 = 20 pi I``, V/A."""
    return 20.0 * np.pi * np.eye(2)
