"""Exact zero-order-hold discretization: the one home of the matrix exponential.

For ``x' = A x + B u + D w`` with ``u`` held over a period ``h`` and ``w`` either held
(``E`` None) or following an exosystem ``w' = E w``, Van Loan's augmented exponential::

    expm([[A, B, D],        [[Ad, Bd, Ed],
          [0, 0, 0],    h) = [0,  I,  0 ],
          [0, 0, E]]         [0,  0,  Ew]]

gives ``x[k+1] = Ad x[k] + Bd u[k] + Ed w[k]`` and ``w[k+1] = Ew w[k]`` exactly, with no
ODE solver. The simulator (:mod:`selftune.sim`), the model-based digital optimum
(:mod:`selftune.model`) and the structured identification (:mod:`selftune.learn`) all
call it.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike

from ..errors import InputError
from ._validation import Array, as_matrix, positive_finite

__all__ = ["Discretization", "augmented", "discretize", "expm_stack", "rotating_hold"]


@dataclass(frozen=True, eq=False)
class Discretization:
    """Exact zero-order-hold discretization of ``x' = A x + B u + D w`` over one period.

    ``x[k+1] = Ad x[k] + Bd u[k] + Ed w[k]`` for ``u`` held over the period and ``w``
    either held (``E`` None) or following ``w' = E w`` from ``w[k]``, in which case
    ``w[k+1] = Ew w[k]``.

    Attributes
    ----------
    Ad : ndarray, shape (n, n)
        ``expm(A h)``.
    Bd : ndarray, shape (n, m)
        ``int_0^h expm(A s) ds B``.
    Ed : ndarray, shape (n, q)
        Effect of ``w[k]`` on ``x[k+1]`` (held or exosystem, as above).
    Ew : ndarray, shape (q, q)
        ``expm(E h)`` (the identity for a held signal).
    h : float
        Sampling period, s.
    """

    Ad: Array
    Bd: Array
    Ed: Array
    Ew: Array
    h: float


def augmented(A: Array, B: Array, D: Array, E: Array | None) -> Array:
    """``[[A, B, D], [0, 0, 0], [0, 0, E]]`` for a stack ``(P, ...)`` of plants.

    Parameters
    ----------
    A : ndarray, shape (P, n, n)
        State matrices.
    B : ndarray, shape (P, n, m)
        Input matrices.
    D : ndarray, shape (P, n, q)
        Exogenous input matrices.
    E : ndarray, shape (q, q) or (P, q, q), or None
        Exosystem matrix; None for a held ``w`` (a zero block).

    Returns
    -------
    ndarray, shape (P, n + m + q, n + m + q)
    """
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


def expm_stack(M: Array, periods: Array, uniform: bool) -> Array:
    """``expm(M h)`` for a stack M (P, k, k) and periods (S,): shape (P, S, k, k).

    The uniform case (S = 1) is cached, keyed by the matrices and the period, unless the
    stack is large (a big batch of plants).

    Parameters
    ----------
    M : ndarray, shape (P, k, k)
        Stack of matrices, 1/s.
    periods : ndarray, shape (S,)
        Periods ``h``, s.
    uniform : bool
        Whether the grid is uniform (one period, S = 1): the result may then be cached.
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
        State matrix, 1/s.
    B : array_like, shape (n, m)
        Input matrix.
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
        If a shape is wrong, a value is not finite, ``h`` is not positive, or the
        exponential overflows (``A h`` far too large).

    Examples
    --------
    >>> import numpy as np
    >>> d = discretize([[-1.0]], [[1.0]], 0.1)
    >>> bool(np.isclose(d.Ad[0, 0], np.exp(-0.1)))
    True
    """
    A_ = as_matrix(A, "A")
    n = A_.shape[0]
    A_ = as_matrix(A_, "A", (n, n))
    B_ = as_matrix(B, "B", (n, None))
    D_ = np.zeros((n, 0)) if D is None else as_matrix(D, "D", (n, None))
    q = D_.shape[1]
    E_ = None if E is None else as_matrix(E, "E", (q, q))
    period = positive_finite(h, "h")
    m = B_.shape[1]
    with np.errstate(over="ignore", invalid="ignore"):
        exp = expm_stack(
            augmented(A_[np.newaxis], B_[np.newaxis], D_[np.newaxis], E_),
            np.array([period]),
            uniform=True,
        )[0, 0]
    if not np.all(np.isfinite(exp)):
        raise InputError(
            f"h: the exponential of A h overflows (h = {period:g} s, largest |A| entry "
            f"{float(np.max(np.abs(A_))):.3g}); the sampling period is far too long for A"
        )
    return Discretization(
        Ad=exp[:n, :n].copy(),
        Bd=exp[:n, n : n + m].copy(),
        Ed=exp[:n, n + m :].copy(),
        Ew=exp[n + m :, n + m :].copy(),
        h=period,
    )


def rotating_hold(
    A: ArrayLike, B: ArrayLike, h: float, electrical_speed: float, advance: float = 0.0
) -> Array:
    """The input matrix of a stationary-frame vector held over a sample, in the rotor frame.

    A PWM inverter holds the voltage vector in the stationary frame while the rotor (dq)
    frame turns at ``w_e``: over ``[t_k, t_k + h)`` the dq input is ``Rot(advance - w_e s)
    a_k``, with ``advance`` the angle by which the drive turned its command ahead (the
    usual compensation centres it: ``w_e h / 2``; an inverter's dead-time voltage, set at
    the sample's start, has 0). Then ``x_(k+1) = Ad x_k + Bd' a_k + ...`` exactly with
    ``Bd' = int_0^h expm(A (h - s)) B Rot(advance - w_e s) ds``, computed as the exogenous
    matrix of a held vector turning by ``v' = [[0, w_e], [-w_e, 0]] v`` (:func:`discretize`).
    For ``w_e = 0`` and no advance it is the zero-order hold's Bd. n = m = 2 (dq).

    Parameters
    ----------
    A : array_like, shape (2, 2)
        State matrix in the rotor frame, 1/s.
    B : array_like, shape (2, 2)
        Input matrix.
    h : float
        Sampling period, s.
    electrical_speed : float
        ``w_e``, rad/s.
    advance : float
        Angle the held vector starts ahead of the rotor frame's, rad.

    Returns
    -------
    ndarray, shape (2, 2)
        ``Bd'``.
    """
    w = float(electrical_speed)
    B_ = np.asarray(B, dtype=float)
    turning = discretize(A, B_, h, D=B_, E=[[0.0, w], [-w, 0.0]]).Ed
    c, s = np.cos(advance), np.sin(advance)
    return np.asarray(turning @ np.array([[c, -s], [s, c]]), dtype=np.float64)
