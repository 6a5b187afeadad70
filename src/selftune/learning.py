"""Learning optimal controllers from sampled data, without the model.

Two learners, both off-policy: one batch of data (one or more :class:`Trajectory`
episodes) is reused for every policy-iteration step (Jiang & Jiang 2012).

- :func:`learn_lqr`: optimal state feedback ``u = -K x`` of ``x' = A x + B u`` with A
  and B unknown: returns K*, P* and the estimated B.
- :func:`learn_output_regulation`: adaptive optimal output regulation (Gao & Jiang 2016)
  of ``x' = A x + B u + D w, w' = E w, e = C x + F w`` with A, B, D unknown and C, E, F
  known: returns K*, P* and the feedforward (X*, U*).

Policy iteration (Kleinman) starts from a stabilizing ``K0``; at step j the data
equation (:mod:`selftune.data_equation`) is solved for ``P_j`` (the value of ``K_j``),
``K_(j+1) = R^-1 B' P_j`` and, for output regulation, ``M = (D + A X - X E)' P_j``.

Accuracy on noise-free data is set by the quadrature of the data equation: second order
in the sampling period when the input changes every sample, fourth order when it is
held over two or more samples (found in the data). On the paper's motor, 5 ms at 10 us:
``||Theta - Theta*|| / ||Theta*||`` about 3e-7, and 1e-9 to 1e-10 with a two-sample hold.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from ._validation import (
    as_matrix,
    check_weights,
)
from .data_equation import (
    IntervalMoments,
    RegressionSolution,
    interval_moments,
    regression,
    solve_regression,
)
from .errors import ConvergenceError, InputError, UnsolvableError
from .regulation import RegulatorSolution, minimize_weighted_norm
from .trajectory import Trajectory, as_trajectories
from .vectorize import unpack_theta, unvec, vec

__all__ = [
    "IterationRecord",
    "LQRLearningResult",
    "LearnedSolution",
    "estimated_B",
    "feedforward",
    "learn_lqr",
    "learn_output_regulation",
    "policy_iteration",
    "policy_step",
]

Array = NDArray[np.float64]
Method = Literal["auto", "customized", "general"]


@dataclass(frozen=True)
class IterationRecord:
    """One policy-iteration step.

    Attributes
    ----------
    iteration : int
        j, counting from 0 (``K_0`` is the initial policy).
    P : ndarray, shape (n, n)
        ``P_j``, the learned value of the policy ``K_j``.
    K : ndarray, shape (m, n)
        ``K_(j+1)``, the improved policy.
    theta : ndarray
        The solved unknowns ``[vecs(P_j); vec(K_(j+1)); vec(M_j)]``.
    change : float
        ``||P_j - P_(j-1)||_F / ||P_j||_F`` (inf at j = 0).
    regression : RegressionSolution
        Rank, residual and conditioning of the step's regression.
    """

    iteration: int
    P: Array
    K: Array
    theta: Array
    change: float
    regression: RegressionSolution = field(repr=False)


def _smallest_eigenvalue(P: Array) -> float:
    return float(np.min(np.linalg.eigvalsh(0.5 * (P + P.T))))


def _rounding_floor(solution: RegressionSolution) -> float:
    """The relative change of P that rounding alone causes in a solve of this conditioning.

    A least-squares solve is accurate to about ``condition * eps``; once P changes by no
    more than that, further steps only move it by rounding, and the iteration has
    converged as far as the data allow.
    """
    return 100.0 * float(np.finfo(float).eps) * solution.condition


def policy_iteration(
    moments: IntervalMoments,
    K0: Array,
    Q: Array,
    R: Array,
    *,
    X: Array | None = None,
    exogenous: bool = True,
    max_iterations: int = 50,
    tolerance: float = 1e-9,
    allow_deficient: Sequence[str] = (),
) -> tuple[list[IterationRecord], bool]:
    """Off-policy policy iteration on precomputed data moments.

    Parameters
    ----------
    moments : IntervalMoments
        The data, reused for every step.
    K0 : ndarray, shape (m, n)
        Initial stabilizing policy.
    Q, R : ndarray
        Cost weights.
    X : ndarray, shape (n, q), optional
        ``xbar = x - X w``.
    exogenous : bool
        Learn the M block too.
    max_iterations : int
        Upper bound on the number of steps.
    tolerance : float
        Stop when the relative change of P is at most this (or at most the rounding
        floor ``100 eps cond`` of the regression, when that is larger).
    allow_deficient : sequence of str
        Blocks allowed to lack rank (see :func:`solve_regression`).

    Returns
    -------
    history : list of IterationRecord
    converged : bool

    Raises
    ------
    ExcitationError
        If the data do not determine the unknowns.
    ConvergenceError
        If a learned ``P_j`` is not positive definite.
    """
    K = K0
    history: list[IterationRecord] = []
    for iteration in range(max_iterations):
        record = policy_step(
            moments,
            K,
            Q,
            R,
            X=X,
            exogenous=exogenous,
            allow_deficient=allow_deficient,
            iteration=iteration,
            previous=history[-1].P if history else None,
        )
        history.append(record)
        if record.change <= max(tolerance, _rounding_floor(record.regression)):
            return history, True
        K = record.K
    return history, False


def policy_step(
    moments: IntervalMoments,
    K: Array,
    Q: Array,
    R: Array,
    *,
    X: Array | None = None,
    exogenous: bool = True,
    allow_deficient: Sequence[str] = (),
    known: Mapping[str, Array] | None = None,
    iteration: int = 0,
    previous: Array | None = None,
) -> IterationRecord:
    """One policy-iteration step: evaluate ``K`` (= K_j) on the data, improve it.

    Parameters are those of :func:`policy_iteration`, plus ``known`` (blocks of Theta
    already learned, see :func:`~selftune.data_equation.solve_regression`), the step's
    number and the previous ``P`` (for the recorded change).

    Raises
    ------
    ExcitationError
        If the data do not determine the unknowns.
    ConvergenceError
        If the learned ``P_j`` is not positive definite.
    """
    n, m = moments.n, moments.m
    q = moments.q if exogenous else 0
    solution = solve_regression(
        regression(moments, K, Q, R, X, exogenous=exogenous),
        allow_deficient=allow_deficient,
        known=known,
    )
    P, K_next, _ = unpack_theta(solution.theta, n, m, q)
    smallest = _smallest_eigenvalue(P)
    if smallest <= 0.0:
        raise ConvergenceError(
            f"policy iteration step {iteration}: the learned P is not positive definite "
            f"(smallest eigenvalue {smallest:.3g}); K0 may not stabilize the plant, or the "
            "data are too noisy or too short"
        )
    change = (
        float("inf")
        if previous is None
        else float(np.linalg.norm(P - previous)) / float(np.linalg.norm(P))
    )
    return IterationRecord(
        iteration=iteration,
        P=P,
        K=K_next,
        theta=solution.theta,
        change=change,
        regression=solution,
    )


def _not_converged(history: list[IterationRecord], tolerance: float) -> ConvergenceError:
    return ConvergenceError(
        f"policy iteration did not converge in {len(history)} steps: the last relative change "
        f"of P was {history[-1].change:.3g} > tolerance {tolerance:.3g}; allow more iterations, "
        "or loosen the tolerance if the data are noisy"
    )


def _check_settings(max_iterations: int, tolerance: float) -> None:
    if isinstance(max_iterations, bool) or not isinstance(max_iterations, int | np.integer):
        raise InputError(f"max_iterations: must be a whole number, got {max_iterations!r}")
    if max_iterations < 1:
        raise InputError(f"max_iterations: must be at least 1, got {max_iterations}")
    if not (np.isfinite(tolerance) and tolerance > 0):
        raise InputError(f"tolerance: must be a positive number, got {tolerance!r}")


def estimated_B(P: Array, K: Array, R: Array) -> Array:
    """``B = (R K_(j+1) P_j^-1)'`` from ``K_(j+1) = R^-1 B' P_j``."""
    return np.asarray(np.linalg.solve(P, (R @ K).T), dtype=np.float64)


class _PolicyIterationFacts:
    """``iterations``, ``rank``, ``unknowns`` and ``rows`` read off a policy-iteration history."""

    history: tuple[IterationRecord, ...]

    @property
    def iterations(self) -> int:
        """Number of policy-iteration steps."""
        return len(self.history)

    @property
    def rank(self) -> int:
        """Rank of the last policy-iteration regression."""
        return self.history[-1].regression.rank

    @property
    def unknowns(self) -> int:
        """Number of unknowns of each policy-iteration regression."""
        return self.history[-1].regression.unknowns

    @property
    def rows(self) -> int:
        """Number of regression rows (intervals)."""
        return self.history[-1].regression.rows


@dataclass(frozen=True)
class LQRLearningResult(_PolicyIterationFacts):
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
    _check_settings(max_iterations, tolerance)
    if any(episode.w is not None and np.any(episode.w) for episode in episodes):
        raise InputError(
            "the data carry a non-zero exogenous signal w, which learn_lqr would ignore; "
            "use learn_output_regulation"
        )
    stripped = [Trajectory(t=e.t, x=e.x, u=e.u) for e in episodes]
    moments = interval_moments(stripped, interval)
    history, converged = policy_iteration(
        moments, K0, Q, R, exogenous=False, max_iterations=max_iterations, tolerance=tolerance
    )
    if not converged:
        raise _not_converged(history, tolerance)
    last = history[-1]
    return LQRLearningResult(
        K=last.K,
        P=last.P,
        B=estimated_B(last.P, last.K, R),
        history=tuple(history),
        converged=converged,
    )


@dataclass(frozen=True)
class LearnedSolution(RegulatorSolution, _PolicyIterationFacts):
    """An optimal output regulator learned from data.

    The attributes of :class:`~selftune.regulation.RegulatorSolution` (K, P, X, U, the
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

    Raises
    ------
    UnsolvableError
        If ``C X + F = 0`` has no solution.
    """
    n = C.shape[1]
    q = F.shape[1]
    N = np.kron(np.eye(q), C)
    particular = np.linalg.lstsq(N, -vec(F), rcond=None)[0]
    if np.linalg.norm(N @ particular + vec(F)) > 1e-10 * max(1.0, float(np.linalg.norm(F))):
        raise UnsolvableError(
            "C X + F = 0 has no solution: some column of F is not in the range of C"
        )
    basis = scipy.linalg.null_space(N, rcond=1e-12)
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
    _check_settings(max_iterations, tolerance)
    if method not in ("auto", "customized", "general"):
        raise InputError(f"method: must be 'auto', 'customized' or 'general', got {method!r}")
    held = not np.any(E)
    moments = interval_moments(episodes, interval, held=held)
    X_particular, null_basis = solutions_of_output_equation(C, F)
    if method == "auto":
        method = "general" if null_basis else "customized"
    if method == "customized" and null_basis:
        raise InputError(
            "method 'customized' needs a unique X from C X + F = 0 (C of full column rank); "
            f"here the solutions form a space of dimension {len(null_basis)}: use 'general'"
        )
    weight_X = Q if _smallest_eigenvalue(Q) > 0 else np.eye(n)
    weight_U = R
    if method == "customized":
        X = X_particular
        history, converged = policy_iteration(
            moments, K0, Q, R, X=X, max_iterations=max_iterations, tolerance=tolerance
        )
        if not converged:
            raise _not_converged(history, tolerance)
        last = history[-1]
        P, K, M = unpack_theta(last.theta, n, m, q)
        B = estimated_B(P, K, R)
        U = feedforward(P, K, M, R, weight_U)
        return LearnedSolution(
            K=K,
            P=P,
            X=X,
            U=U,
            exogenous_block=M,
            B=B,
            method=method,
            history=tuple(history),
            converged=True,
        )
    # General (Gao & Jiang 2016): policy iteration with X_0 = 0, i.e. xbar = x.
    history, converged = policy_iteration(
        moments, K0, Q, R, max_iterations=max_iterations, tolerance=tolerance
    )
    if not converged:
        raise _not_converged(history, tolerance)
    last = history[-1]
    P, K, M0 = unpack_theta(last.theta, n, m, q)
    B = estimated_B(P, K, R)
    D = np.linalg.solve(P, M0.T)
    policy = history[-2].K if len(history) > 1 else K0  # K_j that the last step evaluated
    sylvester: list[Array] = []
    solves: list[RegressionSolution] = []
    for X_i in [X_particular, *null_basis]:
        solution = solve_regression(regression(moments, policy, Q, R, X_i))
        P_i, _, M_i = unpack_theta(solution.theta, n, m, q)
        sylvester.append(D - np.linalg.solve(P_i, M_i.T))  # S(X_i) = X_i E - A X_i
        solves.append(solution)
    # S(X) - B U = D with X = X_1 + sum_i alpha_i N_i; minimize Tr(X'QX + U'RU).
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
    W = scipy.linalg.block_diag(np.kron(np.eye(q), weight_X), np.kron(np.eye(q), weight_U))
    y = minimize_weighted_norm(constraint, vec(D - S_particular), W, G=directions, z0=offset)
    z = offset + directions @ y
    X = unvec(z[: n * q], n, q)
    U = unvec(z[n * q :], m, q)
    S_X = S_particular + sum(
        (alpha * S for alpha, S in zip(y[: len(S_null)], S_null, strict=True)),
        np.zeros((n, q)),
    )
    return LearnedSolution(
        K=K,
        P=P,
        X=X,
        U=U,
        exogenous_block=(D - S_X).T @ P,
        B=B,
        method=method,
        history=tuple(history),
        converged=True,
        sylvester_regressions=tuple(solves),
    )


def feedforward(P: Array, K: Array, M: Array, R: Array, weight_U: Array | None = None) -> Array:
    """The feedforward U from learned ``P_j``, ``K_(j+1)`` and ``M = (D + AX - XE)' P_j``.

    ``B = (R K P^-1)'`` and the regulator equation ``B U = -(D + A X - X E) = -P^-1 M'``
    give U (the least ``Tr(U' W U)`` one, ``W = weight_U`` or R, when B has more columns
    than rank).
    """
    B = estimated_B(P, K, R)
    drift = np.asarray(np.linalg.solve(P, M.T), dtype=np.float64)
    weight = R if weight_U is None else weight_U
    q = drift.shape[1]
    vec_U = minimize_weighted_norm(np.kron(np.eye(q), B), -vec(drift), np.kron(np.eye(q), weight))
    return unvec(vec_U, B.shape[1], q)
