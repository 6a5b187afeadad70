"""A self-tuning session on a simulated motor, by the name of its algorithm."""

from __future__ import annotations

from typing import Literal

from ..errors import InputError
from ..model import SPMSM
from ..sim import DriveSettings, RealisticDrive, SimulatedDrive
from ._drive import Drive
from ._offpolicy import offpolicy
from ._onpolicy import algorithm1, algorithm2, algorithm3
from ._results import TuningResult
from ._settings import TuningSettings

__all__ = ["ALGORITHMS", "AlgorithmName", "run_algorithm"]

AlgorithmName = Literal["1", "2", "3", "offpolicy"]

#: The algorithms by name, as the command line and the reproduction list them.
ALGORITHMS: tuple[AlgorithmName, ...] = ("1", "2", "3", "offpolicy")


def run_algorithm(
    name: AlgorithmName,
    motor: SPMSM,
    settings: TuningSettings | None = None,
    drive: DriveSettings | None = None,
) -> TuningResult:
    """Run a self-tuning session on a simulated ``motor`` (the learner is told only p,
    the speed, the torque reference and the nameplate flux, which Algorithm 3 only uses
    as a rough guess).

    Parameters
    ----------
    name : {"1", "2", "3", "offpolicy"}
        The algorithm.
    motor : SPMSM
        The motor (nameplate values): simulated exactly by
        :class:`selftune.sim.SimulatedDrive`, or by a :class:`selftune.sim.RealisticDrive`
        with the effects of ``drive`` (which may heat it: its true flux is then not the
        nameplate's the learner is told).
    settings : TuningSettings, optional
        The session's settings (default: :class:`TuningSettings`).
    drive : DriveSettings, optional
        A realistic drive's effects (delay, PWM, dead time, noise, ADC, temperature);
        None: the ideal drive.

    Returns
    -------
    TuningResult
    """
    settings = TuningSettings() if settings is None else settings
    plant: Drive
    if drive is None:
        plant = SimulatedDrive(
            motor=motor,
            speed=settings.speed,
            h=settings.h,
            input_hold=settings.input_hold,
        )
    else:
        if settings.input_hold != 1:
            raise InputError(
                f"input_hold: a realistic drive's controller updates every sample; set "
                f"input_hold = 1 (got {settings.input_hold})"
            )
        plant = RealisticDrive(motor, settings.speed, settings.h, drive)
    return _run(name, plant, settings, motor.phi_pm)


def _run(
    name: AlgorithmName, drive: Drive, settings: TuningSettings, phi_pm: float
) -> TuningResult:
    if name == "1":
        return algorithm1(drive, settings, phi_pm)
    if name == "2":
        return algorithm2(drive, settings, phi_pm)
    if name == "3":
        return algorithm3(drive, settings, phi_pm)
    if name == "offpolicy":
        return offpolicy(drive, settings, phi_pm)
    raise InputError(f"algorithm: must be 1, 2, 3 or offpolicy, got {name!r}")
