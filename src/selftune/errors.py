"""Exceptions raised by selftune.

Every error a user can cause derives from :class:`SelftuneError`, so a caller (and the
command-line interface) can tell a user mistake from a bug. Errors about bad values also
derive from :class:`ValueError`, as numpy and scipy users expect.
"""

from __future__ import annotations

import threading

__all__ = [
    "ConsistencyError",
    "ConvergenceError",
    "DataFileError",
    "ExcitationError",
    "InputError",
    "SelftuneDeprecationWarning",
    "SelftuneError",
    "UnsolvableError",
]


class SelftuneError(Exception):
    """Base class of every error selftune raises on purpose."""


class InputError(SelftuneError, ValueError):
    """A value given to selftune is invalid (wrong shape, not finite, out of range).

    The message names the argument or field and what is wrong with it.
    """


class DataFileError(InputError):
    """A data or configuration file cannot be read, or its content is invalid.

    The message names the file and, where there is one, the key, column or row.
    """


class UnsolvableError(SelftuneError, ValueError):
    """An output regulation or LQR problem has no solution.

    The message names the condition that fails (stabilizability, the rank condition of
    the regulator equations, detectability) and, where it applies, the eigenvalue.
    """


class ExcitationError(SelftuneError):
    """The data do not excite the plant enough to determine the unknowns.

    The message gives the rank found, the rank needed, the deficient block of the
    regression and what to change in the experiment.
    """


class ConvergenceError(SelftuneError):
    """Learning failed: policy iteration diverged, did not converge, or produced a value
    matrix P that is not positive definite."""


class ConsistencyError(SelftuneError):
    """The data contradict what was stated about them, or what any result would rest on.

    For example a log whose voltages act a sample later than stated (a commanded voltage
    logged as applied), or a fit whose residual the measurement noise cannot explain. The
    message gives the statistic, the likely cause and the remedy.
    """


INTERRUPTED = threading.Event()
"""Set by the command-line interface when Ctrl-C arrives; cleared when a command starts
and ends.

SIGINT raises KeyboardInterrupt, but Python can lose it: raised in a weak-reference
callback it goes to ``sys.unraisablehook``, and raised while a C function runs (CPython's
``int()`` of a string, as matplotlib's font matching calls it) it can be replaced by that
function's own error and then caught. Code that puts output in place calls
:func:`raise_if_interrupted` first, so an interrupted command never leaves a result.
"""


def raise_if_interrupted() -> None:
    """Raise KeyboardInterrupt if Ctrl-C arrived during the current command
    (:data:`INTERRUPTED`), even if the KeyboardInterrupt it raised was lost."""
    if INTERRUPTED.is_set():
        raise KeyboardInterrupt


class SelftuneDeprecationWarning(FutureWarning):
    """A name selftune still reads but will not forever (a renamed configuration key or
    argument). The command line shows it as one line ``selftune: warning: ...`` after a
    command that succeeds; Python shows it as a FutureWarning."""
