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
inputs as regulated outputs). A drive runs the integrator at its sampling period (the
``h`` given to :func:`solve_optimal_regulation`, the law's); the digital optimum of that
loop is :func:`~selftune.model.solve_digital_regulation`. Both return a
:class:`ModelBasedSolution`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from ..core import (
    Array,
    ControlLaw,
    WithLaw,
    as_matrix,
    check_positive_definite,
    check_weights,
    is_positive_definite,
    pack_theta,
)
from ..errors import InputError, UnsolvableError
from ..loop import SampledLoop
from ._problem import RegulationProblem

__all__ = [
    "ModelBasedSolution",
    "OptimumCost",
    "check_integral_weight",
    "solve_optimal_regulation",
]


#: The costs a model-based optimum minimizes: the continuous integral (the paper's), or a
#: sampled loop's (:class:`~selftune.loop.SampledLoop`).
OptimumCost = Literal["continuous", "digital", "sampled"]


@dataclass(frozen=True, eq=False)
class ModelBasedSolution(WithLaw):
    """The optimal controller computed from the model: the truth learners are judged by.

    One type for the optimum of the continuous loop (:func:`solve_optimal_regulation`,
    ``loop.h = 0``) and of a sampled loop with its computation delay
    (:func:`~selftune.model.solve_digital_regulation`). The gains are the law's
    (:class:`~selftune.core.WithLaw`: ``K``, ``K_i``, ``X``, ``U``, ``L``, ``state``).

    Attributes
    ----------
    law : ControlLaw
        The law a drive runs. Continuous optimum: ``u = U w - K xbar [- K_i z]`` (with
        integral action the integrator runs at the drive's ``h`` given to the solver).
        Sampled loop: ``K`` over ``[xbar_k; ubar_(k-d); ...; ubar_(k-1)]`` (V/A on the
        state, V/V on the delayed inputs), ``history = d``.
    P : ndarray
        Value matrix of the loop's state (with integral action the integrator's states
        last): the optimal cost from the initial state ``s`` is ``s' P s``.
    loop : SampledLoop
        The loop this is the optimum of: its period (0: continuous), input delay and
        integrator (``C, F, Q_i``).
    problem : RegulationProblem
        The problem solved.
    Q, R : ndarray
        The continuous cost weights given.
    cost : {"continuous", "digital", "sampled"}
        The cost minimized (see the solvers).
    exogenous_block : ndarray, shape (q, n [+ r]), or None
        Continuous optimum: ``M = (D + A X - X E)' P`` (the data equation's unknown,
        ``[D + AX - XE; 0]' P`` with integral action); None for a sampled loop.
    Ad, Bd, Ed : ndarray or None
        Sampled loop: the sampled plant (``expm(A h)``, the effect of the applied
        voltage, of the held reference); None for the continuous optimum.
    """

    law: ControlLaw
    P: Array
    loop: SampledLoop
    problem: RegulationProblem
    Q: Array
    R: Array
    cost: OptimumCost = "continuous"
    exogenous_block: Array | None = None
    Ad: Array | None = None
    Bd: Array | None = None
    Ed: Array | None = None

    @property
    def h(self) -> float:
        """The loop's sampling period, s (0 for the continuous optimum)."""
        return self.loop.h

    @property
    def input_delay(self) -> int:
        """d, the loop's computation delay in samples (0 for the continuous optimum)."""
        return self.loop.input_delay

    @property
    def integral_weight(self) -> Array | None:
        """``Q_i``, the weight of the integrator; None without integral action."""
        return self.loop.Q_i

    @property
    def sampled_plant(self) -> tuple[Array, Array, Array]:
        """``(Ad, Bd, Ed)``: the sampled plant of a sampled loop's optimum.

        Raises
        ------
        InputError
            For the continuous optimum (it has no sampled plant).
        """
        if self.Ad is None or self.Bd is None or self.Ed is None:
            raise InputError("sampled_plant: the continuous optimum has no sampled plant")
        return self.Ad, self.Bd, self.Ed

    @property
    def theta(self) -> Array:
        """Theta = [vecs(P); vec(K); vec(M)] of the continuous optimum (K = ``[K, K_i]``
        with integral action): the unknowns of the paper's data equation.

        Raises
        ------
        InputError
            For the optimum of a sampled loop (its learner has no Theta).
        """
        if self.exogenous_block is None:
            raise InputError(
                "theta: the unknowns of the continuous data equation; this is the optimum "
                "of a sampled loop (compare K, U and P instead)"
            )
        gain = self.K if self.K_i is None else np.hstack([self.K, self.K_i])
        return pack_theta(self.P, gain, self.exogenous_block)


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
    problem: RegulationProblem, Q: Array, R: Array, loop: SampledLoop
) -> tuple[Array, Array]:
    """``K`` (``[K, K_i]`` with integral action) and P of the continuous loop: the plant,
    augmented with the integral of ``C xbar`` when the loop has an integrator."""
    plant = (problem.A, problem.B)
    if loop.Q_i is None:
        return loop.optimum(plant, loop.weights(Q, R))
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
    h: float | None = None,
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
    h : float, optional
        The sampling period of the drive's integrator ``z_(k+1) = z_k + h e_k``, s: the
        law's ``h``; needed with ``integral_weight``.

    Returns
    -------
    ModelBasedSolution
        Of the continuous loop (``loop.h = 0``, ``cost = "continuous"``).

    Raises
    ------
    UnsolvableError
        Names the failing condition (stabilizability, Remark 1's rank at an eigenvalue of E,
        detectability; with integral action, of the augmented plant).
    InputError
        If Q, R or Q_i have the wrong shape or are not symmetric positive (semi)definite,
        or integral action is asked without h.
    """
    Q, R = check_weights(Q, R, problem.n, problem.m)
    if integral_weight is None:
        loop = SampledLoop(0.0)
    else:
        Q_i = check_integral_weight(integral_weight, problem.r)
        loop = SampledLoop(0.0, C=problem.C, F=problem.F, Q_i=Q_i)
    problem.check_solvable()
    gain, P = _optimal_gain(problem, Q, R, loop)
    X, U = problem.solve_regulator_equations(Q if is_positive_definite(Q) else None, R)
    M = (problem.D + problem.A @ X - X @ problem.E).T @ P[: problem.n]
    for matrix in (Q, R, P, M):
        matrix.setflags(write=False)
    return ModelBasedSolution(
        law=loop.law(gain, X, U, h=h),
        P=P,
        loop=loop,
        problem=problem,
        Q=Q,
        R=R,
        exogenous_block=M,
    )
