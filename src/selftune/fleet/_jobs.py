"""A fleet's logs and what each gives: the jobs (:func:`find_jobs`, from files,
directories, globs or a manifest CSV) and one log's row of the results
(:func:`learn_row`: ``selftune learn`` on it, never raising)."""

from __future__ import annotations

import csv
import glob
import io
import json
import os
import re
import time
import tomllib
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..config import LEARN_TABLES, learn_log
from ..core._atomic import read_regular_file
from ..errors import DataFileError, InputError, error_line

__all__ = [
    "LOG_SUFFIXES",
    "MANIFEST_COLUMNS",
    "LogJob",
    "find_jobs",
    "learn_row",
    "read_manifest",
]

#: The suffixes of the logs a directory or a glob gives (``selftune learn``'s formats).
LOG_SUFFIXES = (".csv", ".npz")

#: The manifest's own columns; any other is ``table.key`` of CONFIG.toml.
MANIFEST_COLUMNS = ("path", "drive", "group", "config")

#: The largest manifest read, bytes.
MANIFEST_BYTES = 64 * 2**20

#: A cell read as a plain string when it is not a TOML value (``digital`` for
#: ``"digital"``).
_BARE_WORD = re.compile(r"^[A-Za-z_][\w.-]*$")


@dataclass(frozen=True)
class LogJob:
    """One log of a fleet and how to learn it.

    Attributes
    ----------
    path : str
        The log (CSV or NPZ).
    drive : str
        The drive's id: the manifest's, or the file's name without its extension.
    group : str
        The drives it is compared with (same motor): the manifest's, or the name of the
        log's directory.
    config : str
        Its CONFIG.toml.
    overrides : dict
        ``{table: {key: value}}`` over the configuration (the manifest's columns).
    overridden_by : str
        Where the overrides come from (``"manifest.csv row 3"``), for messages.
    """

    path: str
    drive: str
    group: str
    config: str
    overrides: dict[str, dict[str, Any]] = field(default_factory=dict)
    overridden_by: str = ""


def _is_manifest(path: Path) -> bool:
    """Whether a CSV file's header starts with ``path`` (a manifest, not a log)."""
    try:
        with path.open("rb") as stream:
            head = stream.read(256).decode("utf-8", errors="replace").removeprefix("\ufeff")
    except OSError:
        return False
    first = head.splitlines()[0] if head else ""
    return first.split(",")[0].strip().strip('"') == "path"


def _cell(text: str, where: str) -> Any:
    """A manifest cell's TOML value (a bare word is a string)."""
    try:
        return tomllib.loads(f"value = {text}")["value"]
    except tomllib.TOMLDecodeError:
        if _BARE_WORD.match(text):
            return text
        raise DataFileError(f"{where}: not a TOML value ({text[:40]!r})") from None


def _override_column(name: str, manifest: str) -> tuple[str, str]:
    table, dot, key = name.partition(".")
    known = ", ".join(MANIFEST_COLUMNS)
    if not dot:
        raise DataFileError(
            f"{manifest}: column {name!r}: unknown (known: {known}, or table.key of the"
            " configuration, e.g. learning.electrical_speed)"
        )
    if key not in LEARN_TABLES.get(table, ()):
        tables = ", ".join(f"[{t}] {' '.join(k)}" for t, k in LEARN_TABLES.items())
        raise DataFileError(
            f"{manifest}: column {name!r}: no key of the configuration (tables: {tables})"
        )
    return table, key


