"""Kleinman's policy iteration, off-policy: the one loop of every ADP learner.

:func:`policy_iteration` runs a learner's step (evaluate ``K_j`` on the data, improve
it) until P settles, keeping the history and stopping at the tolerance or the rounding
floor of the step's regression; :func:`discounted_policy_iteration` runs it at each
discount of a schedule (integral action: :mod:`._servo`, :mod:`._digital`).

The continuous learners' step, :func:`policy_step`: the data equation
(:mod:`._regression`) is solved for ``P_j`` (the value of the policy ``K_j``),
``K_(j+1) = R^-1 B' P_j`` and, with an exogenous signal, ``M = (D + A X - X E)' P_j``.
One batch of data is reused for every step (Jiang & Jiang 2012). The learners of
:mod:`._continuous` and the paper's algorithms (:mod:`selftune.tuning`) are built from
it.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from ...core import (
    Array,
    minimize_weighted_norm,
    positive_finite,
    positive_integer,
    unpack_theta,
    unvec,
    vec,
)
from ...errors import ConvergenceError, InputError, PolicyIterationFailure
from ._moments import IntervalMoments
from ._regression import RegressionSolution, regression, solve_regression

__all__ = [
    "MAX_TOLERANCE",
    "IterationRecord",
    "NextDiscount",
    "PolicyIterationFacts",
    "PolicyStep",
    "Stage",
    "check_iteration_settings",
    "discounted_policy_iteration",
    "estimated_B",
    "feedforward",
    "moments_step",
    "not_converged",
    "policy_iteration",
    "policy_step",
]


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
    coordinates : ndarray, shape (n, n), optional
        ``T`` of the coordinates ``x = T x~`` the regression was solved in (None: x's
        own). P's rounding is the regression's in them, so P's changes are measured
        there (:meth:`visited`).
    """

    iteration: int
    P: Array
    K: Array
    theta: Array
    change: float
    regression: RegressionSolution = field(repr=False)
    coordinates: Array | None = field(default=None, repr=False)

    def visited(self, P: Array) -> Array:
        """``T'P T``: a value matrix in the regression's coordinates (P itself without).

        Parameters
        ----------
        P : ndarray, shape (n, n)
            A value matrix over the record's state (its own P or another step's).
        """
        T = self.coordinates
        return P if T is None else np.asarray(T.T @ P @ T, dtype=np.float64)

    @property
    def rounding(self) -> float:
        """The relative change of P (in the regression's coordinates) that rounding alone
        causes in this step's solve (:func:`_rounding_floor`)."""
        return _rounding_floor(self.regression)


#: The loosest stopping tolerance accepted (see :func:`check_iteration_settings`).
MAX_TOLERANCE = 1e-3


def _smallest_eigenvalue(P: Array) -> float:
    return float(np.min(np.linalg.eigvalsh(0.5 * (P + P.T))))


def _rounding_floor(solution: RegressionSolution) -> float:
    """The relative change of P that rounding alone causes in a solve of this conditioning.

    A least-squares solve is accurate to about ``condition * eps``; once P changes by no
    more than that, further steps only move it by rounding, and the iteration has
    converged as far as the data allow.
    """
    return 100.0 * float(np.finfo(float).eps) * solution.condition


#: One policy-iteration step, ``step(K_j, j)``: evaluate the policy ``K_j`` on the data and
#: improve it; the record's ``change`` is inf (:func:`policy_iteration` fills it in).
PolicyStep = Callable[[Array, int], IterationRecord]


def policy_iteration(
    step: PolicyStep,
    K0: Array,
    settings: tuple[int, float],
    *,
    context: str = "",
) -> list[IterationRecord]:
    """Policy iteration from ``K0`` until P settles: the loop of every learner.

    Parameters
    ----------
    step : callable
        ``step(K_j, j)`` evaluates ``K_j`` on the data and improves it (the learner's
        regression: :func:`moments_step` for the continuous data equation).
    K0 : ndarray, shape (m, n)
        Initial stabilizing policy.
    settings : (int, float)
        ``(max_iterations, tolerance)``: at most that many steps; stop when the relative
        change of P is at most the tolerance (or at most the rounding floor
        ``100 eps cond`` of the step's regression, when that is larger).
    context : str
        Put before the message when the iteration does not converge (e.g. the discount).

    Returns
    -------
    history : list of IterationRecord
        The steps, the last one converged.

    Raises
    ------
    ConvergenceError
        If the steps are used up before P settles (:func:`not_converged`), or from
        ``step``.
    """
    max_iterations, tolerance = settings
    K = K0
    history: list[IterationRecord] = []
    for iteration in range(max_iterations):
        record = step(K, iteration)
        if history:
            now, previous = record.visited(record.P), record.visited(history[-1].P)
            change = float(np.linalg.norm(now - previous)) / float(np.linalg.norm(now))
            record = replace(record, change=change)
        history.append(record)
        if record.change <= max(tolerance, record.rounding):
            return history
        K = record.K
    raise not_converged(history, tolerance, context)


