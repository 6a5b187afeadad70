"""The NPZ trajectory file: reader and writer (the format is specified in
:mod:`selftune.learn.data._io`)."""

from __future__ import annotations

import zipfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ...core import Array, atomic_path
from ...core._atomic import open_zip, read_npy_data, read_npy_header
from ...core._validation import LIMITS, check_time_resolution
from ...errors import InputError
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

__all__ = ["load_npz", "load_npz_columns", "npz_dimensions", "save_npz"]

_ARRAY_NAMES = ("t", "x", "u", "w", "angle")
_REQUIRED_ARRAYS = ("t", "x", "u")
# One value per sample time: 1-D; the others are samples x channels (1-D: one channel).
_VECTORS = {"t": "one time per sample", "angle": "one angle per sample time"}
# An NPZ archive holds at most five arrays: a longer zip directory is refused unread.
_ZIP_MAX_MEMBERS = 16
_ZIP_MAX_DIRECTORY = 1 << 16


def save_npz(trajectory: Trajectory, path: PathLike) -> None:
    """Write a trajectory as an NPZ archive (arrays ``t``, ``x``, ``u``, ``w``,
    ``angle``), atomically.

    Parameters
    ----------
    trajectory : Trajectory
        The samples to write; ``u`` is saved with N rows, ``w`` (if any) with its own row
        count (N or N + 1), ``angle`` (if any) with N + 1.
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
    check_trajectory(trajectory, "save_npz")
    # Any: numpy's stubs would match a keyword to savez's own allow_pickle.
    arrays: dict[str, Any] = {"t": trajectory.t, "x": trajectory.x, "u": trajectory.u}
    for name, array in (("w", trajectory.w), ("angle", trajectory.angle)):
        if array is not None:
            arrays[name] = array
    # The temporary name ends in .npz, so numpy writes exactly to it.
    with atomic_path(path, suffix=".npz") as temporary:
        np.savez(temporary, **arrays)


def _member_names(
    path: Path, archive: zipfile.ZipFile, columns: bool = False
) -> dict[str, zipfile.ZipInfo]:
    """The archive's arrays by name; unknown (but for a log's ``columns``), duplicate,
    missing or too large ones refused."""
    members: dict[str, zipfile.ZipInfo] = {}
    for info in archive.infolist():
        name = info.filename.removesuffix(".npy")
        if name == info.filename:
            raise file_error(path, f"unexpected member {quote(info.filename)}: not a .npy array")
        if name in members:
            raise file_error(path, f"array {quote(name)} appears twice")
        members[name] = info
    extra = [name for name in members if name not in _ARRAY_NAMES and not columns]
    missing = [name for name in _REQUIRED_ARRAYS if name not in members and not columns]
    for names, what in ((extra, "unexpected"), (missing, "missing")):
        if names:
            listed = ", ".join(quote(name) if extra else repr(name) for name in names)
            raise file_error(
                path,
                f"{what} array{'s' if len(names) > 1 else ''} {listed} "
                "(expected t, x, u and optionally w and angle)",
            )
    total, limit = sum(info.file_size for info in members.values()), LIMITS["npz_bytes"]
    if total > limit:
        message = f"the arrays are {total} bytes uncompressed (by the archive's directory)"
        raise file_error(path, f"{message}; at most {limit} ({limit / 2**20:g} MiB) are read")
    return members


@contextmanager
def _npz_archive(
    path: Path, columns: bool = False
) -> Iterator[tuple[zipfile.ZipFile, dict[str, zipfile.ZipInfo]]]:
    """The open archive and its checked members (a log's ``columns``: any names, at most
    :data:`~._data_file.MAX_LOG_COLUMNS` (256)); nothing is decompressed yet."""
    most = MAX_LOG_COLUMNS if columns else _ZIP_MAX_MEMBERS
    with open_zip(path, most, _ZIP_MAX_DIRECTORY, "an NPZ archive") as archive:
        yield archive, _member_names(path, archive, columns)


@contextmanager
def _reading(path: Path, name: str) -> Iterator[None]:
    """Any failure of the block (a corrupt archive can make zipfile, zlib or numpy raise
    nearly any exception type) as one DataFileError naming the array."""
    try:
        yield
    except InputError as exc:
        raise file_error(path, f"array {name!r}: {exc}") from None
    except Exception as exc:
        raise file_error(
            path, f"array {name!r}: cannot read ({type(exc).__name__}: {exc})"
        ) from None


def _member(path: Path, archive: zipfile.ZipFile, info: zipfile.ZipInfo) -> NDArray[np.generic]:
    """One array, its size checked from its header before its data are decompressed."""
    with _reading(path, info.filename[:-4]), archive.open(info) as stream:
        return read_npy_data(stream, read_npy_header(stream, LIMITS["samples"]))


def _member_shape(path: Path, archive: zipfile.ZipFile, info: zipfile.ZipInfo) -> tuple[int, ...]:
    with _reading(path, info.filename[:-4]), archive.open(info) as stream:
        shape, _, dtype = read_npy_header(stream, LIMITS["samples"])
    _check_kind(path, info.filename[:-4], dtype, shape)
    return shape


def npz_dimensions(path: Path) -> tuple[int, int, int]:
    """``(n, m, q)`` from the archive's directory and the arrays' ``.npy`` headers alone."""
    with _npz_archive(path) as (archive, members):
        shapes = {name: _member_shape(path, archive, info) for name, info in members.items()}
    n, m, q = (shapes[k][-1] if len(shapes.get(k, ())) == 2 else int(k in shapes) for k in "xuw")
    if not n or not m:
        raise file_error(path, f"array {'x' if not n else 'u'!r}: has no channels")
    check_channels(path, "arrays x, u, w", n, m, q)
    return n, m, q


def _check_kind(path: Path, name: str, dtype: np.dtype[Any], shape: tuple[int, ...]) -> None:
    """Real numbers (integer or floating point), of the expected dimension."""
    if dtype.kind not in "iuf":
        message = f"expected integer or floating-point numbers, got dtype {dtype.str!r}"
        raise file_error(path, f"array {name!r}: {message}")
    if len(shape) not in ((1,) if name in _VECTORS else (1, 2)):
        expected = f"1-D ({_VECTORS[name]})" if name in _VECTORS else "2-D (samples x channels)"
        raise file_error(path, f"array {name!r}: expected {expected}, got shape {shape}")


def _as_float(path: Path, name: str, array: NDArray[np.generic]) -> Array:
    """A float copy of a real numeric array of the expected dimension."""
    _check_kind(path, name, array.dtype, array.shape)
    values = np.asarray(array, dtype=np.float64)
    beyond = first_beyond(np.where(np.isfinite(values), values, 0.0))  # NaN: Trajectory
    if beyond is not None:
        raise file_error(path, f"array {name!r}: at {tuple(beyond[0])}: {beyond[1]}")
    if name == "t" and array.dtype.kind == "f":
        with _reading(path, name):
            check_time_resolution(array, "the time column")  # in the stored precision
    return values


def load_npz(path: PathLike) -> Trajectory:
    """Read a trajectory from an NPZ archive (see :mod:`selftune.learn.data._io` for the format).

    Parameters
    ----------
    path : str or os.PathLike
        The file, whatever its suffix.

    Returns
    -------
    Trajectory
        The samples; ``u`` has N rows (a last row, if stored, is dropped), ``w`` keeps
        its stored row count, and ``angle`` is the array ``angle``, if there is one.

    Raises
    ------
    DataFileError
        If the file cannot be read, is not an NPZ archive or is corrupt, lacks ``t``,
        ``x`` or ``u``, holds any other array than these, ``w`` and ``angle``, or an array
        is not real numbers (object, string, bool, complex) or has the wrong dimension or
        shape. The one-line message names the file and the array.
    """
    target = Path(path)
    with _npz_archive(target) as (archive, members):
        arrays = {name: _member(target, archive, info) for name, info in members.items()}
    floats = {name: _as_float(target, name, array) for name, array in arrays.items()}
    return build(
        target, floats["t"], floats["x"], floats["u"], floats.get("w"), floats.get("angle")
    )


def load_npz_columns(path: PathLike, names: Sequence[str]) -> dict[str, Array]:
    """The arrays ``names`` of a drive's own NPZ log: each a 1-D array (one value per
    row) of integer or floating-point numbers, under a name the ``[log]`` table gives; the
    archive's other arrays are not read.

    Parameters
    ----------
    path : str or os.PathLike
        The archive, whatever its suffix.
    names : sequence of str
        The arrays wanted.

    Returns
    -------
    dict of str to ndarray
        The arrays as floats (not finite values are kept: the log's reader names them).

    Raises
    ------
    DataFileError
        Naming the file and the array: a missing one (with the arrays there are), one
        that is not 1-D real numbers, a corrupt archive, more than 256 MiB of arrays.
    """
    target = Path(path)
    with _npz_archive(target, columns=True) as (archive, members):
        absent = [name for name in names if name not in members]
        if absent:
            raise file_error(target, f"no array {absent[0]!r} (arrays: {_listing(list(members))})")
        arrays = {name: _member(target, archive, members[name]) for name in names}
    return {name: _column(target, name, array) for name, array in arrays.items()}


def _listing(names: list[str], limit: int = 12) -> str:
    """``a, b, c`` of the first ``limit`` names, ``...`` after."""
    shown = ", ".join(quote(name, 24) for name in names[:limit])
    return shown + (", ..." if len(names) > limit else "")


def _column(path: Path, name: str, array: NDArray[np.generic]) -> Array:
    """One column of a log: 1-D real numbers, as floats."""
    if array.dtype.kind not in "iuf":
        message = f"expected integer or floating-point numbers, got dtype {array.dtype.str!r}"
        raise file_error(path, f"array {name!r}: {message}")
    if array.ndim != 1:
        raise file_error(
            path, f"array {name!r}: expected 1-D (one value per row), got shape {array.shape}"
        )
    return np.asarray(array, dtype=np.float64)