def read_manifest(path: str, config: str) -> list[LogJob]:
    """The jobs of a manifest CSV: a row per log.

    The header names the columns: ``path`` (required; relative to the manifest's
    directory), ``drive`` (required), ``group`` and ``config`` (a CONFIG.toml for the
    row, relative to the manifest; default ``config``), and any ``table.key`` of the
    configuration, whose non-empty cells (TOML values: ``150.0``, ``[[1, 0], [0, 1]]``,
    ``digital``) override the configuration for the row.

    Parameters
    ----------
    path : str
        The manifest.
    config : str
        The configuration of the rows that name none.

    Raises
    ------
    DataFileError
        One line naming the manifest, and the row and column where there is one (a log
        on two rows is one: each log is one drive's).
    """
    raw = read_regular_file(path, MANIFEST_BYTES, "a manifest")
    try:
        text = raw.decode("utf-8").removeprefix("\ufeff")
    except UnicodeDecodeError as exc:
        where = f"not UTF-8 text at byte {exc.start}"
        raise DataFileError(f"{path}: not a manifest ({where})") from None
    rows = list(csv.reader(io.StringIO(text)))
    if not rows:
        raise DataFileError(f"{path}: empty manifest (its header: path,drive[,group,config,...])")
    header = [name.strip() for name in rows[0]]
    for required in ("path", "drive"):
        if required not in header:
            raise DataFileError(f"{path}: no column {required!r} in the header")
    overrides = {
        index: _override_column(name, path)
        for index, name in enumerate(header)
        if name not in MANIFEST_COLUMNS
    }
    home = Path(path).parent
    jobs = []
    rows_of: dict[str, int] = {}  # each log's row: a log is one drive's, once
    for number, values in enumerate(rows[1:], start=2):
        if not any(value.strip() for value in values):
            continue
        where = f"{path}: row {number}"
        if len(values) != len(header):
            raise DataFileError(f"{where}: {len(values)} fields, the header has {len(header)}")
        cells = dict(zip(header, (value.strip() for value in values), strict=True))
        for required in ("path", "drive"):
            if not cells[required]:
                raise DataFileError(f"{where}, column {required}: empty")
        settings: dict[str, dict[str, Any]] = {}
        for index, (table, key) in overrides.items():
            if values[index].strip():
                value = _cell(values[index].strip(), f"{where}, column {header[index]}")
                settings.setdefault(table, {})[key] = value
        log = home / cells["path"]
        key = os.path.normcase(os.path.abspath(log))
        if key in rows_of:
            raise DataFileError(
                f"{where}, column path: {cells['path']} is row {rows_of[key]}'s log too: each "
                "log is one drive's and is learned once"
            )
        rows_of[key] = number
        jobs.append(
            LogJob(
                path=os.fspath(log),
                drive=cells["drive"],
                group=cells.get("group") or log.parent.name,
                config=os.fspath(home / cells["config"]) if cells.get("config") else config,
                overrides=settings,
                overridden_by=f"{path} row {number}" if settings else "",
            )
        )
    return jobs


def _logs_in(directory: Path) -> Iterator[Path]:
    for found in sorted(directory.rglob("*")):
        if found.suffix.lower() in LOG_SUFFIXES and found.is_file():
            if not any(part.startswith(".") for part in found.relative_to(directory).parts):
                yield found


def find_jobs(logs: Sequence[str], config: str) -> list[LogJob]:
    """The jobs of ``selftune fleet LOGS...``.

    Each argument is a manifest CSV (its header starts with ``path``:
    :func:`read_manifest`), a log file, a directory (its ``.csv`` and ``.npz`` logs,
    recursively, manifests and hidden files left out) or a glob. Without a manifest the
    drive's id is the file's name without its extension, its group the directory's name.
    A log that several arguments name is learned once, as the first names it.

    Parameters
    ----------
    logs : sequence of str
        The arguments.
    config : str
        CONFIG.toml.

    Raises
    ------
    InputError
        If an argument is none of these, or no log is found.
    """
    jobs: list[LogJob] = []
    for argument in logs:
        target = Path(argument)
        if target.is_dir():
            found = [p for p in _logs_in(target) if not (p.suffix == ".csv" and _is_manifest(p))]
        elif target.is_file() and target.suffix.lower() == ".csv" and _is_manifest(target):
            jobs += read_manifest(argument, config)
            continue
        elif os.path.lexists(target):
            found = [target]
        else:
            found = [Path(p) for p in sorted(glob.glob(argument, recursive=True))]
            found = [p for p in found if p.suffix.lower() in LOG_SUFFIXES and p.is_file()]
            if not found:
                raise InputError(
                    f"{argument}: no such log, directory or manifest, and no log matches it"
                )
        jobs += [LogJob(os.fspath(p), p.stem, p.absolute().parent.name, config) for p in found]
    if not jobs:
        raise InputError(
            "LOGS: no log found (give .csv or .npz logs, directories of them, globs or a"
            " manifest CSV)"
        )
    return _once(jobs)


