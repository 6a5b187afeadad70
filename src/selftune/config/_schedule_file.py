"""MOTOR.toml's optional ``[schedule]`` table: the speeds a controller is scheduled over.

::

    [schedule]
    speeds = [20.0, 100.0, 200.0]   # mechanical rad/s, strictly increasing: the grid
    # or
    speed_range = [20.0, 200.0]     # [min, max], mechanical rad/s: the grid is chosen

With ``speeds`` the design starts from that grid; with ``speed_range`` from its two ends;
in both cases it adds the speeds the check between them asks for
(:func:`selftune.model.design_schedule`). Exactly one of the two keys; every speed a
finite number in the plausible range of a speed, not too fast for the motor (the rule of
``[operating_point] speed``). A schedule may cross zero (negative speeds: the rotor
turning backwards); the firmware's argument is the signed electrical speed ``p speed``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core import finite_float
from ..core._validation import check_electrical_speed, check_range
from ..errors import InputError
from ..model import Motor
from ._toml import ConfigTable

__all__ = ["SCHEDULE_KEYS", "ScheduleConfig", "schedule_config"]

#: The keys of MOTOR.toml's [schedule] table (exactly one of them).
SCHEDULE_KEYS = ("speeds", "speed_range")


@dataclass(frozen=True)
class ScheduleConfig:
    """The [schedule] table of MOTOR.toml.

    Attributes
    ----------
    speeds : tuple of float
        The initial grid, mechanical rad/s, strictly increasing (two or more).
    key : {"speeds", "speed_range"}
        Which key gave them (``speed_range``: its two ends, the rest chosen).
    """

    speeds: tuple[float, ...]
    key: str

    @property
    def automatic(self) -> bool:
        """Whether the grid between the ends is chosen by the design (``speed_range``)."""
        return self.key == "speed_range"


def _speeds(table: ConfigTable, key: str, motor: Motor | None) -> tuple[float, ...]:
    """The list of ``key``: finite speeds, each in range (and not too fast for ``motor``,
    when known), strictly increasing."""
    value = table.data[key]
    if not isinstance(value, list) or not value:
        raise table.error(key, f"must be a list of speeds in rad/s (mechanical), got {value!r}")
    speeds = []
    for entry in value:
        if isinstance(entry, bool) or not isinstance(entry, int | float):
            raise table.error(key, f"entries must be numbers (rad/s), found {entry!r}")
        try:
            speed = check_range(finite_float(entry, "speed"), "speed")
            if motor is not None:
                check_electrical_speed(speed, motor.p, max(motor.L_d, motor.L_q))
        except (InputError, OverflowError) as exc:
            raise table.error(key, str(exc).removeprefix("speed: ")) from None
        speeds.append(speed)
    if len(speeds) < 2:
        raise table.error(key, f"needs at least two speeds (rad/s), got {value!r}")
    if not np.all(np.diff(speeds) > 0.0):
        raise table.error(key, f"must increase strictly, got {value!r}")
    return tuple(speeds)


def schedule_config(table: ConfigTable, motor: Motor | None) -> ScheduleConfig:
    """The speeds of a [schedule] table, validated for ``motor``.

    Parameters
    ----------
    table : ConfigTable
        The [schedule] table (its keys already checked against :data:`SCHEDULE_KEYS`).
    motor : SPMSM or IPMSM or None
        The motor of the file (its pole pairs and inductance bound the speed); None: not
        known yet (a learning configuration's schedule, designed on the motor learned).

    Returns
    -------
    ScheduleConfig

    Raises
    ------
    DataFileError
        One line naming the file, ``[schedule]`` and the key: neither or both keys, a
        value that is not a list of numbers, a speed out of range or too fast for the
        motor, speeds not strictly increasing, or a ``speed_range`` not of two speeds.
    """
    present = [key for key in SCHEDULE_KEYS if key in table]
    if len(present) != 1:
        raise table.error(
            present[-1] if present else None,
            "give exactly one of speeds = [...] (the grid) or speed_range = [min, max] "
            "(mechanical rad/s)",
        )
    key = present[0]
    speeds = _speeds(table, key, motor)
    if key == "speed_range" and len(speeds) != 2:
        raise table.error(key, f"must be [min, max], got {len(speeds)} speeds")
    return ScheduleConfig(speeds, key)
