"""The CSV trajectory file: reader and writer (the format is specified in
:mod:`selftune.learn.data._io`)."""

from __future__ import annotations

import itertools
import math
import re
from collections.abc import Callable, Iterator
from io import BytesIO
from pathlib import Path
from typing import IO, NamedTuple, Protocol, TypeVar

import numpy as np

from ...core import Array, atomic_path, first_non_increasing
from ...core._atomic import open_regular_file, read_regular_file
from ...core._validation import LIMITS
from ._data_file import (
    MAX_LOG_COLUMNS,
    PathLike,
    build,
    check_channels,
    check_trajectory,
    file_error,
    first_beyond,
    quote,
)
from ._trajectory import Trajectory

__all__ = [
    "CsvHeader",
    "csv_dimensions",
    "load_csv",
    "load_csv_columns",
    "read_csv_chunks",
    "save_csv",
]

_CSV_CHUNK_ROWS = 10_000
# Bytes of data lines checked and parsed at a time (a block ends at a line end): what
# reading holds besides the file's bytes and the table is a block and its numbers.
_CSV_BLOCK_BYTES = 1 << 22
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
    """The column names of a CSV file and what they hold: the names, n, m, q, and
    whether the last column is the rotor angle ``theta``."""

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


def _split_header(path: Path, raw: bytes) -> tuple[str, int]:
    """The header line (decoded) and where the data lines start; an empty file is an error."""
    start = len(_UTF8_BOM) if raw.startswith(_UTF8_BOM) else 0
    newline = raw.find(b"\n", start)
    header_end, body = (len(raw), len(raw)) if newline < 0 else (newline, newline + 1)
    header = _decode(path, raw[start:header_end], 1).removesuffix("\r")
    if not header.strip(_FIELD_WHITESPACE) and not raw[body:].strip():
        raise file_error(path, f"empty file (expected a header {_HEADER} and rows)")
    return header, body


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


def _locate_csv_error(path: Path, lines: list[str], names: list[str], first: int = 2) -> None:
    """Find the first malformed data line or field and raise a DataFileError about it
    (``lines`` start at line ``first`` of the file; the header is line 1)."""
    for index, line in enumerate(lines):
        number = index + first
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


#: Characters a data line read as it arrives may hold (the file reader's grammar).
_STREAM_BAD = re.compile(r"[^0-9eE.+\-, \t\r\n]")


def read_csv_chunks(stream: IO[str], source: str, rows: int) -> Iterator[tuple[CsvHeader, Array]]:
    """The rows of a CSV trajectory (the format of :func:`load_csv`) as they arrive,
    ``rows`` at a time: a pipe or standard input is read line by line, never whole.

    Parameters
    ----------
    stream : text stream
        The file or standard input, at its start.
    source : str
        Its name, for messages.
    rows : int
        Rows per chunk (the last may have fewer).

    Yields
    ------
    header : CsvHeader
        The columns.
    table : ndarray, shape (rows, columns)
        The next rows, in the header's order.

    Raises
    ------
    DataFileError
        As :func:`load_csv`, naming the line and the column, when the bad line arrives.
    """
    path = Path(source)
    line = stream.readline()
    if not line:
        raise file_error(path, f"empty: expected the header line {_HEADER}")
    header = _parse_header(path, line.lstrip("\ufeff").rstrip("\r\n"))
    number, last_time = 2, -math.inf
    while True:
        lines = [text.rstrip("\r\n") for text in itertools.islice(stream, rows)]
        while lines and not lines[-1].strip(_FIELD_WHITESPACE):  # trailing blank lines
            lines.pop()
        if not lines:
            return
        try:
            if _STREAM_BAD.search("".join(lines)):
                raise ValueError
            table = np.array([text.split(",") for text in lines], dtype=float)
            if table.shape != (len(lines), len(header.names)):
                raise ValueError
        except ValueError:
            _locate_csv_error(path, lines, header.names, number)
            raise file_error(path, f"line {number}: malformed data rows") from None
        beyond = first_beyond(table)
        if beyond is not None:
            (row, column), what = beyond
            place = f"line {number + row}, column {column + 1} ({header.names[column]})"
            raise file_error(path, f"{place}: {what}")
        times = np.concatenate([[last_time], table[:, 0]])
        k = first_non_increasing(times)
        if k is not None:
            raise file_error(
                path,
                f"line {number + k}, column 1 (t): time {float(times[k + 1])!r} is not "
                f"greater than {float(times[k])!r}; times must be strictly increasing",
            )
        last_time = float(table[-1, 0])
        number += len(lines)
        yield header, table


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
    (names, n, m, q, angle), table = _read_table(target, _parse_header)
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


class _Named(Protocol):
    @property
    def names(self) -> list[str]: ...


_Header = TypeVar("_Header", bound=_Named)


class _Columns(NamedTuple):
    """The header of a log with columns of its own names (:func:`load_csv_columns`)."""

    names: list[str]


