"""Learning optimal controllers from sampled data, without the model.

Two learners, both off-policy: one batch of data (one or more :class:`Trajectory`
episodes) is reused for every policy-iteration step (Jiang & Jiang 2012).

- :func:`learn_lqr`: optimal state feedback ``u = -K x`` of ``x' = A x + B u`` with A
  and B unknown: returns K*, P* and the estimated B.
- :func:`learn_output_regulation`: adaptive optimal output regulation (Gao & Jiang 2016)
  of ``x' = A x + B u + D w, w' = E w, e = C x + F w`` with A, B, D unknown and C, E, F
  known: returns K*, P* and the feedforward (X*, U*).

Policy iteration (Kleinman, :mod:`._policy_iteration`) starts from a stabilizing ``K0``;
at step j the data equation is solved for ``P_j`` (the value of ``K_j``),
``K_(j+1) = R^-1 B' P_j`` and, for output regulation, ``M = (D + A X - X E)' P_j``.

Accuracy on noise-free data is set by the quadrature of the data equation: second order
in the sampling period when the input changes every sample, fourth order when it is
held over two or more samples (found in the data). On the paper's motor, 5 ms at 10 us:
``||Theta - Theta*|| / ||Theta*||`` about 3e-7, and 1e-9 to 1e-10 with a two-sample hold.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike

from ..core import (
    RANK_TOLERANCE,
    Array,
    RegulatorSolution,
    as_matrix,
    check_weights,
    is_positive_definite,
    minimize_weighted_norm,
    unpack_theta,
    unvec,
    vec,
)
from ..errors import InputError, UnsolvableError
from ._moments import IntervalMoments, interval_moments
from ._policy_iteration import (
    IterationRecord,
    PolicyIterationFacts,
    check_iteration_settings,
    estimated_B,
    feedforward,
    moments_step,
    policy_iteration,
)
from ._regression import RegressionSolution, regression, solve_regression
from ._trajectory import Trajectory, as_trajectories

__all__ = [
    "LQRLearningResult",
    "LearnedSolution",
    "learn_lqr",
    "learn_output_regulation",
    "lqr_from_moments",
    "regulator_from_moments",
    "solutions_of_output_equation",
]

Method = Literal["auto", "customized", "general"]


@dataclass(frozen=True)
class LQRLearningResult(PolicyIterationFacts):
    """Optimal state feedback learned from data.

    Attributes
    ----------
    K : ndarray, shape (m, n)
        Learned optimal gain (``u = -K x``), the last improved policy.
    P : ndarray, shape (n, n)
        Learned value matrix (of the last evaluated policy).
    B : ndarray, shape (n, m)
        Estimated input matrix.
    history : tuple of IterationRecord
    converged : bool
    """

    K: Array
    P: Array
    B: Array
    history: tuple[IterationRecord, ...]
    converged: bool


def learn_lqr(
    data: Trajectory | Sequence[Trajectory],
    Q: ArrayLike,
    R: ArrayLike,
    K0: ArrayLike,
    *,
    interval: int = 10,
    max_iterations: int = 50,
    tolerance: float = 1e-9,
) -> LQRLearningResult:
    """Learn the optimal state feedback of an unknown linear plant from data.

    Parameters
    ----------
    data : Trajectory or sequence of Trajectory
        Samples of ``x' = A x + B u`` under any input that excites it (e.g. a stabilizing
        policy plus exploration noise); several episodes may be given.
    Q : array_like, shape (n, n)
        State weight, symmetric positive semidefinite.
    R : array_like, shape (m, m)
        Input weight, symmetric positive definite.
    K0 : array_like, shape (m, n)
        Stabilizing initial policy ``u = -K0 x``.
    interval : int
        Samples per regression interval.
    max_iterations : int
        Upper bound on policy-iteration steps.
    tolerance : float
        Relative change of P at which iteration stops.

    Returns
    -------
    LQRLearningResult

    Raises
    ------
    ExcitationError
        If the data do not determine the unknowns (says which block and what to change).
    ConvergenceError
        If a learned P is not positive definite or the iteration does not converge.
    InputError
        On wrong shapes or values, or if the data carry a non-zero exogenous signal.
    """
    episodes = as_trajectories(data)
    n, m = episodes[0].n, episodes[0].m
    Q, R = check_weights(Q, R, n, m)
    K0 = as_matrix(K0, "K0", (m, n))
    max_iterations, tolerance = check_iteration_settings(max_iterations, tolerance)
    if any(episode.w is not None and np.any(episode.w) for episode in episodes):
        raise InputError(
            "the data carry a non-zero exogenous signal w, which learn_lqr would ignore; "
            "use learn_output_regulation"
        )
    stripped = [Trajectory(t=e.t, x=e.x, u=e.u) for e in episodes]
    moments = interval_moments(stripped, interval)
    return lqr_from_moments(moments, (Q, R, K0), (max_iterations, tolerance))


def lqr_from_moments(
    moments: IntervalMoments, cost: tuple[Array, Array, Array], settings: tuple[int, float]
) -> LQRLearningResult:
    """:func:`learn_lqr` on precomputed (validated) moments, which may carry instruments.

    Parameters
    ----------
    moments : IntervalMoments
        The data (without an exogenous signal).
    cost : (Q, R, K0)
        Weights and the stabilizing initial policy.
    settings : (int, float)
        ``(max_iterations, tolerance)``.

    Returns
    -------
    LQRLearningResult
    """
    Q, R, K0 = cost
    history = policy_iteration(moments_step(moments, Q, R), K0, settings)
    last = history[-1]
    return LQRLearningResult(
        K=last.K,
        P=last.P,
        B=estimated_B(last.P, last.K, R),
        history=tuple(history),
        converged=True,
    )


@dataclass(frozen=True)
class LearnedSolution(RegulatorSolution, PolicyIterationFacts):
    """An optimal output regulator learned from data.

    The attributes of :class:`~selftune.core.RegulatorSolution` (K, P, X, U, the
    exogenous block, L, theta), as the model-based solution has them, plus the estimates
    the learner makes on the way and its history.

    Attributes
    ----------
    B : ndarray, shape (n, m)
        Estimated input matrix.
    method : str
        ``"customized"`` (one regression family with the unique X) or ``"general"``
        (Gao & Jiang 2016: a basis of the solutions of CX + F = 0 and the Sylvester map).
    history : tuple of IterationRecord
        The policy-iteration steps.
    converged : bool
    sylvester_regressions : tuple of RegressionSolution
        The general method's extra solves, one per basis element of CX + F = 0.
    """

    B: Array
    method: str
    history: tuple[IterationRecord, ...]
    converged: bool
    sylvester_regressions: tuple[RegressionSolution, ...] = ()

    @property
    def least_squares_solves(self) -> int:
        """All least-squares solves: the policy-iteration steps plus the Sylvester solves."""
        return len(self.history) + len(self.sylvester_regressions)


def solutions_of_output_equation(C: Array, F: Array) -> tuple[Array, list[Array]]:
    """A particular solution of ``C X + F = 0`` and a basis of the solutions of ``C X = 0``.

    Parameters
    ----------
    C : ndarray, shape (r, n)
        Output matrix.
    F : ndarray, shape (r, q)
        Exogenous output matrix.

    Returns
    -------
    X0 : ndarray, shape (n, q)
        A particular solution.
    basis : list of ndarray, shape (n, q)
        A basis of the solutions of ``C X = 0``.

    Raises
    ------
    UnsolvableError
        If ``C X + F = 0`` has no solution.
    """
    n = C.shape[1]
    q = F.shape[1]
    N = np.kron(np.eye(q), C)
    particular = np.linalg.lstsq(N, -vec(F), rcond=None)[0]
    if np.linalg.norm(N @ particular + vec(F)) > RANK_TOLERANCE * max(
        1.0, float(np.linalg.norm(F))
    ):
        raise UnsolvableError(
            "C X + F = 0 has no solution: some column of F is not in the range of C"
        )
    basis = scipy.linalg.null_space(N, rcond=RANK_TOLERANCE)
    return unvec(particular, n, q), [unvec(basis[:, i], n, q) for i in range(basis.shape[1])]


def learn_output_regulation(
    data: Trajectory | Sequence[Trajectory],
    C: ArrayLike,
    E: ArrayLike,
    F: ArrayLike,
    Q: ArrayLike,
    R: ArrayLike,
    K0: ArrayLike,
    *,
    interval: int = 10,
    max_iterations: int = 50,
    tolerance: float = 1e-9,
    method: Method = "auto",
) -> LearnedSolution:
    """Learn the optimal output regulator of an unknown plant from data (Gao & Jiang 2016).

    The plant ``x' = A x + B u + D w`` has A, B, D unknown; the exosystem ``w' = E w`` and
    the output ``e = C x + F w`` are known. The learner returns K*, P* and the feedforward
    (X*, U*) with ``u = -K*(x - X* w) + U* w``; when the regulator equations have many
    solutions (m > r), (X*, U*) minimizes ``Tr(X'QX + U'RU)`` (Remark 2, with the cost
    weights; Q must then be positive definite).

    Parameters
    ----------
    data : Trajectory or sequence of Trajectory
        Samples with ``w``. With ``E = 0``, ``w`` is held over each sample (a digital
        reference); with ``E != 0``, ``w`` is the exosystem state at every sample time.
        The data must excite the exogenous block: a constant ``w`` does not (perturb it).
    C : array_like, shape (r, n)
    E : array_like, shape (q, q)
    F : array_like, shape (r, q)
    Q : array_like, shape (n, n)
        State weight, symmetric positive semidefinite.
    R : array_like, shape (m, m)
        Input weight, symmetric positive definite.
    K0 : array_like, shape (m, n)
        Stabilizing initial feedback.
    interval : int
        Samples per regression interval.
    max_iterations : int
    tolerance : float
        Relative change of P at which iteration stops.
    method : {"auto", "customized", "general"}
        ``"customized"`` (the paper's, Sec. III-A) needs a unique X from ``C X + F = 0``
        (C of full column rank) and runs one regression family with ``xbar = x - X w``.
        ``"general"`` is Gao & Jiang's algorithm: policy iteration on ``x``, then one more
        solve per element of a basis of the solutions of ``C X + F = 0`` to learn the
        Sylvester map ``S(X) = X E - A X``. ``"auto"`` picks customized when it applies.

    Returns
    -------
    LearnedSolution

    Raises
    ------
    ExcitationError, ConvergenceError, UnsolvableError, InputError
    """
    episodes = as_trajectories(data)
    first = episodes[0]
    n, m, q = first.n, first.m, first.q
    if q == 0:
        raise InputError(
            "the data have no exogenous signal w; output regulation needs it (use learn_lqr "
            "for plain state feedback)"
        )
    C = as_matrix(C, "C", (None, n))
    r = C.shape[0]
    E = as_matrix(E, "E", (q, q))
    F = as_matrix(F, "F", (r, q))
    Q, R = check_weights(Q, R, n, m)
    K0 = as_matrix(K0, "K0", (m, n))
    max_iterations, tolerance = check_iteration_settings(max_iterations, tolerance)
    if method not in ("auto", "customized", "general"):
        raise InputError(f"method: must be 'auto', 'customized' or 'general', got {method!r}")
    moments = interval_moments(episodes, interval, w_kind="exosystem" if np.any(E) else "held")
    return regulator_from_moments(
        moments, (C, E, F), (Q, R, K0), method, (max_iterations, tolerance)
    )


def regulator_from_moments(
    moments: IntervalMoments,
    output: tuple[Array, Array, Array],
    cost: tuple[Array, Array, Array],
    method: Method,
    settings: tuple[int, float],
) -> LearnedSolution:
    """:func:`learn_output_regulation` on precomputed (validated) moments, which may carry
    instruments.

    Parameters
    ----------
    moments : IntervalMoments
        The data.
    output : (C, E, F)
        Regulated output and exosystem.
    cost : (Q, R, K0)
        Weights and the stabilizing initial policy.
    method : {"auto", "customized", "general"}
        As :func:`learn_output_regulation`.
    settings : (int, float)
        ``(max_iterations, tolerance)``.

    Returns
    -------
    LearnedSolution
    """
    C, _, F = output
    Q, R, K0 = cost
    n = moments.n
    X_particular, null_basis = solutions_of_output_equation(C, F)
    if method == "auto":
        method = "general" if null_basis else "customized"
    if method == "customized" and null_basis:
        raise InputError(
            "method 'customized' needs a unique X from C X + F = 0 (C of full column rank); "
            f"here the solutions form a space of dimension {len(null_basis)}: use 'general'"
        )
    X_policy = X_particular if method == "customized" else None
    history = policy_iteration(moments_step(moments, Q, R, X_policy), K0, settings)
    if method == "customized":
        return _customized(history, X_particular, R)
    weight_X = Q if is_positive_definite(Q) else np.eye(n)
    return _general(moments, history, (K0, Q, R), (X_particular, null_basis), weight_X)


def _customized(history: list[IterationRecord], X: Array, R: Array) -> LearnedSolution:
    """The paper's method: the last step's Theta with the unique X gives P, K, U."""
    n, q = X.shape
    m = R.shape[0]
    P, K, M = unpack_theta(history[-1].theta, n, m, q)
    return LearnedSolution(
        K=K,
        P=P,
        X=X,
        U=feedforward(P, K, M, R),
        exogenous_block=M,
        B=estimated_B(P, K, R),
        method="customized",
        history=tuple(history),
        converged=True,
    )


def _general(
    moments: IntervalMoments,
    history: list[IterationRecord],
    problem: tuple[Array, Array, Array],
    solutions: tuple[Array, list[Array]],
    weight_X: Array,
) -> LearnedSolution:
    """Gao & Jiang (2016): policy iteration on x (X_0 = 0), then the Sylvester map
    ``S(X) = X E - A X`` on a particular solution and a basis of ``C X = 0``, then the
    (X, U) of least ``Tr(X' W_X X + U' R U)`` subject to ``S(X) - B U = D``.

    ``problem`` is ``(K0, Q, R)``.
    """
    n, m, q = moments.n, moments.m, moments.q
    X_particular, null_basis = solutions
    K0, Q, R = problem
    P, K, M0 = unpack_theta(history[-1].theta, n, m, q)
    B = estimated_B(P, K, R)
    D = np.asarray(np.linalg.solve(P, M0.T), dtype=np.float64)
    policy = history[-2].K if len(history) > 1 else K0  # K_j that the last step evaluated
    sylvester: list[Array] = []
    solves: list[RegressionSolution] = []
    for X_i in [X_particular, *null_basis]:
        solution = solve_regression(regression(moments, policy, Q, R, X_i))
        P_i, _, M_i = unpack_theta(solution.theta, n, m, q)
        sylvester.append(D - np.linalg.solve(P_i, M_i.T))  # S(X_i) = X_i E - A X_i
        solves.append(solution)
    X, U, S_X = _min_trace_pair(B, D, (X_particular, null_basis), sylvester, (weight_X, R))
    return LearnedSolution(
        K=K,
        P=P,
        X=X,
        U=U,
        exogenous_block=(D - S_X).T @ P,
        B=B,
        method="general",
        history=tuple(history),
        converged=True,
        sylvester_regressions=tuple(solves),
    )


def _min_trace_pair(
    B: Array,
    D: Array,
    solutions: tuple[Array, list[Array]],
    sylvester: list[Array],
    weights: tuple[Array, Array],
) -> tuple[Array, Array, Array]:
    """``S(X) - B U = D`` with ``X = X_1 + sum_i alpha_i N_i``; the (X, U) of least
    ``Tr(X' W_X X + U' W_U U)`` (Remark 2), and ``S(X)``."""
    n, m = B.shape
    q = D.shape[1]
    X_particular, null_basis = solutions
    S_particular, S_null = sylvester[0], sylvester[1:]
    constraint = np.hstack(
        [
            np.column_stack([vec(S) for S in S_null]) if S_null else np.zeros((n * q, 0)),
            -np.kron(np.eye(q), B),
        ]
    )
    directions = np.zeros((n * q + m * q, len(S_null) + m * q))
    for index, N_i in enumerate(null_basis):
        directions[: n * q, index] = vec(N_i)
    directions[n * q :, len(S_null) :] = np.eye(m * q)
    offset = np.concatenate([vec(X_particular), np.zeros(m * q)])
    W = scipy.linalg.block_diag(np.kron(np.eye(q), weights[0]), np.kron(np.eye(q), weights[1]))
    y = minimize_weighted_norm(constraint, vec(D - S_particular), W, G=directions, z0=offset)
    z = offset + directions @ y
    S_X = S_particular + sum(
        (alpha * S for alpha, S in zip(y[: len(S_null)], S_null, strict=True)),
        np.zeros((n, q)),
    )
    return unvec(z[: n * q], n, q), unvec(z[n * q :], m, q), S_X
