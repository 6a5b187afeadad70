"""A self-tuning session on a simulated motor, by the name of its algorithm."""

from __future__ import annotations

from typing import Literal

from ..errors import InputError
from ..model import SPMSM
from ..sim import SimulatedDrive
from ._offpolicy import offpolicy
from ._onpolicy import algorithm1, algorithm2, algorithm3
from ._results import TuningResult
from ._settings import TuningSettings

__all__ = ["ALGORITHMS", "AlgorithmName", "run_algorithm"]

AlgorithmName = Literal["1", "2", "3", "offpolicy"]

#: The algorithms by name, as the command line and the reproduction list them.
ALGORITHMS: tuple[AlgorithmName, ...] = ("1", "2", "3", "offpolicy")


def run_algorithm(
    name: AlgorithmName, motor: SPMSM, settings: TuningSettings | None = None
) -> TuningResult:
    """Run a self-tuning session on a simulated ``motor`` (the learner is told only p,
    the speed, the torque reference and, except for Algorithm 3, the flux).

    Parameters
    ----------
    name : {"1", "2", "3", "offpolicy"}
        The algorithm.
    motor : SPMSM
        The true motor, simulated exactly by :class:`selftune.sim.SimulatedDrive`.
    settings : TuningSettings, optional
        The session's settings (default: :class:`TuningSettings`).

    Returns
    -------
    TuningResult
    """
    settings = TuningSettings() if settings is None else settings
    drive = SimulatedDrive(
        motor=motor,
        speed=settings.speed,
        sampling=settings.sampling,
        input_hold=settings.input_hold,
    )
    if name == "1":
        return algorithm1(drive, settings, motor.phi_pm)
    if name == "2":
        return algorithm2(drive, settings, motor.phi_pm)
    if name == "3":
        return algorithm3(drive, settings)
    if name == "offpolicy":
        return offpolicy(drive, settings, motor.phi_pm)
    raise InputError(f"algorithm: must be 1, 2, 3 or offpolicy, got {name!r}")
