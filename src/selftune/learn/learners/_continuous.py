"""Learning optimal controllers from sampled data, without the model.

Two learners, both off-policy: one batch of data (one or more :class:`Trajectory`
episodes) is reused for every policy-iteration step (Jiang & Jiang 2012).

- :func:`learn_lqr`: optimal state feedback ``u = -K x`` of ``x' = A x + B u`` with A
  and B unknown: returns K*, P* and the estimated B.
- :func:`learn_regulator`: adaptive optimal output regulation (Gao & Jiang 2016)
  of ``x' = A x + B u + D w, w' = E w, e = C x + F w`` with A, B, D unknown and C, E, F
  known: returns K*, P* and the feedforward (X*, U*) (:func:`learn_output_regulation`
  is its deprecated alias with the arguments of earlier releases).

Both take the data, the :class:`LearningProblem`, K0 and the :class:`LearningOptions`,
and return a :class:`LearnedController` (without a verdict: that is
:func:`~selftune.learn.learn_controller`'s).

Policy iteration (Kleinman, :mod:`._policy_iteration`) starts from a stabilizing ``K0``;
at step j the data equation is solved for ``P_j`` (the value of ``K_j``),
``K_(j+1) = R^-1 B' P_j`` and, for output regulation, ``M = (D + A X - X E)' P_j``.

Accuracy on noise-free data is set by the quadrature of the data equation: second order
in the sampling period when the input changes every sample, fourth order when it is
held over two or more samples (found in the data). On the paper's motor, 5 ms at 10 us:
``||Theta - Theta*|| / ||Theta*||`` about 3e-7, and 1e-9 to 1e-10 with a two-sample hold.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import Literal

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike

from ...core import (
    RANK_TOLERANCE,
    Array,
    ControlLaw,
    is_positive_definite,
    minimize_weighted_norm,
    unpack_theta,
    unvec,
    vec,
)
from ...errors import InputError, SelftuneDeprecationWarning, UnsolvableError
from .._problem import LearningOptions, LearningProblem
from .._result import Formulation, LearnedController
from ..data._trajectory import Trajectory, as_trajectories
from ._moments import IntervalMoments, WKind, interval_moments
from ._policy_iteration import (
    IterationRecord,
    estimated_B,
    feedforward,
    moments_step,
    policy_iteration,
)
from ._regression import RegressionSolution, regression, solve_regression

__all__ = [
    "learn_lqr",
    "learn_output_regulation",
    "learn_regulator",
    "lqr_from_moments",
    "regulator_from_moments",
    "solutions_of_output_equation",
]


def learn_lqr(
    data: Trajectory | Sequence[Trajectory],
    problem: LearningProblem,
    K0: ArrayLike,
    options: LearningOptions | None = None,
) -> LearnedController:
    """Learn the optimal state feedback of an unknown linear plant from data.

    Parameters
    ----------
    data : Trajectory or sequence of Trajectory
        Samples of ``x' = A x + B u`` under any input that excites it (e.g. a stabilizing
        policy plus exploration noise); several episodes may be given.
    problem : LearningProblem
        The cost weights Q, R (no regulated output: C None).
    K0 : array_like, shape (m, n)
        Stabilizing initial policy ``u = -K0 x``.
    options : LearningOptions, optional
        ``interval`` (samples per regression row), ``max_iterations`` and ``tolerance``
        (relative change of P at which iteration stops).

    Returns
    -------
    LearnedController
        The law ``u = -K x``, the learned value and B, the history; no verdict.

    Raises
    ------
    ExcitationError
        If the data do not determine the unknowns (says which block and what to change).
    ConvergenceError
        If a learned P is not positive definite or the iteration does not converge.
    InputError
        On wrong shapes or values, or if the data carry a non-zero exogenous signal.
    """
    options = LearningOptions() if options is None else options
    episodes = as_trajectories(data)
    K0_ = _checked(episodes, problem, K0)
    if any(episode.w is not None and np.any(episode.w) for episode in episodes):
        raise InputError(
            "the data carry a non-zero exogenous signal w, which learn_lqr would ignore; "
            "use learn_regulator"
        )
    stripped = [Trajectory(t=e.t, x=e.x, u=e.u) for e in episodes]
    moments = interval_moments(stripped, options.interval)
    settings = (options.max_iterations, options.tolerance)
    return lqr_from_moments(moments, (problem.Q, problem.R, K0_), settings)


def _checked(episodes: Sequence[Trajectory], problem: LearningProblem, K0: ArrayLike) -> Array:
    """K0 validated, and the data's dimensions checked against the problem's."""
    first = episodes[0]
    if (first.n, first.m) != (problem.n, problem.m):
        raise InputError(
            f"Q, R: are {problem.n}x{problem.n} and {problem.m}x{problem.m}, but the data "
            f"have n = {first.n} states and m = {first.m} inputs"
        )
    return problem.initial_policy(K0)


def lqr_from_moments(
    moments: IntervalMoments, cost: tuple[Array, Array, Array], settings: tuple[int, float]
) -> LearnedController:
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
    LearnedController
    """
    Q, R, K0 = cost
    history = policy_iteration(moments_step(moments, Q, R), K0, settings)
    last = history[-1]
    n, m = last.P.shape[0], R.shape[0]
    return LearnedController(
        law=ControlLaw.regulator(last.K, np.zeros((n, 0)), np.zeros((m, 0))),
        P=last.P,
        B=estimated_B(last.P, last.K, R),
        history=tuple(history),
    )


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


