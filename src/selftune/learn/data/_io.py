"""Trajectory files: CSV and NPZ, which selftune reads and writes, and MATLAB's MAT,
which it reads.

CSV
    A header line ``t,x1,...,xn,u1,...,um`` followed by optional ``w1,...,wq``, then
    optionally ``theta``, then one row per sample time (N + 1 rows, at least 2). Columns
    appear exactly in that order, numbered contiguously from 1 (``x1,x2``, not ``x0`` or
    ``x01``); ``theta``, the electrical rotor angle, can only be the last column. Every
    field is a finite decimal number (``1``, ``-0.5``, ``2.5e-3``; surrounding spaces or
    tabs are allowed); ``nan``, ``inf``, empty fields and quoted fields are errors. The
    input of the last row is not used (``u[k]`` is held over ``[t[k], t[k+1])``), but it
    must be a number all the same; on save it repeats the last held input. A held ``w``
    with N rows is written with its last value repeated, so it loads back with N + 1 rows
    whose last row is the repeated one. Lines end in ``\\n`` or ``\\r\\n``; blank lines at
    the end of the file are ignored, blank lines elsewhere are errors; a UTF-8 byte-order
    mark is accepted. Values are written with ``repr``, so a round trip is bit-exact.

NPZ
    A ``numpy.savez`` archive with arrays ``t`` (N + 1,), ``x`` (N + 1, n), ``u`` (N, m)
    or (N + 1, m), and optionally ``w`` (N + 1, q) or (N, q) and ``angle`` (N + 1,); a
    1-D ``x``, ``u`` or ``w`` is one channel. Arrays must be integer or floating point;
    nothing else may be in the archive. Pickled (object) arrays are never loaded. Saved
    ``u`` has N rows and ``w`` keeps its row count, so a round trip is exact.

MAT
    A MATLAB file saved with ``-v7`` (or v4 to v7; not v7.3, which is HDF5: refused with
    a one-line error) holding the numeric (real) matrices ``t``, ``x``, ``u`` and
    optionally ``w`` and ``angle``, as the NPZ arrays; ``t`` and ``angle`` are vectors
    (1 x K or K x 1), the others samples x channels (a 1 x K row: one channel). Nothing
    else may be in the file. Read only (:mod:`._mat`).

A drive's own log (its column names and units, phase currents, duty cycles) is read
through a ``[log]`` table instead (:mod:`._frames`), from CSV, NPZ or MAT.

All
    The angle (the CSV column ``theta``, the NPZ array ``angle``:
    :attr:`Trajectory.angle <selftune.learn.Trajectory>`) is the electrical rotor angle at
    each sample time, rad, unwrapped or not; the learners use it to model an inverter's
    dead time from the phase currents' signs. Its values obey the same rules as the
    others, and it is not one of the learning problem's channels n + m + q.

    Only regular files are read. Sizes are bounded before anything is allocated (256 MiB
    of CSV or of NPZ arrays uncompressed, the angle included, by the archive's directory
    and the arrays' headers; 1,000,000 sample times; 12 channels n + m + q, so at most 14
    columns with ``t`` and the angle: ``LIMITS`` of :mod:`selftune.core`); values are at
    most 1e50 in magnitude.

Every problem with a file's content raises :class:`~selftune.errors.DataFileError` with
a one-line message naming the file and the line and column (CSV) or the array (NPZ).
Writes are atomic: a failed save leaves no partial file and keeps any existing file.

Here are the entry points, which choose the format by the file's suffix; the formats
live in :mod:`._csv`, :mod:`._npz` and :mod:`._mat`, what they share in
:mod:`._data_file`.
"""

from __future__ import annotations

from pathlib import Path

from ...core._validation import LIMITS
from ._csv import CsvHeader, csv_dimensions, load_csv, read_csv_chunks, save_csv
from ._data_file import PathLike, file_error
from ._mat import load_mat, mat_dimensions
from ._npz import load_npz, npz_dimensions, save_npz
from ._trajectory import Trajectory

