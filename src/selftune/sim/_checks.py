"""Input checks and the time grid of the simulator (arrays that may be batches of plants)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..core import Array, first_non_increasing, positive_finite, positive_integer
from ..errors import InputError

__all__ = [
    "UNIFORM_ROUNDING_FACTOR",
    "Seed",
    "TimeGrid",
    "amplitude_for",
    "as_float_array",
    "as_generator",
    "as_stack",
    "check_amplitude",
    "sample_times",
    "shape_text",
    "square_stack",
    "time_grid",
    "uniform_period",
]

#: Seed accepted by the simulator: an integer, a ready Generator, or None (fresh entropy).
Seed = int | np.random.Generator | None

#: Relative spread of the sampling periods, in units of the rounding of the sample
#: times, below which a grid counts as uniform (one cached discretization).
UNIFORM_ROUNDING_FACTOR = 16.0


def as_float_array(value: ArrayLike, name: str) -> Array:
    try:
        array = np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name}: not numeric ({exc})") from None
    if not np.all(np.isfinite(array)):
        raise InputError(f"{name}: contains NaN or infinite values")
    return array


def shape_text(shape: tuple[int | None, ...]) -> str:
    parts = ["any" if s is None else str(s) for s in shape]
    return "(" + ", ".join(parts) + ("," if len(parts) == 1 else "") + ")"


def as_stack(
    value: ArrayLike,
    name: str,
    shape: tuple[int | None, ...],
    *,
    batch: bool,
) -> Array:
    """A finite array of ``shape`` (None: any), or with ``batch`` a stack ``(P, *shape)``.

    Returns the array with a leading batch axis (of length 1 when not batched).
    """
    array = as_float_array(value, name)
    expected = shape_text(shape)
    wanted = expected
    if batch:
        wanted += f" or a batch (P, {expected[1:]}"
    elif array.ndim == len(shape) + 1:
        wanted += " (use simulate_batch for a batch of plants)"
    if array.ndim == len(shape):
        stack = array[np.newaxis]
    elif batch and array.ndim == len(shape) + 1:
        stack = array
    else:
        raise InputError(f"{name}: expected shape {wanted}, got shape {array.shape}")
    for axis, size in enumerate(shape):
        if size is not None and stack.shape[axis + 1] != size:
            raise InputError(f"{name}: expected shape {wanted}, got shape {array.shape}")
    return stack


def square_stack(A: ArrayLike, batch: bool) -> Array:
    """The state matrix as a stack (P or 1, n, n)."""
    array = as_float_array(A, "A")
    wanted = "(n, n)" + (" or a batch (P, n, n)" if batch else "")
    dims_ok = array.ndim == 2 or (batch and array.ndim == 3)
    if not dims_ok or array.shape[-1] != array.shape[-2]:
        if array.ndim == 3 and not batch:
            wanted += " (use simulate_batch for a batch of plants)"
        raise InputError(f"A: expected a square matrix {wanted}, got shape {array.shape}")
    return array if array.ndim == 3 else array[np.newaxis]


def check_amplitude(value: ArrayLike, name: str) -> Array:
    """A positive finite scalar or vector (one amplitude per input channel)."""
    amplitude = as_float_array(value, name)
    if amplitude.ndim > 1 or amplitude.size == 0:
        raise InputError(
            f"{name}: expected a number or a vector (m,) of per-input amplitudes, "
            f"got shape {amplitude.shape}"
        )
    if np.any(amplitude <= 0.0):
        raise InputError(f"{name}: amplitudes must be positive, got {amplitude.tolist()}")
    amplitude.setflags(write=False)
    return amplitude


def amplitude_for(amplitude: Array, m: int, name: str) -> Array:
    if amplitude.ndim == 1 and amplitude.shape[0] != m:
        raise InputError(
            f"{name}: expected {m} amplitudes (one per input), got {amplitude.shape[0]}"
        )
    return amplitude


def as_generator(seed: Seed) -> np.random.Generator:
    if isinstance(seed, np.random.Generator):
        return seed
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int | np.integer)):
        raise InputError(
            f"seed: expected an integer, a numpy Generator or None, got {type(seed).__name__}"
        )
    if seed is not None and seed < 0:
        raise InputError(f"seed: must be non-negative, got {seed}")
    return np.random.default_rng(seed)


@dataclass(frozen=True, eq=False)
class TimeGrid:
    t: Array  # (N + 1,) sample times, s
    h: float | None  # the sampling period when uniform, else None
    steps: Array  # (N,) sampling periods, s

    @property
    def num_samples(self) -> int:
        return int(self.steps.shape[0])


def sample_times(t: ArrayLike, name: str = "t") -> Array:
    times = as_float_array(t, name)
    if times.ndim != 1:
        raise InputError(f"{name}: expected a 1-D array of sample times, got shape {times.shape}")
    if times.shape[0] < 2:
        raise InputError(f"{name}: need at least 2 sample times (1 sample), got {times.shape[0]}")
    k = first_non_increasing(times)
    if k is not None:
        raise InputError(
            f"{name}: sample times must be strictly increasing, but {name}[{k + 1}] = "
            f"{times[k + 1]!r} <= {name}[{k}] = {times[k]!r}"
        )
    return times


def uniform_period(times: Array) -> float | None:
    """The sampling period if the grid is uniform up to the rounding of the times."""
    steps = np.diff(times)
    period = float(times[-1] - times[0]) / steps.shape[0]
    rounding = UNIFORM_ROUNDING_FACTOR * np.finfo(float).eps * float(np.max(np.abs(times)))
    if float(np.max(np.abs(steps - period))) <= rounding:
        return period
    return None


def time_grid(h: float | None, num_samples: int | None, t: ArrayLike | None) -> TimeGrid:
    if t is not None:
        if h is not None or num_samples is not None:
            raise InputError("t: give either the sample times t, or h and num_samples, not both")
        times = sample_times(t)
        period = uniform_period(times)
        steps = np.diff(times) if period is None else np.full(times.shape[0] - 1, period)
        return TimeGrid(t=times, h=period, steps=steps)
    if h is None or num_samples is None:
        raise InputError(
            "h, num_samples: give the sampling period h (s) and the number of samples, "
            "or the sample times t"
        )
    period = positive_finite(h, "h")
    count = positive_integer(num_samples, "num_samples")
    times = period * np.arange(count + 1, dtype=float)
    return TimeGrid(t=times, h=period, steps=np.full(count, period))


def check_finite_states(x: Array, t: Array) -> None:
    """Raise if a state of ``x`` (P, N + 1, n) at the times ``t`` (N + 1,) overflowed."""
    if np.isfinite(x).all():
        return
    bad = ~np.all(np.isfinite(x), axis=2)
    if np.any(bad):
        plant, k = (int(i) for i in np.argwhere(bad)[0])
        where = f" of plant {plant}" if x.shape[0] > 1 else ""
        raise InputError(
            f"the simulated state{where} overflows at sample {k} (t = {t[k]:.6g} s): the "
            "closed loop A - B K is unstable over this horizon; stabilize it or shorten the run"
        )
