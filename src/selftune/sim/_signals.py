"""Exogenous signals ``w`` for the simulator: held (a digital reference) or an exosystem.

- **held** (``E`` is None, i.e. ``E = 0`` to a learner): ``w[k]`` is held over each sample
  like ``u``; :func:`constant`, :func:`steps` and :func:`held` (sample-and-hold any
  function of time, e.g. the paper's ``w_base + w_d(t)``) make such signals.
- **exosystem** (:func:`exosystem`): ``w' = E w`` evolves continuously inside each sample,
  and the policy uses ``w[k] = w(t[k])``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike

from ..core import Array, augmented, expm_stack
from ..core._propagate import plant_last, propagate_steps, propagate_uniform
from ..errors import InputError
from ._checks import UNIFORM_ROUNDING_FACTOR, as_float_array, sample_times, uniform_period

__all__ = [
    "ConstantSignal",
    "ExogenousSignal",
    "Exosystem",
    "HeldSignal",
    "StepSignal",
    "check_signal_values",
    "constant",
    "exosystem",
    "held",
    "steps",
]


@runtime_checkable
class ExogenousSignal(Protocol):
    """What :func:`simulate` needs of an exogenous signal ``w``.

    ``E`` is None for a signal held over each sample (a digital reference; ``E = 0`` to a
    learner), or the (q, q) matrix of an exosystem ``w' = E w``. ``values(t)`` gives
    ``w(t[k])`` at the N + 1 sample times, shape (N + 1, q), or (P, N + 1, q) for a batch
    of plants with different signals.
    """

    @property
    def E(self) -> Array | None:
        """Exosystem matrix (q, q), or None when the signal is held over each sample."""
        ...

    def values(self, t: ArrayLike) -> Array:
        """``w`` at the sample times ``t`` (s): shape (N + 1, q) or (P, N + 1, q).

        Parameters
        ----------
        t : array_like, shape (N + 1,)
            Sample times, s.
        """
        ...


class _Held:
    """A signal held over each sample: ``E`` is None (``E = 0`` to a learner)."""

    @property
    def E(self) -> None:
        """None: the signal is held (``E = 0``)."""
        return None


def check_signal_values(values: ArrayLike, count: int, name: str) -> Array:
    array = as_float_array(values, name)
    if array.ndim == 1:
        array = array[:, np.newaxis]
    if array.ndim not in (2, 3) or array.shape[-2] != count:
        raise InputError(
            f"{name}: expected shape ({count}, q) (one row per sample time) or a batch "
            f"(P, {count}, q), got shape {array.shape}"
        )
    return array


@dataclass(frozen=True, init=False, eq=False)
class ConstantSignal(_Held):
    """A constant exogenous signal (held), ``w(t) = w``.

    Attributes
    ----------
    w : ndarray, shape (q,) or (P, q)
        The value, one per plant for a batch.
    """

    w: Array

    def __init__(self, w: ArrayLike) -> None:
        value = as_float_array(w, "constant: w")
        if value.ndim == 0:
            value = value.reshape(1)
        if value.ndim not in (1, 2):
            raise InputError(
                f"constant: w: expected shape (q,) or a batch (P, q), got shape {value.shape}"
            )
        value.setflags(write=False)
        object.__setattr__(self, "w", value)

    def values(self, t: ArrayLike) -> Array:
        """``w`` repeated at each of the N + 1 sample times: (N + 1, q) or (P, N + 1, q).

        Parameters
        ----------
        t : array_like, shape (N + 1,)
            Sample times, s.
        """
        count = np.asarray(t).shape[0]
        shape = (*self.w.shape[:-1], count, self.w.shape[-1])
        return np.broadcast_to(self.w[..., np.newaxis, :], shape).copy()


@dataclass(frozen=True, init=False, eq=False)
class StepSignal(_Held):
    """A piecewise-constant exogenous signal (held) that steps at given times.

    ``w(t) = values[0]`` before ``times[0]`` and ``values[i + 1]`` from ``times[i]`` on.
    Sampled at the sample instants: a step between two instants takes effect at the next
    one; a step time that equals a sample time up to rounding takes effect at that sample.

    Parameters
    ----------
    times : array_like, shape (S,)
        Step times, s, strictly increasing.
    values : array_like, shape (S + 1, q) or (P, S + 1, q)
        The value before the first step, then after each step (kept as ``levels``).

    Attributes
    ----------
    times : ndarray, shape (S,)
        Step times, s, strictly increasing.
    levels : ndarray, shape (S + 1, q) or (P, S + 1, q)
        The value before the first step, then after each step.
    """

    times: Array
    levels: Array

    def __init__(self, times: ArrayLike, values: ArrayLike) -> None:
        step_times = as_float_array(times, "steps: times")
        if step_times.ndim == 0:
            step_times = step_times.reshape(1)
        if step_times.ndim != 1:
            raise InputError(
                f"steps: times: expected a 1-D array of step times, got shape {step_times.shape}"
            )
        if np.any(np.diff(step_times) <= 0.0):
            raise InputError("steps: times: must be strictly increasing")
        levels = as_float_array(values, "steps: values")
        count = step_times.shape[0] + 1
        if levels.ndim == 1:
            levels = levels[:, np.newaxis]
        if levels.ndim not in (2, 3) or levels.shape[-2] != count:
            raise InputError(
                f"steps: values: expected shape ({count}, q): the value before the first "
                f"step, then one after each of the {count - 1} steps (or a batch "
                f"(P, {count}, q)), got shape {levels.shape}"
            )
        step_times.setflags(write=False)
        levels.setflags(write=False)
        object.__setattr__(self, "times", step_times)
        object.__setattr__(self, "levels", levels)

    def values(self, t: ArrayLike) -> Array:
        """``w(t[k])``, shape (N + 1, q) or (P, N + 1, q).

        Parameters
        ----------
        t : array_like, shape (N + 1,)
            Sample times, s.
        """
        times = np.asarray(t, dtype=float)
        scale = max(float(np.max(np.abs(times))), float(np.max(np.abs(self.times))))
        rounding = UNIFORM_ROUNDING_FACTOR * np.finfo(float).eps * scale
        index = np.searchsorted(self.times, times + rounding, side="right")
        return np.take(self.levels, index, axis=-2)


@dataclass(frozen=True, eq=False)
class HeldSignal(_Held):
    """Any function of time, sampled at the sample instants and held over each sample.

    Attributes
    ----------
    function : callable
        Maps the sample times ``t`` (N + 1,), s, to ``w(t)``, shape (N + 1, q), (N + 1,)
        when q = 1, or (P, N + 1, q) for a batch. Must accept the whole array at once.
    """

    function: Callable[[Array], ArrayLike]

    def __post_init__(self) -> None:
        if not callable(self.function):
            raise InputError(
                f"held: function: expected a callable of the sample times, "
                f"got {type(self.function).__name__}"
            )

    def values(self, t: ArrayLike) -> Array:
        """``function(t)`` checked: shape (N + 1, q) or (P, N + 1, q).

        Parameters
        ----------
        t : array_like, shape (N + 1,)
            Sample times, s.
        """
        times = np.array(t, dtype=float)
        times.setflags(write=False)
        return check_signal_values(self.function(times), times.shape[0], "held: function(t)")


@dataclass(frozen=True, init=False, eq=False)
class Exosystem:
    """The state of an exosystem ``w' = E w`` with ``w(t[0]) = w0``, continuous in time.

    Attributes
    ----------
    E : ndarray, shape (q, q)
        Exosystem matrix, 1/s.
    w0 : ndarray, shape (q,) or (P, q)
        Value at the first sample time, one per plant for a batch.
    """

    E: Array
    w0: Array

    def __init__(self, E: ArrayLike, w0: ArrayLike) -> None:
        matrix = as_float_array(E, "exosystem: E")
        if matrix.ndim != 2 or matrix.shape[0] != matrix.shape[1]:
            raise InputError(f"exosystem: E: expected a square matrix (q, q), got {matrix.shape}")
        q = matrix.shape[0]
        initial = as_float_array(w0, "exosystem: w0")
        if initial.ndim == 0:
            initial = initial.reshape(1)
        if initial.ndim not in (1, 2) or initial.shape[-1] != q:
            raise InputError(
                f"exosystem: w0: expected shape ({q},) or a batch (P, {q}), got {initial.shape}"
            )
        matrix.setflags(write=False)
        initial.setflags(write=False)
        object.__setattr__(self, "E", matrix)
        object.__setattr__(self, "w0", initial)

    def values(self, t: ArrayLike) -> Array:
        """``w(t[k]) = expm(E (t[k] - t[0])) w0``, exact up to rounding: (N + 1, q) or batch.

        Parameters
        ----------
        t : array_like, shape (N + 1,)
            Sample times, s.
        """
        times = sample_times(t, "exosystem: t")
        period = uniform_period(times)
        q = self.E.shape[0]
        initial = self.w0.reshape(-1, q)
        empty = np.zeros((1, q, 0))
        M = augmented(self.E[np.newaxis], empty, empty, None)
        count = times.shape[0] - 1
        forcing = np.zeros((count, q, initial.shape[0]))
        if period is not None:
            Ew = expm_stack(M, np.array([period]), uniform=True)[:, 0]  # (1, q, q)
            w = propagate_uniform(plant_last(Ew), forcing, initial.T)
        else:
            periods, index = np.unique(np.diff(times), return_inverse=True)
            Ew = expm_stack(M, periods, uniform=False)[0]  # (S, q, q)
            w = propagate_steps(Ew.transpose(0, 2, 1)[..., np.newaxis], index, forcing, initial.T)
        values = w.transpose(2, 0, 1)  # (P, N + 1, q)
        return values if self.w0.ndim == 2 else values[0]


def constant(w: ArrayLike) -> ConstantSignal:
    """A constant, held exogenous signal ``w`` (q,) or a batch (P, q).

    Parameters
    ----------
    w : array_like, shape (q,) or (P, q)
        The value, one per plant for a batch.
    """
    return ConstantSignal(w)


def steps(times: ArrayLike, values: ArrayLike) -> StepSignal:
    """A held signal starting at ``values[0]`` and stepping to ``values[i + 1]`` at ``times[i]``.

    Parameters
    ----------
    times : array_like, shape (S,)
        Step times, s, strictly increasing.
    values : array_like, shape (S + 1, q) or (P, S + 1, q)
        The initial value, then the value after each step.

    Examples
    --------
    >>> reference = steps([1e-3], [[0.0, 0.0], [0.0, 10.0]])  # T* 0 -> 10 N m at 1 ms
    """
    return StepSignal(times, values)


def held(function: Callable[[Array], ArrayLike]) -> HeldSignal:
    """Sample any function of time at the sample instants and hold it over each sample.

    ``function`` takes the array of sample times (s) and returns ``w`` at those times,
    shape (N + 1, q) (or (N + 1,) for q = 1, or (P, N + 1, q) for a batch).

    Parameters
    ----------
    function : callable
        Maps the array of sample times, s, to ``w`` at those times.

    Examples
    --------
    The paper's perturbed reference ``w_base + w_d(t)``:

    >>> import numpy as np
    >>> w_base = np.array([9.2, 10.0])
    >>> reference = held(
    ...     lambda t: w_base + np.column_stack([np.sin(1000 * t), 0.1 * np.cos(3000 * t)])
    ... )
    """
    return HeldSignal(function)


def exosystem(E: ArrayLike, w0: ArrayLike) -> Exosystem:
    """The exosystem ``w' = E w`` from ``w(t[0]) = w0``; w evolves inside each sample.

    Parameters
    ----------
    E : array_like, shape (q, q)
        Exosystem matrix, 1/s.
    w0 : array_like, shape (q,) or (P, q)
        Value at the first sample time, one per plant for a batch.

    Examples
    --------
    A sinusoid of 50 Hz, ``w = [sin(2 pi 50 t), cos(2 pi 50 t)]``:

    >>> import numpy as np
    >>> omega = 2 * np.pi * 50
    >>> signal = exosystem([[0.0, omega], [-omega, 0.0]], [0.0, 1.0])
    """
    return Exosystem(E, w0)
