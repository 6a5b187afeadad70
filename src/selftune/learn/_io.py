"""Trajectory files: CSV and NPZ, the only two formats selftune reads and writes.

CSV
    A header line ``t,x1,...,xn,u1,...,um`` followed by optional ``w1,...,wq``, then one
    row per sample time (N + 1 rows, at least 2). Columns appear exactly in that order,
    numbered contiguously from 1 (``x1,x2``, not ``x0`` or ``x01``). Every field is a
    finite decimal number (``1``, ``-0.5``, ``2.5e-3``; surrounding spaces or tabs are
    allowed); ``nan``, ``inf``, empty fields and quoted fields are errors. The input of
    the last row is not used (``u[k]`` is held over ``[t[k], t[k+1])``), but it must be a
    number all the same; on save it repeats the last held input. A held ``w`` with N
    rows is written with its last value repeated, so it loads back with N + 1 rows whose
    last row is the repeated one. Lines end in ``\\n`` or ``\\r\\n``; blank lines at the
    end of the file are ignored, blank lines elsewhere are errors; a UTF-8 byte-order mark
    is accepted. Values are written with ``repr``, so a round trip is bit-exact.

NPZ
    A ``numpy.savez`` archive with arrays ``t`` (N + 1,), ``x`` (N + 1, n), ``u`` (N, m)
    or (N + 1, m), and optionally ``w`` (N + 1, q) or (N, q); a 1-D ``x``, ``u`` or ``w``
    is one channel. Arrays must be integer or floating point; nothing else may be in the
    archive. Pickled (object) arrays are never loaded. Saved ``u`` has N rows and ``w``
    keeps its row count, so a round trip is exact.

Both
    Only regular files are read. Sizes are bounded before anything is allocated (256 MiB
    of CSV or of NPZ arrays uncompressed, by the archive's directory and the arrays'
    headers; 1,000,000 sample times; 12 channels n + m + q: ``LIMITS`` of
    :mod:`selftune.core`); values are at most 1e50 in magnitude.

Every problem with a file's content raises :class:`~selftune.errors.DataFileError` with
a one-line message naming the file and the line and column (CSV) or the array (NPZ).
Writes are atomic: a failed save leaves no partial file and keeps any existing file.
"""

from __future__ import annotations

import math
import os
import re
import zipfile
from collections.abc import Iterator
from contextlib import contextmanager
from io import StringIO
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..core import Array, atomic_path, first_non_increasing
from ..core._atomic import (
    open_regular_file,
    open_zip,
    read_npy_data,
    read_npy_header,
    read_regular_file,
)
from ..core._validation import DATA_VALUE_LIMIT, LIMITS, check_time_resolution
from ..errors import DataFileError, InputError
from ._trajectory import Trajectory

__all__ = [
    "load_csv",
    "load_npz",
    "load_trajectory",
    "save_csv",
    "save_npz",
    "save_trajectory",
    "trajectory_dimensions",
]

PathLike = str | os.PathLike[str]

_SUFFIXES = (".csv", ".npz")
_CSV_CHUNK_ROWS = 10_000
# Characters a CSV data line may contain. Restricting them first keeps the numeric
# grammar to plain decimals (no nan, inf, hex, underscores or exotic whitespace),
# which numpy's parser and Python's float agree on.
_CSV_DATA_BYTES = b"0123456789eE.+-, \t\n\r"
_UTF8_BOM = b"\xef\xbb\xbf"
_BAD_FIELD_CHARACTER = re.compile(r"[^0-9eE.+\- \t]")
_FIELD_WHITESPACE = " \t"
_ARRAY_NAMES = ("t", "x", "u", "w")
_REQUIRED_ARRAYS = ("t", "x", "u")
# An NPZ archive holds at most four arrays: a longer zip directory is refused unread.
_ZIP_MAX_MEMBERS = 16
_ZIP_MAX_DIRECTORY = 1 << 16


# --------------------------------------------------------------------------- helpers


def _error(path: Path, message: str) -> DataFileError:
    """A DataFileError whose one-line message starts with the file name."""
    text = f"{path}: {message}"
    return DataFileError(text.replace("\r", " ").replace("\n", " "))


def _quote(text: str, limit: int = 40) -> str:
    """``repr`` of a (possibly long) piece of file content, shortened for a message."""
    return repr(text[:limit]) + "..." if len(text) > limit else repr(text)


def _build(path: Path, t: Array, x: Array, u: Array, w: Array | None) -> Trajectory:
    try:
        return Trajectory(t=t, x=x, u=u, w=w)
    except InputError as exc:  # the message names the field (and the time rule)
        raise _error(path, str(exc)) from None


