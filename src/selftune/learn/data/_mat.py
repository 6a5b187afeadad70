"""MATLAB ``.mat`` files (the format is specified in :mod:`selftune.learn.data._io`):
read with :func:`scipy.io.loadmat`, versions 4 to 7 (``save -v7``, MATLAB's default);
a v7.3 file (HDF5) is refused with a one-line error.

Each variable is a numeric matrix (double, single or integer; real): ``t``, ``x``,
``u``, ``w``, ``angle`` as the NPZ arrays, or a drive's own columns, one vector per
column (:func:`load_mat_columns`). MATLAB stores a vector as a 1 x K or K x 1 matrix;
both read as one value per row.
"""

from __future__ import annotations

from collections.abc import Sequence
from io import BytesIO
from pathlib import Path
from typing import Any

import numpy as np

from ...core import Array
from ...core._atomic import read_regular_file
from ...core._validation import LIMITS
from ._data_file import PathLike, build, check_channels, file_error, first_beyond, quote
from ._trajectory import Trajectory

__all__ = ["load_mat", "load_mat_columns", "mat_dimensions"]

_ARRAY_NAMES = ("t", "x", "u", "w", "angle")
_REQUIRED_ARRAYS = ("t", "x", "u")
_VECTORS = ("t", "angle")
_NUMERIC_CLASSES = (
    "double", "single", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64",
    "uint64",
)  # fmt: skip


def _contents(path: Path) -> tuple[bytes, dict[str, tuple[tuple[int, ...], str]]]:
    """The file's bytes and its variables' shapes and classes (from their headers)."""
    from scipy.io import matlab, whosmat

    raw = read_regular_file(path, LIMITS["npz_bytes"], "a MAT file")
    try:
        major, _ = matlab.matfile_version(BytesIO(raw))
    except Exception as exc:
        raise file_error(path, f"not a MAT file ({type(exc).__name__}: {exc})") from None
    if major == 2:
        raise file_error(
            path,
            "a MATLAB v7.3 (HDF5) file, which is not read: save it with save(..., '-v7') "
            "or write the log as CSV",
        )
    try:
        listing = whosmat(BytesIO(raw))
    except Exception as exc:
        raise file_error(path, f"cannot read ({type(exc).__name__}: {exc})") from None
    variables = {name: (tuple(int(size) for size in shape), kind) for name, shape, kind in listing}
    total = 8 * sum(int(np.prod(shape)) for shape, _ in variables.values())
    if total > LIMITS["npz_bytes"]:
        limit = LIMITS["npz_bytes"]
        raise file_error(
            path, f"the variables hold {total} bytes as float64; at most {limit} are read"
        )
    return raw, variables


def _load(path: Path, raw: bytes, names: Sequence[str]) -> dict[str, Any]:
    from scipy.io import loadmat

    try:
        return loadmat(BytesIO(raw), variable_names=list(names), squeeze_me=False)
    except Exception as exc:
        raise file_error(path, f"cannot read ({type(exc).__name__}: {exc})") from None


def _numeric(path: Path, name: str, kind: str, shape: tuple[int, ...]) -> None:
    if kind not in _NUMERIC_CLASSES:
        raise file_error(path, f"variable {quote(name)}: expected a numeric matrix, got a {kind}")
    if len(shape) != 2:
        raise file_error(path, f"variable {quote(name)}: expected a matrix, got shape {shape}")


def _vector(path: Path, name: str, shape: tuple[int, ...]) -> None:
    if min(shape) != 1 and 0 not in shape:
        raise file_error(
            path, f"variable {quote(name)}: expected a vector (one value per row), got {shape}"
        )


def _as_float(path: Path, name: str, value: Any, vector: bool) -> Array:
    """A variable as floats: a vector 1-D, a matrix samples x channels (a 1 x K row of
    several samples: one channel); complex values refused."""
    array = np.asarray(value)
    if array.dtype.kind not in "iuf":
        raise file_error(path, f"variable {quote(name)}: expected real numbers, got {array.dtype}")
    values = np.asarray(array, dtype=np.float64)
    if vector or values.shape[0] == 1:
        values = values.reshape(-1)
    beyond = first_beyond(np.where(np.isfinite(values), values, 0.0))
    if beyond is not None:
        raise file_error(path, f"variable {quote(name)}: at {tuple(beyond[0])}: {beyond[1]}")
    return values


def _trajectory_variables(path: Path) -> tuple[bytes, dict[str, tuple[tuple[int, ...], str]]]:
    raw, variables = _contents(path)
    extra = [name for name in variables if name not in _ARRAY_NAMES]
    missing = [name for name in _REQUIRED_ARRAYS if name not in variables]
    for names, what in ((extra, "unexpected"), (missing, "missing")):
        if names:
            listed = ", ".join(quote(name) for name in names)
            raise file_error(
                path, f"{what} variable(s) {listed} (expected t, x, u and optionally w and angle)"
            )
    for name, (shape, kind) in variables.items():
        _numeric(path, name, kind, shape)
        if name in _VECTORS:
            _vector(path, name, shape)
    return raw, variables


def mat_dimensions(path: PathLike) -> tuple[int, int, int]:
    """``(n, m, q)`` of a MAT file from its variables' headers (no values are read)."""
    target = Path(path)
    _, variables = _trajectory_variables(target)

    def channels(name: str) -> int:
        if name not in variables:
            return 0
        rows, columns = variables[name][0]
        return 1 if rows == 1 else columns

    n, m, q = channels("x"), channels("u"), channels("w")
    if not n or not m:
        raise file_error(target, f"variable {'x' if not n else 'u'!r}: has no channels")
    check_channels(target, "variables x, u, w", n, m, q)
    return n, m, q


def load_mat(path: PathLike) -> Trajectory:
    """Read a trajectory from a MAT file: variables ``t``, ``x``, ``u`` and optionally
    ``w`` and ``angle``, as the NPZ arrays (:func:`~._npz.load_npz`).

    Parameters
    ----------
    path : str or os.PathLike
        The file, whatever its suffix.

    Raises
    ------
    DataFileError
        Naming the file and the variable: a v7.3 file, a missing or unexpected variable,
        one that is not a real numeric matrix, or shapes that do not match.
    """
    target = Path(path)
    raw, variables = _trajectory_variables(target)
    loaded = _load(target, raw, list(variables))
    values = {name: _as_float(target, name, loaded[name], name in _VECTORS) for name in variables}
    return build(
        target, values["t"], values["x"], values["u"], values.get("w"), values.get("angle")
    )


def load_mat_columns(path: PathLike, names: Sequence[str]) -> dict[str, Array]:
    """The vectors ``names`` of a drive's own MAT log (one value per row, real numbers);
    its other variables are not read.

    Parameters
    ----------
    path : str or os.PathLike
        The file, whatever its suffix.
    names : sequence of str
        The variables wanted.

    Returns
    -------
    dict of str to ndarray
        The vectors as floats (not finite values are kept: the log's reader names them).

    Raises
    ------
    DataFileError
        Naming the file and the variable: a v7.3 file, a missing variable (with the
        variables there are), one that is not a real numeric vector.
    """
    target = Path(path)
    raw, variables = _contents(target)
    for name in names:
        if name not in variables:
            shown = ", ".join(quote(item, 24) for item in list(variables)[:12])
            raise file_error(target, f"no variable {quote(name)} (variables: {shown})")
        shape, kind = variables[name]
        _numeric(target, name, kind, shape)
        _vector(target, name, shape)
    loaded = _load(target, raw, names)
    return {name: _as_float(target, name, loaded[name], True) for name in names}
