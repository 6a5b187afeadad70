"""The profile of an online run, PROFILE.toml, read by :func:`load_online_config`::

    [online]
    duration = 120.0        # s of drive time
    [[online.profile]]      # piecewise linear in time; factors on the motor's values
    time = 0.0
    R_s = 1.0
    phi_pm = 1.0
    [[online.profile]]
    time = 120.0
    R_s = 1.4
    phi_pm = 0.92

Each ``[[online.profile]]`` row is a point: ``time`` (s), the factors ``R_s`` and
``phi_pm`` and optionally ``L_s`` (default 1) on the motor's values. The rows' times start
at 0 and do not decrease; two rows at one time make a step (a fault: the first is the
value before, the second from then on); the last row's values hold after it, and its time
must reach ``duration``. The rules are :class:`~selftune.sim.ParameterProfile`'s; every
error is one line naming the file, the row as written (counted from 1) and the key::

    profile.toml: [[online.profile]] row 2: time: -1.0 s is before row 1's 0.0 s (...)
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

from numpy.typing import ArrayLike

from ..errors import DataFileError, InputError
from ..sim import ParameterFactors, ParameterProfile
from ._toml import ConfigFile, ConfigTable, _clip, _type_name, one_line

__all__ = ["MAX_DURATION", "ONLINE_TABLES", "PROFILE_KEYS", "OnlineConfig", "load_online_config"]

#: The tables of a profile file and their keys.
ONLINE_TABLES: Mapping[str, tuple[str, ...]] = MappingProxyType({"online": ("duration", "profile")})
#: The longest run a profile may ask for, s of drive time.
MAX_DURATION = 3600.0
#: The keys of a ``[[online.profile]]`` row.
PROFILE_KEYS = ("time", "R_s", "phi_pm", "L_s")


@dataclass(frozen=True, eq=False)
class OnlineConfig:
    """The content of a profile file (``selftune tune --online``).

    Attributes
    ----------
    duration : float
        Drive time to run, s.
    profile : ParameterProfile
        Factors on the motor's R_s, L_s and phi_pm over time (covering ``duration``).
    source : str
        The file name, for messages.
    """

    duration: float
    profile: ParameterProfile
    source: str = ""

    def factors(self, t: ArrayLike) -> ParameterFactors:
        """The factors on R_s, L_s, phi_pm at times ``t`` (s; any shape):
        :meth:`ParameterProfile.factors`.

        Parameters
        ----------
        t : float or array_like
            Times, s.
        """
        return self.profile.factors(t)


class _ProfileRow(ConfigTable):
    """One ``[[online.profile]]`` row: messages name it ``[[online.profile]] row i``."""

    def __init__(self, file: str, row: int, data: Mapping[str, Any]) -> None:
        self.row = row
        super().__init__(file, "online.profile", data, PROFILE_KEYS)

    def error(self, key: str | None, message: str) -> DataFileError:
        """A :class:`DataFileError` about ``key`` of this row (or the whole row if None).

        Parameters
        ----------
        key : str or None
            The key the message is about; None for the whole row.
        message : str
            What is wrong.
        """
        where = f"[[{self.name}]] row {self.row}" + ("" if key is None else f": {_clip(key)}")
        return DataFileError(one_line(f"{self.file}: {where}: {message}"))


def load_online_config(path: str | os.PathLike[str]) -> OnlineConfig:
    """Read a profile file (the format in the module docstring).

    Parameters
    ----------
    path : str or os.PathLike
        The TOML file.

    Returns
    -------
    OnlineConfig

    Raises
    ------
    DataFileError
        One line naming the file, the table or row and the key, for anything missing,
        unknown, of the wrong type, or against the profile's rules.
    """
    config = ConfigFile(path, ONLINE_TABLES)
    online = config.table("online", required=True)
    duration = online.positive("duration")
    if duration > MAX_DURATION:
        raise online.error(
            "duration",
            f"{duration:g} s is more than {MAX_DURATION:g} s of drive time (the simulated "
            "hardware-like drive runs at about twice real time: an hour takes half an hour)",
        )
    rows = online.data.get("profile")
    if rows is None:
        raise online.error(
            "profile", "missing: give the points as [[online.profile]] rows (time, R_s, phi_pm)"
        )
    if not isinstance(rows, list) or not rows or not all(isinstance(r, dict) for r in rows):
        got = "no row" if rows == [] else _type_name(rows)
        raise online.error("profile", f"must be [[online.profile]] rows (tables), got {got}")
    tables = [_ProfileRow(config.file, index + 1, row) for index, row in enumerate(rows)]
    columns = {
        key: [table.number(key, 1.0 if key == "L_s" else None) for table in tables]
        for key in PROFILE_KEYS
    }
    try:
        profile = ParameterProfile(**columns)
    except InputError as exc:  # the profile's own rules: "row i: key: reason"
        found = re.fullmatch(r"row (\d+): (\w+): (.*)", str(exc))
        if found is None:
            raise online.error("profile", str(exc)) from None
        row, key, reason = found.groups()
        raise tables[int(row) - 1].error(key, reason) from None
    last = float(profile.time[-1])
    if last < duration:
        raise online.error(
            "duration",
            f"{duration:g} s is beyond the profile's last time, {last:g} s: add a "
            "[[online.profile]] row at or after it",
        )
    return OnlineConfig(duration=duration, profile=profile, source=config.file)
