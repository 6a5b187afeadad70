"""The CSV trajectory file: reader and writer (the format is specified in
:mod:`selftune.learn.data._io`)."""

from __future__ import annotations

import math
import re
from io import StringIO
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ...core import Array, atomic_path, first_non_increasing
from ...core._atomic import open_regular_file, read_regular_file
from ...core._validation import LIMITS
from ._data_file import (
    PathLike,
    build,
    check_channels,
    check_trajectory,
    file_error,
    first_beyond,
    quote,
)
from ._trajectory import Trajectory

__all__ = ["csv_dimensions", "load_csv", "save_csv"]

_CSV_CHUNK_ROWS = 10_000
# Characters a CSV data line may contain. Restricting them first keeps the numeric
# grammar to plain decimals (no nan, inf, hex, underscores or exotic whitespace),
# which numpy's parser and Python's float agree on.
_CSV_DATA_BYTES = b"0123456789eE.+-, \t\n\r"
_UTF8_BOM = b"\xef\xbb\xbf"
_BAD_FIELD_CHARACTER = re.compile(r"[^0-9eE.+\- \t]")
_FIELD_WHITESPACE = " \t"
_HEADER = "t,x1..xn,u1..um[,w1..wq][,theta]"
_ANGLE = "theta"  # the column of the electrical rotor angle (Trajectory.angle)


class CsvHeader(NamedTuple):
    """The column names of a CSV file and what they hold."""

    names: list[str]
    n: int
    m: int
    q: int
    angle: bool  # a last column 'theta'


def _columns(trajectory: Trajectory) -> list[str]:
    sizes = (("x", trajectory.n), ("u", trajectory.m), ("w", trajectory.q))
    names = ["t"] + [f"{letter}{i}" for letter, size in sizes for i in range(1, size + 1)]
    return names + ([_ANGLE] if trajectory.angle is not None else [])


def _table(trajectory: Trajectory) -> Array:
    """All columns, one row per sample time; held signals repeat their last value."""
    u = np.vstack([trajectory.u, trajectory.u[-1:]])
    blocks = [trajectory.t.reshape(-1, 1), trajectory.x, u]
    if trajectory.w is not None:
        w = trajectory.w
        if w.shape[0] == trajectory.num_samples:
            w = np.vstack([w, w[-1:]])
        blocks.append(w)
    if trajectory.angle is not None:
        blocks.append(trajectory.angle.reshape(-1, 1))
    return np.hstack(blocks)


def _format_rows(rows: Array) -> str:
    """CSV lines (each ending in a newline) with the shortest exact ``repr`` of each value."""
    return "".join(",".join(map(repr, row)) + "\n" for row in rows.tolist())


def save_csv(trajectory: Trajectory, path: PathLike) -> None:
    """Write a trajectory as CSV (see :mod:`selftune.learn.data._io` for the format), atomically.

    Parameters
    ----------
    trajectory : Trajectory
        The samples to write. The last row repeats the last held input, and the last held
        ``w`` if ``w`` has N rows; the angle, if any, is the last column ``theta``.
    path : str or os.PathLike
        The file, whatever its suffix. An existing file is replaced only once the new one
        is complete.

    Raises
    ------
    InputError
        If ``trajectory`` is not a :class:`Trajectory`.
    OSError
        If the file cannot be written.
    """
    check_trajectory(trajectory, "save_csv")
    table = _table(trajectory)
    header = ",".join(_columns(trajectory)) + "\n"
    with (
        atomic_path(path, suffix=".csv") as temporary,
        temporary.open("w", encoding="utf-8", newline="\n") as stream,
    ):
        stream.write(header)
        for start in range(0, table.shape[0], _CSV_CHUNK_ROWS):
            stream.write(_format_rows(table[start : start + _CSV_CHUNK_ROWS]))


def _alternatives(options: list[str]) -> str:
    """``'a'``, ``'a' or 'b'``, ``'a', 'b' or 'c'``."""
    quoted = [repr(option) for option in options]
    return quoted[0] if len(quoted) == 1 else ", ".join(quoted[:-1]) + " or " + quoted[-1]


