"""Exceptions raised by selftune.

Every error a user can cause derives from :class:`SelftuneError`, so a caller (and the
command-line interface) can tell a user mistake from a bug. Errors about bad values also
derive from :class:`ValueError`, as numpy and scipy users expect.

A learner that refuses data raises a :class:`Refusal`: one class per cause, each with the
numbers of its message as fields, so a caller tells the causes apart by type, never by
words. Each cause also derives from the error class that names its kind
(:class:`ConsistencyError`, :class:`ExcitationError`, :class:`ConvergenceError`,
:class:`InputError`), and its message is the one line the command-line interface prints.

- :class:`ConfigurationMismatch` (a ConsistencyError): key;
- :class:`MisalignedLog` (a ConfigurationMismatch): key, stated_shift, found_shift;
- :class:`ModelMissesEffect` (a ConsistencyError): statistic, threshold, causes;
- :class:`TooLittleData` (an ExcitationError): relative_se, max_relative_se,
  data_seconds, needed_seconds;
- :class:`NotExciting` (an ExcitationError): rank, rank_needed, block;
- :class:`TooShort` (an ExcitationError): samples, samples_needed;
- :class:`CurrentOverrange` (an InputError): peak, full_scale;
- :class:`CoarseTimeResolution` (an InputError): resolution, step;
- :class:`SamplingJitter` (an InputError): episode, spread, max_spread;
- :class:`NumericalFailure` (an InputError): what;
- :class:`NotStabilizing` (a ConvergenceError): spectral_radius, max_radius, unstable,
  plausible;
- :class:`PolicyIterationFailure` (a ConvergenceError): step, symptom.
"""

from __future__ import annotations

import copy
import os
import re
import threading
from typing import Any, Self

__all__ = [
    "CoarseTimeResolution",
    "ConfigurationMismatch",
    "ConsistencyError",
    "ConvergenceError",
    "CurrentOverrange",
    "DataFileError",
    "ExcitationError",
    "InputError",
    "MisalignedLog",
    "ModelMissesEffect",
    "NotExciting",
    "NotStabilizing",
    "NumericalFailure",
    "PolicyIterationFailure",
    "Refusal",
    "SamplingJitter",
    "SelftuneDeprecationWarning",
    "SelftuneError",
    "TooLittleData",
    "TooShort",
    "UnsolvableError",
    "error_line",
]


#: numpy's repr of a scalar, ``np.float64(0.5)``: a message shows the number alone.
_NUMPY_SCALAR = re.compile(r"\bnp\.(?:float|int|uint|complex|bool|str)_?\d*\(([^()]*)\)")


class SelftuneError(Exception):
    """Base class of every error selftune raises on purpose.

    Its message shows numbers as a user writes them: a numpy scalar's repr
    (``np.float64(0.5)``, from a value formatted with ``!r``) is shown as ``0.5``.
    """

    def __init__(self, *args: object) -> None:
        if args and isinstance(args[0], str):
            args = (_NUMPY_SCALAR.sub(r"\1", args[0]), *args[1:])
        super().__init__(*args)

    def retold(self, message: str) -> Self:
        """This error with another message: the same class and fields.

        Parameters
        ----------
        message : str
            The new message (its ``str()``).
        """
        error = copy.copy(self)
        error.args = (_NUMPY_SCALAR.sub(r"\1", message),)
        return error


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


class Refusal(SelftuneError):
    """The data do not support what was asked of them: the base of the refusal causes.

    Each cause is a subclass with the numbers of its message as fields; the message is
    built where the refusal is raised and is its ``str()``.
    """

    def __reduce__(self) -> tuple[Any, ...]:
        # the fields are keyword-only: rebuild from the message and the fields, so that a
        # refusal survives pickling (a worker process) and copying (:meth:`retold`)
        return (_restored, (type(self), self.args, dict(vars(self))))


def _restored(kind: type[Refusal], args: tuple[Any, ...], fields: dict[str, Any]) -> Refusal:
    """A refusal of class ``kind`` with the message ``args`` and the ``fields``."""
    error = kind.__new__(kind, *args)
    error.args = args
    error.__dict__.update(fields)
    return error


