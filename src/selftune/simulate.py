"""Exact sampled-data simulation of LTI plants under a linear policy, with exploration.

The plant and, optionally, an exosystem::

    x' = A x + B u + D w,        w' = E w   (or w held over each sample)

run under the sampled policy, applied with a zero-order hold over ``[t[k], t[k+1])``::

    u[k] = -K (x[k] - X w[k]) + U w[k] + rho[k]

``K`` (m x n), ``X`` (n x q) and ``U`` (m x q) default to zero; ``rho`` is the exploration
signal. The simulation is exact up to rounding: each sample is propagated by the matrix
exponential of the augmented matrix (zero-order-hold discretization, Van Loan's method)::

    expm([[A, B, D],        [[Phi, Gamma_u, Gamma_w],
          [0, 0, 0],    h) = [0,   I,       0      ],
          [0, 0, E]]         [0,   0,       Phi_w  ]]

so ``x[k+1] = Phi x[k] + Gamma_u u[k] + Gamma_w w[k]`` with no ODE solver. The exogenous
signal ``w`` is of one of two kinds, matching :class:`~selftune.trajectory.Trajectory`:

- **held** (``E`` is None, i.e. ``E = 0`` to a learner): ``w[k]`` is held over each sample
  like ``u``; :func:`constant`, :func:`steps` and :func:`held` (sample-and-hold any
  function of time, e.g. the paper's ``w_base + w_d(t)``) make such signals.
- **exosystem** (:func:`exosystem`): ``w' = E w`` evolves continuously inside each sample,
  and the policy uses ``w[k] = w(t[k])``.

Either way the returned trajectory stores all N + 1 values ``w(t[k])``; for a held signal
the last one is unused by the learners.

Exploration generators (:func:`uniform`, :func:`prbs`, :func:`sum_of_sines`) draw from one
``numpy.random.Generator`` per run, made from ``seed``, so runs are reproducible.

:func:`simulate_batch` runs P plants (a batch of parameter sets) in one vectorized time
loop and returns a :class:`TrajectoryBatch`.

Examples
--------
The paper's motor (Sec. V): ``K0 = 20 pi I``, uniform exploration of 1 V, the held
reference ``w = w_base + w_d(t)``, 500 samples at 10 us:

>>> import numpy as np
>>> from selftune import SPMSM
>>> motor = SPMSM.paper()
>>> problem = motor.regulation_problem(speed=10.0)
>>> w_base = motor.exogenous(speed=10.0, torque=10.0)
>>> reference = held(
...     lambda t: w_base + np.column_stack([np.sin(1000 * t), 0.1 * np.cos(3000 * t)])
... )
>>> data = simulate(problem.A, problem.B, D=problem.D, exogenous=reference,
...                 K=20 * np.pi * np.eye(2), exploration=uniform(1.0),
...                 h=1e-5, num_samples=500, seed=0)
>>> data.x.shape, data.u.shape, data.w.shape
((501, 2), (500, 2), (501, 2))
"""

from __future__ import annotations

import math
import operator
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from typing import Protocol, runtime_checkable

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from ._validation import positive_finite
from .errors import InputError
from .trajectory import Trajectory

__all__ = [
    "BinaryExploration",
    "ConstantSignal",
    "Discretization",
    "ExogenousSignal",
    "Exosystem",
    "Exploration",
    "HeldSignal",
    "SinusoidalExploration",
    "StepSignal",
    "TrajectoryBatch",
    "UniformExploration",
    "constant",
    "discretize",
    "exosystem",
    "held",
    "prbs",
    "simulate",
    "simulate_batch",
    "steps",
    "sum_of_sines",
    "uniform",
]

Array = NDArray[np.float64]

#: Seed accepted by :func:`simulate`: an integer, a ready Generator, or None (fresh entropy).
Seed = int | np.random.Generator | None

#: Relative spread of the sampling periods, in units of the rounding of the sample
#: times, below which a grid counts as uniform (one cached discretization).
_UNIFORM_ROUNDING_FACTOR = 16.0


# -- input checks -------------------------------------------------------------------------


def _as_float_array(value: ArrayLike, name: str) -> Array:
    try:
        array = np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name}: not numeric ({exc})") from None
    if not np.all(np.isfinite(array)):
        raise InputError(f"{name}: contains NaN or infinite values")
    return array


def _shape_text(shape: tuple[int | None, ...]) -> str:
    parts = ["any" if s is None else str(s) for s in shape]
    return "(" + ", ".join(parts) + ("," if len(parts) == 1 else "") + ")"


def _as_stack(
    value: ArrayLike,
    name: str,
    shape: tuple[int | None, ...],
    *,
    batch: bool,
) -> Array:
    """A finite array of ``shape`` (None: any), or with ``batch`` a stack ``(P, *shape)``.

    Returns the array with a leading batch axis (of length 1 when not batched).
    """
    array = _as_float_array(value, name)
    expected = _shape_text(shape)
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


def _square(A: ArrayLike, batch: bool) -> Array:
    """The state matrix as a stack (P or 1, n, n)."""
    array = _as_float_array(A, "A")
    wanted = "(n, n)" + (" or a batch (P, n, n)" if batch else "")
    dims_ok = array.ndim == 2 or (batch and array.ndim == 3)
    if not dims_ok or array.shape[-1] != array.shape[-2]:
        if array.ndim == 3 and not batch:
            wanted += " (use simulate_batch for a batch of plants)"
        raise InputError(f"A: expected a square matrix {wanted}, got shape {array.shape}")
    return array if array.ndim == 3 else array[np.newaxis]


def _count(value: object, name: str) -> int:
    """A positive integer (not a bool, not a float)."""
    if isinstance(value, bool):
        raise InputError(f"{name}: expected a positive integer, got {value!r}")
    try:
        number = operator.index(value)  # type: ignore[arg-type]
    except TypeError:
        raise InputError(f"{name}: expected a positive integer, got {value!r}") from None
    if number < 1:
        raise InputError(f"{name}: expected a positive integer, got {number}")
    return int(number)


