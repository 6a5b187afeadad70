"""A controller from a JSON result: :func:`load_control_law`, :func:`load_law_result`.

Every selftune JSON that carries a controller names it ``control_law`` with every matrix
(:meth:`selftune.core.ControlLaw.document`): ``selftune tune --json``, ``selftune learn
--json``. :func:`load_control_law` reads it back; an online run's JSON
(``selftune tune --online --json``) gives its last switch's law, or the cold law if it
switched none. :func:`load_law_result` adds what the file says of the drive the law was
made for (:class:`LawResult`), and the law's schedule where the file has one: over speed
(``schedule``, :meth:`selftune.model.SpeedSchedule.document`: ``selftune solve`` and
``tune`` with a ``[schedule]`` table), over the q-axis current reference
(``current_schedule``: ``tune`` with a ``[saturation]`` table), or over both
(``speed_current_schedule``: ``tune`` with both tables; the one used where a file has
several). Every schedule the file states is read, and refused unless its laws have the
form of the law (only the gains vary). Every error is one line naming the file and the
key.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from ..core import ControlLaw
from ..core._atomic import read_regular_file
from ..errors import DataFileError, InputError
from ..model import CurrentSchedule, SpeedCurrentSchedule, SpeedSchedule
from ..model._schedule import same_structure

__all__ = ["LawResult", "load_control_law", "load_law_result"]

#: The largest JSON file read, bytes (a result with its history is well under 10 MB).
_LIMIT = 64 << 20


def _law_document(document: Any) -> tuple[Any, str]:
    """The ``control_law`` mapping of a result and its key path."""
    if not isinstance(document, Mapping):
        raise InputError("expected a JSON object with a 'control_law'")
    online = document.get("online")
    if isinstance(online, Mapping) and isinstance(online.get("switches"), list):
        switches = [s for s in online["switches"] if isinstance(s, Mapping)]
        if switches:
            return switches[-1].get("control_law"), "online.switches[-1].control_law"
        cold = document.get("cold")
        if isinstance(cold, Mapping):
            return cold.get("control_law"), "cold.control_law"
    return document.get("control_law"), "control_law"


@dataclass(frozen=True)
class LawResult:
    """A JSON result's controller and what the file says of the drive it was made for.

    Attributes
    ----------
    law : ControlLaw
        The controller (see :func:`load_control_law`).
    key : str
        Where the file holds it (``"control_law"``, ``"online.switches[-1].control_law"``).
    h : float or None
        The sampling period, s: the law's (with integral action), else the file's ``h``
        (``learn``, ``tune --online``) or ``settings.h`` (``tune``); None if none.
    input_delay : int or None
        The computation delay, samples: ``input_delay`` (``learn``) or the drive's
        (``tune --online``); None where the file does not say (``tune``).
    motor : dict or None
        The motor's ``R_s``, ``L_s``, ``phi_pm``, ``p`` (``tune``, ``tune --online``);
        None where the file names none (``learn``: a log, not a motor).
    dc_voltage : float or None
        The drive's DC bus, V (``tune --online``); None where the file does not say.
    scheduled : bool
        Whether the file schedules the law (a ``schedule`` key over speed, a
        ``current_schedule`` over ``i_q*``, or a ``speed_current_schedule`` over both,
        beside the law or at the top; the last is the one read where there are several).
    schedule : SpeedSchedule or CurrentSchedule or SpeedCurrentSchedule or None
        That schedule (its laws in the convention of ``law``); None without one.
    """

    law: ControlLaw
    key: str
    h: float | None
    input_delay: int | None
    motor: dict[str, float] | None
    dc_voltage: float | None
    scheduled: bool
    schedule: SpeedSchedule | CurrentSchedule | SpeedCurrentSchedule | None = None


def _read_document(path: str | os.PathLike[str]) -> Any:
    """The JSON document at ``path``."""
    name = os.fspath(path)
    try:
        raw = read_regular_file(path, _LIMIT, "a JSON result")
        return json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DataFileError(f"{name}: not a JSON file ({exc})") from None
    except InputError as exc:
        raise DataFileError(str(exc)) from None


def _law_of(document: Any, name: str) -> tuple[ControlLaw, Mapping[str, Any], str]:
    """The controller of ``document`` (from the file ``name``), its mapping and key."""
    try:
        law, key = _law_document(document)
    except InputError as exc:
        raise DataFileError(f"{name}: {exc}") from None
    if not isinstance(law, Mapping):
        raise DataFileError(f"{name}: {key}: missing (a selftune result names its controller so)")
    values: dict[str, Any] = {}
    for field in ("K", "X", "U", "history", "K_i", "C", "F", "h"):
        if field in ("K", "X", "U", "history") and field not in law:
            raise DataFileError(f"{name}: {key}.{field}: missing")
        values[field] = law.get(field)
    try:
        return ControlLaw(**values), law, key
    except (InputError, TypeError, ValueError) as exc:
        raise DataFileError(f"{name}: {key}: {exc}") from None


def load_control_law(path: str | os.PathLike[str]) -> ControlLaw:
    """The controller a JSON result names (see the module).

    Parameters
    ----------
    path : str or os.PathLike
        The JSON file.

    Raises
    ------
    DataFileError
        ``"<file>: <key>: <why>"``, if the file is not JSON, has no controller, or a
        matrix is missing or does not fit.
    """
    return _law_of(_read_document(path), os.fspath(path))[0]


def _number(table: Any, key: str) -> float | None:
    value = table.get(key) if isinstance(table, Mapping) else None
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value) if math.isfinite(value) else None


def _motor(document: Mapping[str, Any]) -> dict[str, float] | None:
    motor = document.get("motor")
    inductances = ("L_s",) if _number(motor, "L_s") is not None else ("L_d", "L_q")
    values = {key: _number(motor, key) for key in ("R_s", *inductances, "phi_pm", "p")}
    if any(value is None for value in values.values()):
        return None
    return {key: float(value) for key, value in values.items() if value is not None}


def load_law_result(path: str | os.PathLike[str]) -> LawResult:
    """The controller a JSON result names and what the file says of its drive.

    Parameters
    ----------
    path : str or os.PathLike
        The JSON file (``selftune learn``, ``tune`` or ``tune --online``).

    Raises
    ------
    DataFileError
        As :func:`load_control_law`.
    """
    document = _read_document(path)
    law, mapping, key = _law_of(document, os.fspath(path))
    drive = document.get("drive")
    drive_settings = drive.get("settings", drive) if isinstance(drive, Mapping) else None
    stated = _stated_schedules(document, mapping, os.fspath(path), law, key)
    kind = next(iter(stated), "schedule")  # the first: the one the firmware runs
    schedule = stated.get(kind)
    design = document.get(f"{kind}_design") if schedule is not None else None
    h = law.h
    for table in (design, document, document.get("settings")):
        h = h if h is not None else _number(table, "h")
    delay = _number(design, "input_delay")
    delay = delay if delay is not None else _number(document, "input_delay")
    if delay is None:
        delay = _number(drive_settings, "input_delay")
    return LawResult(
        law=law,
        key=key,
        h=h,
        input_delay=None if delay is None else int(delay),
        motor=_motor(document),
        dc_voltage=_number(drive_settings, "dc_voltage"),
        scheduled=_given(mapping, document, kind),
        schedule=schedule,
    )


#: The schedule keys a JSON result may hold, the one read first first.
_SCHEDULE_KEYS = ("speed_current_schedule", "current_schedule", "schedule")


def _stated_schedules(
    document: Any, mapping: Mapping[str, Any], name: str, law: ControlLaw, key: str
) -> dict[str, SpeedSchedule | CurrentSchedule | SpeedCurrentSchedule | None]:
    """Every schedule the file states (beside the law or at the top), in the order of
    :data:`_SCHEDULE_KEYS` (None: the key holds null), each read whole and refused unless
    its laws have the form of the law at ``key`` (only the gains may vary): a file whose
    tables disagree is not one result, whichever of them is exported."""
    stated: dict[str, SpeedSchedule | CurrentSchedule | SpeedCurrentSchedule | None] = {}
    for kind in _SCHEDULE_KEYS:
        if not _given(mapping, document, kind):
            continue
        table = mapping.get(kind, document.get(kind))
        schedule: SpeedSchedule | CurrentSchedule | SpeedCurrentSchedule | None = (
            _speed_current_schedule(table, name)
            if kind == "speed_current_schedule"
            else _schedule(table, name, kind)
        )
        if schedule is not None:
            try:
                same_structure([law, schedule.first_law], [key, "its first law"])
            except InputError as exc:
                raise DataFileError(
                    f"{name}: {kind}: {str(exc).removeprefix('laws: ')}: a schedule's laws "
                    f"have the form of {key} (only the gains vary)"
                ) from None
        stated[kind] = schedule
    return stated


def _given(mapping: Mapping[str, Any], document: Any, key: str) -> bool:
    """Whether ``key`` is beside the law or at the document's top."""
    return key in mapping or key in document