def _check_channels(path: Path, where: str, n: int, m: int, q: int) -> None:
    if n + m + q > LIMITS["channels"]:
        channels = f"{n + m + q} channels (n = {n}, m = {m}, q = {q})"
        raise _error(path, f"{where}: {channels}; at most {LIMITS['channels']} are read")


def _check_trajectory(trajectory: object, caller: str) -> None:
    if not isinstance(trajectory, Trajectory):
        raise InputError(f"{caller}: expected a Trajectory, got {type(trajectory).__name__}")


def _format_for(path: Path) -> str:
    suffix = path.suffix.lower()
    if suffix not in _SUFFIXES:
        accepted = " or ".join(repr(item) for item in _SUFFIXES)
        found = repr(path.suffix) if path.suffix else "no suffix"
        raise _error(path, f"unknown file type ({found}); expected a {accepted} file")
    return suffix


# --------------------------------------------------------------------------- dispatch
def load_trajectory(path: PathLike) -> Trajectory:
    """Read a trajectory from a ``.csv`` or ``.npz`` file (chosen by the suffix).

    Parameters
    ----------
    path : str or os.PathLike
        The file; the suffix (case-insensitive) selects the format.

    Returns
    -------
    Trajectory
        The samples in the file.

    Raises
    ------
    DataFileError
        If the suffix is neither ``.csv`` nor ``.npz``, the file cannot be read, or its
        content is invalid; the one-line message names the file and the line and column
        or the array.

    Examples
    --------
    >>> trajectory = load_trajectory("run.csv")  # doctest: +SKIP
    >>> trajectory.n, trajectory.m, trajectory.num_samples  # doctest: +SKIP
    (2, 1, 1000)
    """
    target = Path(path)
    if _format_for(target) == ".csv":
        return load_csv(target)
    return load_npz(target)


def trajectory_dimensions(path: PathLike) -> tuple[int, int, int]:
    """``(n, m, q)`` of a ``.csv`` or ``.npz`` file from its header only: the CSV header
    line, or the archive's directory and the arrays' ``.npy`` headers (no rows are read).

    Parameters
    ----------
    path : str or os.PathLike
        The file; the suffix (case-insensitive) selects the format.

    Returns
    -------
    tuple of int
        ``(n, m, q)``: states, inputs, exogenous signals (0 without ``w``).

    Raises
    ------
    DataFileError
        As :func:`load_trajectory`, for what the header shows.
    """
    target = Path(path)
    if _format_for(target) == ".csv":
        return _csv_dimensions(target)
    with _npz_archive(target) as (archive, members):
        shapes = {name: _member_shape(target, archive, info) for name, info in members.items()}
    n, m, q = (shapes[k][-1] if len(shapes.get(k, ())) == 2 else int(k in shapes) for k in "xuw")
    if not n or not m:
        raise _error(target, f"array {'x' if not n else 'u'!r}: has no channels")
    _check_channels(target, "arrays x, u, w", n, m, q)
    return n, m, q


def save_trajectory(trajectory: Trajectory, path: PathLike) -> None:
    """Write a trajectory to a ``.csv`` or ``.npz`` file (chosen by the suffix), atomically.

    Parameters
    ----------
    trajectory : Trajectory
        The samples to write.
    path : str or os.PathLike
        The file; the suffix (case-insensitive) selects the format. An existing file is
        replaced only once the new one is complete.

    Raises
    ------
    DataFileError
        If the suffix is neither ``.csv`` nor ``.npz``.
    InputError
        If ``trajectory`` is not a :class:`Trajectory`.
    OSError
        If the file cannot be written (e.g. the directory does not exist).
    """
    target = Path(path)
    if _format_for(target) == ".csv":
        save_csv(trajectory, target)
    else:
        save_npz(trajectory, target)


# --------------------------------------------------------------------------- CSV


def _csv_columns(trajectory: Trajectory) -> list[str]:
    sizes = (("x", trajectory.n), ("u", trajectory.m), ("w", trajectory.q))
    return ["t"] + [f"{letter}{i}" for letter, size in sizes for i in range(1, size + 1)]


def _csv_table(trajectory: Trajectory) -> Array:
    """All columns, one row per sample time; held signals repeat their last value."""
    u = np.vstack([trajectory.u, trajectory.u[-1:]])
    blocks = [trajectory.t.reshape(-1, 1), trajectory.x, u]
    if trajectory.w is not None:
        w = trajectory.w
        if w.shape[0] == trajectory.num_samples:
            w = np.vstack([w, w[-1:]])
        blocks.append(w)
    return np.hstack(blocks)


