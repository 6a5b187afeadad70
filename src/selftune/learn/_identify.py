"""Identify-then-design (certainty equivalence): the baseline every ADP result is held to.

The exact discrete model ``x_(k+1) = Ad x_k + Bd a_k + Ed w_k`` fitted to the log
(:mod:`._discrete_model`) is taken as the truth and the optimum of the target designed on
it (Tu & Recht 2019; Mania, Tu & Recht 2019):

- ``"digital"``: the optimum of ``sum_k h (xbar' Q xbar + ubar' R ubar [+ z' Q_i z])`` of
  the sampled loop with the drive's computation delay (the discrete Riccati equation of
  the delay-augmented plant);
- ``"sampled"``: the digital controller that is optimal for the CONTINUOUS cost, the
  currents between samples included (Van Loan's exact weights of one sample);
- ``"continuous"``: the continuous-time optimum, from the continuous plant recovered by
  the matrix logarithm (exact for noise-free data when every mode satisfies
  ``|Im lambda| h < pi``).

The regulator equations are solved on the identified model too (``(Ad - I) X + Bd U +
Ed = 0`` for the digital targets, the continuous ones for the continuous target), with X
from ``C X + F = 0`` weighted as the model-based optimum weights it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from ..core import (
    Array,
    ControlLaw,
    continuous_from_discrete,
    delay_augmented,
    dlqr,
    integrator_augmented,
    is_positive_definite,
    lqr,
    sampled_data_weights,
    solve_regulator,
)
from ..errors import InputError
from ._discrete_model import DiscreteModel
from ._problem import LearningProblem

__all__ = ["Design", "design_continuous", "design_digital"]


@dataclass(frozen=True)
class Design:
    """A controller designed on an identified model.

    Attributes
    ----------
    law : ControlLaw
        The controller.
    P : ndarray
        Its value matrix (of the augmented state for the digital targets).
    B : ndarray
        The identified input matrix: Bd (digital targets) or B (continuous target).
    """

    law: ControlLaw
    P: Array
    B: Array


def _weights_X(problem: LearningProblem) -> Array:
    return problem.Q if is_positive_definite(problem.Q) else np.eye(problem.n)


def _regulator(
    problem: LearningProblem, A: Array, B: Array, D: Array, E: Array
) -> tuple[Array, Array]:
    """(X, U) of the problem's regulator equations on a given (A, B, D, E)."""
    n, m = problem.n, problem.m
    if problem.C is None or problem.F is None:
        return np.zeros((n, 0)), np.zeros((m, 0))
    return solve_regulator((A, B, problem.C, D, E, problem.F), _weights_X(problem), problem.R)


def design_digital(
    model: DiscreteModel, problem: LearningProblem, delay: int, cost: str = "digital"
) -> Design:
    """The optimal digital controller of the identified sampled loop with its delay.

    Parameters
    ----------
    model : DiscreteModel
        The identified ``(Ad, Bd, Ed)``.
    problem : LearningProblem
        Weights, regulated output and integral action.
    delay : int
        d, the drive's computation delay, samples.
    cost : {"digital", "sampled"}
        The digital cost, or the continuous cost integrated exactly over each sample.

    Returns
    -------
    Design
    """
    h, n, m = model.h, problem.n, problem.m
    Az, Bz = delay_augmented(model.Ad, model.Bd, delay)
    Qz, Rz, Nz = _digital_weights(model, problem, delay, cost)
    if problem.integral_weight is not None:
        assert problem.C is not None and problem.F is not None
        C_full = np.hstack([problem.C, np.zeros((problem.r, delay * m))])
        Az, Bz = integrator_augmented(Az, Bz, C_full, h)
        Qz = scipy.linalg.block_diag(Qz, h * problem.integral_weight)
        Nz = np.vstack([Nz, np.zeros((problem.r, m))])
    K, P = dlqr(Az, Bz, Qz, Rz, Nz)
    held = np.zeros((problem.q, problem.q))
    X, U = _regulator(problem, model.Ad - np.eye(n), model.Bd, model.Ed, held)
    return Design(law=_law(problem, K, (X, U), delay, h), P=P, B=model.Bd)


def _digital_weights(
    model: DiscreteModel, problem: LearningProblem, delay: int, cost: str
) -> tuple[Array, Array, Array]:
    """``(Qz, Rz, Nz)`` of the delay-augmented state for the digital or sampled cost."""
    h, n, m = model.h, problem.n, problem.m
    size = n + delay * m
    Qz, Nz = np.zeros((size, size)), np.zeros((size, m))
    if cost == "digital":
        Qz[:n, :n] = h * problem.Q
        return Qz, h * problem.R, Nz
    if cost != "sampled":
        raise InputError(f"cost: must be 'digital' or 'sampled', got {cost!r}")
    A, B, _ = continuous_from_discrete(model.Ad, model.Bd, h)
    Qd, Rd, N = sampled_data_weights(A, B, problem.Q, problem.R, h)
    Qz[:n, :n] = Qd
    if delay == 0:
        return Qz, Rd, N
    # the applied input is the oldest delayed one: its cross term joins the state weight,
    # its own weight is charged when it is computed (d samples earlier)
    Qz[:n, n : n + m] = N
    Qz[n : n + m, :n] = N.T
    return Qz, Rd, Nz


def _law(
    problem: LearningProblem, K: Array, steady: tuple[Array, Array], history: int, h: float
) -> ControlLaw:
    """The law of a gain over ``[x; delayed inputs; z]``: K's last r columns are K_i."""
    X, U = steady
    width = problem.n + history * problem.m
    if problem.integral_weight is None:
        return ControlLaw(K, X, U, history=history)
    return ControlLaw(
        K[:, :width], X, U, history=history, K_i=K[:, width:], C=problem.C, F=problem.F, h=h
    )


def design_continuous(model: DiscreteModel, problem: LearningProblem) -> Design:
    """The continuous-time optimum of the plant whose exact discretization is the model.

    Parameters
    ----------
    model : DiscreteModel
        The identified ``(Ad, Bd, Ed)`` (``w`` held: E = 0).
    problem : LearningProblem
        Weights, regulated output and integral action.

    Returns
    -------
    Design
        The law ``u = -K (x - X w) + U w`` (with ``- K_i z`` for integral action, the
        integrator run at the sampling period).
    """
    A, B, D = continuous_from_discrete(model.Ad, model.Bd, model.h, model.Ed)
    if problem.integral_weight is not None:
        assert problem.C is not None
        A_aug, B_aug = integrator_augmented(A, B, problem.C)
        Q_aug = scipy.linalg.block_diag(problem.Q, problem.integral_weight)
        K, P = lqr(A_aug, B_aug, Q_aug, problem.R)
    else:
        K, P = lqr(A, B, problem.Q, problem.R)
    E = np.zeros((problem.q, problem.q)) if problem.E is None else problem.E
    X, U = _regulator(problem, A, B, D, E)
    return Design(law=_law(problem, K, (X, U), 0, model.h), P=P, B=B)
