"""Safe file input and output: results complete or absent, inputs bounded regular files.

- :func:`atomic_path`, :func:`write_text`, :func:`write_json`: one output file, written
  completely or not at all, and only over a regular file (:func:`check_output_file`
  refuses symbolic links, devices, directories and read-only files);
- :func:`output_directory`, :func:`check_output_directory`: a set of output files in a
  directory, put in place as one set, so that a failed or interrupted run leaves
  nothing and a rerun never mixes its files with an earlier run's;
- their temporaries (:mod:`._temporaries`): one a killed run left is removed by the next;
- :func:`open_regular_file`, :func:`read_regular_file`: input files are regular files
  (FIFOs, devices and directories are refused before anything blocks) of bounded size;
  :func:`open_zip`, :func:`read_npy_header`, :func:`read_npy_data`: a zip archive's
  and a ``.npy`` array's size, checked before anything is decompressed.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import shutil
import signal
import stat
import struct
import tempfile
import threading
import zipfile
from collections.abc import Callable, Collection, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any, BinaryIO

import numpy as np
from numpy.typing import NDArray

from .._interrupts import despite_interrupts
from ..errors import DataFileError, InputError, raise_if_interrupted
from ._temporaries import CREATE_NEW, remove_stale_temporaries, temporary_path

__all__ = [
    "atomic_path",
    "check_output_directory",
    "check_output_file",
    "finite_or_null",
    "open_regular_file",
    "open_zip",
    "output_directory",
    "read_npy_data",
    "read_npy_header",
    "read_regular_file",
    "to_jsonable",
    "write_json",
    "write_text",
]

NpyHeader = tuple[tuple[int, ...], bool, np.dtype[Any]]


def _kind(mode: int) -> str:
    """What a file is, in words."""
    for test, text in (
        (stat.S_ISREG, "a regular file"),
        (stat.S_ISDIR, "a directory"),
        (stat.S_ISLNK, "a symbolic link"),
        (stat.S_ISFIFO, "a FIFO (named pipe)"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
    ):
        if test(mode):
            return text
    return "not a regular file"  # pragma: no cover - every POSIX type is named above


# --------------------------------------------------------------------------- input


def open_regular_file(path: str | os.PathLike[str]) -> BinaryIO:
    """Open ``path`` for binary reading if it is a regular file (after symbolic links).

    The file is checked with ``stat`` before it is opened, and opened non-blocking, so a
    FIFO or a device is refused without waiting for a writer; the open file is checked
    again (``fstat``), so a file swapped in meanwhile is refused too.

    Parameters
    ----------
    path : str or os.PathLike
        The file.

    Raises
    ------
    DataFileError
        ``"<path>: cannot read the file (<why>)"``: absent, unreadable, or not a regular
        file (a directory, a FIFO, a device, a socket).
    """
    name = os.fspath(path)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        mode = os.stat(name).st_mode
        if not stat.S_ISREG(mode):
            raise DataFileError(f"{name}: cannot read the file (it is {_kind(mode)})")
        descriptor = os.open(name, flags)
    except OSError as exc:
        raise DataFileError(f"{name}: cannot read the file ({exc.strerror or exc})") from None
    try:
        mode = os.fstat(descriptor).st_mode
        if not stat.S_ISREG(mode):
            raise DataFileError(f"{name}: cannot read the file (it is {_kind(mode)})")
        return os.fdopen(descriptor, "rb")
    except BaseException:
        os.close(descriptor)
        raise


def read_regular_file(path: str | os.PathLike[str], limit: int, what: str) -> bytes:
    """The content of the regular file ``path``, refused if larger than ``limit`` bytes.

    Parameters
    ----------
    path : str or os.PathLike
        The file (see :func:`open_regular_file`).
    limit : int
        Largest size read, bytes.
    what : str
        What the file is, for the message (e.g. ``"a CSV data file"``).

    Raises
    ------
    DataFileError
        If the file cannot be read (:func:`open_regular_file`) or is too large.
    """
    name = os.fspath(path)
    with open_regular_file(path) as stream:
        size = os.fstat(stream.fileno()).st_size
        # The size (read(k) allocates k bytes first), then what the file may have grown
        # by since, up to one byte past the limit.
        data = stream.read(size + 1) if size <= limit else b""
        if len(data) > size:
            data += stream.read(limit - len(data) + 1)
    if size > limit or len(data) > limit:
        raise DataFileError(
            f"{name}: the file is {max(size, len(data))} bytes, more than the {limit} bytes"
            f" ({limit / 2**20:g} MiB) {what} may have"
        )
    return data


def _zip_directory_size(stream: BinaryIO) -> tuple[int, int]:
    """``(members, bytes)`` of a zip archive's directory, from its end record ((0, 0) if
    there is none: zipfile refuses the file)."""
    size = stream.seek(0, os.SEEK_END)
    tail_size = min(size, 22 + 0xFFFF)  # the end record and the longest comment
    stream.seek(size - tail_size)
    tail = stream.read(tail_size)
    at = tail.rfind(b"PK\x05\x06")
    if at < 0 or len(tail) - at < 22:
        return 0, 0
    members, directory = struct.unpack("<HI", tail[at + 10 : at + 16])
    return int(members), int(directory)


@contextmanager
def open_zip(
    path: str | os.PathLike[str], max_members: int, max_directory: int, what: str
) -> Iterator[zipfile.ZipFile]:
    """The regular file ``path`` open as a zip archive, its directory's size checked from
    its end record before the directory is parsed (a huge one is refused unread).

    Parameters
    ----------
    path : str or os.PathLike
        The archive (see :func:`open_regular_file`).
    max_members : int
        Most members the directory may list.
    max_directory : int
        Largest size of the directory, bytes.
    what : str
        What the archive should be, for messages (e.g. ``"an NPZ archive"``).

    Raises
    ------
    DataFileError
        ``"<path>: not <what> (<why>)"``, or as :func:`open_regular_file`.
    """
    name = os.fspath(path)
    with open_regular_file(path) as stream:
        members, directory = _zip_directory_size(stream)
        if members > max_members or directory > max_directory:
            raise DataFileError(f"{name}: not {what} ({members} members in {directory} bytes)")
        try:
            archive = zipfile.ZipFile(stream)
        except Exception as exc:  # a corrupt archive raises nearly any exception type
            raise DataFileError(f"{name}: not {what} ({type(exc).__name__}: {exc})") from None
        with archive:
            yield archive


def read_npy_header(stream: IO[bytes], max_rows: int) -> NpyHeader:
    """``(shape, fortran_order, dtype)`` of the ``.npy`` array that ``stream`` starts with.

    Parameters
    ----------
    stream : binary file
        At the start of the ``.npy`` data.
    max_rows : int
        Largest first dimension accepted.

    Raises
    ------
    InputError
        If the array holds Python objects (never unpickled) or has more rows than
        ``max_rows``.
    ValueError
        If the header is not a ``.npy`` header of version 1.0 or 2.0.
    """
    version = np.lib.format.read_magic(stream)
    if version == (1, 0):
        header: NpyHeader = np.lib.format.read_array_header_1_0(stream)
    elif version == (2, 0):
        header = np.lib.format.read_array_header_2_0(stream)
    else:
        raise ValueError(f".npy format version {version[0]}.{version[1]} is not read")
    shape, _, dtype = header
    if dtype.hasobject:
        raise InputError("holds Python objects, which are never unpickled (allow_pickle)")
    if len(shape) and shape[0] > max_rows:
        raise InputError(f"{shape[0]} rows; at most {max_rows} are read")
    return header


def read_npy_data(stream: IO[bytes], header: NpyHeader) -> NDArray[Any]:
    """The array ``header`` describes, read from ``stream`` (just after the header) to its end.

    Exactly the array's bytes are read, then the rest of the stream (in small pieces) to
    count what follows; reading to the end lets a zip member check its CRC.

    Parameters
    ----------
    stream : binary file
        Just after the header (see :func:`read_npy_header`).
    header : tuple
        ``(shape, fortran_order, dtype)``.

    Raises
    ------
    InputError
        If bytes follow the array's data.
    ValueError
        If the data are shorter than the header says.
    """
    shape, fortran, dtype = header
    count = math.prod(shape)
    size = count * dtype.itemsize
    data = stream.read(size)
    if len(data) < size:
        raise ValueError(f"{size - len(data)} bytes of data missing")
    left = 0
    while chunk := stream.read(1 << 16):
        left += len(chunk)
    if left:
        raise InputError(f"{left} bytes after the data")
    array = np.frombuffer(data, dtype=dtype, count=count) if count else np.empty(0, dtype)
    return array.reshape(shape[::-1]).T if fortran else array.reshape(shape)


# --------------------------------------------------------------------------- one file


def check_output_file(path: str | os.PathLike[str]) -> None:
    """Raise unless ``path`` can be written atomically: absent or a writable regular file,
    in an existing writable directory.

    Replacing ``path`` by a rename would replace whatever is there, so a symbolic link, a
    device (``/dev/null``), a directory or a read-only file (even for root) is refused.

    Parameters
    ----------
    path : str or os.PathLike
        The file to be written.

    Raises
    ------
    InputError
        ``"<path>: cannot write the file (<why>)"``.
    """
    name = os.fspath(path)
    reason = None
    try:
        mode: int | None = os.lstat(name).st_mode
    except FileNotFoundError:
        mode = None
    except OSError as exc:
        reason = exc.strerror or str(exc)
        mode = None
    directory = os.path.dirname(name) or "."
    if reason is not None:
        pass
    elif not name or name.endswith(("/", os.sep)):
        reason = "no file name"
    elif mode is not None and not stat.S_ISREG(mode):
        reason = f"it is {_kind(mode)}; only a regular file is replaced"
    elif mode is not None and (not mode & 0o222 or not os.access(name, os.W_OK)):
        reason = "it is read-only"
    elif not os.path.isdir(directory):
        reason = f"the directory {directory} does not exist"
    elif not os.access(directory, os.W_OK | os.X_OK):
        reason = f"the directory {directory} is not writable"
    if reason is not None:
        raise InputError(f"{name}: cannot write the file ({reason})")


@contextmanager
def atomic_path(path: str | os.PathLike[str], suffix: str = "") -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success move it over ``path`` atomically.

    On any exception the temporary file is removed and ``path`` is left untouched.
    ``suffix`` gives the temporary file an extension (some writers, e.g. numpy's
    ``savez`` or matplotlib's ``savefig``, choose a format by it).

    Parameters
    ----------
    path : str or os.PathLike
        The file to write; it must be absent or a writable regular file
        (:func:`check_output_file`, checked before and again just before the rename).
    suffix : str, optional
        Extension of the temporary file (default ``".tmp"``).
    """
    check_output_file(path)
    target = Path(path)
    directory = target.parent if str(target.parent) else Path(".")
    remove_stale_temporaries(directory, target.name, directories=False)
    temporary = temporary_path(directory, target.name, suffix or ".tmp")
    try:  # created inside: a Ctrl-C just after the file exists still removes it
        os.close(os.open(temporary, CREATE_NEW, 0o600))
        yield temporary
        os.chmod(temporary, _mode_for(target))
        check_output_file(path)
        raise_if_interrupted()  # a Ctrl-C that Python lost still stops the write
        os.replace(temporary, target)
    except BaseException:
        despite_interrupts(lambda: temporary.unlink(missing_ok=True))
        raise