def learn_regulator(
    data: Trajectory | Sequence[Trajectory],
    problem: LearningProblem,
    K0: ArrayLike,
    options: LearningOptions | None = None,
    *,
    formulation: Formulation | Literal["auto"] = "auto",
) -> LearnedController:
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
    problem : LearningProblem
        C, E, F and the cost weights Q, R (no integral action: :func:`learn_servo`).
    K0 : array_like, shape (m, n)
        Stabilizing initial feedback.
    options : LearningOptions, optional
        ``interval`` (samples per regression row), ``max_iterations`` and ``tolerance``
        (relative change of P at which iteration stops).
    formulation : {"auto", "customized", "general"}
        ``"customized"`` (the paper's, Sec. III-A) needs a unique X from ``C X + F = 0``
        (C of full column rank) and runs one regression family with ``xbar = x - X w``.
        ``"general"`` is Gao & Jiang's algorithm: policy iteration on ``x``, then one more
        solve per element of a basis of the solutions of ``C X + F = 0`` to learn the
        Sylvester map ``S(X) = X E - A X``. ``"auto"`` picks customized when it applies.

    Returns
    -------
    LearnedController
        With ``exogenous_block``, ``formulation`` and (general) ``extra_regressions``; no
        verdict.

    Raises
    ------
    ExcitationError, ConvergenceError, UnsolvableError, InputError
    """
    options = LearningOptions() if options is None else options
    episodes = as_trajectories(data)
    K0_ = _checked(episodes, problem, K0)
    if episodes[0].q == 0:
        raise InputError(
            "the data have no exogenous signal w; output regulation needs it (use learn_lqr "
            "for plain state feedback)"
        )
    if problem.C is None or problem.E is None or problem.F is None:
        raise InputError("C: output regulation needs the regulated output (C, E, F)")
    if episodes[0].q != problem.q:
        raise InputError(
            f"F: has {problem.q} columns, but the data have {episodes[0].q} exogenous channels w"
        )
    if formulation not in ("auto", "customized", "general"):
        raise InputError(
            f"formulation: must be 'auto', 'customized' or 'general', got {formulation!r}"
        )
    w_kind: WKind = "held" if problem.held else "exosystem"
    moments = interval_moments(episodes, options.interval, w_kind=w_kind)
    return regulator_from_moments(
        moments,
        (problem.C, problem.E, problem.F),
        (problem.Q, problem.R, K0_),
        formulation,
        (options.max_iterations, options.tolerance),
    )


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
    method: Formulation | Literal["auto"] = "auto",
) -> LearnedController:
    """Deprecated: :func:`learn_regulator`, in the order every learner takes (the data, the
    problem, K0, the options). This thin alias keeps the arguments of earlier releases
    (``method`` is now ``formulation``) and warns.

    Parameters
    ----------
    data : Trajectory or sequence of Trajectory
        As :func:`learn_regulator`.
    C, E, F : array_like
        The regulated output and the exosystem.
    Q, R : array_like
        The cost weights.
    K0 : array_like, shape (m, n)
        Stabilizing initial feedback.
    interval, max_iterations, tolerance
        As :class:`LearningOptions`.
    method : {"auto", "customized", "general"}
        The formulation.

    Returns
    -------
    LearnedController
    """
    warnings.warn(
        "learn_output_regulation(data, C, E, F, Q, R, K0) is deprecated: call "
        "learn_regulator(data, LearningProblem(Q, R, C=C, E=E, F=F), K0, options)",
        SelftuneDeprecationWarning,
        stacklevel=2,
    )
    options = LearningOptions(interval=interval, max_iterations=max_iterations, tolerance=tolerance)
    problem = LearningProblem(Q, R, C=C, E=E, F=F)
    return learn_regulator(data, problem, K0, options, formulation=method)


def regulator_from_moments(
    moments: IntervalMoments,
    output: tuple[Array, Array, Array],
    cost: tuple[Array, Array, Array],
    formulation: Formulation | Literal["auto"],
    settings: tuple[int, float],
) -> LearnedController:
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
    formulation : {"auto", "customized", "general"}
        As :func:`learn_regulator`.
    settings : (int, float)
        ``(max_iterations, tolerance)``.

    Returns
    -------
    LearnedController
    """
    C, _, F = output
    Q, R, K0 = cost
    n = moments.n
    X_particular, null_basis = solutions_of_output_equation(C, F)
    if formulation == "auto":
        formulation = "general" if null_basis else "customized"
    if formulation == "customized" and null_basis:
        raise InputError(
            "formulation 'customized' needs a unique X from C X + F = 0 (C of full column rank); "
            f"here the solutions form a space of dimension {len(null_basis)}: use 'general'"
        )
    X_policy = X_particular if formulation == "customized" else None
    history = policy_iteration(moments_step(moments, Q, R, X_policy), K0, settings)
    if formulation == "customized":
        return _customized(history, X_particular, R)
    weight_X = Q if is_positive_definite(Q) else np.eye(n)
    return _general(moments, history, (K0, Q, R), (X_particular, null_basis), weight_X)


def _customized(history: list[IterationRecord], X: Array, R: Array) -> LearnedController:
    """The paper's method: the last step's Theta with the unique X gives P, K, U."""
    n, q = X.shape
    m = R.shape[0]
    P, K, M = unpack_theta(history[-1].theta, n, m, q)
    return LearnedController(
        law=ControlLaw.regulator(K, X, feedforward(P, K, M, R)),
        P=P,
        B=estimated_B(P, K, R),
        history=tuple(history),
        exogenous_block=M,
        formulation="customized",
    )


def _general(
    moments: IntervalMoments,
    history: list[IterationRecord],
    problem: tuple[Array, Array, Array],
    solutions: tuple[Array, list[Array]],
    weight_X: Array,
) -> LearnedController:
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
    return LearnedController(
        law=ControlLaw.regulator(K, X, U),
        P=P,
        B=B,
        history=tuple(history),
        exogenous_block=(D - S_X).T @ P,
        formulation="general",
        extra_regressions=tuple(solves),
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
