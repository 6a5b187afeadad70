"""Exploration signals ``rho`` added to the policy's input: uniform, binary, sum of sines.

Each draws from the ``numpy.random.Generator`` the simulator makes from its ``seed``, so
a run is reproducible.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike

from ..core import Array, positive_integer
from ..errors import InputError
from ._checks import amplitude_for, as_float_array, check_amplitude

__all__ = [
    "BinaryExploration",
    "Exploration",
    "SinusoidalExploration",
    "UniformExploration",
    "prbs",
    "sum_of_sines",
    "uniform",
]


@runtime_checkable
class Exploration(Protocol):
    """What :func:`simulate` needs of an exploration signal ``rho``.

    ``sample(t, m, rng, batch)`` returns ``rho``, shape ``(*batch, N, m)``: ``rho[k]`` is
    added to the policy's input at ``t[k]`` and held over the sample. All randomness must
    come from ``rng``, so that a seed reproduces the run.
    """

    def sample(
        self, t: ArrayLike, m: int, rng: np.random.Generator, batch: tuple[int, ...] = ()
    ) -> Array:
        """``rho`` for the N samples of the times ``t`` (N + 1,), s: shape (*batch, N, m).

        Parameters
        ----------
        t : array_like, shape (N + 1,)
            Sample times, s.
        m : int
            Number of inputs.
        rng : numpy.random.Generator
            Source of all randomness.
        batch : tuple of int, optional
            Leading batch shape, e.g. ``(P,)`` for P plants (default ``()``).
        """
        ...


@dataclass(frozen=True, init=False, eq=False)
class _BoundedExploration:
    """An exploration ``amplitude`` times a signal in ``[-1, 1]``: the one ``sample``.

    Subclasses give their configuration name (for errors) and ``_unit``, the signal in
    ``[-1, 1]``, shape (*batch, N, m).
    """

    amplitude: Array
    _name = "exploration"

    def __init__(self, amplitude: ArrayLike) -> None:
        name = f"{self._name}: amplitude"
        object.__setattr__(self, "amplitude", check_amplitude(amplitude, name))

    def sample(
        self, t: ArrayLike, m: int, rng: np.random.Generator, batch: tuple[int, ...] = ()
    ) -> Array:
        """``rho`` for the N samples of the times ``t``: shape (*batch, N, m).

        Parameters
        ----------
        t : array_like, shape (N + 1,)
            Sample times, s.
        m : int
            Number of inputs.
        rng : numpy.random.Generator
            Source of all randomness.
        batch : tuple of int, optional
            Leading batch shape, e.g. ``(P,)`` for P plants (default ``()``).
        """
        amplitude = amplitude_for(self.amplitude, m, f"{self._name}: amplitude")
        times = np.asarray(t, dtype=float)[:-1]
        return self._unit(times, m, rng, batch) * amplitude

    def _unit(
        self, times: Array, m: int, rng: np.random.Generator, batch: tuple[int, ...]
    ) -> Array:
        raise NotImplementedError


@dataclass(frozen=True, init=False, eq=False)
class UniformExploration(_BoundedExploration):
    """A new value uniform in ``[-amplitude, amplitude]`` every sample (the paper's).

    Attributes
    ----------
    amplitude : ndarray, shape () or (m,)
        Bound, in the input's unit (V for the motor); one per input or common.
    """

    _name = "uniform"

    def _unit(
        self, times: Array, m: int, rng: np.random.Generator, batch: tuple[int, ...]
    ) -> Array:
        return rng.uniform(-1.0, 1.0, size=(*batch, times.shape[0], m))


@dataclass(frozen=True, init=False, eq=False)
class BinaryExploration(_BoundedExploration):
    """Random binary signal ``+-amplitude`` that can switch only every ``hold_samples``.

    Each block of ``hold_samples`` samples (aligned with the first sample) takes an
    independent random sign per input, so every level is held for at least
    ``hold_samples`` samples (except a block cut short by the end of the run).

    Attributes
    ----------
    amplitude : ndarray, shape () or (m,)
        Level, in the input's unit; one per input or common.
    hold_samples : int
        Minimum hold, samples.
    """

    hold_samples: int
    _name = "prbs"

    def __init__(self, amplitude: ArrayLike, hold_samples: int = 1) -> None:
        super().__init__(amplitude)
        hold = positive_integer(hold_samples, "prbs: hold_samples")
        object.__setattr__(self, "hold_samples", hold)

    def _unit(
        self, times: Array, m: int, rng: np.random.Generator, batch: tuple[int, ...]
    ) -> Array:
        count = times.shape[0]
        blocks = -(-count // self.hold_samples)
        signs = 2.0 * rng.integers(0, 2, size=(*batch, blocks, m)) - 1.0
        return np.repeat(signs, self.hold_samples, axis=-2)[..., :count, :]


@dataclass(frozen=True, init=False, eq=False)
class SinusoidalExploration(_BoundedExploration):
    """A sum of sinusoids with random phases, sampled at the sample instants and held.

    ``rho_i(t) = (amplitude_i / F) sum_f sin(2 pi f t + phase_(i, f))`` over the F
    frequencies, so ``|rho_i| <= amplitude_i``; the phases are drawn uniformly in
    ``[0, 2 pi)`` per input (and per plant) from the run's generator.

    Attributes
    ----------
    amplitude : ndarray, shape () or (m,)
        Peak bound, in the input's unit; one per input or common.
    frequencies : ndarray, shape (F,)
        Frequencies, Hz, positive.
    """

    frequencies: Array
    _name = "sum_of_sines"

    def __init__(self, amplitude: ArrayLike, frequencies: ArrayLike) -> None:
        super().__init__(amplitude)
        values = as_float_array(frequencies, "sum_of_sines: frequencies")
        if values.ndim == 0:
            values = values.reshape(1)
        if values.ndim != 1 or values.size == 0:
            raise InputError(
                f"sum_of_sines: frequencies: expected a non-empty 1-D array (F,) in Hz, "
                f"got shape {values.shape}"
            )
        if np.any(values <= 0.0):
            raise InputError(
                f"sum_of_sines: frequencies: must be positive (Hz), got {values.tolist()}"
            )
        values.setflags(write=False)
        object.__setattr__(self, "frequencies", values)

    def _unit(
        self, times: Array, m: int, rng: np.random.Generator, batch: tuple[int, ...]
    ) -> Array:
        count_f = self.frequencies.shape[0]
        phases = rng.uniform(0.0, 2.0 * np.pi, size=(*batch, 1, m, count_f))
        angles = 2.0 * np.pi * times[:, np.newaxis, np.newaxis] * self.frequencies + phases
        return np.sin(angles).sum(axis=-1) / count_f


def uniform(amplitude: ArrayLike) -> UniformExploration:
    """Exploration uniform in ``[-amplitude, amplitude]``, a new value every sample.

    ``amplitude`` is a number or one per input (m,), in the input's unit (V for the motor).

    Parameters
    ----------
    amplitude : float or array_like, shape (m,)
        Bound, in the input's unit.
    """
    return UniformExploration(amplitude)


def prbs(amplitude: ArrayLike, hold_samples: int = 1) -> BinaryExploration:
    """Random binary exploration ``+-amplitude``, held at least ``hold_samples`` samples.

    Parameters
    ----------
    amplitude : float or array_like, shape (m,)
        Level, in the input's unit (V for the motor); one per input or common.
    hold_samples : int, optional
        Minimum hold of each level, samples (default 1).
    """
    return BinaryExploration(amplitude, hold_samples)


def sum_of_sines(amplitude: ArrayLike, frequencies: ArrayLike) -> SinusoidalExploration:
    """Exploration by a sum of sinusoids (Hz) with random phases, peak ``<= amplitude``.

    Parameters
    ----------
    amplitude : float or array_like, shape (m,)
        Peak bound, in the input's unit (V for the motor); one per input or common.
    frequencies : array_like, shape (F,)
        Frequencies, Hz, positive.
    """
    return SinusoidalExploration(amplitude, frequencies)