def _mode_for(target: Path) -> int:
    """What a plain ``open(target, "w")`` gives: the file's mode, or 0666 less the umask."""
    try:
        return target.stat().st_mode & 0o777
    except FileNotFoundError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask


# --------------------------------------------------------------------------- a set of files


def _foreign_entries(directory: Path, names: Collection[str]) -> list[str]:
    """Entries of ``directory`` that are not regular files named in ``names``."""
    with os.scandir(directory) as entries:
        return sorted(
            entry.name
            for entry in entries
            if entry.name not in names or not entry.is_file(follow_symlinks=False)
        )


def _existing_ancestor(target: Path) -> Path:
    current = target.absolute().parent
    while not os.path.lexists(current):
        current = current.parent
    return current


def check_output_directory(
    path: str | os.PathLike[str], names: Collection[str], what: str, contents: bool = True
) -> None:
    """Raise unless ``path`` can receive a set of outputs named ``names``.

    ``path`` must be absent (created, with its parents, once the set is complete) or a
    writable directory (or a symbolic link to one) that holds nothing but regular files
    named in ``names``: a previous output set of the same command, which the new set
    replaces. Anything else there is the user's, and is refused rather than mixed or
    deleted.

    Parameters
    ----------
    path : str or os.PathLike
        The output directory.
    names : collection of str
        The file names of an output set.
    what : str
        What the set is, for the message (e.g. ``"selftune reproduce output"``).
    contents : bool, optional
        Check what the directory holds (default True); False checks only that it is a
        writable directory or can be created.

    Raises
    ------
    InputError
        ``"<path>: cannot write the <what> there (<why>)"``.
    """
    name, target = os.fspath(path), Path(path)

    def refuse(reason: str) -> InputError:
        return InputError(f"{name}: cannot write the {what} there ({reason})")

    if not name:
        raise refuse("no directory name")
    if os.path.lexists(target):
        if not target.is_dir():
            mode = os.lstat(target).st_mode
            raise refuse(f"it is {_kind(mode)}, not a directory")
        foreign = _foreign_entries(target, names) if contents else []
        if foreign:
            listing = ", ".join(repr(entry) for entry in foreign[:3])
            more = f" and {len(foreign) - 3} more" if len(foreign) > 3 else ""
            raise refuse(
                f"the directory holds {listing}{more}, not a previous {what};"
                " choose a new or empty directory"
            )
        if not os.access(target, os.W_OK | os.X_OK):
            raise refuse("the directory is not writable")
        return
    ancestor = _existing_ancestor(target)
    if not ancestor.is_dir():
        raise refuse(f"{ancestor} is not a directory")
    if not os.access(ancestor, os.W_OK | os.X_OK):
        raise refuse(f"the directory {ancestor} is not writable")