#: The schedules a JSON result may state, by key (each class names its grid).
_SCHEDULES: dict[str, type[SpeedSchedule] | type[CurrentSchedule]] = {
    "schedule": SpeedSchedule,
    "current_schedule": CurrentSchedule,
}


def _schedule(
    table: Any, name: str, key: str = "schedule", label: str | None = None
) -> SpeedSchedule | CurrentSchedule | None:
    """The schedule a JSON result's ``key`` states (None if it has none): ``schedule``
    over ``electrical_speed``, ``current_schedule`` over ``current`` (messages name it
    ``label``, default ``key``)."""
    if table is None:
        return None
    kind = _SCHEDULES[key]
    key = key if label is None else label
    grid_key, points = kind.variable, kind.points
    if not isinstance(table, Mapping):
        raise DataFileError(f"{name}: {key}: must be an object, got {type(table).__name__}")
    for field in (grid_key, "K", "U", "X", "history"):
        if field not in table:
            raise DataFileError(f"{name}: {key}.{field}: missing")
    grid = table[grid_key]
    if not isinstance(grid, list):
        raise DataFileError(f"{name}: {key}.{grid_key}: must be a list of {points}")
    laws = []
    for field in ("K", "U", "X", "K_i"):
        entries = table.get(field)
        if (field != "K_i" or entries is not None) and (
            not isinstance(entries, list) or len(entries) != len(grid)
        ):
            raise DataFileError(
                f"{name}: {key}.{field}: must list one matrix per {kind.point} ({len(grid)})"
            )
    K_i = table.get("K_i")
    try:
        for index in range(len(grid)):
            gains = (table["K"][index], table["X"][index], table["U"][index])
            integral = None if K_i is None else K_i[index]
            laws.append(
                ControlLaw(
                    *gains,
                    table["history"],
                    integral,
                    table.get("C"),
                    table.get("F"),
                    table.get("h"),
                )
            )
        return kind(grid, laws)
    except (InputError, TypeError, ValueError) as exc:
        raise DataFileError(f"{name}: {key}: {exc}") from None