class ConfigurationMismatch(Refusal, ConsistencyError):
    """The data contradict what the configuration states about them.

    Attributes
    ----------
    key : str
        The configuration key at fault (``"structure"``, ``"logged_input"``,
        ``"input_delay"``).
    """

    def __init__(self, message: str, *, key: str) -> None:
        super().__init__(message)
        self.key = key


class MisalignedLog(ConfigurationMismatch):
    """The logged voltages act at another sample than the configuration states.

    Attributes
    ----------
    key : str
        ``"input_delay"`` when the data show another computation delay than stated, else
        ``"logged_input"``.
    stated_shift : int
        The shift the configuration states, samples (the voltage applied during sample k
        is in row ``k - shift``).
    found_shift : int
        The shift the data show, samples.
    """

    def __init__(self, message: str, *, key: str, stated_shift: int, found_shift: int) -> None:
        super().__init__(message, key=key)
        self.stated_shift = stated_shift
        self.found_shift = found_shift


class ModelMissesEffect(Refusal, ConsistencyError):
    """No linear model explains the data: a test statistic beyond its threshold.

    Attributes
    ----------
    statistic : float
        The test's statistic.
    threshold : float
        The largest value the statistic may take.
    causes : tuple of str
        The likely causes, most likely first.
    """

    def __init__(
        self, message: str, *, statistic: float, threshold: float, causes: tuple[str, ...]
    ) -> None:
        super().__init__(message)
        self.statistic = statistic
        self.threshold = threshold
        self.causes = causes


class TooLittleData(Refusal, ExcitationError):
    """The standard errors of the result exceed the limits: too little data for the noise.

    Attributes
    ----------
    relative_se : (float, float)
        The relative standard errors of K and U reached.
    max_relative_se : (float, float)
        The largest allowed for K and U.
    data_seconds : float
        The length of the data, s.
    needed_seconds : float
        The length of the same kind of data that would bring them within the limits, s.
    """

    def __init__(
        self,
        message: str,
        *,
        relative_se: tuple[float, float],
        max_relative_se: tuple[float, float],
        data_seconds: float,
        needed_seconds: float,
    ) -> None:
        super().__init__(message)
        self.relative_se = relative_se
        self.max_relative_se = max_relative_se
        self.data_seconds = data_seconds
        self.needed_seconds = needed_seconds


class NotExciting(Refusal, ExcitationError):
    """The data do not excite every unknown: a regression that lacks rank.

    Attributes
    ----------
    rank : int
        The rank found.
    rank_needed : int
        The rank needed (the number of unknowns).
    block : str or None
        The deficient block of the regression (None if the message names none).
    columns : tuple of int
        The regressors that move together (indices into the regression's columns; empty
        if the message names none).
    """

    def __init__(
        self,
        message: str,
        *,
        rank: int,
        rank_needed: int,
        block: str | None,
        columns: tuple[int, ...] = (),
    ) -> None:
        super().__init__(message)
        self.rank = rank
        self.rank_needed = rank_needed
        self.block = block
        self.columns = columns


class TooShort(Refusal, ExcitationError):
    """The data have fewer samples, transitions or intervals than the learner needs.

    Attributes
    ----------
    samples : int or None
        How many the data give (None if the message says none).
    samples_needed : int or None
        How many are needed (None if the message says none).
    """

    def __init__(
        self, message: str, *, samples: int | None = None, samples_needed: int | None = None
    ) -> None:
        super().__init__(message)
        self.samples = samples
        self.samples_needed = samples_needed


class CurrentOverrange(Refusal, InputError):
    """A simulated experiment drove the current beyond the current sensor's full scale:
    the log's readings are clipped (the ADC's extreme codes), which no model explains.

    Attributes
    ----------
    peak : float
        The largest true current magnitude of the experiment, A.
    full_scale : float
        The ADC's full scale ``adc_range``, A.
    """

    def __init__(self, message: str, *, peak: float, full_scale: float) -> None:
        super().__init__(message)
        self.peak = peak
        self.full_scale = full_scale