@contextmanager
def _interrupts_deferred() -> Iterator[None]:
    """Hold SIGINT and SIGTERM back (in the main thread) while the block runs."""
    if not hasattr(signal, "pthread_sigmask") or threading.current_thread() is not (
        threading.main_thread()
    ):
        yield
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def _swap_files(source: Path, target: Path) -> None:
    """Move ``target``'s files out and ``source``'s in; on any failure, undo."""
    old, new = sorted(os.listdir(target)), sorted(os.listdir(source))
    backup = Path(tempfile.mkdtemp(prefix=".selftune-previous.", dir=target))
    moved_old: list[str] = []
    moved_new: list[str] = []
    try:
        for entry in old:
            os.rename(target / entry, backup / entry)
            moved_old.append(entry)
        for entry in new:
            os.rename(source / entry, target / entry)
            moved_new.append(entry)
    except BaseException:
        for entry in moved_new:
            os.rename(target / entry, source / entry)
        for entry in moved_old:
            os.rename(backup / entry, target / entry)
        os.rmdir(backup)
        raise
    for entry in old:
        os.unlink(backup / entry)
    os.rmdir(backup)
    os.rmdir(source)


def _directory_mode() -> int:
    umask = os.umask(0)
    os.umask(umask)
    return 0o777 & ~umask