def _speed_current_schedule(table: Any, name: str) -> SpeedCurrentSchedule | None:
    """The schedule over speed and current a JSON result's ``speed_current_schedule``
    states (None if it has none): its matrices indexed ``[current][speed]``, each
    current's row read as a ``schedule`` over ``electrical_speed``."""
    if table is None:
        return None
    key = "speed_current_schedule"
    if not isinstance(table, Mapping):
        raise DataFileError(f"{name}: {key}: must be an object, got {type(table).__name__}")
    for field in ("electrical_speed", "current", "K", "U", "X", "history"):
        if field not in table:
            raise DataFileError(f"{name}: {key}.{field}: missing")
    currents = table["current"]
    if not isinstance(currents, list):
        raise DataFileError(f"{name}: {key}.current: must be a list of currents")
    for field in ("K", "U", "X", "K_i"):
        entries = table.get(field)
        if (field != "K_i" or entries is not None) and (
            not isinstance(entries, list) or len(entries) != len(currents)
        ):
            raise DataFileError(
                f"{name}: {key}.{field}: must list one row of matrices per current "
                f"({len(currents)})"
            )
    rows = []
    for index in range(len(currents)):
        row = {
            **{field: table.get(field) for field in ("electrical_speed", "history", "C", "F", "h")},
            **{field: table[field][index] for field in ("K", "U", "X") },
            "K_i": None if table.get("K_i") is None else table["K_i"][index],
        }  # fmt: skip
        schedule = _schedule(row, name, "schedule", f"{key} (current {index})")
        assert schedule is not None
        rows.append(schedule.laws)
    try:
        return SpeedCurrentSchedule(table["electrical_speed"], currents, rows)
    except (InputError, TypeError, ValueError) as exc:
        raise DataFileError(f"{name}: {key}: {exc}") from None
