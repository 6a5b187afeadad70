"""Self-tuning results compared with the model-based optimum (evaluation only).

The sessions of :mod:`selftune.tuning` never see the model; this module is where a
result meets the truth: the parameter error against ``Theta*``, the true cost of each
applied policy, and the closed-loop torque step on the true motor.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core import Array, policy_value
from ..errors import UnsolvableError
from ..learn import LearningProblem, Trajectory
from ..model import SPMSM, ModelBasedSolution, Motor, solve_optimal_regulation
from ..sim import DriveSettings, constant, simulate
from ..tuning import TuningResult, TuningSettings

__all__ = [
    "TuningEvaluation",
    "block_error",
    "closed_loop_response",
    "evaluate",
    "feedback_value",
    "learner_integral_weight",
    "steady_state",
]


@dataclass(frozen=True)
class TuningEvaluation:
    """A :class:`TuningResult` compared with the model-based optimum (evaluation only).

    Attributes
    ----------
    optimum : ModelBasedSolution
    theta_error : ndarray, shape (iterations,)
        ``||Theta_j - Theta*||`` (2-norm) after each iteration.
    learned_cost : ndarray, shape (iterations,)
        ``xbar(0)' P_j xbar(0)``, the learned cost-to-go of ``K_j`` from ``x(0) = 0``.
    true_cost : ndarray, shape (iterations,)
        The true value of the applied feedback ``K_j`` for the same step
        (:func:`feedback_value`): what ``P_j`` estimates; never below the optimum's;
        ``inf`` if ``K_j`` does not stabilize. A wrong feedforward ``U_j`` shifts the
        steady state instead (:func:`steady_state`), which an infinite-horizon cost
        cannot weigh.
    final_theta_error : float
        ``||Theta - Theta*|| / ||Theta*||`` of the result (NaN for the digital target).
    K_error, U_error : float
        ``||K - K*|| / ||K*||`` and ``||U - U*|| / ||U*||``, K the feedback of the
        currents and the delayed voltages (the block the quality's ``K_relative_se`` is
        over); NaN if the laws' K differ in shape.
    excess_cost : float
        The true cost of the result's feedback over the optimum's, minus 1, for the
        torque step from rest: on the continuous loop (continuous target, NaN with
        integral action) or on the sampled loop with the drive's delay and the same
        integral weight (digital target, :mod:`._digital_evaluation`).
    K_i_error : float
        ``||K_i - K_i*|| / ||K_i*||``; NaN without integral action.
    """

    optimum: ModelBasedSolution
    theta_error: Array
    learned_cost: Array
    true_cost: Array
    final_theta_error: float
    K_error: float
    U_error: float
    excess_cost: float = float("nan")
    K_i_error: float = float("nan")


def steady_state(
    motor: SPMSM, settings: TuningSettings, K: Array, X: Array, U: Array, w: Array
) -> Array | None:
    """The currents where ``u = -K (x - X w) + U w`` settles on the true motor, A.

    The controller acts on its own ``w`` (its flux may differ from the true one); the
    motor's back-EMF is its own: ``0 = (A - B K) x + B (U + K X) w + D w_true``.

    Parameters
    ----------
    motor : SPMSM
        The true motor.
    settings : TuningSettings
        Speed and torque reference.
    K : ndarray, shape (2, 2)
        Feedback gain, V/A.
    X, U : ndarray, shape (2, 2)
        Steady-state map and feedforward of the controller.
    w : ndarray, shape (2,)
        The controller's ``w``.

    Returns
    -------
    ndarray, shape (2,), or None
        None if ``A - B K`` is not Hurwitz (no steady state).
    """
    problem = motor.regulation_problem(settings.speed)
    A, B, D = problem.A, problem.B, problem.D
    closed_loop = A - B @ K
    if np.max(np.linalg.eigvals(closed_loop).real) >= 0:
        return None
    w_true = motor.exogenous(settings.speed, settings.torque)
    return np.asarray(np.linalg.solve(closed_loop, -(B @ (U + K @ X) @ w + D @ w_true)))


def feedback_value(motor: SPMSM, settings: TuningSettings, K: Array) -> float:
    """The true cost (5) of the feedback ``u - U* w = -K (x - X* w)`` for the torque step
    from rest: ``xbar_0' P_K xbar_0`` with ``xbar_0 = -X* w_true`` (about the true
    operating point) and ``P_K`` the value of K on the true motor; ``inf`` if K does not
    stabilize it. It is what a learned ``P_j`` estimates, and never below the optimum.

    Parameters
    ----------
    motor : SPMSM
        The true motor.
    settings : TuningSettings
        Speed, torque reference and cost weights.
    K : ndarray, shape (2, 2)
        Feedback gain, V/A.
    """
    problem = motor.regulation_problem(settings.speed)
    try:
        value = policy_value(problem.A, problem.B, K, settings.Q, settings.R)
    except UnsolvableError:
        return float("inf")
    start = -motor.current_reference(settings.torque)  # -X* w_true: x_e = [0, i_q*]
    return float(start @ value @ start)


def evaluate(
    result: TuningResult,
    motor: SPMSM,
    settings: TuningSettings,
    drive: DriveSettings | None = None,
) -> TuningEvaluation:
    """Compare a self-tuning result with the model-based optimum of ``motor``.

    Parameters
    ----------
    result : TuningResult
        The self-tuning result.
    motor : SPMSM
        The true motor (nameplate values).
    settings : TuningSettings
        The settings the result was learned with.
    drive : DriveSettings, optional
        The realistic drive it was learned on (its delay and temperature); None for the
        ideal drive.
    """
    if result.target == "digital":
        from ._digital_evaluation import evaluate_digital

        return evaluate_digital(result, motor, settings, drive)
    weight = learner_integral_weight(motor, settings) if result.law.K_i is not None else None
    optimum = solve_optimal_regulation(
        motor.regulation_problem(settings.speed),
        settings.Q,
        settings.R,
        integral_weight=weight,
        h=settings.h,
    )
    theta_star = optimum.theta
    x_bar0 = -result.X @ result.w  # the learner's own start: what its P_j are about
    theta_error, learned_cost, true_cost = [], [], []
    for item in result.history:
        if item.theta.shape == theta_star.shape:
            theta_error.append(float(np.linalg.norm(item.theta - theta_star)))
        else:
            theta_error.append(float("nan"))
        learned_cost.append(
            float(x_bar0 @ item.P @ x_bar0) if item.P.shape == (2, 2) else float("nan")
        )
        true_cost.append(
            feedback_value(motor, settings, item.K_applied)
            if item.K_applied.shape == (2, 2)
            else float("nan")
        )
    norm = float(np.linalg.norm(theta_star))
    optimal_cost = feedback_value(motor, settings, optimum.K)
    excess = float("nan")
    if weight is None and 0.0 < optimal_cost < float("inf"):
        excess = feedback_value(motor, settings, result.K) / optimal_cost - 1.0
    return TuningEvaluation(
        optimum=optimum,
        theta_error=np.array(theta_error),
        learned_cost=np.array(learned_cost),
        true_cost=np.array(true_cost),
        final_theta_error=float("nan")
        if result.theta is None
        else float(np.linalg.norm(result.theta - theta_star)) / norm,
        K_error=block_error(result.law.K, optimum.law.K),
        U_error=block_error(result.U, optimum.U),
        excess_cost=excess,
        K_i_error=block_error(result.law.K_i, optimum.law.K_i),
    )


def block_error(learned: Array | None, best: Array | None) -> float:
    """``||learned - best|| / ||best||`` of one block of a law (K, K_i or U); NaN where
    either has no such block or their shapes differ.

    Parameters
    ----------
    learned, best : ndarray or None
        The block of the result and of the optimum.
    """
    if learned is None or best is None or learned.shape != best.shape:
        return float("nan")
    return float(np.linalg.norm(learned - best) / np.linalg.norm(best))


def learner_integral_weight(motor: Motor, settings: TuningSettings) -> Array | None:
    """The integral weight a session's learner uses (the settings' ``Q_i``, else the
    default of :class:`selftune.learn.LearningProblem`), so the optimum compared is of the
    same cost.

    Parameters
    ----------
    motor : SPMSM or IPMSM
        The motor (kept for the callers; the weight depends on C and Q only).
    settings : TuningSettings
        Cost weights and K0.
    """
    problem = LearningProblem(  # the integrated current error's weight: C's and Q's only
        settings.Q, settings.R, C=np.eye(2), F=np.zeros((2, 1)), integral_action=True,
        integral_weight=settings.Q_i,
    )  # fmt: skip
    return problem.integral_weight


def closed_loop_response(
    motor: SPMSM,
    settings: TuningSettings,
    K: Array,
    X: Array,
    U: Array,
    w: Array | None = None,
    duration: float = 0.01,
) -> Trajectory:
    """The torque step from rest under ``u = -K (x - X w) + U w`` (evaluation, from the model).

    Parameters
    ----------
    motor : SPMSM
        The true motor.
    settings : TuningSettings
        Speed, torque reference and sampling period.
    K, X, U : ndarray
        The controller.
    w : ndarray, optional
        The controller's ``w`` (default the true ``[p speed phi_pm, T*]``); Algorithm 3's
        controller uses its identified flux.
    duration : float
        Length of the response, s.
    """
    problem = motor.regulation_problem(settings.speed)
    w_true = motor.exogenous(settings.speed, settings.torque)
    w_controller = w_true if w is None else np.asarray(w, dtype=float)
    # The motor's back-EMF is D w_true; the controller acts on its own w.
    scale = np.divide(w_true, w_controller, out=np.ones_like(w_true), where=w_controller != 0.0)
    D = problem.D @ np.diag(scale)
    return simulate(
        problem.A,
        problem.B,
        D=D,
        exogenous=constant(w_controller),
        K=K,
        X=X,
        U=U,
        h=settings.h,
        num_samples=round(duration / settings.h),
    )
