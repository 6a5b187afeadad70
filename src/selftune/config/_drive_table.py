"""MOTOR.toml's ``[drive]`` table: the simulated drive ``selftune tune`` runs on.

Without the table, ``tune`` runs on the ideal drive (:class:`selftune.sim.SimulatedDrive`,
the paper's). With it, on :class:`selftune.sim.RealisticDrive` with the effects the keys
set; every key is optional and an absent key leaves its effect out::

    [drive]
    input_delay = 1              # samples of computation delay (0, 1 or 2)
    switching_frequency = 10e3   # Hz; one PWM period per sample (sets the sampling period)
    pwm = "carrier"              # "average" (period-average voltage) or "carrier"
    dead_time = 2e-6             # s (needs dc_voltage)
    dead_time_compensation = false
    dc_voltage = 540.0           # V: the voltage limit V_dc / sqrt(3), dead time, carrier
    current_noise = 0.01         # A rms per phase
    adc_bits = 12                # with adc_range (A): quantization of the phase currents
    adc_range = 50.0
    temperature_rise = 0.0       # K above the nameplate's: R_s +0.39%/K, phi_pm -0.1%/K
    logged_input = "applied"     # or "commanded": what row k of the drive's log holds
    voltage_hold = "stationary"  # or "rotor": what the inverter holds over a sample
    encoder_counts = 4096        # counts a mechanical turn: the log's angle in whole counts
"""

from __future__ import annotations

from typing import Any

from ..errors import DataFileError, InputError
from ..sim import DriveSettings
from ._motor_file import MOTOR_TABLES
from ._toml import ConfigTable

__all__ = ["DRIVE_KEYS", "drive_settings"]

#: Keys of MOTOR.toml's optional [drive] table.
DRIVE_KEYS = MOTOR_TABLES["drive"]


def _count(table: ConfigTable, key: str, default: int, maximum: int) -> int:
    if key not in table:
        return default
    value = table.number(key)
    if not value.is_integer() or not 0 <= value <= maximum:
        raise table.error(key, f"must be a whole number from 0 to {maximum}, got {value:g}")
    return int(value)


def _non_negative(table: ConfigTable, key: str) -> float:
    value = table.number(key, 0.0)
    if value < 0.0:
        raise table.error(key, f"must be >= 0, got {value:g}")
    return value


def drive_settings(table: ConfigTable) -> tuple[DriveSettings, float | None]:
    """The drive of a ``[drive]`` table, and the sampling period it sets (if any).

    Parameters
    ----------
    table : ConfigTable
        The ``[drive]`` table.

    Returns
    -------
    settings : DriveSettings
    h : float or None
        ``1 / switching_frequency``, s, if the table gives it.

    Raises
    ------
    DataFileError
        Naming the key, for a value of the wrong type or range, or a needed companion
        missing (e.g. dead time without the DC-bus voltage).
    """
    values: dict[str, Any] = {
        "input_delay": _count(table, "input_delay", 0, 2),
        "pwm": table.choice("pwm", ("average", "carrier"), "average"),
        "dead_time": _non_negative(table, "dead_time"),
        "dead_time_compensation": table.flag("dead_time_compensation", False),
        "dc_voltage": table.ranged("dc_voltage") if "dc_voltage" in table else None,
        "current_noise": _non_negative(table, "current_noise"),
        "adc_bits": table.positive_integer("adc_bits", maximum=32) if "adc_bits" in table else None,
        "adc_range": table.positive("adc_range") if "adc_range" in table else None,
        "temperature_rise": table.number("temperature_rise", 0.0),
        "logged_input": table.choice("logged_input", ("applied", "commanded"), "applied"),
        "voltage_hold": table.choice("voltage_hold", ("stationary", "rotor"), "stationary"),
        "encoder_counts": (
            table.positive_integer("encoder_counts", maximum=2**32)
            if "encoder_counts" in table
            else None
        ),
    }
    h = None
    if "switching_frequency" in table:
        h = 1.0 / table.ranged("switching_frequency")
    try:
        return DriveSettings(**values), h
    except DataFileError:
        raise
    except InputError as exc:  # a rule across keys: name the key it is about
        key, _, reason = str(exc).partition(": ")
        raise table.error(key if key in DRIVE_KEYS else None, reason or str(exc)) from None