def _amplitude(value: ArrayLike, name: str) -> Array:
    """A positive finite scalar or vector (one amplitude per input channel)."""
    amplitude = _as_float_array(value, name)
    if amplitude.ndim > 1 or amplitude.size == 0:
        raise InputError(
            f"{name}: expected a number or a vector (m,) of per-input amplitudes, "
            f"got shape {amplitude.shape}"
        )
    if np.any(amplitude <= 0.0):
        raise InputError(f"{name}: amplitudes must be positive, got {amplitude.tolist()}")
    amplitude.setflags(write=False)
    return amplitude


def _amplitude_for(amplitude: Array, m: int, name: str) -> Array:
    if amplitude.ndim == 1 and amplitude.shape[0] != m:
        raise InputError(
            f"{name}: expected {m} amplitudes (one per input), got {amplitude.shape[0]}"
        )
    return amplitude


def _as_generator(seed: Seed) -> np.random.Generator:
    if isinstance(seed, np.random.Generator):
        return seed
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int | np.integer)):
        raise InputError(
            f"seed: expected an integer, a numpy Generator or None, got {type(seed).__name__}"
        )
    if seed is not None and seed < 0:
        raise InputError(f"seed: must be non-negative, got {seed}")
    return np.random.default_rng(seed)


# -- time grid ----------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class _TimeGrid:
    t: Array  # (N + 1,) sample times, s
    h: float | None  # the sampling period when uniform, else None
    steps: Array  # (N,) sampling periods, s

    @property
    def num_samples(self) -> int:
        return int(self.steps.shape[0])


def _sample_times(t: ArrayLike, name: str = "t") -> Array:
    times = _as_float_array(t, name)
    if times.ndim != 1:
        raise InputError(f"{name}: expected a 1-D array of sample times, got shape {times.shape}")
    if times.shape[0] < 2:
        raise InputError(f"{name}: need at least 2 sample times (1 sample), got {times.shape[0]}")
    differences = np.diff(times)
    if np.any(differences <= 0.0):
        k = int(np.argmax(differences <= 0.0))
        raise InputError(
            f"{name}: sample times must be strictly increasing, but {name}[{k + 1}] = "
            f"{times[k + 1]!r} <= {name}[{k}] = {times[k]!r}"
        )
    return times


def _uniform_period(times: Array) -> float | None:
    """The sampling period if the grid is uniform up to the rounding of the times."""
    steps = np.diff(times)
    period = float(times[-1] - times[0]) / steps.shape[0]
    rounding = _UNIFORM_ROUNDING_FACTOR * np.finfo(float).eps * float(np.max(np.abs(times)))
    if float(np.max(np.abs(steps - period))) <= rounding:
        return period
    return None


def _time_grid(h: float | None, num_samples: int | None, t: ArrayLike | None) -> _TimeGrid:
    if t is not None:
        if h is not None or num_samples is not None:
            raise InputError("t: give either the sample times t, or h and num_samples, not both")
        times = _sample_times(t)
        period = _uniform_period(times)
        steps = np.diff(times) if period is None else np.full(times.shape[0] - 1, period)
        return _TimeGrid(t=times, h=period, steps=steps)
    if h is None or num_samples is None:
        raise InputError(
            "h, num_samples: give the sampling period h (s) and the number of samples, "
            "or the sample times t"
        )
    period = positive_finite(h, "h")
    count = _count(num_samples, "num_samples")
    times = period * np.arange(count + 1, dtype=float)
    return _TimeGrid(t=times, h=period, steps=np.full(count, period))


# -- discretization -----------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Discretization:
    """Exact zero-order-hold discretization of ``x' = A x + B u + D w`` over one period.

    ``x[k+1] = Phi x[k] + Gamma_u u[k] + Gamma_w w[k]`` for ``u`` held over the period and
    ``w`` either held (``E`` None) or following ``w' = E w`` from ``w[k]``, in which case
    ``w[k+1] = Phi_w w[k]``.

    Attributes
    ----------
    Phi : ndarray, shape (n, n)
        ``expm(A h)``.
    Gamma_u : ndarray, shape (n, m)
        ``int_0^h expm(A s) ds B``.
    Gamma_w : ndarray, shape (n, q)
        Effect of ``w[k]`` on ``x[k+1]`` (held or exosystem, as above).
    Phi_w : ndarray, shape (q, q)
        ``expm(E h)`` (the identity for a held signal).
    h : float
        Sampling period, s.
    """

    Phi: Array
    Gamma_u: Array
    Gamma_w: Array
    Phi_w: Array
    h: float


def _augmented(A: Array, B: Array, D: Array, E: Array | None) -> Array:
    """``[[A, B, D], [0, 0, 0], [0, 0, E]]`` for a stack ``(P, ...)`` of plants."""
    plants, n, m = B.shape
    q = D.shape[2]
    size = n + m + q
    M = np.zeros((plants, size, size))
    M[:, :n, :n] = A
    M[:, :n, n : n + m] = B
    M[:, :n, n + m :] = D
    if E is not None:
        M[:, n + m :, n + m :] = E
    return M


#: Largest stack of augmented matrices whose exponential is cached, bytes.
_CACHE_MAX_BYTES = 1 << 20


@lru_cache(maxsize=32)
def _expm_cached(data: bytes, shape: tuple[int, ...], h: float) -> Array:
    M = np.frombuffer(data, dtype=float).reshape(shape)
    result = scipy.linalg.expm(M * h)
    result.setflags(write=False)
    return result


def _expm_stack(M: Array, periods: Array, uniform: bool) -> Array:
    """``expm(M h)`` for a stack M (P, k, k) and periods (S,): shape (P, S, k, k).

    The uniform case (S = 1) is cached, keyed by the matrices and the period, unless the
    stack is large (a big batch of plants).
    """
    if uniform and M.nbytes <= _CACHE_MAX_BYTES:
        result = _expm_cached(np.ascontiguousarray(M).tobytes(), M.shape, float(periods[0]))
        return result[:, np.newaxis]
    return scipy.linalg.expm(M[:, np.newaxis] * periods[np.newaxis, :, np.newaxis, np.newaxis])


