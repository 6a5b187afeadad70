"""Discrete Lyapunov (Stein) equations: the value of a policy, one plant or a stack.

The solves behind :func:`~selftune.core.dpolicy_value`, :func:`~selftune.core.dpolicy_values`
and the Hewer step of :func:`~selftune.core.dlqr` (:mod:`._dlinalg`): the stage weight of a
gain, the spectral radii of closed loops, and ``P = A' P A + W`` solved directly (the
Kronecker system, batched over a stack) or by the bilinear transformation where the
direct solve is ill-conditioned or large.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.linalg

from ._validation import Array

#: The discrete Lyapunov equation of fewer states than this is solved directly (the
#: Kronecker system of n^2 unknowns), of more by the bilinear transformation: scipy's
#: choice in :func:`scipy.linalg.solve_discrete_lyapunov`.
_DIRECT_SIZE = 10


def _stage_weight(K: Array, Q: Array, R: Array, N: Array) -> Array:
    """``Q - N K - K'N' + K'RK``: the stage cost of ``u = -K x`` as a quadratic form in x
    (of each gain of a stack ``(p, m, n)``)."""
    K_T = np.swapaxes(K, -1, -2)
    weight = Q - N @ K - K_T @ N.T + K_T @ R @ K
    return np.asarray(0.5 * (weight + np.swapaxes(weight, -1, -2)), dtype=np.float64)


def _spectral_radius(M: Array) -> float:
    return float(_spectral_radii(M[np.newaxis])[0]) if M.size else 0.0


def _spectral_radii(M: Array) -> Array:
    """``max |eig|`` of each matrix of a stack ``(p, n, n)``, n >= 1 (one call)."""
    return np.asarray(np.max(np.abs(np.linalg.eigvals(M)), axis=-1), dtype=np.float64)


def _kronecker_stein(closed_loops: Array, weights: Array) -> tuple[Array, bool]:
    """The direct solutions of ``P_i = A_i' P_i A_i + W_i`` for a stack ``(p, n, n)``, and
    whether scipy warned about the conditioning of any of them.

    The Kronecker system of scipy's direct discrete Lyapunov solve,
    ``(I - A_i' (x) A_i') vec(P_i) = vec(W_i)``, one batched LU solve for the stack (the
    same products and the same solver, slice by slice, as one call per matrix).
    """
    count, n = closed_loops.shape[0], closed_loops.shape[1]
    transposed = closed_loops.transpose(0, 2, 1)
    kronecker = np.einsum("pij,pkl->pikjl", transposed, transposed).reshape(count, n * n, n * n)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", scipy.linalg.LinAlgWarning)
        solution = scipy.linalg.solve(np.eye(n * n) - kronecker, weights.reshape(count, n * n, 1))
    return solution.reshape(count, n, n), bool(caught)


def _stein(closed_loop: Array, weight: Array) -> Array:
    """The solution of ``P = closed_loop' P closed_loop + weight``, symmetrized.

    The direct (Kronecker) solve is the most accurate, but scipy warns about its
    conditioning whenever P's entries span many decades (an integrator beside fast
    currents); its residual is what counts, so it is checked, and the bilinear solve is
    used when it is the better one. From :data:`_DIRECT_SIZE` states on, the bilinear
    solve is the one used (scipy's own choice).
    """

    def residual(P: Array) -> float:
        return float(np.linalg.norm(closed_loop.T @ P @ closed_loop - P + weight))

    if closed_loop.shape[0] < _DIRECT_SIZE:
        solutions, warned = _kronecker_stein(closed_loop[np.newaxis], weight[np.newaxis])
        P = solutions[0]
    else:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", scipy.linalg.LinAlgWarning)
            P = scipy.linalg.solve_discrete_lyapunov(closed_loop.T, weight, method="bilinear")
        warned = bool(caught)
    if warned:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", scipy.linalg.LinAlgWarning)
            other = scipy.linalg.solve_discrete_lyapunov(closed_loop.T, weight, method="bilinear")
        if residual(other) < residual(P):
            P = other
    return np.asarray(0.5 * (P + P.T), dtype=np.float64)


def _steins(closed_loops: Array, weights: Array) -> Array:
    """:func:`_stein` of each pair of a stack ``(p, n, n)``: one batched direct solve; if
    scipy warns about any of them (or the bilinear solve is the one used), each is solved
    by :func:`_stein`, which checks the bilinear solve where its own direct solve warns."""
    if closed_loops.shape[1] < _DIRECT_SIZE:
        solutions, warned = _kronecker_stein(closed_loops, weights)
        if not warned:
            return np.asarray(0.5 * (solutions + solutions.transpose(0, 2, 1)), dtype=np.float64)
    return np.array([_stein(A, W) for A, W in zip(closed_loops, weights, strict=True)])


def _policy_values(
    A: Array, B: Array, K: Array, Q: Array, R: Array, N: Array
) -> tuple[Array, Array]:
    """The values of ``u = -K x`` (one gain, or one per plant) on a stack of checked plants
    ``(p, n, n)``, ``(p, n, m)`` (``inf`` where it does not stabilize), and the spectral
    radii of ``A - BK``."""
    closed_loops = A - B @ K
    radii = _spectral_radii(closed_loops) if A.shape[1] else np.zeros(A.shape[0])
    stable = radii < 1.0
    P = np.full(closed_loops.shape, np.inf)
    if np.any(stable):
        weights = np.broadcast_to(_stage_weight(K, Q, R, N), closed_loops.shape)
        P[stable] = _steins(closed_loops[stable], weights[stable])
    return P, radii
