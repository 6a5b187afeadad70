"""The optimal output regulator computed from the model: the truth learners are judged by.

``(K, P)`` is the LQR of ``(A, B, Q, R)`` (continuous algebraic Riccati equation) and
``(X, U)`` solves the regulator equations (the min-trace pair of Remark 2 when not
unique); the overall control is ``u = -K (x - X w) + U w``.
"""

from __future__ import annotations

from dataclasses import dataclass

from numpy.typing import ArrayLike

from ..core import Array, RegulatorSolution, check_weights, is_positive_definite, lqr
from ._problem import RegulationProblem

__all__ = ["ModelBasedSolution", "solve_optimal_regulation"]


@dataclass(frozen=True)
class ModelBasedSolution(RegulatorSolution):
    """The optimal output regulator computed from the model (the truth learners meet).

    Attributes
    ----------
    problem : RegulationProblem
        The problem solved.
    Q, R : ndarray
        Cost weights.

    The other attributes are those of :class:`RegulatorSolution`: K* and P* from the
    Riccati equation, X* and U* from the regulator equations.
    """

    problem: RegulationProblem
    Q: Array
    R: Array


def solve_optimal_regulation(
    problem: RegulationProblem, Q: ArrayLike, R: ArrayLike
) -> ModelBasedSolution:
    """The optimal output regulator of ``problem`` for the cost weights ``Q, R``.

    ``(X, U)`` solve the regulator equations (the min-trace pair when not unique, weighted
    by the same ``Q, R``; when Q is only semidefinite, X is weighted by the identity);
    ``(K, P)`` is the LQR of ``(A, B, Q, R)``.

    Parameters
    ----------
    problem : RegulationProblem
        The plant ``(A, B, D)``, exosystem ``E`` and regulated output ``(C, F)``.
    Q : array_like, shape (n, n)
        State weight, symmetric positive semidefinite with ``(A, Q)`` detectable.
    R : array_like, shape (m, m)
        Input weight, symmetric positive definite.

    Raises
    ------
    UnsolvableError
        Names the failing condition (stabilizability, Remark 1's rank at an eigenvalue of E,
        detectability).
    InputError
        If Q, R have the wrong shape or are not symmetric positive (semi)definite.
    """
    Q, R = check_weights(Q, R, problem.n, problem.m)
    problem.check_solvable()
    K, P = lqr(problem.A, problem.B, Q, R)
    X, U = problem.solve_regulator_equations(Q if is_positive_definite(Q) else None, R)
    for matrix in (Q, R, K, P, X, U):
        matrix.setflags(write=False)
    M = (problem.D + problem.A @ X - X @ problem.E).T @ P
    M.setflags(write=False)
    return ModelBasedSolution(K=K, P=P, X=X, U=U, exogenous_block=M, problem=problem, Q=Q, R=R)