__all__ = [
    "CsvHeader",
    "file_format_of",
    "load_csv",
    "load_mat",
    "load_npz",
    "load_trajectory",
    "read_csv_chunks",
    "save_csv",
    "save_npz",
    "save_trajectory",
    "trajectory_dimensions",
]

_SUFFIXES = (".csv", ".npz", ".mat")
_WRITTEN = (".csv", ".npz")


def file_format_of(path: Path, suffixes: tuple[str, ...] = _SUFFIXES) -> str:
    """The suffix of ``path`` (lower case) if it is one of ``suffixes``, else the one-line
    error that names the accepted ones."""
    suffix = path.suffix.lower()
    if suffix not in suffixes:
        accepted = ", ".join(repr(item) for item in suffixes[:-1]) + f" or {suffixes[-1]!r}"
        found = repr(path.suffix) if path.suffix else "no suffix"
        raise file_error(path, f"unknown file type ({found}); expected a {accepted} file")
    return suffix


def load_trajectory(path: PathLike) -> Trajectory:
    """Read a trajectory from a ``.csv``, ``.npz`` or ``.mat`` file (chosen by the suffix).

    Parameters
    ----------
    path : str or os.PathLike
        The file; the suffix (case-insensitive) selects the format.

    Returns
    -------
    Trajectory
        The samples in the file (with the rotor angle, if the file has one).

    Raises
    ------
    DataFileError
        If the suffix is not ``.csv``, ``.npz`` or ``.mat``, the file cannot be read, or
        its content is invalid; the one-line message names the file and the line and
        column, the array or the variable.

    Examples
    --------
    >>> trajectory = load_trajectory("run.csv")  # doctest: +SKIP
    >>> trajectory.n, trajectory.m, trajectory.num_samples  # doctest: +SKIP
    (2, 1, 1000)
    """
    target = Path(path)
    readers = {".csv": load_csv, ".npz": load_npz, ".mat": load_mat}
    return readers[file_format_of(target)](target)


def trajectory_dimensions(path: PathLike) -> tuple[int, int, int]:
    """``(n, m, q)`` of a ``.csv``, ``.npz`` or ``.mat`` file from its header only: the CSV
    header line, the archive's directory and the arrays' ``.npy`` headers, or the MAT
    variables' headers (no rows are read).

    Parameters
    ----------
    path : str or os.PathLike
        The file; the suffix (case-insensitive) selects the format.

    Returns
    -------
    tuple of int
        ``(n, m, q)``: states, inputs, exogenous signals (0 without ``w``). The rotor
        angle, if the file has one, is not among them.

    Raises
    ------
    DataFileError
        As :func:`load_trajectory`, for what the header shows.
    """
    target = Path(path)
    readers = {".csv": csv_dimensions, ".npz": npz_dimensions, ".mat": mat_dimensions}
    return readers[file_format_of(target)](target)


def save_trajectory(trajectory: Trajectory, path: PathLike) -> None:
    """Write a trajectory to a ``.csv`` or ``.npz`` file (chosen by the suffix), atomically.

    Parameters
    ----------
    trajectory : Trajectory
        The samples to write (with the rotor angle, if it has one).
    path : str or os.PathLike
        The file; the suffix (case-insensitive) selects the format. An existing file is
        replaced only once the new one is complete.

    Raises
    ------
    DataFileError
        If the suffix is neither ``.csv`` nor ``.npz``, or the trajectory has more sample
        times than :func:`load_trajectory` reads (``LIMITS["samples"]``): nothing is
        written that could not be read back.
    InputError
        If ``trajectory`` is not a :class:`Trajectory`.
    OSError
        If the file cannot be written (e.g. the directory does not exist).
    """
    target = Path(path)
    file_format = file_format_of(target, _WRITTEN)
    if isinstance(trajectory, Trajectory) and len(trajectory.t) > LIMITS["samples"]:
        raise file_error(
            target,
            f"not written: {len(trajectory.t)} sample times, and at most"
            f" {LIMITS['samples']} are read from a data file",
        )
    if file_format == ".csv":
        save_csv(trajectory, target)
    else:
        save_npz(trajectory, target)
