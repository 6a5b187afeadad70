"""The temporaries of outputs being written (:mod:`._atomic`), and those a killed run left.

A temporary is named ``.<output>.<pid>.<random><suffix>`` beside its output, by
:func:`temporary_path`, before it is created (so the writer can remove it whenever it is
interrupted); one that a killed process left (SIGKILL cannot be caught) is removed by the
next run writing the same output, once no process with that pid runs
(:func:`remove_stale_temporaries`).
"""

from __future__ import annotations

import os
import re
import secrets
import shutil
from pathlib import Path

__all__ = ["CREATE_NEW", "remove_stale_temporaries", "temporary_path"]

# What follows ".<output>." in the name of one of our temporaries: the writer's pid, the
# random part, and the suffix.
_TEMPORARY_TAIL = re.compile(r"([1-9][0-9]*)\.[a-z0-9_]+(?:\.[A-Za-z0-9]+)?")


#: Flags of ``os.open`` that create a new file, never through a symbolic link.
CREATE_NEW = (
    os.O_WRONLY
    | os.O_CREAT
    | os.O_EXCL
    | getattr(os, "O_NOFOLLOW", 0)
    | getattr(os, "O_CLOEXEC", 0)
)


def temporary_path(directory: Path, name: str, suffix: str) -> Path:
    """A free name in ``directory`` for this process's temporary of the output ``name``:
    ``.<name>.<pid>.<random><suffix>``. It is named before it is created, so that the
    writer can remove it whenever it is interrupted; the pid makes it this process's.

    Parameters
    ----------
    directory : Path
        Where the output is written.
    name : str
        The output's file name.
    suffix : str
        The temporary's extension (some writers choose a format by it).
    """
    while True:
        candidate = directory / f".{name}.{os.getpid()}.{secrets.token_hex(4)}{suffix}"
        if not os.path.lexists(candidate):
            return candidate


def _process_gone(pid: int) -> bool:
    """True if no process ``pid`` runs (on POSIX; elsewhere never: ``os.kill`` would end
    the process)."""
    if os.name != "posix":
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except (OSError, OverflowError):  # another user's process, or not a pid at all
        return False
    return False


def remove_stale_temporaries(directory: Path, name: str, directories: bool) -> None:
    """Remove the temporaries of the output ``name`` in ``directory`` whose writer no
    longer runs (killed while it wrote: SIGKILL cannot be caught, so it could not remove
    them).

    Only our own naming (``.<name>.<pid>.<random><suffix>``, see
    :func:`temporary_path`) of the expected kind (a directory, or a regular file) is
    removed, and only once no process ``pid`` runs: a run writing the same output at the
    same time keeps its temporary. (A pid, unlike an age threshold, says whether a long
    run is still writing; a reused pid only keeps a leftover until that process ends.)

    Parameters
    ----------
    directory : Path
        Where the output is written.
    name : str
        The output's file name.
    directories : bool
        Remove temporary directories (an output set) rather than files.
    """
    prefix = f".{name}."
    try:
        scan = os.scandir(directory)
    except OSError:
        return
    with scan as entries:
        stale = [
            entry
            for entry in entries
            if entry.name.startswith(prefix)
            and (match := _TEMPORARY_TAIL.fullmatch(entry.name[len(prefix) :])) is not None
            and _process_gone(int(match[1]))
        ]
    for entry in stale:
        try:
            if directories and entry.is_dir(follow_symlinks=False):
                shutil.rmtree(entry.path)
            elif not directories and entry.is_file(follow_symlinks=False):
                os.unlink(entry.path)
        except OSError:  # removed meanwhile by another run, or not ours to remove
            pass
