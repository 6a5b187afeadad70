"""What the two trajectory file formats share: the error, the checks, the trajectory built.

The formats themselves are specified in :mod:`selftune.learn.data._io`; the CSV reader and
writer live in :mod:`selftune.learn.data._csv`, the NPZ ones in :mod:`selftune.learn.data._npz`.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from ...core import Array
from ...core._validation import DATA_VALUE_LIMIT, LIMITS
from ...errors import DataFileError, InputError
from ._trajectory import Trajectory

__all__ = [
    "MAX_LOG_COLUMNS",
    "PathLike",
    "build",
    "check_channels",
    "check_trajectory",
    "file_error",
    "first_beyond",
    "quote",
]

PathLike = str | os.PathLike[str]

#: The most columns a drive's own log (read through a ``[log]`` table) may have: a CSV
#: header's names, an NPZ archive's arrays.
MAX_LOG_COLUMNS = 256


def file_error(path: Path, message: str) -> DataFileError:
    """A DataFileError whose one-line message starts with the file name."""
    text = f"{path}: {message}"
    return DataFileError(text.replace("\r", " ").replace("\n", " "))


def quote(text: str, limit: int = 40) -> str:
    """``repr`` of a (possibly long) piece of file content, shortened for a message."""
    return repr(text[:limit]) + "..." if len(text) > limit else repr(text)


def build(
    path: Path, t: Array, x: Array, u: Array, w: Array | None, angle: Array | None
) -> Trajectory:
    """The trajectory of a file's arrays; Trajectory's own checks as a DataFileError."""
    try:
        return Trajectory(t=t, x=x, u=u, w=w, angle=angle)
    except InputError as exc:  # the message names the field (and the time rule)
        raise file_error(path, str(exc)) from None


def check_channels(path: Path, where: str, n: int, m: int, q: int) -> None:
    """At most ``LIMITS["channels"]`` channels n + m + q (the angle is not one of them)."""
    if n + m + q > LIMITS["channels"]:
        channels = f"{n + m + q} channels (n = {n}, m = {m}, q = {q})"
        raise file_error(path, f"{where}: {channels}; at most {LIMITS['channels']} are read")


def check_trajectory(trajectory: object, caller: str) -> None:
    """Refuse to save anything but a Trajectory."""
    if not isinstance(trajectory, Trajectory):
        raise InputError(f"{caller}: expected a Trajectory, got {type(trajectory).__name__}")


def first_beyond(values: Array) -> tuple[list[int], str] | None:
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
