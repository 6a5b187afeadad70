"""The optimal servo controller (integral action) learned by continuous-time ADP.

The plant ``x' = A x + B u + D w`` (A, B, D unknown), with ``w`` held over each sample
(E = 0) or the exosystem state ``w' = E w``, and the regulated error ``e = C x + F w``
with ``C X + F = 0`` for a unique X (C of full column rank). Integral action augments the
state with ``z``, the integral of ``e``; since ``C X + F = 0``, ``e = C xbar``::

    xi = [xbar; z],   xbar = x - X w,   z' = C xbar
    xi' = A_a xi + B_a u + G w,   A_a = [[A, 0], [C, 0]],   B_a = [B; 0],
                                  G = [D + A X - X E; 0]

(with a held ``w``, inside each sample: ``xbar`` jumps where ``w`` steps, ``z`` does
not). The optimal servo controller minimizes ``int xbar'Q xbar + z'Q_i z + ubar'R ubar``:
``u = U w - K xbar - K_i z`` with ``[K, K_i]`` the LQR gain of ``(A_a, B_a)`` for
``Q_a = diag(Q, Q_i)`` and R, and U from the regulator equations ``A X + B U + D = X E``.
The drive runs the integrator at its sampling period (:class:`~selftune.core.ControlLaw`).

**The discounted data equation.** For a discount rate ``gamma >= 0`` (1/s) and a policy
``u = -K_j xi`` with ``A_a - B_a K_j - gamma/2 I`` Hurwitz, the value ``P_j`` of
``int_0^inf e^(-gamma t) (xi'Q_a xi + u'R u) dt`` solves::

    (A_a - B_a K_j)'P_j + P_j (A_a - B_a K_j) - gamma P_j + Q_a + K_j'R K_j = 0

and ``K_(j+1) = R^-1 B_a'P_j``. Along ANY applied input,
``d/ds [e^(-gamma (s-t)) xi'P_j xi] = e^(-gamma (s-t)) [-gamma xi'P_j xi + 2 xi'P_j
(A_a xi + B_a u + G w)]``; the Lyapunov equation turns ``2 xi'P_j A_a xi - gamma
xi'P_j xi`` into ``-xi'(Q_a + K_j'R K_j) xi + 2 xi'P_j B_a K_j xi``, and
``B_a'P_j = R K_(j+1)``, so over any ``[t, t + T]``::

    e^(-gamma T) xi'P_j xi (t+T) - xi'P_j xi (t)
        = int_t^(t+T) e^(-gamma (s-t)) [ -xi'(Q_a + K_j'R K_j) xi
                                         + 2 (u + K_j xi)' R K_(j+1) xi + 2 w'M xi ] ds,
    M = G'P_j = (D + A X - X E)' [rows 1..n of P_j]          (q x (n + r))

This is the data equation of :mod:`._moments` for the state ``[x; z]`` with
``X_a = [X; 0]`` (so ``xi = [x; z] - X_a w``), ``Q_a`` and ``K_j`` over ``xi``, with the
moments weighted by the discount: :func:`~selftune.learn.regression` is unchanged. Its
unknowns ``Theta = [vecs(P_j); vec(K_(j+1)); vec(M)]`` number
``(n+r)(n+r+1)/2 + m (n+r) + q (n+r)`` (26 for the motor). ``z`` is not logged: the
moments compute it from the data (:func:`~selftune.learn.interval_moments`, ``integrator``).
The feedforward follows as without integral action, from the plant's columns: the
integrator's rows of ``B_a`` and G are zero, so ``P_j B_a = (R K_(j+1))'`` and
``P_j G = M'`` give ``B = P_xx^-1 (R K_x)'`` and ``G_x = P_xx^-1 M_x'`` from the x columns
of ``K_(j+1)`` and M alone (the best determined: see Accuracy), and ``B U = -G_x``.

**The schedule.** The initial policy ``[K0, 0]`` leaves the integrator's r eigenvalues at
0: it is stabilizing for every ``gamma > 0`` but not for ``gamma = 0``. Policy iteration
runs to convergence at each discount of a decreasing schedule, each discount's policy
starting the next, and the last discount is exactly 0: the undiscounted moments, the
same quadrature as the learner without integral action. The next discount is read off
what was learned (a continuous-time counterpart of Lamperski 2020). With ``P_j`` the
value of ``K_j`` at ``gamma`` and ``A_(j+1) = A_a - B_a K_(j+1)``::

    (A_(j+1) - gamma/2 I)'P_j + P_j (A_(j+1) - gamma/2 I) = -W,
    W = Q_a + K_(j+1)'R K_(j+1) + (K_(j+1) - K_j)'R (K_(j+1) - K_j)

so with ``mu`` the smallest eigenvalue of ``P_j^-1 W`` (the decay rate ``xi'P_j xi``
certifies), ``A_(j+1) - gamma'/2 I`` is Hurwitz for every ``gamma' > gamma - mu``. The
next discount is ``gamma - mu / 2`` (half the certified step: a margin for the errors of
the learned P, quadrature and noise), or 0 once that is not positive. The first discount
is a tenth (:data:`FIRST_DISCOUNT`) of the ``mu`` of K0 on the plant alone
(``W = Q + K0'R K0``, P the value of K0, learned once from the undiscounted moments
without the integrator), the rate the data's own loop decays at: well below it the
integrator's cost dominates the value of ``[K0, 0]`` (``P_zz = Q_i / gamma``), so the
first improvement is large against the quadrature error of the learned values (at the
rate itself it was not, for motors of high inductance, and the value then seemed to rise
in the first step). Where W is singular (a semidefinite Q) ``mu`` is 0 and
certifies nothing; ``tr(W) / tr(P)``, a rate of the same scale, takes its place, and the
positive definiteness of each learned P (:func:`~selftune.learn.policy_step`) is then
the only check.

The discounted moments integrate the weight exactly against the same interpolants as the
undiscounted ones (:mod:`._moments`), so every step carries the same quadrature error; the
discounted steps only need to hand a stabilizing policy to the next discount, and the
result is that of the last, undiscounted, step.

**Accuracy.** On noise-free data the error is that of the quadrature (second order in
the sampling period h; none when the state is linear inside each sample, A = 0),
amplified by the regression's conditioning, which the integrator makes worse than
without it: ``z`` is slow, so exploration that changes every sample correlates weakly
with it, and ``K_i`` (the z columns of ``K_(j+1)``) is the least determined block. On the
paper's motor at 10 us, 30 ms of data under a 10 V PRBS held 0.2 ms give ``[K, K_i]``
within 1.1e-6 of the servo optimum and U within 4e-6 (6e-8 for K without integral
action), falling as h^2; under the paper's white 1 V exploration over 20 ms, 3e-4.
Low-frequency exploration (a PRBS with holds), a larger exploration against the
operating point and longer data help. Against measurement noise, learn from the
output-error model's smoothed states (``noise = "smoothed"``, the default): with 0.1 mA
of noise on the same 30 ms it is 8e-5 off, while the instrumental-variable estimate
(``"instruments"``), noisy already without the integrator, is refused by the verdict
(standard error of K 90%).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from itertools import pairwise

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike

from ...core import (
    Array,
    ControlLaw,
    finite_float,
    theta_sizes,
    unpack_theta,
)
from ...errors import ConvergenceError, InputError, TooShort
from .._problem import LearningOptions, LearningProblem, padded_policy
from .._result import DiscountStage, LearnedController
from ..data._trajectory import Trajectory, as_trajectories
from ..evidence._alignment import sampling_period
from ._continuous import solutions_of_output_equation
from ._moments import IntervalMoments, WKind, interval_moments
from ._policy_iteration import (
    NextDiscount,
    PolicyStep,
    Stage,
    discounted_policy_iteration,
    estimated_B,
    feedforward,
    moments_step,
    policy_step,
)

__all__ = [
    "DISCOUNT_STEP",
    "FIRST_DISCOUNT",
    "MAX_DISCOUNTS",
    "DiscountStage",
    "learn_servo",
    "servo_from_moments",
]

#: The fraction of the certified decrease of the discount taken at each stage.
DISCOUNT_STEP = 0.5

#: The first discount as a fraction of the decay rate K0 certifies on the plant alone.
FIRST_DISCOUNT = 0.1

#: The most discounts a schedule may run through before it must have reached 0.
MAX_DISCOUNTS = 60


MomentsAt = Callable[[float], IntervalMoments]


def learn_servo(
    data: Trajectory | Sequence[Trajectory],
    problem: LearningProblem,
    K0: ArrayLike,
    options: LearningOptions | None = None,
    *,
    discounts: Sequence[float] | None = None,
) -> LearnedController:
    """Learn the optimal servo controller of an unknown plant from data.

    Parameters
    ----------
    data : Trajectory or sequence of Trajectory
        Samples with ``w`` (held over each sample when E = 0, the exosystem state at every
        sample time otherwise), the applied input in row k, uniformly sampled (the drive
        runs the integrator at that period).
    problem : LearningProblem
        Regulated output ``e = C x + F w`` (C: r x n of full column rank), exosystem E,
        the weights Q, R and, with ``integral_action``, ``Q_i`` (the weight of z).
    K0 : array_like, shape (m, n) or (m, n + r)
        The stabilizing feedback the data start from (on ``xbar``; zeros on ``z`` when
        only m x n is given).
    options : LearningOptions, optional
        ``interval`` (samples per regression row), ``max_iterations`` and ``tolerance``
        of the policy iteration at each discount.
    discounts : sequence of float, optional
        The schedule (1/s, decreasing, each >= 0); by default chosen from the data (see
        the module docstring). A schedule that does not end with 0 learns the discounted
        optimum of its last discount.

    Returns
    -------
    LearnedController
        With ``stages`` (the schedule) and ``exogenous_block``; no verdict.

    Raises
    ------
    ExcitationError, ConvergenceError, InputError
    """
    options = LearningOptions() if options is None else options
    episodes = as_trajectories(data)
    if problem.C is None or problem.E is None or problem.F is None:
        raise InputError("C: the servo controller needs the regulated output (C, E, F)")
    if problem.integral_weight is None:
        raise InputError("integral_action: learn_servo learns integral action; set it on")
    C, E, F = problem.C, problem.E, problem.F
    K0_ = problem.initial_policy(K0, extra=problem.r)
    settings = (options.max_iterations, options.tolerance)
    w_kind: WKind = "exosystem" if np.any(E) else "held"

    def moments_at(discount: float) -> IntervalMoments:
        return interval_moments(
            episodes, options.interval, w_kind=w_kind, integrator=(C, F), discount=discount
        )

    cost = (problem.Q, problem.R, problem.integral_weight, K0_)
    h = sampling_period(episodes)
    return servo_from_moments(moments_at, (C, E, F), cost, settings, h, discounts)


def servo_from_moments(
    moments_at: MomentsAt,
    output: tuple[Array, Array, Array],
    cost: tuple[Array, Array, Array, Array],
    settings: tuple[int, float],
    h: float,
    discounts: Sequence[float] | None = None,
) -> LearnedController:
    """:func:`learn_servo` on moments computed once per discount (validated inputs).

    Parameters
    ----------
    moments_at : callable
        ``moments_at(gamma)``: the moments of the data with integral action
        (``interval_moments(..., integrator=(C, F), discount=gamma)``, instruments
        attached if any); called once per discount of the schedule, 0 first.
    output : (C, E, F)
        Regulated output and exosystem.
    cost : (Q, R, Q_i, K0)
        Weights and the stabilizing initial policy (m x n, or m x (n + r)).
    settings : (int, float)
        ``(max_iterations, tolerance)`` of the policy iteration at each discount.
    h : float
        The sampling period the drive runs the integrator at, s.
    discounts : sequence of float, optional
        The schedule; by default chosen from the data (see the module docstring).

    Returns
    -------
    LearnedController

    Raises
    ------
    ExcitationError
        If the data do not determine the unknowns (the message names the block).
    ConvergenceError
        If a learned P is not positive definite, policy iteration does not converge at a
        discount, or the schedule does not reach 0 in :data:`MAX_DISCOUNTS` discounts.
    InputError
        If C is not of full column rank (X not unique) or the schedule is not valid.
    """
    C, _, F = output
    Q, R, Q_i, K0 = cost
    X, null_basis = solutions_of_output_equation(C, F)
    if null_basis:
        raise InputError(
            "C: the continuous ADP learner with integral action needs a unique X from "
            "C X + F = 0 (C of full column rank); use method = 'identify' for this problem"
        )
    undiscounted = moments_at(0.0)
    n, m, q, r = undiscounted.n - C.shape[0], undiscounted.m, undiscounted.q, C.shape[0]
    if undiscounted.r != r:
        raise InputError(f"moments_at: the moments carry {undiscounted.r} integrator states, C {r}")
    unknowns = sum(theta_sizes(n + r, m, q))
    if undiscounted.intervals < unknowns:
        raise TooShort(
            f"only {undiscounted.intervals} regression intervals for the {unknowns} unknowns of "
            f"the servo controller (integral action adds {r} states to the {n} of the plant): "
            f"use longer data or a shorter interval (at least {unknowns} intervals are needed)",
            samples=undiscounted.intervals,
            samples_needed=unknowns,
        )
    Q_a = scipy.linalg.block_diag(Q, Q_i)
    X_a = np.vstack([X, np.zeros((r, q))])
    K = padded_policy(K0, n, n + r)

    def step_at(gamma: float) -> PolicyStep:
        moments = undiscounted if gamma == 0.0 else moments_at(gamma)
        return moments_step(moments, Q_a, R, X_a)

    def rate(stage: Stage) -> float:
        return _stage_rate(stage, Q_a, R)

    def adaptive(stages: Sequence[Stage]) -> float | None:
        if not stages:
            return _first_discount(undiscounted, K[:, :n], Q, R, X)
        return _next_discount(stages[-1].discount, rate(stages[-1]), len(stages))

    schedule: Sequence[float] | NextDiscount = _checked_schedule(discounts) or adaptive
    history, runs = discounted_policy_iteration(step_at, K, settings, schedule, unit="1/s")
    stages = [
        DiscountStage(run.discount, run.steps[-1].K, run.steps[-1].P, len(run.steps), rate(run))
        for run in runs
    ]
    P, K, M = unpack_theta(history[-1].theta, n + r, m, q)
    # B_a and G have zero integrator rows, so P B_a = (R K)' and P G = M' give B and
    # G_x = D + A X - X E from the plant's columns alone (the best-determined ones)
    P_x, K_x, M_x = P[:n, :n], K[:, :n], M[:, :n]
    U = feedforward(P_x, K_x, M_x, R)
    return LearnedController(
        law=ControlLaw(K_x, X, U, K_i=K[:, n:], C=C, F=F, h=h),
        P=P,
        B=estimated_B(P_x, K_x, R),
        history=tuple(history),
        h=h,
        exogenous_block=M,
        stages=tuple(stages),
    )


def _checked_schedule(discounts: Sequence[float] | None) -> tuple[float, ...]:
    """A given schedule: decreasing rates >= 0 (empty: chosen from the data)."""
    if discounts is None:
        return ()
    schedule = tuple(finite_float(value, "discounts") for value in discounts)
    if not schedule or any(value < 0.0 for value in schedule):
        raise InputError(f"discounts: must be rates >= 0 (1/s), got {list(discounts)!r}")
    if any(later >= earlier for earlier, later in pairwise(schedule)):
        raise InputError(f"discounts: must decrease, got {list(schedule)!r}")
    return schedule


def _stage_rate(stage: Stage, Q_a: Array, R: Array) -> float:
    """:func:`_decay_rate` of a converged stage: ``P = P_j``, ``K = K_(j+1)`` and
    ``W = Q_a + K'R K + (K - K_j)'R (K - K_j)`` (see the module docstring)."""
    K, P = stage.steps[-1].K, stage.steps[-1].P
    change = K - stage.evaluated
    return _decay_rate(P, Q_a + K.T @ R @ K + change.T @ R @ change)


def _decay_rate(P: Array, W: Array) -> float:
    """``mu``, the smallest eigenvalue of ``P^-1 W``, 1/s; ``tr(W) / tr(P)`` where that is
    not positive (W singular: no rate is certified, see the module docstring)."""
    mu = float(scipy.linalg.eigh(0.5 * (W + W.T), 0.5 * (P + P.T), eigvals_only=True)[0])
    return mu if mu > 0.0 else float(np.trace(W) / np.trace(P))


def _first_discount(moments: IntervalMoments, K0: Array, Q: Array, R: Array, X: Array) -> float:
    """:data:`FIRST_DISCOUNT` times the decay rate K0's loop certifies on the plant alone
    (see the module docstring)."""
    record = policy_step(moments.without_integrator(), K0, Q, R, X=X)
    return FIRST_DISCOUNT * _decay_rate(record.P, Q + K0.T @ R @ K0)


def _next_discount(gamma: float, rate: float, stages: int) -> float | None:
    """The discount after ``gamma`` in the schedule read off the data (None: done)."""
    if gamma == 0.0:
        return None
    if stages >= MAX_DISCOUNTS:
        raise ConvergenceError(
            f"the discount schedule did not reach 0 in {MAX_DISCOUNTS} discounts (the last "
            f"was {gamma:.3g} 1/s): the servo's slowest mode is far slower than the loop the "
            "data were taken with; raise the integral weight Q_i"
        )
    following = gamma - DISCOUNT_STEP * rate
    return following if following > 0.0 else 0.0