def discretize(
    A: ArrayLike,
    B: ArrayLike,
    h: float,
    *,
    D: ArrayLike | None = None,
    E: ArrayLike | None = None,
) -> Discretization:
    """Exact zero-order-hold discretization by the matrix exponential of an augmented matrix.

    Parameters
    ----------
    A : array_like, shape (n, n)
    B : array_like, shape (n, m)
    h : float
        Sampling period, s.
    D : array_like, shape (n, q), optional
        Exogenous input matrix (default: no exogenous input, q = 0).
    E : array_like, shape (q, q), optional
        Exosystem ``w' = E w``; None (default) means ``w`` is held over each sample.

    Returns
    -------
    Discretization

    Raises
    ------
    InputError
        If a shape is wrong, a value is not finite or ``h`` is not positive.

    Examples
    --------
    >>> import numpy as np
    >>> d = discretize([[-1.0]], [[1.0]], 0.1)
    >>> bool(np.isclose(d.Phi[0, 0], np.exp(-0.1)))
    True
    """
    A_ = _square(A, batch=False)
    n = A_.shape[1]
    B_ = _as_stack(B, "B", (n, None), batch=False)
    D_ = np.zeros((1, n, 0)) if D is None else _as_stack(D, "D", (n, None), batch=False)
    q = D_.shape[2]
    E_ = None if E is None else _as_stack(E, "E", (q, q), batch=False)
    period = positive_finite(h, "h")
    m = B_.shape[2]
    exp = _expm_stack(_augmented(A_, B_, D_, E_), np.array([period]), uniform=True)[0, 0]
    return Discretization(
        Phi=exp[:n, :n].copy(),
        Gamma_u=exp[:n, n : n + m].copy(),
        Gamma_w=exp[:n, n + m :].copy(),
        Phi_w=exp[n + m :, n + m :].copy(),
        h=period,
    )


# -- propagation, in a plant-last layout ---------------------------------------------------
#
# Inside the simulator, arrays put the plant axis last, e.g. states (N + 1, n, P), so that
# per-plant products are vectorized multiply-adds along contiguous plants and regrouping
# samples into chunks moves whole rows of plants. Matrices are stored as ``T[b, a, p]``
# and act on rows: ``(x T)[a] = sum_b x[b] T[b, a]``.


def _times(s: Array, T: Array) -> Array:
    """Per-plant row product ``s @ T`` over the first axis of ``s``, plants last.

    ``s`` is (b, ..., P1) and ``T`` is (b, a, P2), with P1, P2 in {1, P}; returns
    (a, ..., P). A shared T (P2 = 1) makes one BLAS product; otherwise a loop over b of
    multiply-adds along the plants.
    """
    size_b, size_a = T.shape[0], T.shape[1]
    if size_b == 0:  # no exogenous input (q = 0)
        return np.zeros((size_a, *s.shape[1:-1], max(s.shape[-1], T.shape[2])))
    if T.shape[2] == 1:
        return (T[:, :, 0].T @ s.reshape(size_b, -1)).reshape(size_a, *s.shape[1:])
    # T[b] as (a, 1, ..., 1, P) to broadcast against s[b] (..., P1)
    T_b = T.reshape(size_b, size_a, *(1,) * (s.ndim - 2), T.shape[2])
    out = s[0][np.newaxis] * T_b[0]
    for b in range(1, size_b):
        out += s[b][np.newaxis] * T_b[b]
    return out


def _to_plant_last(rows: Array) -> Array:
    """(P, R, c) plant-major rows as a contiguous (R, c, P) array (one 2-D transpose)."""
    plants, count, size = rows.shape
    flat = np.ascontiguousarray(rows).reshape(plants, count * size)
    return np.ascontiguousarray(flat.T).reshape(count, size, plants)


def _to_plant_major(rows: Array) -> Array:
    """(R, c, P) plant-last rows as a contiguous (P, R, c) array (one 2-D transpose)."""
    count, size, plants = rows.shape
    flat = np.ascontiguousarray(rows).reshape(count * size, plants)
    return np.ascontiguousarray(flat.T).reshape(plants, count, size)


def _plant_last(M: Array) -> Array:
    """A stack of matrices (P, rows, cols) as the row-acting ``T[b, a, p] = M[p, a, b]``."""
    return np.ascontiguousarray(M.transpose(2, 1, 0))


