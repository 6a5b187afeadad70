"""Identify-then-design (certainty equivalence): the baseline every ADP result is held to.

The exact discrete model ``x_(k+1) = Ad x_k + Bd a_k + Ed w_k`` fitted to the log
(:mod:`..evidence._discrete_model`) is taken as the truth and the optimum of the target designed on
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

import numpy as np

from ...core import (
    Array,
    continuous_from_discrete,
    is_positive_definite,
    solve_regulator,
)
from ...loop import Cost
from .._problem import LearningProblem
from .._result import LearnedController
from ..evidence._discrete_model import DiscreteModel

__all__ = ["design_continuous", "design_digital"]


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
    model: DiscreteModel, problem: LearningProblem, delay: int, cost: Cost = "digital"
) -> LearnedController:
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
        The digital cost, or the continuous cost integrated exactly over each sample
        (:class:`~selftune.loop.SampledLoop`).

    Returns
    -------
    LearnedController
        The law, its value (over the augmented state) and the identified Bd; no verdict.
    """
    loop = problem.loop(model.h, delay)
    plant = (model.Ad, model.Bd)
    # the problem checked Q and R, its loop Q_i: the digital cost's weights, h Q, h Q_i
    # and h R on their blocks, are as the Riccati solve requires; Van Loan's are checked
    weights = loop.weights(problem.Q, problem.R, cost, plant=plant)
    K, P = loop.optimum(plant, weights, checked=cost == "digital")
    held = np.zeros((problem.q, problem.q))
    X, U = _regulator(problem, model.Ad - np.eye(problem.n), model.Bd, model.Ed, held)
    return LearnedController(
        law=loop.law(K, X, U), P=P, B=model.Bd, target="digital", method="identify",
        h=model.h, input_delay=delay,
    )  # fmt: skip


def design_continuous(model: DiscreteModel, problem: LearningProblem) -> LearnedController:
    """The continuous-time optimum of the plant whose exact discretization is the model.

    Parameters
    ----------
    model : DiscreteModel
        The identified ``(Ad, Bd, Ed)`` (``w`` held: E = 0).
    problem : LearningProblem
        Weights, regulated output and integral action.

    Returns
    -------
    LearnedController
        The law ``u = -K (x - X w) + U w`` (with ``- K_i z`` for integral action, the
        integrator run at the sampling period).
    """
    A, B, D = continuous_from_discrete(model.Ad, model.Bd, model.h, model.Ed)
    loop = problem.loop(0.0, 0)
    K, P = loop.optimum((A, B), loop.weights(problem.Q, problem.R))
    E = np.zeros((problem.q, problem.q)) if problem.E is None else problem.E
    X, U = _regulator(problem, A, B, D, E)
    law = loop.law(K, X, U, h=model.h)
    return LearnedController(law=law, P=P, B=B, method="identify", h=model.h)