def _duplicate(names: list[str], column: int) -> str:
    """A note for a column (numbered from 1) whose name an earlier column has."""
    return " (a duplicate)" if names[column - 1] in names[: column - 1] else ""


def _parse_header(path: Path, line: str) -> CsvHeader:
    """Column names and what they hold, from the header line; raise on any deviation."""
    names = [field.strip(_FIELD_WHITESPACE) for field in line.split(",")]
    if names[0] != "t":
        raise file_error(
            path, f"line 1, column 1: expected 't' (header {_HEADER}), got {quote(names[0])}"
        )
    order = ("x", "u", "w")
    counts = {"x": 0, "u": 0, "w": 0}
    group = 0  # index in order of the group being read
    angle = False
    for column, name in enumerate(names[1:], start=2):
        if angle:
            raise file_error(
                path,
                f"line 1, column {column}: {quote(name)}{_duplicate(names, column)} after "
                f"{_ANGLE!r}; {_ANGLE!r} must be the last column (header {_HEADER})",
            )
        letter = order[group]
        following = order[group + 1] if counts[letter] and group + 1 < len(order) else None
        options = [f"{letter}{counts[letter] + 1}"]
        options += [f"{following}1"] if following else []
        options += [_ANGLE] if counts["u"] else []  # the angle may end the header
        if name == options[0]:
            counts[letter] += 1
        elif following and name == f"{following}1":
            group += 1
            counts[following] = 1
        elif counts["u"] and name == _ANGLE:
            angle = True
        else:
            note = _duplicate(names, column)
            if name == _ANGLE:
                note += f" ({_ANGLE!r} is the last column, after the u and w columns)"
            raise file_error(
                path,
                f"line 1, column {column}: expected {_alternatives(options)}, "
                f"got {quote(name)}{note}",
            )
    if counts["x"] == 0:
        raise file_error(path, "line 1: no state columns; the header must be t,x1..xn,u1..um")
    if counts["u"] == 0:
        raise file_error(
            path,
            f"line 1: no input columns after 'x{counts['x']}'; the header must be t,x1..xn,u1..um",
        )
    check_channels(path, "line 1", counts["x"], counts["u"], counts["w"])
    return CsvHeader(names, counts["x"], counts["u"], counts["w"], angle)


def _split_header(path: Path, raw: bytes) -> tuple[str, bytes]:
    """The header line (decoded) and the rest; an empty file is an error."""
    header_raw, _, body_raw = raw.removeprefix(_UTF8_BOM).partition(b"\n")
    header = _decode(path, header_raw, 1).removesuffix("\r")
    if not header.strip(_FIELD_WHITESPACE) and not body_raw.strip():
        raise file_error(path, f"empty file (expected a header {_HEADER} and rows)")
    return header, body_raw


def csv_dimensions(path: Path) -> tuple[int, int, int]:
    """``(n, m, q)`` from the header line alone (the rows are not read)."""
    limit = LIMITS["header_bytes"]
    with open_regular_file(path) as stream:
        head = stream.read(limit + len(_UTF8_BOM) + 1)
    if b"\n" not in head and len(head) > limit + len(_UTF8_BOM):
        raise file_error(path, f"line 1: the header is longer than {limit} bytes")
    header, _ = _split_header(path, head)
    parsed = _parse_header(path, header)
    return parsed.n, parsed.m, parsed.q


def _locate_csv_error(path: Path, lines: list[str], names: list[str]) -> None:
    """Find the first malformed data line or field and raise a DataFileError about it."""
    for index, line in enumerate(lines):
        number = index + 2  # the header is line 1
        fields = line.split(",")
        if len(fields) != len(names):
            what = "an empty line" if not line.strip(_FIELD_WHITESPACE) else f"{len(fields)}"
            raise file_error(path, f"line {number}: expected {len(names)} fields, got {what}")
        for column, (name, field) in enumerate(zip(names, fields, strict=True), start=1):
            place = f"line {number}, column {column} ({name})"
            try:
                value: float | None = float(field)
            except ValueError:
                value = None
            if value is not None and not math.isfinite(value):
                raise file_error(path, f"{place}: not a finite number: {quote(field)}")
            if value is None or _BAD_FIELD_CHARACTER.search(field):
                raise file_error(path, f"{place}: not a number: {quote(field)}")