@dataclass(frozen=True)
class Stage:
    """Policy iteration run to convergence at one discount of a schedule.

    Attributes
    ----------
    discount : float
        The discount the step was built with.
    steps : tuple of IterationRecord
        The steps at this discount (numbered from 0).
    evaluated : ndarray, shape (m, n)
        The last policy evaluated, ``K_j`` of the last step: ``steps[-1].P`` is its value.
    """

    discount: float
    steps: tuple[IterationRecord, ...]
    evaluated: Array


#: A discount schedule: the discount after the stages run so far (the first discount
#: after none), None when the schedule is done.
NextDiscount = Callable[[Sequence[Stage]], float | None]


def discounted_policy_iteration(
    step_at: Callable[[float], PolicyStep],
    K0: Array,
    settings: tuple[int, float],
    discounts: Sequence[float] | NextDiscount,
    *,
    unit: str | None = None,
) -> tuple[list[IterationRecord], list[Stage]]:
    """:func:`policy_iteration` at each discount of a schedule, each stage's policy
    starting the next.

    An initial policy that stabilizes the plant only for a discounted cost (with integral
    action: the integrator at the stability limit) is improved at a discount for which it
    is stabilizing, and the discount is then moved towards the undiscounted cost.

    Parameters
    ----------
    step_at : callable
        ``step_at(discount)``: the step (see :func:`policy_iteration`) at that discount.
    K0 : ndarray, shape (m, n)
        The policy the first stage starts from.
    settings : (int, float)
        ``(max_iterations, tolerance)`` at each discount.
    discounts : sequence of float or callable
        The schedule, or the rule that gives the next discount from the stages run so far
        (None: done).
    unit : str, optional
        The discount's unit: a stage that does not converge is then named by its
        discount in the message.

    Returns
    -------
    history : list of IterationRecord
        Every step of every stage.
    stages : list of Stage

    Raises
    ------
    ConvergenceError
        If a stage does not converge, or from ``step_at`` and ``discounts``.
    """
    following = _fixed(discounts) if isinstance(discounts, Sequence) else discounts
    history: list[IterationRecord] = []
    stages: list[Stage] = []
    K = K0
    gamma = following(stages)
    while gamma is not None:
        context = "" if unit is None else f"at the discount {gamma:.4g} {unit}: "
        steps = policy_iteration(step_at(gamma), K, settings, context=context)
        evaluated = steps[-2].K if len(steps) > 1 else K
        history.extend(steps)
        stages.append(Stage(gamma, tuple(steps), evaluated))
        K = steps[-1].K
        gamma = following(stages)
    return history, stages


def _fixed(schedule: Sequence[float]) -> NextDiscount:
    """The rule of a given schedule: its discounts in turn."""

    def following(stages: Sequence[Stage]) -> float | None:
        return schedule[len(stages)] if len(stages) < len(schedule) else None

    return following


def moments_step(
    moments: IntervalMoments, Q: Array, R: Array, X: Array | None = None
) -> PolicyStep:
    """The step of the continuous learners: :func:`policy_step` on these moments.

    Parameters
    ----------
    moments : IntervalMoments
        The data, reused for every step.
    Q, R : ndarray
        Cost weights.
    X : ndarray, shape (n, q), optional
        ``xbar = x - X w``.

    Returns
    -------
    callable
        ``step(K_j, j)``.
    """

    def step(K: Array, iteration: int) -> IterationRecord:
        return policy_step(moments, K, Q, R, X=X, iteration=iteration)

    return step


def policy_step(
    moments: IntervalMoments,
    K: Array,
    Q: Array,
    R: Array,
    *,
    X: Array | None = None,
    allow_deficient: Sequence[str] = (),
    known: Mapping[str, Array] | None = None,
    iteration: int = 0,
) -> IterationRecord:
    """One policy-iteration step: evaluate ``K`` (= K_j) on the data, improve it.

    Parameters
    ----------
    moments : IntervalMoments
        The data.
    K : ndarray, shape (m, n)
        The policy ``K_j`` to evaluate.
    Q, R : ndarray
        Cost weights.
    X : ndarray, shape (n, q), optional
        ``xbar = x - X w``.
    allow_deficient : sequence of str
        Blocks allowed to lack rank (see :func:`~selftune.learn.solve_regression`).
    known : mapping of str to ndarray, optional
        Blocks of Theta already learned (see :func:`~selftune.learn.solve_regression`).
    iteration : int
        The step's number j, for the record and for messages.

    Returns
    -------
    IterationRecord
        With ``change`` inf: :func:`policy_iteration` fills it in.

    Raises
    ------
    ExcitationError
        If the data do not determine the unknowns.
    ConvergenceError
        If the learned ``P_j`` is not positive definite.
    """
    n, m = moments.n, moments.m
    q = moments.q
    solution = solve_regression(
        regression(moments, K, Q, R, X),
        allow_deficient=allow_deficient,
        known=known,
    )
    P, K_next, _ = unpack_theta(solution.theta, n, m, q)
    smallest = _smallest_eigenvalue(P)
    if smallest <= 0.0:
        raise PolicyIterationFailure(
            f"policy iteration step {iteration}: the learned P is not positive definite "
            f"(smallest eigenvalue {smallest:.3g}); K0 may not stabilize the plant, or the "
            "data are too noisy or too short",
            step=iteration,
            symptom="P not positive definite",
        )
    return IterationRecord(
        iteration=iteration,
        P=P,
        K=K_next,
        theta=solution.theta,
        change=float("inf"),
        regression=solution,
    )


