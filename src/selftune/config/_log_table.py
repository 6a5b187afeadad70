"""The ``[log]`` table of CONFIG.toml: a drive's log in its own columns, units and frame
(:func:`load_log_format` -> :class:`~selftune.learn.LogFormat`).

The grammar: each quantity is a key whose value is the file's column name, or a table
``{column = NAME, unit = UNIT}`` (``unit = "counts"`` takes ``scale``, the SI units per
count, and optionally ``offset``, the count of zero: SI value = ``(count - offset) *
scale``)::

    [log]
    time = {column = "timestamp", unit = "ms"}   # "s" (default), "ms", "us"
    i_a = {column = "Ia", unit = "mA"}           # currents: "A" (default), "mA"
    i_b = {column = "Ib", unit = "mA"}           # i_c optional (else -i_a - i_b)
    d_a = "PWM_A"                                # duty cycles: "1" (default, 0 to 1), "%"
    d_b = "PWM_B"
    d_c = "PWM_C"
    u_dc = "Vbus"                                # or a constant, V: u_dc = 540.0
    angle = {column = "theta_el", unit = "deg"}  # electrical: "rad" (default), "deg"
    advance = 1.5                                # see below
    w1 = "emf_ref"                               # the references, as written ("1")
    w2 = "torque_ref"

The currents are ``i_d``, ``i_q`` or ``i_a``, ``i_b`` [, ``i_c``]; the voltages
``u_d``, ``u_q`` (V) or ``u_a``, ``u_b``, ``u_c`` (V) or ``d_a``, ``d_b``, ``d_c`` with
``u_dc`` (V). Every unit may also be ``"counts"``. ``angle`` is needed by the phase
frame; ``advance`` (samples) by phase voltages or duty cycles, and only by them: the
drive modulated row k's voltages at ``theta_k + advance (theta_(k+1) - theta_k)`` (1/2
for the voltage applied over the row's sample by a drive that compensates its delay,
``d + 1/2`` for the one logged when computed, d the input delay;
:mod:`selftune.learn.data._frames`). Every mistake is one line naming the key.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

from ..errors import InputError
from ._toml import ConfigFile, ConfigTable

__all__ = ["LOG_KEYS", "UNITS", "load_log_format"]

_REFERENCES = tuple(f"w{index}" for index in range(1, 11))

#: The keys of the ``[log]`` table.
LOG_KEYS: tuple[str, ...] = (
    "time", "i_d", "i_q", "i_a", "i_b", "i_c", "u_d", "u_q", "u_a", "u_b", "u_c",
    "d_a", "d_b", "d_c", "u_dc", "angle", "advance", *_REFERENCES,
)  # fmt: skip

_TIME = MappingProxyType({"s": 1.0, "ms": 1e-3, "us": 1e-6})
_CURRENT = MappingProxyType({"A": 1.0, "mA": 1e-3})
_VOLTAGE = MappingProxyType({"V": 1.0})
_DUTY = MappingProxyType({"1": 1.0, "%": 0.01})
_ANGLE = MappingProxyType({"rad": 1.0, "deg": math.pi / 180.0})
_AS_WRITTEN = MappingProxyType({"1": 1.0})

#: Each key's units and what each is in SI (the first is the default); ``"counts"``
#: (with ``scale``) is accepted besides.
UNITS: Mapping[str, Mapping[str, float]] = MappingProxyType(
    {
        "time": _TIME,
        **{key: _CURRENT for key in ("i_d", "i_q", "i_a", "i_b", "i_c")},
        **{key: _VOLTAGE for key in ("u_d", "u_q", "u_a", "u_b", "u_c", "u_dc")},
        **{key: _DUTY for key in ("d_a", "d_b", "d_c")},
        "angle": _ANGLE,
        **{key: _AS_WRITTEN for key in _REFERENCES},
    }
)

_SPEC_KEYS = ("column", "unit", "scale", "offset")
_FRAMES = (
    ("currents", (("i_d", "i_q"), ("i_a", "i_b")), ("i_c",)),
    ("voltages", (("u_d", "u_q"), ("u_a", "u_b", "u_c"), ("d_a", "d_b", "d_c")), ()),
)


def _column(table: ConfigTable, key: str) -> Any:
    """The :class:`~selftune.learn.LogColumn` of ``key`` (a name, a table, or for
    ``u_dc`` a constant in V)."""
    from ..learn import LogColumn

    value = table.data[key]
    if key == "u_dc" and isinstance(value, int | float) and not isinstance(value, bool):
        volts = table.positive(key)
        return LogColumn(key, None, value=volts)
    if isinstance(value, str):
        value = {"column": value}
    if not isinstance(value, dict):
        what = "a column name, a table {column = ..., unit = ...}"
        raise table.error(key, f"must be {what}{' or a number (V)' if key == 'u_dc' else ''}")
    # Its keys as "i_a.unit": every message names the quantity and the key.
    spec = ConfigTable(
        table.file,
        table.name,
        {f"{key}.{name}": item for name, item in value.items()},
        [f"{key}.{name}" for name in _SPEC_KEYS],
    )
    column = value.get("column")
    if not isinstance(column, str) or not column:
        raise spec.error(f"{key}.column", "missing: the name of the file's column")
    units = UNITS[key]
    default = next(iter(units))
    unit = spec.choice(f"{key}.unit", (*units, "counts"), default)
    if unit != "counts":
        for name in ("scale", "offset"):
            if f"{key}.{name}" in spec:
                message = f'only with unit = "counts" (this column is in {unit})'
                raise spec.error(f"{key}.{name}", message)
        return LogColumn(key, column, scale=units[unit])
    scale = spec.number(f"{key}.scale")
    if scale == 0.0:
        raise spec.error(f"{key}.scale", "must be nonzero (the SI units per count)")
    return LogColumn(key, column, scale=scale, offset=spec.number(f"{key}.offset", 0.0))


def load_log_format(path: str | os.PathLike[str], tables: Mapping[str, tuple[str, ...]]) -> Any:
    """The ``[log]`` table of a learning configuration, or None if it has none.

    Parameters
    ----------
    path : str or os.PathLike
        CONFIG.toml.
    tables : mapping
        The configuration's tables and their keys (:data:`~._learn_file.LEARN_TABLES`).

    Returns
    -------
    LogFormat or None
        Where the log's quantities are, their units and frames.

    Raises
    ------
    DataFileError
        One line naming the file, ``[log]`` and the key: an unknown key or unit, a
        missing column name, a frame half given or two frames mixed, a missing angle,
        DC bus or advance, or one given where nothing uses it.
    """
    from ..learn import LogFormat

    config = ConfigFile(path, tables)
    if "log" not in config:
        return None
    table = config.table("log")
    if "time" not in table:
        raise table.error("time", "missing: the column of the sample times")
    groups = {}
    for what, frames, optional in _FRAMES:
        given = [frame for frame in frames if any(key in table for key in frame)]
        if len(given) != 1:
            listing = " or ".join(", ".join(frame) for frame in frames)
            mixed = "two frames mixed" if given else "missing"
            raise table.error(
                given[1][0] if len(given) > 1 else None, f"{what}: {mixed}; give {listing}"
            )
        absent = [key for key in given[0] if key not in table]
        if absent:
            raise table.error(absent[0], f"missing: the {what} need {', '.join(given[0])}")
        groups[what] = tuple(_column(table, key) for key in (*given[0], *optional) if key in table)
    references = []
    for index, key in enumerate(_REFERENCES):
        if key in table:
            if index and _REFERENCES[index - 1] not in table:
                raise table.error(
                    key, f"given without {_REFERENCES[index - 1]}: number them from w1"
                )
            references.append(_column(table, key))
    phase_voltages = groups["voltages"][0].key != "u_d"
    if phase_voltages and "advance" not in table:
        raise table.error(
            "advance",
            "missing: the phase voltages were modulated at theta_k + advance (theta_(k+1) - "
            "theta_k): 0.5 for the voltage applied over row k's sample by a drive that "
            "compensates its delay, d + 0.5 for the one logged when computed (d the input "
            "delay)",
        )
    if not phase_voltages and "advance" in table:
        raise table.error("advance", "only phase voltages or duty cycles need it")
    try:
        return LogFormat(
            time=_column(table, "time"),
            currents=groups["currents"],
            voltages=groups["voltages"],
            references=tuple(references),
            angle=_column(table, "angle") if "angle" in table else None,
            dc_voltage=_column(table, "u_dc") if "u_dc" in table else None,
            advance=table.number("advance", 0.0),
        )
    except InputError as exc:
        key, _, reason = str(exc).partition(": ")
        raise table.error(key if key in LOG_KEYS else None, reason) from None