def _parse_names(path: Path, line: str) -> _Columns:
    """A log's own column names: each non-empty and different from the others."""
    names = [field.strip(_FIELD_WHITESPACE) for field in line.split(",")]
    limit = MAX_LOG_COLUMNS
    if len(names) > limit:
        raise file_error(path, f"line 1: {len(names)} columns; at most {limit} are read")
    for column, name in enumerate(names, start=1):
        if not name:
            raise file_error(path, f"line 1, column {column}: an empty column name")
        if name in names[: column - 1]:
            raise file_error(path, f"line 1, column {column}: {quote(name)} (a duplicate)")
    return _Columns(names)


def load_csv_columns(path: PathLike) -> tuple[list[str], Array]:
    """The columns of a drive's own CSV log: a header line of column names (any names,
    each non-empty and unique), then rows of numbers (the grammar of :func:`load_csv`,
    every column a number, at least 2 rows).

    Parameters
    ----------
    path : str or os.PathLike
        The file, whatever its suffix.

    Returns
    -------
    names : list of str
        The column names, in the file's order.
    table : ndarray, shape (rows, columns)
        The values.

    Raises
    ------
    DataFileError
        Naming the file, the line and the column, for anything :func:`load_csv` refuses
        in the rows, an empty or duplicate name, or more columns than
        :data:`~._data_file.MAX_LOG_COLUMNS` (256).
    """
    target = Path(path)
    header, table = _read_table(target, _parse_names)
    beyond = first_beyond(table)
    if beyond is not None:
        (row, column), what = beyond
        name = header.names[column]
        raise file_error(target, f"line {row + 2}, column {column + 1} ({name}): {what}")
    return header.names, table


def _read_table(path: Path, parse: Callable[[Path, str], _Header]) -> tuple[_Header, Array]:
    """The header (``parse`` reads it) and the data rows (one per line, one column per
    name) of a CSV file.

    The file's bytes are held while they are read (and let go on return); the rows are
    parsed a block of lines at a time into the table, so that reading needs about the
    file's size and the table's, not copies of the text.
    """
    raw = read_regular_file(path, LIMITS["csv_bytes"], "a CSV data file")
    header, start = _split_header(path, raw)
    parsed = parse(path, header)
    plain = _is_plain(raw, start)
    end = _data_end(raw, start)
    # A file that is not plain is decoded in full so that the scan can say what is
    # wrong where (and first whether it is UTF-8 text at all; what follows end is ASCII).
    text = None if plain else _decode(path, raw[start:end], 2)
    rows = raw.count(b"\n", start, end) + 1 if end > start else 0
    if rows < 2:
        raise file_error(
            path, f"need at least 2 data rows (sample times) after the header, got {rows}"
        )
    if rows > LIMITS["samples"]:
        raise file_error(path, f"{rows} data rows; at most {LIMITS['samples']} are read")
    table = _parse_rows(raw, start, end, rows, len(parsed.names)) if plain else None
    if table is None:
        # Slow path, only for a malformed file: find the first bad line and field.
        body = raw[start:end].decode("ascii") if text is None else text
        _locate_csv_error(path, body.replace("\r\n", "\n").split("\n"), parsed.names)
        raise file_error(path, "malformed data rows")  # not reached: the scan raises
    return parsed, table


def _is_plain(raw: bytes, start: int) -> bool:
    """Whether the data lines (from ``start``) hold only plain ASCII numbers, commas, spaces,
    tabs and line ends, with every carriage return in a ``\\r\\n``."""
    # What deleting those bytes leaves of the whole file is what it leaves of the header
    # (one pass, and no copy of the rows: for plain rows it leaves nothing of them).
    others = len(raw.translate(None, _CSV_DATA_BYTES))
    if others != len(raw[:start].translate(None, _CSV_DATA_BYTES)):
        return False
    return raw.find(b"\r", start) < 0 or raw.count(b"\r", start) == raw.count(b"\r\n", start)


def _data_end(raw: bytes, start: int) -> int:
    """Where the data lines end: blank lines (spaces, tabs, line ends) at the end of the
    file are ignored. A carriage return counts as a line end only in a ``\\r\\n``."""
    end = len(raw)
    while end > start and (
        raw[end - 1] in b" \t\n" or (raw[end - 1] == ord("\r") and raw[end : end + 1] == b"\n")
    ):
        end -= 1
    return end


def _parse_rows(raw: bytes, start: int, end: int, rows: int, columns: int) -> Array | None:
    """The plain data lines ``raw[start:end]`` as a (rows, columns) table, parsed a block
    of whole lines at a time; None if a line is not ``columns`` numbers numpy can parse
    (numpy skips an empty line, so there are fewer rows: then the slow scan says where)."""
    table = np.empty((rows, columns))
    row = 0
    at = start
    while at < end:
        newline = raw.find(b"\n", min(at + _CSV_BLOCK_BYTES, end) - 1, end)
        stop = end if newline < 0 else newline + 1
        block = raw[at:stop]
        if block.isspace():  # blank lines (numpy would warn that it read no data)
            return None
        if b"\r" in block:
            block = block.replace(b"\r\n", b"\n")
        try:
            values = np.loadtxt(
                BytesIO(block), delimiter=",", comments=None, dtype=np.float64, ndmin=2
            )
        except ValueError:
            return None
        if values.shape[1] != columns:
            return None
        table[row : row + values.shape[0]] = values  # at most rows lines in all
        row += values.shape[0]
        at = stop
    return table if row == rows else None
