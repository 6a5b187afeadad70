"""The optimal output regulator computed from the model: the truth learners are judged by.

``(K, P)`` is the LQR of ``(A, B, Q, R)`` (continuous algebraic Riccati equation) and
``(X, U)`` solves the regulator equations (the min-trace pair of Remark 2 when not
unique); the overall control is ``u = -K (x - X w) + U w``.

With integral action (the optimal servo controller) the state is augmented with ``z``,
the integral of the regulated error ``e = C x + F w``; since ``C X + F = 0``,
``e = C xbar`` with ``xbar = x - X w``::

    [xbar; z]' = A_aug [xbar; z] + B_aug ubar,   A_aug = [[A, 0], [C, 0]],   B_aug = [B; 0]

(the continuous loop of :class:`~selftune.loop.SampledLoop`, h = 0). The optimum of
``int (xbar'Q xbar + z'Q_i z + ubar'R ubar) dt`` is ``u = U w - K xbar - K_i z`` with
``[K, K_i]`` the LQR gain of ``(A_aug, B_aug, blockdiag(Q, Q_i), R)``; it exists when
``rank [[A, B], [C, 0]] = n + r`` (the plant has no zero at s = 0 and at least as many
inputs as regulated outputs). A drive runs the integrator at its sampling period
(:meth:`ModelBasedSolution.law`); the digital optimum of that loop is
:func:`~selftune.model.solve_digital_regulation`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..core import (
    Array,
    ControlLaw,
    RegulatorSolution,
    as_matrix,
    check_positive_definite,
    check_weights,
    is_positive_definite,
    pack_theta,
)
from ..errors import InputError, UnsolvableError
from ..loop import SampledLoop
from ._problem import RegulationProblem

__all__ = ["ModelBasedSolution", "check_integral_weight", "solve_optimal_regulation"]


@dataclass(frozen=True)
class ModelBasedSolution(RegulatorSolution):
    """The optimal output regulator computed from the model (the truth learners meet).

    Attributes
    ----------
    problem : RegulationProblem
        The problem solved.
    Q, R : ndarray
        Cost weights.
    K_i : ndarray, shape (m, r), or None
        Integral gain on ``z``, the integral of ``e`` (V/(A s) for the motor); None
        without integral action.
    integral_weight : ndarray, shape (r, r), or None
        ``Q_i``, the weight of ``z``; None without integral action.

    The other attributes are those of :class:`RegulatorSolution`: K* (on ``xbar``) and
    P* from the Riccati equation, X* and U* from the regulator equations. With integral
    action P* is the value matrix of ``[xbar; z]``, shape (n + r, n + r), and the
    exogenous block is ``M = [D + A X - X E; 0]' P``, shape (q, n + r).
    """

    problem: RegulationProblem
    Q: Array
    R: Array
    K_i: Array | None = None
    integral_weight: Array | None = None

    @property
    def theta(self) -> Array:
        """Theta = [vecs(P); vec(K); vec(M)] (K = ``[K, K_i]`` with integral action)."""
        gain = self.K if self.K_i is None else np.hstack([self.K, self.K_i])
        return pack_theta(self.P, gain, self.exogenous_block)

    def law(self, h: float | None = None) -> ControlLaw:
        """The law a drive runs: ``u = U w - K xbar [- K_i z]``.

        Parameters
        ----------
        h : float, optional
            Sampling period of the drive's integrator ``z_(k+1) = z_k + h e_k``, s;
            needed with integral action.

        Returns
        -------
        ControlLaw
            With ``K_i, C, F, h`` under integral action, else the plain regulator.

        Raises
        ------
        InputError
            If the solution has integral action and h is not a positive number.
        """
        if self.K_i is None:
            return ControlLaw(self.K, self.X, self.U, h=h)
        if h is None:
            raise InputError("h: the integral action's law needs the drive's sampling period")
        return ControlLaw(
            self.K, self.X, self.U, K_i=self.K_i, C=self.problem.C, F=self.problem.F, h=h
        )


def check_integral_weight(integral_weight: ArrayLike, r: int) -> Array:
    """``Q_i`` validated: r x r, symmetric positive definite.

    Parameters
    ----------
    integral_weight : array_like, shape (r, r)
        The weight of the integral of the regulated error.
    r : int
        Regulated-output dimension.

    Returns
    -------
    ndarray, shape (r, r)
        Its symmetric part.

    Raises
    ------
    InputError
        If the shape is not (r, r) or the matrix is not symmetric positive definite.
    """
    weight = as_matrix(integral_weight, "integral_weight", (r, r))
    return check_positive_definite(weight, "integral_weight")


def _optimal_gain(
    problem: RegulationProblem, Q: Array, R: Array, Q_i: Array | None
) -> tuple[Array, Array]:
    """``K`` (``[K, K_i]`` with integral action) and P of the continuous loop: the plant,
    augmented with the integral of ``C xbar`` when ``Q_i`` is given."""
    plant = (problem.A, problem.B)
    if Q_i is None:
        loop = SampledLoop(0.0)
        return loop.optimum(plant, loop.weights(Q, R))
    loop = SampledLoop(0.0, C=problem.C, F=problem.F, Q_i=Q_i)
    try:
        return loop.optimum(plant, loop.weights(Q, R))
    except UnsolvableError as exc:
        raise UnsolvableError(
            f"integral action (the plant augmented with z' = C x): {exc}; it needs rank"
            " [[A, B], [C, 0]] = n + r (no plant zero at s = 0, as many independent inputs"
            " as regulated outputs)"
        ) from None


def solve_optimal_regulation(
    problem: RegulationProblem,
    Q: ArrayLike,
    R: ArrayLike,
    *,
    integral_weight: ArrayLike | None = None,
) -> ModelBasedSolution:
    """The optimal output regulator of ``problem`` for the cost weights ``Q, R``.

    ``(X, U)`` solve the regulator equations (the min-trace pair when not unique, weighted
    by the same ``Q, R``; when Q is only semidefinite, X is weighted by the identity);
    ``(K, P)`` is the LQR of ``(A, B, Q, R)``. With ``integral_weight`` it is the optimal
    servo controller: ``[K, K_i]`` and P are the LQR of the plant augmented with
    ``z' = C xbar`` (``[[A, 0], [C, 0]]``, ``[B; 0]``, ``blockdiag(Q, Q_i)``, R); see the
    module docstring.

    Parameters
    ----------
    problem : RegulationProblem
        The plant ``(A, B, D)``, exosystem ``E`` and regulated output ``(C, F)``.
    Q : array_like, shape (n, n)
        State weight, symmetric positive semidefinite with ``(A, Q)`` detectable.
    R : array_like, shape (m, m)
        Input weight, symmetric positive definite.
    integral_weight : array_like, shape (r, r), optional
        ``Q_i``, the weight of the integral of ``e``, symmetric positive definite (for the
        motor 1/(A^2 s^3) per unit of cost when Q is in 1/(A^2 s)); None (default): no
        integral action.

    Returns
    -------
    ModelBasedSolution
        ``K_i`` and ``integral_weight`` are None without integral action.

    Raises
    ------
    UnsolvableError
        Names the failing condition (stabilizability, Remark 1's rank at an eigenvalue of E,
        detectability; with integral action, of the augmented plant).
    InputError
        If Q, R or Q_i have the wrong shape or are not symmetric positive (semi)definite.
    """
    Q, R = check_weights(Q, R, problem.n, problem.m)
    Q_i = None if integral_weight is None else check_integral_weight(integral_weight, problem.r)
    problem.check_solvable()
    gain, P = _optimal_gain(problem, Q, R, Q_i)
    K = gain[:, : problem.n].copy()
    K_i = None if Q_i is None else gain[:, problem.n :].copy()
    X, U = problem.solve_regulator_equations(Q if is_positive_definite(Q) else None, R)
    M = (problem.D + problem.A @ X - X @ problem.E).T @ P[: problem.n]
    for matrix in (Q, R, K, P, X, U, M, K_i, Q_i):
        if matrix is not None:
            matrix.setflags(write=False)
    return ModelBasedSolution(
        K=K,
        P=P,
        X=X,
        U=U,
        exogenous_block=M,
        problem=problem,
        Q=Q,
        R=R,
        K_i=K_i,
        integral_weight=Q_i,
    )
