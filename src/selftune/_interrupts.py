"""Ctrl-C while a command runs, however it surfaces: :class:`Interrupts` (the command
line's), and :func:`despite_interrupts` for cleanups that must finish.

A module of its own, light (the standard library and :mod:`selftune.errors`): the command
line installs its handler before anything heavy is imported, so that a Ctrl-C while
numpy loads is one line too."""

from __future__ import annotations

import _thread
import signal
import sys
import threading
from collections.abc import Callable
from typing import Any

from .errors import INTERRUPTED

__all__ = ["Interrupts", "caused_by_interrupt", "despite_interrupts"]


def despite_interrupts(
    cleanup: Callable[[], None], left: Callable[[], bool] | None = None, attempts: int = 5
) -> None:
    """Run ``cleanup`` to its end even if KeyboardInterrupts land in it, then raise the
    first of them.

    A command interrupted while it writes removes its temporaries in an ``except``
    clause; a second KeyboardInterrupt there (a second Ctrl-C, or the one
    :class:`Interrupts` delivers again a millisecond after Python lost the first) would
    stop the removal halfway and leave a temporary behind (it did, once in three runs of
    the test of a Ctrl-C swallowed by a callback).

    Parameters
    ----------
    cleanup : callable
        The removal (idempotent: it is run again if interrupted).
    left : callable, optional
        Whether something is left to remove: the removal is run again while it is (a
        removal that ignores its errors, ``shutil.rmtree(path, True)``, can leave part of
        a tree when an interrupt lands in its walk: once in a CI run of that test, after
        "Bad file descriptor").
    attempts : int
        How many times it is tried.
    """
    pending: KeyboardInterrupt | None = None
    for _ in range(attempts):
        try:
            cleanup()
            if left is None or not left():
                break
        except KeyboardInterrupt as interrupt:
            pending = pending or interrupt
    if pending is not None:
        raise pending


class Interrupts:
    """Ctrl-C while a command runs, however it surfaces.

    SIGINT raises KeyboardInterrupt, as by default, and is remembered. An exception Python
    cannot raise (in a finalizer or a weak-reference callback: ``sys.unraisablehook``) is
    not printed; a KeyboardInterrupt that landed there (matplotlib runs many weak-reference
    callbacks while it draws) would be lost and the command would go on to write its
    outputs, so it is remembered and raised again in the main thread a millisecond later,
    once the hook has returned (raised in the hook itself, it would be lost again). Every
    interrupt also sets :data:`selftune.errors.INTERRUPTED`, which output is checked
    against before it is put in place: Python can lose a KeyboardInterrupt in other ways
    too.
    """

    def __init__(self) -> None:
        self.received = False
        self._hook: Any = None
        self._handler: Any = None
        self._in_hook = False
        self._timers: list[threading.Timer] = []

    def __enter__(self) -> Interrupts:
        INTERRUPTED.clear()
        self._hook, sys.unraisablehook = sys.unraisablehook, self._unraisable
        if threading.current_thread() is threading.main_thread():
            self._handler = signal.signal(signal.SIGINT, self._signal)
        return self

    def __exit__(self, *exc_info: object) -> None:
        for timer in self._timers:
            timer.cancel()
        sys.unraisablehook = self._hook
        if self._handler is not None:
            signal.signal(signal.SIGINT, self._handler)
        INTERRUPTED.clear()

    def _signal(self, signum: int, frame: object) -> None:
        self.received = True
        INTERRUPTED.set()
        if self._in_hook:
            self._raise_soon()
            return
        raise KeyboardInterrupt

    def _unraisable(self, unraisable: Any) -> None:
        if not isinstance(unraisable.exc_value, KeyboardInterrupt):
            return
        self.received = True
        INTERRUPTED.set()
        self._in_hook = True
        try:
            self._raise_soon()
        finally:
            self._in_hook = False

    def _raise_soon(self) -> None:
        """Deliver SIGINT to the main thread again, from a timer thread."""
        if self._handler is None:  # not the main thread: nothing to deliver it to
            return
        timer = threading.Timer(1e-3, _thread.interrupt_main)
        timer.daemon = True
        self._timers.append(timer)
        timer.start()


def caused_by_interrupt(exc: BaseException) -> bool:
    """Whether a KeyboardInterrupt is among ``exc``'s causes or contexts.

    Parameters
    ----------
    exc : BaseException
        The exception a command ended with.
    """
    seen: set[int] = set()
    current: BaseException | None = exc
    while current is not None and id(current) not in seen:
        if isinstance(current, KeyboardInterrupt):
            return True
        seen.add(id(current))
        current = current.__cause__ or current.__context__
    return False
