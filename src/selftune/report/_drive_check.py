"""A learned controller on the simulated drive: the steady torque it actually makes.

Evaluation only (the simulated drive knows the true torque, a real drive does not): the
controller runs from rest with a constant reference and no exploration, and the true
electromagnetic torque ``1.5 p phi_pm i_q`` (the motor's own, heated flux) is averaged
over the second half of the run, where the transient has died out; PWM ripple and
measurement noise average out over the thousands of samples. The relative error against
T* is what a drive engineer would measure on a torque bench: it shows a constant voltage
error (dead time), a resistance that drifted since tuning, or a wrong flux in the current
reference.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..core import Array, ControlLaw
from ..model import SPMSM
from ..sim import DriveSettings, RealisticDrive, constant

__all__ = ["STEADY_SECONDS", "steady_torque_error"]

#: Length of the run, s: the second half is averaged.
STEADY_SECONDS = 0.2


def steady_torque_error(
    motor: SPMSM,
    speed: float,
    h: float,
    law: ControlLaw,
    w: Array,
    *,
    settings: DriveSettings | None = None,
    resistance_factor: float = 1.0,
    seconds: float = STEADY_SECONDS,
    seed: int = 0,
) -> float:
    """``(mean torque - T*) / T*`` of ``law`` on the simulated drive, in steady state.

    Parameters
    ----------
    motor : SPMSM
        The true motor (nameplate values; the drive's temperature heats it).
    speed : float
        Held mechanical speed, rad/s.
    h : float
        Sampling period, s.
    law : ControlLaw
        The controller (q = 2: ``w = [p speed phi, T*]`` as it assumes them).
    w : ndarray, shape (2,)
        The controller's constant ``w``; ``w[1]`` is T*, N m.
    settings : DriveSettings, optional
        The drive's effects (default: the ideal drive, :meth:`DriveSettings.ideal`).
    resistance_factor : float
        Multiplies R_s after tuning (e.g. 1.4: the winding 100 K hotter), without
        re-tuning.
    seconds : float
        Length of the run, s.
    seed : int
        Seed of the drive's noise.

    Returns
    -------
    float
        Relative steady torque error (NaN for T* = 0).
    """
    drive_settings = DriveSettings.ideal() if settings is None else settings
    actual = replace(motor, R_s=motor.R_s * resistance_factor)
    drive = RealisticDrive(actual, speed, h, drive_settings)
    record = drive.record(
        law,
        constant(np.asarray(w, dtype=float)),
        num_samples=max(2, round(seconds / h)),
        exploration=None,
        seed=seed,
    )
    torque = record.torque[record.torque.shape[0] // 2 :]
    reference = float(w[1])
    if reference == 0.0:
        return float("nan")
    return (float(np.mean(torque)) - reference) / reference
