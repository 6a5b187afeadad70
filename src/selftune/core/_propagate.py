"""Propagation kernels of the simulator, in a plant-last layout.

Inside the simulator, arrays put the plant axis last, e.g. states (N + 1, n, P), so that
per-plant products are vectorized multiply-adds along contiguous plants and regrouping
samples into chunks moves whole rows of plants. Matrices are stored as ``T[b, a, p]``
and act on rows: ``(x T)[a] = sum_b x[b] T[b, a]``.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ._validation import Array

__all__ = ["plant_last", "propagate_steps", "propagate_uniform", "to_plant_last", "to_plant_major"]


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


def to_plant_last(rows: Array) -> Array:
    """(P, R, c) plant-major rows as a contiguous (R, c, P) array (one 2-D transpose)."""
    plants, count, size = rows.shape
    flat = np.ascontiguousarray(rows).reshape(plants, count * size)
    return np.ascontiguousarray(flat.T).reshape(count, size, plants)


def to_plant_major(rows: Array) -> Array:
    """(R, c, P) plant-last rows as a contiguous (P, R, c) array (one 2-D transpose)."""
    count, size, plants = rows.shape
    flat = np.ascontiguousarray(rows).reshape(count * size, plants)
    return np.ascontiguousarray(flat.T).reshape(plants, count, size)


def plant_last(M: Array) -> Array:
    """A stack of matrices (P, rows, cols) as the row-acting ``T[b, a, p] = M[p, a, b]``."""
    return np.ascontiguousarray(M.transpose(2, 1, 0))


def propagate_uniform(T: Array, f: Array, x0: Array) -> Array:
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


def propagate_steps(T: Array, index: NDArray[np.intp], f: Array, x0: Array) -> Array:
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