def _decode(path: Path, raw: bytes, first_line: int) -> str:
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = first_line + raw.count(b"\n", 0, exc.start)
        byte = raw[exc.start : exc.start + 1].hex()
        raise file_error(path, f"line {line}: not UTF-8 text (byte 0x{byte})") from None


def load_csv(path: PathLike) -> Trajectory:
    """Read a trajectory from a CSV file (see :mod:`selftune.learn.data._io` for the format).

    Parameters
    ----------
    path : str or os.PathLike
        The file, whatever its suffix.

    Returns
    -------
    Trajectory
        The samples; ``w`` (if there are w columns) has N + 1 rows; ``angle`` is the
        ``theta`` column, if there is one.

    Raises
    ------
    DataFileError
        If the file cannot be read or is malformed: wrong, missing, extra, duplicate,
        misplaced or misnumbered columns, a line with the wrong number of fields, a field
        that is not a finite number, fewer than two rows, or times that do not strictly
        increase. The one-line message names the file, the line and the column.
    """
    target = Path(path)
    raw = read_regular_file(target, LIMITS["csv_bytes"], "a CSV data file")
    header, body_raw = _split_header(target, raw)
    names, n, m, q, angle = _parse_header(target, header)
    body, end, rows, plain = _csv_body(target, body_raw)
    table: Array | None = None
    if plain:
        try:
            table = np.loadtxt(
                StringIO(body), delimiter=",", comments=None, dtype=np.float64, ndmin=2
            )
        except ValueError:
            table = None
    if table is None or table.shape != (rows, len(names)):
        # Slow path, only for a malformed file: find the first bad line and field.
        _locate_csv_error(target, body[:end].split("\n"), names)
        raise file_error(target, "malformed data rows")  # not reached: the scan raises
    beyond = first_beyond(table)
    if beyond is not None:
        (row, column), what = beyond
        raise file_error(target, f"line {row + 2}, column {column + 1} ({names[column]}): {what}")
    t = table[:, 0]
    k = first_non_increasing(t)
    if k is not None:
        raise file_error(
            target,
            f"line {k + 3}, column 1 (t): time {float(t[k + 1])!r} is not greater than "
            f"{float(t[k])!r} on line {k + 2}; times must be strictly increasing",
        )
    x = table[:, 1 : 1 + n]
    u = table[:, 1 + n : 1 + n + m]
    w = table[:, 1 + n + m : 1 + n + m + q] if q else None
    return build(target, t, x, u, w, table[:, -1] if angle else None)


def _csv_body(path: Path, body_raw: bytes) -> tuple[str, int, int, bool]:
    """The data lines as text (plain ASCII if they are), where they end, and how many."""
    # Fast check that the data are plain ASCII numbers, commas and line ends; a file that
    # fails it is decoded in full so that the scan can say what is wrong where.
    plain = not body_raw.translate(None, _CSV_DATA_BYTES) and (
        b"\r" not in body_raw or body_raw.count(b"\r") == body_raw.count(b"\r\n")
    )
    body = body_raw.decode("ascii") if plain else _decode(path, body_raw, 2)
    if "\r" in body:
        body = body.replace("\r\n", "\n")
    # Blank lines at the end are ignored (numpy skips empty lines; spaces must go).
    end = len(body)
    while end and body[end - 1] in " \t\n":
        end -= 1
    if body[end:].strip("\n"):
        body = body[:end]
    rows = body.count("\n", 0, end) + 1 if end else 0
    if rows < 2:
        raise file_error(
            path, f"need at least 2 data rows (sample times) after the header, got {rows}"
        )
    if rows > LIMITS["samples"]:
        raise file_error(path, f"{rows} data rows; at most {LIMITS['samples']} are read")
    return body, end, rows, plain