class CoarseTimeResolution(Refusal, InputError):
    """The numbers a time column is stored in are too coarse for its sampling steps.

    Attributes
    ----------
    resolution : float
        The spacing of those numbers at the largest time, s.
    step : float
        The smallest sampling step, s.
    """

    def __init__(self, message: str, *, resolution: float, step: float) -> None:
        super().__init__(message)
        self.resolution = resolution
        self.step = step


class SamplingJitter(Refusal, InputError):
    """The sampling steps of a log are not uniform.

    Attributes
    ----------
    episode : int
        The index of the log.
    spread : float
        The largest deviation of a step from the mean, relative to it.
    max_spread : float
        The largest allowed.
    """

    def __init__(self, message: str, *, episode: int, spread: float, max_spread: float) -> None:
        super().__init__(message)
        self.episode = episode
        self.spread = spread
        self.max_spread = max_spread


class NumericalFailure(Refusal, InputError):
    """A computation on the data failed: values not finite or absurdly large.

    Attributes
    ----------
    what : str
        What failed (``"data"``, ``"data equation"``, ``"factorization"``,
        ``"solution"``).
    """

    def __init__(self, message: str, *, what: str) -> None:
        super().__init__(message)
        self.what = what


class NotStabilizing(Refusal, ConvergenceError):
    """The learned controller does not stabilize every plant the data allow.

    Attributes
    ----------
    spectral_radius : float
        The largest spectral radius of the sampled loop over the plausible models.
    max_radius : float
        The largest accepted (1 less the stability margin).
    unstable : int
        How many plausible models the loop is not stable on with margin.
    plausible : int
        How many plausible models there are.
    """

    def __init__(
        self,
        message: str,
        *,
        spectral_radius: float,
        max_radius: float,
        unstable: int,
        plausible: int,
    ) -> None:
        super().__init__(message)
        self.spectral_radius = spectral_radius
        self.max_radius = max_radius
        self.unstable = unstable
        self.plausible = plausible


class PolicyIterationFailure(Refusal, ConvergenceError):
    """Policy iteration did not behave as theory says (a value that rose, a value matrix
    that is not positive definite).

    Attributes
    ----------
    step : int or None
        The policy-iteration step at fault (None if it is not one step's).
    symptom : str
        What theory rules out: ``"value rose"``, ``"P not positive definite"``,
        ``"P not positive semidefinite"`` or ``"Bd' P Bd not positive definite"``.
    """

    def __init__(self, message: str, *, step: int | None, symptom: str) -> None:
        super().__init__(message)
        self.step = step
        self.symptom = symptom


INTERRUPTED = threading.Event()
"""Set by the command-line interface when Ctrl-C arrives; cleared when a command starts
and ends.

SIGINT raises KeyboardInterrupt, but Python can lose it: raised in a weak-reference
callback it goes to ``sys.unraisablehook``, and raised while a C function runs (CPython's
``int()`` of a string, as matplotlib's font matching calls it) it can be replaced by that
function's own error and then caught. Code that puts output in place calls
:func:`raise_if_interrupted` first, so an interrupted command never leaves a result.
"""


def error_line(error: BaseException) -> str | None:
    """The one line a user's error is told in: what the command line prints after
    ``selftune: error: ``, and what a fleet's table holds for a log that failed.

    Parameters
    ----------
    error : BaseException
        The exception.

    Returns
    -------
    str or None
        The message of a :class:`SelftuneError`, or of an ``OSError`` with the file it
        names in front, on one line; None for any other exception (not a user's error).
    """
    if isinstance(error, SelftuneError):
        message = str(error)
    elif isinstance(error, OSError):
        where = f"{os.fsdecode(error.filename)}: " if error.filename is not None else ""
        message = f"{where}{error.strerror or error}"
    else:
        return None
    return " ".join(message.split())


def raise_if_interrupted() -> None:
    """Raise KeyboardInterrupt if Ctrl-C arrived during the current command
    (:data:`INTERRUPTED`), even if the KeyboardInterrupt it raised was lost."""
    if INTERRUPTED.is_set():
        raise KeyboardInterrupt


class SelftuneDeprecationWarning(FutureWarning):
    """A name selftune still reads but will not forever (a renamed configuration key or
    argument). The command line shows it as one line ``selftune: warning: ...`` after a
    command that succeeds; Python shows it as a FutureWarning."""
