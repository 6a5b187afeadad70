"""Exceptions raised by selftune.

Every error a user can cause derives from :class:`SelftuneError`, so a caller (and the
command-line interface) can tell a user mistake from a bug. Errors about bad values also
derive from :class:`ValueError`, as numpy and scipy users expect.
"""

from __future__ import annotations

__all__ = [
    "ConsistencyError",
    "ConvergenceError",
    "DataFileError",
    "ExcitationError",
    "InputError",
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
