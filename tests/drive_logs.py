"""Test helper: logs of the library's realistic drive for the reference experiment.

The reference experiment of the noise study: a motor held at a speed, a one-sample
computation delay, exploration uniform within 2% of a 540 V bus on each axis every
sample, a torque reference with a +-30% square ripple and a +-10% sine ripple, white
noise on the measured currents inside the loop, a gentle initial controller.
"""

from __future__ import annotations

from dataclasses import replace
from functools import cache

import numpy as np
from numpy.typing import NDArray

from selftune import SPMSM, RegulationProblem
from selftune.core import ControlLaw
from selftune.learn import LearningProblem, Trajectory
from selftune.sim import DriveSettings, RealisticDrive, held, uniform

Array = NDArray[np.float64]

#: The reference experiment's motor (issue: 0.6 ohm, 8 mH, 0.35 Wb, p = 3, 50 rad/s).
REFERENCE_MOTOR = SPMSM(R_s=0.6, L_s=8e-3, phi_pm=0.35, p=3)
Q, R = 1e3 * np.eye(2), np.eye(2)


def gentle_K0(motor: SPMSM, h: float) -> Array:
    """1.25% of the deadbeat gain L_s / h: stable with a one-sample delay."""
    return 0.0125 * motor.L_s / h * np.eye(2)


@cache
def reference_log(
    motor: SPMSM = REFERENCE_MOTOR,
    *,
    speed: float = 50.0,
    torque: float = 5.0,
    h: float = 1e-4,
    seconds: float = 0.5,
    settings: DriveSettings | None = None,
    seed: int = 0,
) -> tuple[Trajectory, RegulationProblem, tuple[LearningProblem, Array]]:
    """A log of the reference experiment, the true problem and what the learner knows:
    the problem and the K0 the log was taken under.

    Made once per session for each set of arguments (several tests refuse or learn the same
    log; the hardware-like drive takes a second of CPU for 0.5 s); its arrays are read-only
    so that no test can change another's log."""
    settings = replace(DriveSettings.ideal(), input_delay=1) if settings is None else settings
    problem = motor.regulation_problem(speed)
    K0 = gentle_K0(motor, h)
    base = motor.exogenous(speed, torque)

    def reference(t: Array) -> Array:
        ripple = 0.3 * torque * np.sign(np.sin(2 * np.pi * 20.0 * t))
        ripple = ripple + 0.1 * torque * np.sin(2 * np.pi * 130.0 * t)
        return base + np.column_stack([0.0 * t, ripple])

    drive = RealisticDrive(motor, speed, h, settings)
    law = ControlLaw.regulator(K0, -problem.F, np.zeros((2, 2)))
    log = drive.run(
        law, held(reference), num_samples=round(seconds / h), exploration=uniform(10.8), seed=seed
    )
    for array in (log.t, log.x, log.u, log.w, log.angle, K0):
        if isinstance(array, np.ndarray):
            array.setflags(write=False)
    known = (LearningProblem(Q, R, C=np.eye(2), F=problem.F), K0)
    return log, problem, known


def noisy(noise: float, delay: int = 1) -> DriveSettings:
    """The ideal drive with a computation delay and current noise (A rms per phase)."""
    return replace(DriveSettings.ideal(), input_delay=delay, current_noise=noise)