def _once(jobs: list[LogJob]) -> list[LogJob]:
    """Each log's first job: arguments that overlap (a directory and a log in it, two
    globs) name it again, and a drive learned twice would count twice in its group."""
    seen: set[str] = set()
    kept = []
    for job in jobs:
        key = os.path.normcase(os.path.abspath(job.path))
        if key not in seen:
            seen.add(key)
            kept.append(job)
    return kept


def _matrix(value: Any) -> str:
    """A matrix as JSON text (empty for none)."""
    return "" if value is None else json.dumps(np.asarray(value, dtype=float).tolist())


def _failed(job: LogJob, error: Exception) -> tuple[str, str]:
    """The row's verdict and one-line error for an exception."""
    line = error_line(error)
    if line is None:  # not a user's error: still one line, never a traceback
        text = " ".join(str(error).split())
        line = f"{job.path}: unexpected failure ({type(error).__name__}: {text})"
    return type(error).__name__, line


def learn_row(job: LogJob) -> dict[str, Any]:
    """The log's row of the results: ``selftune learn`` on it (:func:`~selftune.config.
    learn_log`), its controller, quality and identified motor, or why it failed.

    It never raises for the log's sake: a refusal, an unreadable or hostile file, a bad
    configuration is the row's ``verdict`` (the error's class) and ``error`` (the one
    line ``selftune learn`` prints after ``selftune: error:``).

    Parameters
    ----------
    job : LogJob
        The log.

    Returns
    -------
    dict
        The row (:data:`~selftune.fleet.RESULT_COLUMNS`).
    """
    started = time.perf_counter()
    row: dict[str, Any] = {"path": job.path, "drive": job.drive, "group": job.group}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # as on the command line: never shown
            learned = learn_log(job.path, job.config, job.overrides, job.overridden_by)
    except Exception as exc:  # every failure is the row's, the batch goes on
        row["verdict"], row["error"] = _failed(job, exc)
        row["learn_seconds"] = time.perf_counter() - started
        return row
    result, quality = learned.result, learned.result.verdict
    law, motor = result.law, quality.motor
    dead_time = quality.voltage_error if motor is None else motor.v
    row.update(
        verdict="learned",
        error="",
        method=result.method,
        target=result.target,
        K=_matrix(law.K),
        K_i=_matrix(law.K_i),
        U=_matrix(law.U),
        K_relative_se=quality.K_relative_se,
        K_i_relative_se=quality.K_i_relative_se,
        U_relative_se=quality.U_relative_se,
        R_s_ohm=None if motor is None else motor.R_s,
        R_s_se_ohm=None if motor is None else motor.R_s_se,
        L_s_H=None if motor is None else motor.L_s,
        L_s_se_H=None if motor is None else motor.L_s_se,
        phi_pm_Wb=None if motor is None else motor.phi_pm,
        phi_pm_se_Wb=None if motor is None else motor.phi_pm_se,
        dead_time_V=dead_time,
        dead_time_se_V=None if motor is None else motor.v_se,
        samples=learned.data.num_samples,
        data_seconds=learned.data.duration,
        learn_seconds=time.perf_counter() - started,
    )
    return row