def _format_rows(rows: Array) -> str:
    """CSV lines (each ending in a newline) with the shortest exact ``repr`` of each value."""
    return "".join(",".join(map(repr, row)) + "\n" for row in rows.tolist())


def save_csv(trajectory: Trajectory, path: PathLike) -> None:
    """Write a trajectory as CSV (see the module docstring for the format), atomically.

    Parameters
    ----------
    trajectory : Trajectory
        The samples to write. The last row repeats the last held input, and the last held
        ``w`` if ``w`` has N rows.
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
    _check_trajectory(trajectory, "save_csv")
    table = _csv_table(trajectory)
    header = ",".join(_csv_columns(trajectory)) + "\n"
    with (
        atomic_path(path, suffix=".csv") as temporary,
        temporary.open("w", encoding="utf-8", newline="\n") as stream,
    ):
        stream.write(header)
        for start in range(0, table.shape[0], _CSV_CHUNK_ROWS):
            stream.write(_format_rows(table[start : start + _CSV_CHUNK_ROWS]))


def _parse_header(path: Path, line: str) -> tuple[list[str], int, int, int]:
    """Column names and (n, m, q) from the header line; raise on any deviation."""
    names = [field.strip(_FIELD_WHITESPACE) for field in line.split(",")]
    if names[0] != "t":
        raise _error(
            path,
            f"line 1, column 1: expected 't' (header t,x1..xn,u1..um,w1..wq), "
            f"got {_quote(names[0])}",
        )
    order = ("x", "u", "w")
    counts = {"x": 0, "u": 0, "w": 0}
    group = 0  # index in order of the group being read
    for column, name in enumerate(names[1:], start=2):
        letter = order[group]
        options = [f"{letter}{counts[letter] + 1}"]
        if counts[letter] > 0 and group + 1 < len(order):
            options.append(f"{order[group + 1]}1")
        if name == options[0]:
            counts[letter] += 1
            continue
        if len(options) > 1 and name == options[1]:
            group += 1
            counts[order[group]] = 1
            continue
        expected = " or ".join(repr(option) for option in options)
        note = " (a duplicate)" if name in names[: column - 1] else ""
        raise _error(
            path, f"line 1, column {column}: expected {expected}, got {_quote(name)}{note}"
        )
    if counts["x"] == 0:
        raise _error(path, "line 1: no state columns; the header must be t,x1..xn,u1..um")
    if counts["u"] == 0:
        raise _error(
            path,
            f"line 1: no input columns after 'x{counts['x']}'; the header must be t,x1..xn,u1..um",
        )
    _check_channels(path, "line 1", counts["x"], counts["u"], counts["w"])
    return names, counts["x"], counts["u"], counts["w"]


def _split_header(path: Path, raw: bytes) -> tuple[str, bytes]:
    """The header line (decoded) and the rest; an empty file is an error."""
    header_raw, _, body_raw = raw.removeprefix(_UTF8_BOM).partition(b"\n")
    header = _decode(path, header_raw, 1).removesuffix("\r")
    if not header.strip(_FIELD_WHITESPACE) and not body_raw.strip():
        raise _error(path, "empty file (expected a header t,x1..xn,u1..um,w1..wq and rows)")
    return header, body_raw


def _csv_dimensions(path: Path) -> tuple[int, int, int]:
    limit = LIMITS["header_bytes"]
    with open_regular_file(path) as stream:
        head = stream.read(limit + len(_UTF8_BOM) + 1)
    if b"\n" not in head and len(head) > limit + len(_UTF8_BOM):
        raise _error(path, f"line 1: the header is longer than {limit} bytes")
    header, _ = _split_header(path, head)
    _, n, m, q = _parse_header(path, header)
    return n, m, q


def _locate_csv_error(path: Path, lines: list[str], names: list[str]) -> None:
    """Find the first malformed data line or field and raise a DataFileError about it."""
    for index, line in enumerate(lines):
        number = index + 2  # the header is line 1
        fields = line.split(",")
        if len(fields) != len(names):
            what = "an empty line" if not line.strip(_FIELD_WHITESPACE) else f"{len(fields)}"
            raise _error(path, f"line {number}: expected {len(names)} fields, got {what}")
        for column, (name, field) in enumerate(zip(names, fields, strict=True), start=1):
            place = f"line {number}, column {column} ({name})"
            try:
                value: float | None = float(field)
            except ValueError:
                value = None
            if value is not None and not math.isfinite(value):
                raise _error(path, f"{place}: not a finite number: {_quote(field)}")
            if value is None or _BAD_FIELD_CHARACTER.search(field):
                raise _error(path, f"{place}: not a number: {_quote(field)}")


def _decode(path: Path, raw: bytes, first_line: int) -> str:
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = first_line + raw.count(b"\n", 0, exc.start)
        byte = raw[exc.start : exc.start + 1].hex()
        raise _error(path, f"line {line}: not UTF-8 text (byte 0x{byte})") from None


def load_csv(path: PathLike) -> Trajectory:
    """Read a trajectory from a CSV file (see the module docstring for the format).

    Parameters
    ----------
    path : str or os.PathLike
        The file, whatever its suffix.

    Returns
    -------
    Trajectory
        The samples; ``w`` (if there are w columns) has N + 1 rows.

    Raises
    ------
    DataFileError
        If the file cannot be read or is malformed: wrong, missing, extra, duplicate or
        misnumbered columns, a line with the wrong number of fields, a field that is not a
        finite number, fewer than two rows, or times that do not strictly increase. The
        one-line message names the file, the line and the column.
    """
    target = Path(path)
    raw = read_regular_file(target, LIMITS["csv_bytes"], "a CSV data file")
    header, body_raw = _split_header(target, raw)
    names, n, m, q = _parse_header(target, header)
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
        raise _error(target, "malformed data rows")  # not reached: the scan raises
    beyond = _first_beyond(table)
    if beyond is not None:
        (row, column), what = beyond
        raise _error(target, f"line {row + 2}, column {column + 1} ({names[column]}): {what}")
    t = table[:, 0]
    k = first_non_increasing(t)
    if k is not None:
        raise _error(
            target,
            f"line {k + 3}, column 1 (t): time {float(t[k + 1])!r} is not greater than "
            f"{float(t[k])!r} on line {k + 2}; times must be strictly increasing",
        )
    x = table[:, 1 : 1 + n]
    u = table[:, 1 + n : 1 + n + m]
    w = table[:, 1 + n + m :] if q else None
    return _build(target, t, x, u, w)


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
        raise _error(path, f"need at least 2 data rows (sample times) after the header, got {rows}")
    if rows > LIMITS["samples"]:
        raise _error(path, f"{rows} data rows; at most {LIMITS['samples']} are read")
    return body, end, rows, plain


def _first_beyond(values: Array) -> tuple[list[int], str] | None:
    """Where the first value not finite or beyond DATA_VALUE_LIMIT is, and what is wrong."""
    with np.errstate(invalid="ignore"):
        bad = ~(np.abs(values) <= DATA_VALUE_LIMIT)
    if not np.any(bad):
        return None
    where = [int(index) for index in np.argwhere(bad)[0]]
    value = float(values[tuple(where)])
    if not math.isfinite(value):
        return where, "number out of range (not finite)"
    return where, f"{value!r} is beyond {DATA_VALUE_LIMIT:g} in magnitude (not plausible)"


# --------------------------------------------------------------------------- NPZ


def save_npz(trajectory: Trajectory, path: PathLike) -> None:
    """Write a trajectory as an NPZ archive (arrays ``t``, ``x``, ``u``, ``w``), atomically.

    Parameters
    ----------
    trajectory : Trajectory
        The samples to write; ``u`` is saved with N rows, ``w`` (if any) with its own row
        count (N or N + 1).
    path : str or os.PathLike
        The file, whatever its suffix (numpy's ``.npz`` is not appended). An existing file
        is replaced only once the new one is complete.

    Raises
    ------
    InputError
        If ``trajectory`` is not a :class:`Trajectory`.
    OSError
        If the file cannot be written.
    """
    _check_trajectory(trajectory, "save_npz")
    t, x, u, w = trajectory.t, trajectory.x, trajectory.u, trajectory.w
    # The temporary name ends in .npz, so numpy writes exactly to it.
    with atomic_path(path, suffix=".npz") as temporary:
        if w is None:
            np.savez(temporary, t=t, x=x, u=u)
        else:
            np.savez(temporary, t=t, x=x, u=u, w=w)


def _member_names(path: Path, archive: zipfile.ZipFile) -> dict[str, zipfile.ZipInfo]:
    """The archive's arrays by name; unknown, duplicate, missing or too large ones refused."""
    members: dict[str, zipfile.ZipInfo] = {}
    for info in archive.infolist():
        name = info.filename.removesuffix(".npy")
        if name == info.filename:
            raise _error(path, f"unexpected member {_quote(info.filename)}: not a .npy array")
        if name in members:
            raise _error(path, f"array {_quote(name)} appears twice")
        members[name] = info
    extra = [name for name in members if name not in _ARRAY_NAMES]
    missing = [name for name in _REQUIRED_ARRAYS if name not in members]
    for names, what in ((extra, "unexpected"), (missing, "missing")):
        if names:
            listed = ", ".join(_quote(name) if extra else repr(name) for name in names)
            raise _error(
                path,
                f"{what} array{'s' if len(names) > 1 else ''} {listed} "
                "(expected t, x, u and optionally w)",
            )
    total, limit = sum(info.file_size for info in members.values()), LIMITS["npz_bytes"]
    if total > limit:
        message = f"the arrays are {total} bytes uncompressed (by the archive's directory)"
        raise _error(path, f"{message}; at most {limit} ({limit / 2**20:g} MiB) are read")
    return members


@contextmanager
def _npz_archive(path: Path) -> Iterator[tuple[zipfile.ZipFile, dict[str, zipfile.ZipInfo]]]:
    """The open archive and its checked members; nothing is decompressed yet."""
    with open_zip(path, _ZIP_MAX_MEMBERS, _ZIP_MAX_DIRECTORY, "an NPZ archive") as archive:
        yield archive, _member_names(path, archive)


@contextmanager
def _reading(path: Path, name: str) -> Iterator[None]:
    """Any failure of the block (a corrupt archive can make zipfile, zlib or numpy raise
    nearly any exception type) as one DataFileError naming the array."""
    try:
        yield
    except InputError as exc:
        raise _error(path, f"array {name!r}: {exc}") from None
    except Exception as exc:
        raise _error(path, f"array {name!r}: cannot read ({type(exc).__name__}: {exc})") from None


def _member(path: Path, archive: zipfile.ZipFile, info: zipfile.ZipInfo) -> NDArray[np.generic]:
    """One array, its size checked from its header before its data are decompressed."""
    with _reading(path, info.filename[:-4]), archive.open(info) as stream:
        return read_npy_data(stream, read_npy_header(stream, LIMITS["samples"]))


def _member_shape(path: Path, archive: zipfile.ZipFile, info: zipfile.ZipInfo) -> tuple[int, ...]:
    with _reading(path, info.filename[:-4]), archive.open(info) as stream:
        shape, _, dtype = read_npy_header(stream, LIMITS["samples"])
    _check_kind(path, info.filename[:-4], dtype, shape)
    return shape


def _check_kind(path: Path, name: str, dtype: np.dtype[Any], shape: tuple[int, ...]) -> None:
    """Real numbers (integer or floating point), of the expected dimension."""
    if dtype.kind not in "iuf":
        message = f"expected integer or floating-point numbers, got dtype {dtype.str!r}"
        raise _error(path, f"array {name!r}: {message}")
    if len(shape) not in ((1,) if name == "t" else (1, 2)):
        expected = "1-D (one time per sample)" if name == "t" else "2-D (samples x channels)"
        raise _error(path, f"array {name!r}: expected {expected}, got shape {shape}")


def _as_float(path: Path, name: str, array: NDArray[np.generic]) -> Array:
    """A float copy of a real numeric array of the expected dimension."""
    _check_kind(path, name, array.dtype, array.shape)
    values = np.asarray(array, dtype=np.float64)
    beyond = _first_beyond(np.where(np.isfinite(values), values, 0.0))  # NaN: Trajectory
    if beyond is not None:
        raise _error(path, f"array {name!r}: at {tuple(beyond[0])}: {beyond[1]}")
    if name == "t" and array.dtype.kind == "f":
        with _reading(path, name):
            check_time_resolution(array, "the time column")  # in the stored precision
    return values


def load_npz(path: PathLike) -> Trajectory:
    """Read a trajectory from an NPZ archive (see the module docstring for the format).

    Parameters
    ----------
    path : str or os.PathLike
        The file, whatever its suffix.

    Returns
    -------
    Trajectory
        The samples; ``u`` has N rows (a last row, if stored, is dropped) and ``w`` keeps
        its stored row count.

    Raises
    ------
    DataFileError
        If the file cannot be read, is not an NPZ archive or is corrupt, lacks ``t``,
        ``x`` or ``u``, holds any other array, or an array is not real numbers (object,
        string, bool, complex) or has the wrong dimension or shape. The one-line message
        names the file and the array.
    """
    target = Path(path)
    with _npz_archive(target) as (archive, members):
        arrays = {name: _member(target, archive, info) for name, info in members.items()}
    floats = {name: _as_float(target, name, array) for name, array in arrays.items()}
    return _build(target, floats["t"], floats["x"], floats["u"], floats.get("w"))
