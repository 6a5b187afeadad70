"""Vectorization conventions: the one home of vec, vecs, vecs_hat and the Theta layout.

The conventions are the paper's (Wang 2022, Sec. III-A; Jiang & Jiang 2012):

- ``vec(T)`` stacks the columns of ``T`` (column-major, numpy ``order="F"``).
- ``vecs(P) = [P_11, ..., P_nn, 2 P_12, ..., 2 P_1n, 2 P_23, ..., 2 P_(n-1)n]`` for a
  symmetric ``P``: the diagonal first, then the strictly upper triangle row by row, doubled.
- ``vecs_hat(x) = [x_1^2, ..., x_n^2, x_1 x_2, ..., x_1 x_n, x_2 x_3, ..., x_(n-1) x_n]``,
  so that ``x' P x = vecs_hat(x) @ vecs(P)``.
- ``Theta = [vecs(P); vec(K); vec(M)]`` with ``P`` (n x n), ``K`` (m x n) and
  ``M = (D + A X)' P`` (q x n); its length is ``n(n+1)/2 + m n + q n``.
"""

from __future__ import annotations

from functools import cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "pack_theta",
    "theta_sizes",
    "unpack_theta",
    "unvec",
    "unvecs",
    "vec",
    "vecs",
    "vecs_hat",
    "vecs_hat_from_outer",
]

Array = NDArray[np.float64]