def _propagate_uniform(T: Array, f: Array, x0: Array) -> Array:
    """``x[k+1] = x[k] @ T + f[k]`` for k < N, vectorized in two levels (plants last).

    ``T`` (b, a, P') is the one-step map acting on rows (P' in {1, P}), ``f`` (N, n, P)
    the forcing, ``x0`` (n, P). The N steps are cut into C chunks of L ~ sqrt(N / 2)
    samples: the response to the forcing inside all chunks is computed at once (L
    vectorized steps), the chunk starts follow by the L-step map (C steps), and the states
    inside the chunks by the powers of T. The loop runs about 2 L + C ~ 3 sqrt(N / 2)
    times instead of N. Returns x, shape (N + 1, n, P).
    """
    count, n, plants = f.shape
    length = max(1, math.isqrt(max(count // 2, 1)))
    chunks = -(-count // length)
    full = count // length
    # state[j, :, c]: first the forcing f[c * length + j - 1] (zero past the end), then in
    # place the response j samples into chunk c from a zero start
    state = np.empty((length + 1, n, chunks, plants))
    state[0] = 0.0
    state[1:, :, :full] = f[: full * length].reshape(full, length, n, plants).transpose(1, 2, 0, 3)
    if full < chunks:
        rest = count - full * length
        state[1 : rest + 1, :, full] = f[full * length :]
        state[rest + 1 :, :, full] = 0.0
    for j in range(1, length + 1):
        state[j] += _times(state[j - 1], T)
    # powers[j] = T^j acting on rows, computed plant-major and stored plant-last
    T_major = T.transpose(2, 0, 1)  # (P', b, a)
    power = np.broadcast_to(np.eye(n), T_major.shape)
    powers = np.empty((length + 1, *T.shape))
    for j in range(length + 1):
        powers[j] = power.transpose(1, 2, 0)
        power = power @ T_major
    # the state at the start of each chunk, by the map over a whole chunk
    starts = np.empty((chunks + 1, n, plants))
    starts[0] = x0
    for c in range(chunks):
        starts[c + 1] = _times(starts[c], powers[length])
        starts[c + 1] += state[length, :, c]
    # the states inside the chunks: the response plus the free motion from the start
    start_rows = np.ascontiguousarray(starts[:chunks].transpose(1, 0, 2))  # (n, C, P)
    inside = state[:length]
    inside[0] = start_rows
    for j in range(1, length):
        inside[j] += _times(start_rows, powers[j])
    x = np.empty((count + 1, n, plants))
    x[: full * length].reshape(full, length, n, plants)[...] = inside[:, :, :full].transpose(
        2, 0, 1, 3
    )
    if full < chunks:  # a last, partial chunk
        x[full * length :] = inside[: count + 1 - full * length, :, full]
    else:
        x[count] = starts[chunks]
    return x


def _propagate_steps(T: Array, index: NDArray[np.intp], f: Array, x0: Array) -> Array:
    """``x[k+1] = x[k] @ T[index[k]] + f[k]``, one step at a time (non-uniform grid).

    ``T`` (S, b, a, P'), ``index`` (N,), ``f`` (N, n, P), ``x0`` (n, P); plants last.
    """
    count, n, plants = f.shape
    x = np.empty((count + 1, n, plants))
    x[0] = x0
    for k in range(count):
        x[k + 1] = _times(x[k], T[index[k]])
        x[k + 1] += f[k]
    return x


# -- exogenous signals --------------------------------------------------------------------


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
        """``w`` at the sample times ``t`` (s): shape (N + 1, q) or (P, N + 1, q)."""
        ...


def _check_signal_values(values: ArrayLike, count: int, name: str) -> Array:
    array = _as_float_array(values, name)
    if array.ndim == 1:
        array = array[:, np.newaxis]
    if array.ndim not in (2, 3) or array.shape[-2] != count:
        raise InputError(
            f"{name}: expected shape ({count}, q) (one row per sample time) or a batch "
            f"(P, {count}, q), got shape {array.shape}"
        )
    return array


@dataclass(frozen=True, init=False, eq=False)
class ConstantSignal:
    """A constant exogenous signal (held), ``w(t) = w``.

    Attributes
    ----------
    w : ndarray, shape (q,) or (P, q)
        The value, one per plant for a batch.
    """

    w: Array

    def __init__(self, w: ArrayLike) -> None:
        value = _as_float_array(w, "constant: w")
        if value.ndim == 0:
            value = value.reshape(1)
        if value.ndim not in (1, 2):
            raise InputError(
                f"constant: w: expected shape (q,) or a batch (P, q), got shape {value.shape}"
            )
        value.setflags(write=False)
        object.__setattr__(self, "w", value)

    @property
    def E(self) -> None:
        """None: the signal is held (``E = 0``)."""
        return None

    def values(self, t: ArrayLike) -> Array:
        """``w`` repeated at each of the N + 1 sample times: (N + 1, q) or (P, N + 1, q)."""
        count = np.asarray(t).shape[0]
        shape = (*self.w.shape[:-1], count, self.w.shape[-1])
        return np.broadcast_to(self.w[..., np.newaxis, :], shape).copy()


@dataclass(frozen=True, init=False, eq=False)
class StepSignal:
    """A piecewise-constant exogenous signal (held) that steps at given times.

    ``w(t) = values[0]`` before ``times[0]`` and ``values[i + 1]`` from ``times[i]`` on.
    Sampled at the sample instants: a step between two instants takes effect at the next
    one; a step time that equals a sample time up to rounding takes effect at that sample.

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
        step_times = _as_float_array(times, "steps: times")
        if step_times.ndim == 0:
            step_times = step_times.reshape(1)
        if step_times.ndim != 1:
            raise InputError(
                f"steps: times: expected a 1-D array of step times, got shape {step_times.shape}"
            )
        if np.any(np.diff(step_times) <= 0.0):
            raise InputError("steps: times: must be strictly increasing")
        levels = _as_float_array(values, "steps: values")
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

    @property
    def E(self) -> None:
        """None: the signal is held (``E = 0``)."""
        return None

    def values(self, t: ArrayLike) -> Array:
        """``w(t[k])``, shape (N + 1, q) or (P, N + 1, q)."""
        times = np.asarray(t, dtype=float)
        scale = max(float(np.max(np.abs(times))), float(np.max(np.abs(self.times))))
        rounding = _UNIFORM_ROUNDING_FACTOR * np.finfo(float).eps * scale
        index = np.searchsorted(self.times, times + rounding, side="right")
        return np.take(self.levels, index, axis=-2)


@dataclass(frozen=True, eq=False)
class HeldSignal:
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

    @property
    def E(self) -> None:
        """None: the signal is held (``E = 0``)."""
        return None

    def values(self, t: ArrayLike) -> Array:
        """``function(t)`` checked: shape (N + 1, q) or (P, N + 1, q)."""
        times = np.array(t, dtype=float)
        times.setflags(write=False)
        return _check_signal_values(self.function(times), times.shape[0], "held: function(t)")


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
        matrix = _as_float_array(E, "exosystem: E")
        if matrix.ndim != 2 or matrix.shape[0] != matrix.shape[1]:
            raise InputError(f"exosystem: E: expected a square matrix (q, q), got {matrix.shape}")
        q = matrix.shape[0]
        initial = _as_float_array(w0, "exosystem: w0")
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
        """``w(t[k]) = expm(E (t[k] - t[0])) w0``, exact up to rounding: (N + 1, q) or batch."""
        times = _sample_times(t, "exosystem: t")
        period = _uniform_period(times)
        q = self.E.shape[0]
        initial = self.w0.reshape(-1, q)
        empty = np.zeros((1, q, 0))
        M = _augmented(self.E[np.newaxis], empty, empty, None)
        count = times.shape[0] - 1
        forcing = np.zeros((count, q, initial.shape[0]))
        if period is not None:
            Phi_w = _expm_stack(M, np.array([period]), uniform=True)[:, 0]  # (1, q, q)
            w = _propagate_uniform(_plant_last(Phi_w), forcing, initial.T)
        else:
            periods, index = np.unique(np.diff(times), return_inverse=True)
            Phi_w = _expm_stack(M, periods, uniform=False)[0]  # (S, q, q)
            w = _propagate_steps(
                Phi_w.transpose(0, 2, 1)[..., np.newaxis], index, forcing, initial.T
            )
        values = w.transpose(2, 0, 1)  # (P, N + 1, q)
        return values if self.w0.ndim == 2 else values[0]


def constant(w: ArrayLike) -> ConstantSignal:
    """A constant, held exogenous signal ``w`` (q,) or a batch (P, q)."""
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

    Examples
    --------
    A sinusoid of 50 Hz, ``w = [sin(2 pi 50 t), cos(2 pi 50 t)]``:

    >>> import numpy as np
    >>> omega = 2 * np.pi * 50
    >>> signal = exosystem([[0.0, omega], [-omega, 0.0]], [0.0, 1.0])
    """
    return Exosystem(E, w0)


# -- exploration --------------------------------------------------------------------------


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
        """``rho`` for the N samples of the times ``t`` (N + 1,), s: shape (*batch, N, m)."""
        ...


@dataclass(frozen=True, init=False, eq=False)
class UniformExploration:
    """A new value uniform in ``[-amplitude, amplitude]`` every sample (the paper's).

    Attributes
    ----------
    amplitude : ndarray, shape () or (m,)
        Bound, in the input's unit (V for the motor); one per input or common.
    """

    amplitude: Array

    def __init__(self, amplitude: ArrayLike) -> None:
        object.__setattr__(self, "amplitude", _amplitude(amplitude, "uniform: amplitude"))

    def sample(
        self, t: ArrayLike, m: int, rng: np.random.Generator, batch: tuple[int, ...] = ()
    ) -> Array:
        """Independent uniform values, shape (*batch, N, m)."""
        amplitude = _amplitude_for(self.amplitude, m, "uniform: amplitude")
        count = np.asarray(t).shape[0] - 1
        return rng.uniform(-1.0, 1.0, size=(*batch, count, m)) * amplitude


@dataclass(frozen=True, init=False, eq=False)
class BinaryExploration:
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

    amplitude: Array
    hold_samples: int

    def __init__(self, amplitude: ArrayLike, hold_samples: int = 1) -> None:
        object.__setattr__(self, "amplitude", _amplitude(amplitude, "prbs: amplitude"))
        object.__setattr__(self, "hold_samples", _count(hold_samples, "prbs: hold_samples"))

    def sample(
        self, t: ArrayLike, m: int, rng: np.random.Generator, batch: tuple[int, ...] = ()
    ) -> Array:
        """The binary sequence, shape (*batch, N, m)."""
        amplitude = _amplitude_for(self.amplitude, m, "prbs: amplitude")
        count = np.asarray(t).shape[0] - 1
        blocks = -(-count // self.hold_samples)
        signs = 2.0 * rng.integers(0, 2, size=(*batch, blocks, m)) - 1.0
        levels = np.repeat(signs, self.hold_samples, axis=-2)[..., :count, :]
        return levels * amplitude


@dataclass(frozen=True, init=False, eq=False)
class SinusoidalExploration:
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

    amplitude: Array
    frequencies: Array

    def __init__(self, amplitude: ArrayLike, frequencies: ArrayLike) -> None:
        object.__setattr__(self, "amplitude", _amplitude(amplitude, "sum_of_sines: amplitude"))
        values = _as_float_array(frequencies, "sum_of_sines: frequencies")
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

    def sample(
        self, t: ArrayLike, m: int, rng: np.random.Generator, batch: tuple[int, ...] = ()
    ) -> Array:
        """The sampled sum of sinusoids, shape (*batch, N, m)."""
        amplitude = _amplitude_for(self.amplitude, m, "sum_of_sines: amplitude")
        count_f = self.frequencies.shape[0]
        phases = rng.uniform(0.0, 2.0 * np.pi, size=(*batch, 1, m, count_f))
        times = np.asarray(t, dtype=float)[:-1]
        angles = 2.0 * np.pi * times[:, np.newaxis, np.newaxis] * self.frequencies + phases
        return np.sin(angles).sum(axis=-1) * (amplitude / count_f)


def uniform(amplitude: ArrayLike) -> UniformExploration:
    """Exploration uniform in ``[-amplitude, amplitude]``, a new value every sample.

    ``amplitude`` is a number or one per input (m,), in the input's unit (V for the motor).
    """
    return UniformExploration(amplitude)


def prbs(amplitude: ArrayLike, hold_samples: int = 1) -> BinaryExploration:
    """Random binary exploration ``+-amplitude``, held at least ``hold_samples`` samples."""
    return BinaryExploration(amplitude, hold_samples)


def sum_of_sines(amplitude: ArrayLike, frequencies: ArrayLike) -> SinusoidalExploration:
    """Exploration by a sum of sinusoids (Hz) with random phases, peak ``<= amplitude``."""
    return SinusoidalExploration(amplitude, frequencies)


# -- results ------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class TrajectoryBatch:
    """Trajectories of P plants sampled at the same times (read-only arrays, SI units).

    Attributes
    ----------
    t : ndarray, shape (N + 1,)
        Sample times, s.
    x : ndarray, shape (P, N + 1, n)
        States.
    u : ndarray, shape (P, N, m)
        Inputs, held over each sample (exploration included).
    w : ndarray, shape (P, N + 1, q), or None
        Exogenous signal at each sample time (see :class:`~selftune.trajectory.Trajectory`).
    exploration : ndarray, shape (P, N, m)
        The exploration part ``rho`` of ``u``.
    """

    t: Array
    x: Array
    u: Array
    w: Array | None
    exploration: Array

    @property
    def num_plants(self) -> int:
        """P, the number of plants."""
        return int(self.x.shape[0])

    def __len__(self) -> int:
        return self.num_plants

    def trajectory(self, index: int) -> Trajectory:
        """The trajectory of plant ``index`` (0-based; negative counts from the end)."""
        plants = self.num_plants
        if isinstance(index, bool) or not isinstance(index, int | np.integer):
            raise InputError(f"index: expected an integer, got {type(index).__name__}")
        if not -plants <= index < plants:
            raise InputError(f"index: must be in [{-plants}, {plants}), got {index}")
        w = None if self.w is None else self.w[index]
        return Trajectory(t=self.t, x=self.x[index], u=self.u[index], w=w)

    def trajectories(self) -> list[Trajectory]:
        """All P trajectories."""
        return [self.trajectory(i) for i in range(self.num_plants)]


# -- the simulator ------------------------------------------------------------------------


def _batch_size(stacks: dict[str, Array], num_plants: int | None) -> int:
    """The common batch size P of stacks whose leading axis is 1 (shared) or P."""
    size, source = num_plants, "num_plants"
    for name, stack in stacks.items():
        count = int(stack.shape[0])
        if count == 1:
            continue
        if size is None:
            size, source = count, name
        elif count != size:
            raise InputError(f"{name}: a batch of {count} plants, but {source} gives {size}")
    return 1 if size is None else size


def _run(
    A: ArrayLike,
    B: ArrayLike,
    *,
    D: ArrayLike | None,
    exogenous: ExogenousSignal | ArrayLike | None,
    K: ArrayLike | None,
    X: ArrayLike | None,
    U: ArrayLike | None,
    exploration: Exploration | ArrayLike | None,
    x0: ArrayLike | None,
    h: float | None,
    num_samples: int | None,
    t: ArrayLike | None,
    seed: Seed,
    batch: bool,
    num_plants: int | None,
) -> TrajectoryBatch:
    A_ = _square(A, batch)
    n = A_.shape[1]
    B_ = _as_stack(B, "B", (n, None), batch=batch)
    m = B_.shape[2]
    if D is None:
        if exogenous is not None:
            raise InputError("exogenous: given, but the plant has no exogenous input (D is None)")
        for name, value in (("X", X), ("U", U)):
            if value is not None:
                raise InputError(f"{name}: given, but the plant has no exogenous input (D is None)")
        D_ = np.zeros((1, n, 0))
    else:
        D_ = _as_stack(D, "D", (n, None), batch=batch)
        if exogenous is None:
            raise InputError(
                f"exogenous: D has {D_.shape[2]} columns, so an exogenous signal w is needed "
                "(constant, steps, held or exosystem)"
            )
    q = D_.shape[2]
    K_ = np.zeros((1, m, n)) if K is None else _as_stack(K, "K", (m, n), batch=batch)
    X_ = np.zeros((1, n, q)) if X is None else _as_stack(X, "X", (n, q), batch=batch)
    U_ = np.zeros((1, m, q)) if U is None else _as_stack(U, "U", (m, q), batch=batch)
    x0_ = np.zeros((1, n)) if x0 is None else _as_stack(x0, "x0", (n,), batch=batch)
    grid = _time_grid(h, num_samples, t)
    count = grid.num_samples

    # exogenous signal at the sample times, and its exosystem matrix (None: held)
    E: Array | None = None
    if exogenous is None:
        w = np.zeros((1, count + 1, 0))
    else:
        if isinstance(exogenous, ExogenousSignal):
            if exogenous.E is not None:
                E = _as_stack(exogenous.E, "exogenous: E", (q, q), batch=False)[0]
            values = _check_signal_values(exogenous.values(grid.t), count + 1, "exogenous")
        else:
            values = _check_signal_values(exogenous, count + 1, "exogenous")
        if values.shape[-1] != q:
            raise InputError(f"exogenous: has {values.shape[-1]} channels, but D has {q} columns")
        if values.ndim == 3 and not batch:
            raise InputError(
                f"exogenous: expected shape ({count + 1}, {q}), got a batch {values.shape} "
                "(use simulate_batch for a batch of plants)"
            )
        w = values.reshape(-1, count + 1, q)

    # exploration as an array, or a generator to draw from once the batch size is known
    rho_given: Array | None = None
    if exploration is not None and not isinstance(exploration, Exploration):
        rho_given = _as_float_array(exploration, "exploration")
        if rho_given.ndim == 2 or (batch and rho_given.ndim == 3):
            rho_given = rho_given.reshape(-1, *rho_given.shape[-2:])
            valid = rho_given.shape[1:] == (count, m)
        else:
            valid = False
        if not valid:
            wanted = f"({count}, {m})" + (f" or a batch (P, {count}, {m})" if batch else "")
            raise InputError(
                f"exploration: expected an Exploration (uniform, prbs, sum_of_sines), None, "
                f"or an array of shape {wanted}, got shape {np.shape(exploration)}"
            )

    stacks = {"A": A_, "B": B_, "D": D_, "K": K_, "X": X_, "U": U_, "x0": x0_, "exogenous": w}
    if rho_given is not None:
        stacks["exploration"] = rho_given
    if num_plants is not None:
        num_plants = _count(num_plants, "num_plants")
    plants = _batch_size(stacks, num_plants)

    rng = _as_generator(seed)
    if rho_given is not None:
        rho = np.broadcast_to(rho_given, (plants, count, m))
    elif exploration is not None:
        assert isinstance(exploration, Exploration)
        drawn = exploration.sample(grid.t.copy(), m, rng, (plants,) if batch else ())
        rho = _check_exploration(drawn, plants, count, m)
    else:
        rho = np.zeros((plants, count, m))

    # discretization of each distinct plant (A, B, D shared or batched)
    plant_count = max(A_.shape[0], B_.shape[0], D_.shape[0])
    M = _augmented(
        np.broadcast_to(A_, (plant_count, n, n)),
        np.broadcast_to(B_, (plant_count, n, m)),
        np.broadcast_to(D_, (plant_count, n, q)),
        E,
    )
    if grid.h is not None:
        periods = np.array([grid.h])
        index = np.zeros(count, dtype=np.intp)
    else:
        periods, index = np.unique(grid.steps, return_inverse=True)
    exp = _expm_stack(M, periods, uniform=grid.h is not None)  # (P', S, k, k)
    Phi = exp[..., :n, :n]
    Gamma_u = exp[..., :n, n : n + m]
    Gamma_w = exp[..., :n, n + m :]

    # closed loop: x[k+1] = (Phi - Gamma_u K) x[k] + (Gamma_u L + Gamma_w) w[k] + Gamma_u rho[k]
    L = U_ + K_ @ X_  # (P'', m, q): u = -K x + L w + rho
    closed = Phi - Gamma_u @ K_[:, np.newaxis]  # (P'', S, n, n)
    w_gain = Gamma_u @ L[:, np.newaxis] + Gamma_w  # (P'', S, n, q)
    # forcing plant-major (a matmul per plant), the propagation plant-last (see _times)
    x0_last = np.ascontiguousarray(np.broadcast_to(x0_, (plants, n)).T)
    with np.errstate(over="ignore", invalid="ignore"):
        if grid.h is not None:
            forcing = w[:, :count] @ w_gain[:, 0].transpose(0, 2, 1)
            forcing = forcing + rho @ Gamma_u[:, 0].transpose(0, 2, 1)
            x_last = _propagate_uniform(_plant_last(closed[:, 0]), _to_plant_last(forcing), x0_last)
        else:
            w_steps = w[:, :count, np.newaxis, :]  # (P_w, N, 1, q)
            forcing = (w_steps @ w_gain[:, index].transpose(0, 1, 3, 2))[:, :, 0]
            forcing = (
                forcing
                + (rho[:, :, np.newaxis, :] @ Gamma_u[:, index].transpose(0, 1, 3, 2))[:, :, 0]
            )
            closed_steps = np.ascontiguousarray(closed.transpose(1, 3, 2, 0))  # (S, b, a, P'')
            x_last = _propagate_steps(closed_steps, index, _to_plant_last(forcing), x0_last)
        x = _to_plant_major(x_last)
        u = rho - x[:, :count] @ K_.transpose(0, 2, 1)
        u += w[:, :count] @ L.transpose(0, 2, 1)
    _check_finite_states(x, grid.t)
    w_out = None if q == 0 else np.broadcast_to(w, (plants, count + 1, q))
    arrays = [grid.t, x, u, rho] + ([] if w_out is None else [w_out])
    for array in arrays:
        if array.flags.writeable:
            array.setflags(write=False)
    return TrajectoryBatch(t=grid.t, x=x, u=u, w=w_out, exploration=np.asarray(rho))


def _check_exploration(drawn: ArrayLike, plants: int, count: int, m: int) -> Array:
    rho = _as_float_array(drawn, "exploration.sample")
    if rho.shape == (count, m):
        rho = rho[np.newaxis]
    if rho.shape not in ((plants, count, m), (1, count, m)):
        raise InputError(
            f"exploration.sample: expected shape {(count, m)} or {(plants, count, m)}, "
            f"got {rho.shape}"
        )
    return np.broadcast_to(rho, (plants, count, m))


def _check_finite_states(x: Array, t: Array) -> None:
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


def simulate(
    A: ArrayLike,
    B: ArrayLike,
    *,
    D: ArrayLike | None = None,
    exogenous: ExogenousSignal | ArrayLike | None = None,
    K: ArrayLike | None = None,
    X: ArrayLike | None = None,
    U: ArrayLike | None = None,
    exploration: Exploration | ArrayLike | None = None,
    x0: ArrayLike | None = None,
    h: float | None = None,
    num_samples: int | None = None,
    t: ArrayLike | None = None,
    seed: Seed = None,
    input_hold: int = 1,
) -> Trajectory:
    """Simulate ``x' = A x + B u + D w`` exactly under ``u = -K (x - X w) + U w + rho``.

    Each ``u[k]`` is held over ``[t[k], t[k+1])`` (zero-order hold) and the plant is
    propagated by the matrix exponential, so the samples are exact up to rounding for any
    sampling period. Give either ``h`` and ``num_samples`` (times ``k h`` from 0) or the
    sample times ``t`` (a non-uniform grid is allowed; a uniform one, up to the rounding of
    the times, uses one cached discretization).

    Parameters
    ----------
    A : array_like, shape (n, n)
        State matrix, 1/s.
    B : array_like, shape (n, m)
        Input matrix.
    D : array_like, shape (n, q), optional
        Exogenous input matrix; needs ``exogenous``.
    exogenous : ExogenousSignal or array_like, optional
        The signal ``w``: :func:`constant`, :func:`steps`, :func:`held` (held over each
        sample), :func:`exosystem` (``w' = E w`` inside each sample), or an array (N + 1, q)
        of held values at the sample times.
    K : array_like, shape (m, n), optional
        Feedback gain (default 0: open loop).
    X : array_like, shape (n, q), optional
        Steady-state map, ``x_ss = X w`` (default 0).
    U : array_like, shape (m, q), optional
        Feedforward, ``u_ss = U w`` (default 0).
    exploration : Exploration or array_like, optional
        ``rho``: :func:`uniform`, :func:`prbs`, :func:`sum_of_sines`, an array (N, m), or
        None (default: no exploration).
    x0 : array_like, shape (n,), optional
        Initial state (default 0).
    h : float, optional
        Sampling period, s (with ``num_samples``).
    num_samples : int, optional
        N, the number of samples (with ``h``).
    t : array_like, shape (N + 1,), optional
        Sample times, s, strictly increasing (instead of ``h`` and ``num_samples``).
    seed : int, numpy.random.Generator or None, optional
        Source of the exploration's randomness; the same integer reproduces the run,
        None draws fresh entropy.
    input_hold : int, optional
        The controller updates ``u`` (and a held ``w``) every ``input_hold`` samples and
        holds it in between, while the state is sampled every ``h`` (a controller at a
        fraction of the measurement rate). Needs ``h`` and ``num_samples``. Learners
        integrate such data to fourth order (see :mod:`selftune.data_equation`).

    Returns
    -------
    Trajectory
        ``t`` (N + 1,), ``x`` (N + 1, n), ``u`` (N, m) with the exploration included, and
        ``w`` (N + 1, q) (None without D): ``w(t[k])``, for a held signal the last row is
        ``w(t[N])``, unused by the learners.

    Raises
    ------
    InputError
        Naming the argument, if a shape is wrong, a value is not finite, the time grid is
        invalid, or the state overflows (an unstable closed loop over a long horizon).

    Examples
    --------
    >>> import numpy as np
    >>> data = simulate([[-1.0]], [[1.0]], x0=[1.0], h=0.01, num_samples=100)
    >>> bool(np.isclose(data.x[-1, 0], np.exp(-1.0), rtol=1e-12))
    True
    """
    hold = _count(input_hold, "input_hold")
    if hold > 1:
        return _simulate_held_inputs(
            A, B, D=D, exogenous=exogenous, K=K, X=X, U=U, exploration=exploration, x0=x0,
            h=h, num_samples=num_samples, t=t, seed=seed, hold=hold,
        )  # fmt: skip
    result = _run(
        A, B, D=D, exogenous=exogenous, K=K, X=X, U=U, exploration=exploration, x0=x0,
        h=h, num_samples=num_samples, t=t, seed=seed, batch=False, num_plants=None,
    )  # fmt: skip
    return result.trajectory(0)


def _simulate_held_inputs(
    A: ArrayLike,
    B: ArrayLike,
    *,
    D: ArrayLike | None,
    exogenous: ExogenousSignal | ArrayLike | None,
    K: ArrayLike | None,
    X: ArrayLike | None,
    U: ArrayLike | None,
    exploration: Exploration | ArrayLike | None,
    x0: ArrayLike | None,
    h: float | None,
    num_samples: int | None,
    t: ArrayLike | None,
    seed: Seed,
    hold: int,
) -> Trajectory:
    """:func:`simulate` with the controller at 1/``hold`` of the sampling rate.

    The closed loop runs at the controller's period ``hold h``; the samples in between
    are then filled in exactly from the discretization over ``j h``, j = 1 .. hold - 1.
    """
    if t is not None or h is None or num_samples is None:
        raise InputError("input_hold: needs a uniform grid given by h and num_samples")
    period = positive_finite(h, "h")
    count = _count(num_samples, "num_samples")
    if exploration is not None and not isinstance(exploration, Exploration):
        raise InputError("input_hold: give the exploration as a generator (uniform, prbs, ...)")
    if exogenous is not None and not isinstance(exogenous, ExogenousSignal):
        raise InputError("input_hold: give the exogenous signal as a signal object (held, ...)")
    updates = -(-count // hold)
    coarse = _run(
        A, B, D=D, exogenous=exogenous, K=K, X=X, U=U, exploration=exploration, x0=x0,
        h=hold * period, num_samples=updates, t=None, seed=seed, batch=False, num_plants=None,
    ).trajectory(0)  # fmt: skip
    E = None if exogenous is None else exogenous.E
    n, q = coarse.n, coarse.q
    x = np.empty((updates * hold + 1, n))
    u = np.repeat(coarse.u, hold, axis=0)
    w = None if coarse.w is None else np.empty((updates * hold + 1, q))
    x[::hold] = coarse.x
    if w is not None and coarse.w is not None:
        w[::hold] = coarse.w
    w_start = np.zeros((updates, 0)) if coarse.w is None else coarse.w[:-1]
    for step in range(1, hold):
        exact = discretize(A, B, step * period, D=D, E=E)
        x[step::hold] = coarse.x[:-1] @ exact.Phi.T + coarse.u @ exact.Gamma_u.T
        if q:
            x[step::hold] += w_start @ exact.Gamma_w.T
            assert w is not None
            w[step::hold] = w_start @ exact.Phi_w.T
    stop = count + 1
    return Trajectory(
        t=np.arange(stop) * period,
        x=x[:stop],
        u=u[:count],
        w=None if w is None else w[:stop],
    )


def simulate_batch(
    A: ArrayLike,
    B: ArrayLike,
    *,
    D: ArrayLike | None = None,
    exogenous: ExogenousSignal | ArrayLike | None = None,
    K: ArrayLike | None = None,
    X: ArrayLike | None = None,
    U: ArrayLike | None = None,
    exploration: Exploration | ArrayLike | None = None,
    x0: ArrayLike | None = None,
    h: float | None = None,
    num_samples: int | None = None,
    t: ArrayLike | None = None,
    seed: Seed = None,
    num_plants: int | None = None,
) -> TrajectoryBatch:
    """Simulate P plants at once, vectorized over the batch (one time loop for all).

    Takes the arguments of :func:`simulate`; each of ``A`` (P, n, n), ``B`` (P, n, m),
    ``D`` (P, n, q), ``K`` (P, m, n), ``X`` (P, n, q), ``U`` (P, m, q), ``x0`` (P, n), an
    exogenous signal with batched values (P, N + 1, q) and an exploration array
    (P, N, m) may be a batch, or unbatched to share it among all plants. An exploration
    generator draws an independent signal for each plant (so plant i does not see the
    same ``rho`` as a single run with the same seed). An exosystem's ``E`` is shared.

    Parameters
    ----------
    num_plants : int, optional
        P when no argument is batched (e.g. one plant under P exploration draws).

    Returns
    -------
    TrajectoryBatch
        ``x`` (P, N + 1, n), ``u`` (P, N, m), ``w`` (P, N + 1, q) or None, ``exploration``
        (P, N, m), ``t`` (N + 1,); ``.trajectory(i)`` gives plant i's :class:`Trajectory`.

    Raises
    ------
    InputError
        As :func:`simulate`, and if the batch sizes differ between arguments.

    Examples
    --------
    >>> import numpy as np
    >>> A = -np.arange(1.0, 4.0).reshape(3, 1, 1)  # three scalar plants
    >>> batch = simulate_batch(A, [[1.0]], x0=[1.0], h=0.1, num_samples=10)
    >>> batch.x.shape
    (3, 11, 1)
    """
    return _run(
        A, B, D=D, exogenous=exogenous, K=K, X=X, U=U, exploration=exploration, x0=x0,
        h=h, num_samples=num_samples, t=t, seed=seed, batch=True, num_plants=num_plants,
    )  # fmt: skip