def not_converged(
    history: list[IterationRecord], tolerance: float, context: str = ""
) -> ConvergenceError:
    """The error to raise when policy iteration used up its steps without converging.

    Parameters
    ----------
    history : list of IterationRecord
        The policy-iteration steps taken (the last one's ``change`` is reported).
    tolerance : float
        Relative change of P at which the iteration would have stopped.
    context : str
        Put before the message (e.g. the discount).
    """
    return ConvergenceError(
        f"{context}policy iteration did not converge in {len(history)} steps: the last "
        f"relative change of P was {history[-1].change:.3g} > tolerance {tolerance:.3g}; allow "
        "more iterations, or loosen the tolerance if the data are noisy"
    )


def check_iteration_settings(max_iterations: int, tolerance: float) -> tuple[int, float]:
    """``max_iterations`` a whole number >= 1 and ``tolerance`` in (0, :data:`MAX_TOLERANCE`].

    Policy iteration converges quadratically, so once P changes by at most 1e-3 the next
    policy is exact to about the square of that; a looser tolerance would stop before the
    iteration has converged and return a policy the data do not support.

    Parameters
    ----------
    max_iterations : int
        Upper bound on policy-iteration steps.
    tolerance : float
        Relative change of P at which the iteration stops.

    Returns
    -------
    max_iterations : int
    tolerance : float
    """
    max_iterations = positive_integer(max_iterations, "max_iterations")
    tolerance = positive_finite(tolerance, "tolerance")
    if tolerance > MAX_TOLERANCE:
        raise InputError(
            f"tolerance: the relative change of P at which iteration stops must be at most "
            f"{MAX_TOLERANCE:g} (e.g. 1e-9), got {tolerance!r}"
        )
    return max_iterations, tolerance


def estimated_B(P: Array, K: Array, R: Array) -> Array:
    """``B = (R K_(j+1) P_j^-1)'`` from ``K_(j+1) = R^-1 B' P_j``.

    Parameters
    ----------
    P : ndarray, shape (n, n)
        Learned value matrix ``P_j``.
    K : ndarray, shape (m, n)
        Learned next gain ``K_(j+1)``.
    R : ndarray, shape (m, m)
        Input weight.

    Returns
    -------
    B : ndarray, shape (n, m)
    """
    return np.asarray(np.linalg.solve(P, (R @ K).T), dtype=np.float64)


class PolicyIterationFacts:
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


def feedforward(P: Array, K: Array, M: Array, R: Array, weight_U: Array | None = None) -> Array:
    """The feedforward U from learned ``P_j``, ``K_(j+1)`` and ``M = (D + AX - XE)' P_j``.

    ``B = (R K P^-1)'`` and the regulator equation ``B U = -(D + A X - X E) = -P^-1 M'``
    give U (the least ``Tr(U' W U)`` one, ``W = weight_U`` or R, when B has more columns
    than rank).

    Parameters
    ----------
    P : ndarray, shape (n, n)
        Learned value matrix ``P_j``.
    K : ndarray, shape (m, n)
        Learned next gain ``K_(j+1)``.
    M : ndarray, shape (q, n)
        Learned exogenous block ``(D + AX - XE)' P_j``.
    R : ndarray, shape (m, m)
        Input weight.
    weight_U : ndarray, shape (m, m), optional
        Weight of the least-norm U (default R).

    Returns
    -------
    U : ndarray, shape (m, q)
    """
    B = estimated_B(P, K, R)
    drift = np.asarray(np.linalg.solve(P, M.T), dtype=np.float64)
    weight = R if weight_U is None else weight_U
    q = drift.shape[1]
    vec_U = minimize_weighted_norm(np.kron(np.eye(q), B), -vec(drift), np.kron(np.eye(q), weight))
    return unvec(vec_U, B.shape[1], q)