@cache
def _upper_pairs(n: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Row and column indices of the vecs ordering: the diagonal, then the upper triangle."""
    diagonal = np.arange(n)
    upper_rows, upper_cols = np.triu_indices(n, k=1)
    rows = np.concatenate([diagonal, upper_rows])
    cols = np.concatenate([diagonal, upper_cols])
    rows.setflags(write=False)
    cols.setflags(write=False)
    return rows, cols


def vec(T: ArrayLike) -> Array:
    """Stack the columns of a matrix into a vector (column-major).

    Parameters
    ----------
    T : array_like, shape (rows, cols)

    Returns
    -------
    ndarray, shape (rows * cols,)
    """
    return np.asarray(T, dtype=float).ravel(order="F")


def unvec(v: ArrayLike, rows: int, cols: int) -> Array:
    """Inverse of :func:`vec`: a ``rows x cols`` matrix from its stacked columns.

    Parameters
    ----------
    v : array_like, shape (rows * cols,)
        The stacked columns.
    rows : int
        Number of rows.
    cols : int
        Number of columns.

    Returns
    -------
    ndarray, shape (rows, cols)
    """
    v = np.asarray(v, dtype=float)
    if v.shape != (rows * cols,):
        raise ValueError(f"unvec: expected a vector of length {rows * cols}, got shape {v.shape}")
    return v.reshape((rows, cols), order="F")


def vecs(P: ArrayLike) -> Array:
    """The paper's vecs of a symmetric matrix: diagonal, then doubled upper triangle.

    Parameters
    ----------
    P : array_like, shape (n, n)
        Symmetric matrix (only the diagonal and the upper triangle are read).

    Returns
    -------
    ndarray, shape (n (n + 1) / 2,)

    Raises
    ------
    ValueError
        If ``P`` is not a square matrix.
    """
    P = np.asarray(P, dtype=float)
    if P.ndim != 2 or P.shape[0] != P.shape[1]:
        raise ValueError(f"vecs: expected a square matrix, got shape {P.shape}")
    n = P.shape[0]
    rows, cols = _upper_pairs(n)
    out = P[rows, cols].copy()
    out[n:] *= 2.0
    return out


def unvecs(v: ArrayLike, n: int) -> Array:
    """Inverse of :func:`vecs`: the symmetric ``n x n`` matrix.

    Parameters
    ----------
    v : array_like, shape (n (n + 1) / 2,)
        ``vecs`` of the matrix.
    n : int
        Size of the matrix.

    Returns
    -------
    ndarray, shape (n, n)
    """
    v = np.asarray(v, dtype=float)
    if v.shape != (n * (n + 1) // 2,):
        raise ValueError(
            f"unvecs: expected a vector of length {n * (n + 1) // 2}, got shape {v.shape}"
        )
    rows, cols = _upper_pairs(n)
    values = v.copy()
    values[n:] *= 0.5
    P = np.zeros((n, n))
    P[rows, cols] = values
    P[cols, rows] = values
    return P


def vecs_hat(x: ArrayLike) -> Array:
    """The quadratic monomials of ``x`` in vecs order, so ``x'Px = vecs_hat(x) @ vecs(P)``.

    Parameters
    ----------
    x : array_like, shape (..., n)
        One vector or a stack of vectors (leading axes are kept).

    Returns
    -------
    ndarray, shape (..., n (n + 1) / 2)
    """
    x = np.asarray(x, dtype=float)
    if x.ndim == 0:
        raise ValueError("vecs_hat: expected a vector (or a stack of vectors), got a scalar")
    rows, cols = _upper_pairs(x.shape[-1])
    return x[..., rows] * x[..., cols]


def vecs_hat_from_outer(M: ArrayLike) -> Array:
    """``vecs_hat`` read off a (sum of) outer product(s).

    For ``M = x x'`` this equals ``vecs_hat(x)``; it is linear in ``M``, so sums and
    integrals of outer products map to sums and integrals of ``vecs_hat``.

    Parameters
    ----------
    M : array_like, shape (..., n, n)
        Symmetric matrix or stack of them.

    Returns
    -------
    ndarray, shape (..., n (n + 1) / 2)

    Raises
    ------
    ValueError
        If the last two axes of ``M`` are not those of a square matrix.
    """
    M = np.asarray(M, dtype=float)
    if M.ndim < 2 or M.shape[-2] != M.shape[-1]:
        raise ValueError(
            "vecs_hat_from_outer: expected a square matrix (or a stack of them),"
            f" got shape {M.shape}"
        )
    rows, cols = _upper_pairs(M.shape[-1])
    return M[..., rows, cols]


def theta_sizes(n: int, m: int, q: int) -> tuple[int, int, int]:
    """Lengths of the three blocks of Theta: ``(n(n+1)/2, m n, q n)``.

    Parameters
    ----------
    n : int
        State dimension.
    m : int
        Input dimension.
    q : int
        Exogenous-signal dimension.
    """
    return n * (n + 1) // 2, m * n, q * n


def pack_theta(P: ArrayLike, K: ArrayLike, M: ArrayLike | None = None) -> Array:
    """Theta = [vecs(P); vec(K); vec(M)] (M omitted for plain LQR).

    Parameters
    ----------
    P : array_like, shape (n, n)
        Value matrix.
    K : array_like, shape (m, n)
        Feedback gain.
    M : array_like, shape (q, n), optional
        The exogenous block ``(D + A X)' P``.
    """
    parts = [vecs(P), vec(K)]
    if M is not None:
        parts.append(vec(M))
    return np.concatenate(parts)


def unpack_theta(theta: ArrayLike, n: int, m: int, q: int = 0) -> tuple[Array, Array, Array]:
    """Split Theta into ``(P, K, M)``; ``M`` has shape (q, n) (empty when q = 0).

    Parameters
    ----------
    theta : array_like, shape (n (n + 1) / 2 + m n + q n,)
        Theta = [vecs(P); vec(K); vec(M)].
    n : int
        State dimension.
    m : int
        Input dimension.
    q : int, optional
        Exogenous-signal dimension (default 0: plain LQR, no ``M`` block).

    Returns
    -------
    P : ndarray, shape (n, n)
        Value matrix.
    K : ndarray, shape (m, n)
        Feedback gain.
    M : ndarray, shape (q, n)
        The exogenous block ``(D + A X)' P``.
    """
    theta = np.asarray(theta, dtype=float)
    size_P, size_K, size_M = theta_sizes(n, m, q)
    if theta.shape != (size_P + size_K + size_M,):
        raise ValueError(
            f"unpack_theta: expected length {size_P + size_K + size_M} for n={n}, m={m}, "
            f"q={q}, got shape {theta.shape}"
        )
    P = unvecs(theta[:size_P], n)
    K = unvec(theta[size_P : size_P + size_K], m, n)
    M = unvec(theta[size_P + size_K :], q, n)
    return P, K, M
