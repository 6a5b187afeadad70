"""Atomic file output: a result file is either complete or absent, never partial."""

from __future__ import annotations

import dataclasses
import json
import math
import os
import tempfile
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

import numpy as np

__all__ = ["atomic_path", "finite_or_null", "to_jsonable", "write_json", "write_text"]


@contextmanager
def atomic_path(path: str | os.PathLike[str], suffix: str = "") -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success move it over ``path`` atomically.

    On any exception the temporary file is removed and ``path`` is left untouched.
    ``suffix`` gives the temporary file an extension (some writers, e.g. numpy's
    ``savez`` or matplotlib's ``savefig``, choose a format by it).

    Parameters
    ----------
    path : str or os.PathLike
        The file to write.
    suffix : str, optional
        Extension of the temporary file (default ``".tmp"``).
    """
    target = Path(path)
    directory = target.parent if str(target.parent) else Path(".")
    handle, temporary_name = tempfile.mkstemp(
        prefix=f".{target.name}.",
        suffix=suffix or ".tmp",
        dir=directory,
    )
    os.close(handle)
    temporary = Path(temporary_name)
    try:
        yield temporary
        os.chmod(temporary, _mode_for(target))
        os.replace(temporary, target)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise


def _mode_for(target: Path) -> int:
    """The permissions a plain ``open(target, "w")`` would give: the existing file's, or
    0666 less the umask (mkstemp's temporary files are 0600)."""
    try:
        return target.stat().st_mode & 0o777
    except FileNotFoundError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask


def write_text(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write.
    text : str
        Its content.
    """
    with atomic_path(path) as temporary:
        temporary.write_text(text, encoding="utf-8")


def _write_with(path: str | os.PathLike[str], writer: Callable[[IO[str]], None]) -> None:
    with atomic_path(path) as temporary, temporary.open("w", encoding="utf-8") as stream:
        writer(stream)


def to_jsonable(value: Any) -> Any:
    """Convert a value to JSON types, recursively.

    numpy arrays become nested lists and numpy scalars numbers; a dataclass instance
    becomes the mapping of its fields (so a JSON document is derived from the typed
    result, not hand-copied); mappings, lists and tuples are converted item by item.

    Parameters
    ----------
    value : Any
        The value to convert.
    """
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {
            item.name: to_jsonable(getattr(value, item.name)) for item in dataclasses.fields(value)
        }
    if isinstance(value, Mapping):
        return {str(key): to_jsonable(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [to_jsonable(item) for item in value]
    return value


def finite_or_null(value: Any) -> Any:
    """Replace non-finite floats (recursively, in dicts and lists) by None: JSON has no inf.

    Parameters
    ----------
    value : Any
        A JSON-ready value (see :func:`to_jsonable`).
    """
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {key: finite_or_null(item) for key, item in value.items()}
    if isinstance(value, list):
        return [finite_or_null(item) for item in value]
    return value


def write_json(path: str | os.PathLike[str], data: Any) -> None:
    """Write ``data`` as indented JSON atomically; numpy values become lists and numbers.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write.
    data : Any
        The document; converted by :func:`to_jsonable`.
    """
    _write_with(path, lambda stream: json.dump(to_jsonable(data), stream, indent=2))