@contextmanager
def output_directory(
    path: str | os.PathLike[str], names: Collection[str], what: str
) -> Iterator[Path]:
    """Yield an empty temporary directory beside ``path``; on success put its files at
    ``path`` as one set.

    ``path`` is checked first (:func:`check_output_directory`). An absent ``path``
    becomes the temporary directory by one rename; an existing one (a previous set) has
    its files replaced by the new ones, with SIGINT and SIGTERM held back until all are
    in place, and every move undone if one fails. On any exception (an interrupt too) the
    temporary directory is removed and ``path`` is left as it was.

    Parameters
    ----------
    path : str or os.PathLike
        The output directory.
    names : collection of str
        The file names an output set may have (besides those written this time); if
        empty, what ``path`` holds is checked only once the new set is written.
    what : str
        What the set is, for messages.
    """
    check_output_directory(path, names, what, contents=bool(names))
    target = Path(path).resolve() if Path(path).is_symlink() else Path(path).absolute()
    home = target.parent if target.parent.is_dir() else _existing_ancestor(target)
    remove_stale_temporaries(home, target.name, directories=True)
    temporary = temporary_path(home, target.name, ".tmp")
    try:  # created inside: a Ctrl-C just after the directory exists still removes it
        temporary.mkdir(mode=0o700)
        yield temporary
        written = set(os.listdir(temporary))
        with _interrupts_deferred():
            raise_if_interrupted()  # a Ctrl-C that Python lost still stops the set
            check_output_directory(path, set(names) | written, what)
            if os.path.lexists(target):
                _swap_files(temporary, target)
            else:
                target.parent.mkdir(parents=True, exist_ok=True)
                os.chmod(temporary, _directory_mode())
                os.rename(temporary, target)
    except BaseException:
        if temporary != target:
            despite_interrupts(lambda: shutil.rmtree(temporary, True), temporary.exists)
        raise


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
