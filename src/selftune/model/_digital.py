"""The optimal digital controller computed from the model: the truth for a sampled drive.

A digital drive samples ``x_k = x(t_k)`` and the reference ``w_k`` at ``t_k = k h``,
computes the voltage ``u_k`` and applies it, held, over ``[t_(k+d), t_(k+d+1))``: d is the
computation delay in samples (d = 1 on most drives). The reference is held over each
sample (E = 0). With the exact zero-order-hold discretization
``x_(k+1) = Ad x_k + Bd u_(k-d) + Ed w_k`` and the delay-augmented state
``z_k = [xbar_k; ubar_(k-d); ...; ubar_(k-1)]`` (``xbar = x - X w``, ``ubar = u - U w``),
the optimal law is::

    u_k = U w_k - K [x_k - X w_k; u_(k-d) - U w_k; ...; u_(k-1) - U w_k]

with ``(X, U)`` from the regulator equations (the same as in continuous time when E = 0)
and ``K`` from the discrete Riccati equation of the augmented plant (:func:`dlqr`). Units
are SI: for the motor, x in A, u in V, h in s.

The loop (its augmented state ``zeta_k = [xbar_k; ubar_(k-d); ...; ubar_(k-1); z_k]``,
the integrator with integral action), its two costs (``"digital"``, computable from
samples, and ``"sampled"``, the continuous cost integrated exactly over each sample with
the voltage actually applied), their weights and the Riccati equation are those of
:class:`selftune.loop.SampledLoop`, which the learners' identify-then-design asks too: P
is the value, the optimal cost from ``zeta_0`` is ``zeta_0' P zeta_0``, and ``K``'s last r
columns are ``K_i``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..core import (
    Array,
    as_matrix,
    check_weights,
    discretize,
    is_positive_definite,
    positive_finite,
    positive_integer,
)
from ..errors import InputError, UnsolvableError
from ..loop import Cost, SampledLoop
from ._optimum import ModelBasedSolution, check_integral_weight
from ._problem import RegulationProblem

__all__ = ["DigitalCost", "solve_digital_regulation"]

#: The costs a digital optimum can minimize (see :func:`solve_digital_regulation`).
DigitalCost = Cost


def _check_arguments(
    problem: RegulationProblem, h: float, input_delay: int, cost: str
) -> tuple[float, int]:
    """The sampling period and the delay, validated; E = 0 and a known cost."""
    if np.any(problem.E != 0.0):
        raise InputError(
            "E: digital regulation needs E = 0 (the reference w held over each sample, a"
            " digital reference); this problem's w moves within a sample"
        )
    period = positive_finite(h, "h")
    delay = positive_integer(input_delay, "input_delay", minimum=0)
    if cost not in ("digital", "sampled"):
        raise InputError(f"cost: expected 'digital' or 'sampled', got {cost!r}")
    return period, delay


def _sampled_plant(
    plant: tuple[ArrayLike, ArrayLike, ArrayLike], problem: RegulationProblem
) -> tuple[Array, Array, Array]:
    n, m, q = problem.n, problem.m, problem.q
    Ad = as_matrix(plant[0], "plant Ad", (n, n))
    Bd = as_matrix(plant[1], "plant Bd", (n, m))
    Ed = as_matrix(plant[2], "plant Ed", (n, q))
    return Ad.copy(), Bd.copy(), Ed.copy()


def _sampled_regulator(
    problem: RegulationProblem, Ad: Array, Bd: Array, Ed: Array
) -> tuple[Array, Array]:
    """``(X, U)`` of ``(Ad - I) X + Bd U + Ed = 0``, ``C X + F = 0`` (r = m)."""
    n, m = problem.n, problem.m
    if problem.r != m:
        raise InputError(
            f"plant: the sampled regulator equations need as many regulated outputs as inputs "
            f"(r = {problem.r}, m = {m})"
        )
    lhs = np.block([[Ad - np.eye(n), Bd], [problem.C, np.zeros((problem.r, m))]])
    rhs = -np.vstack([Ed, problem.F])
    try:
        solution = np.linalg.solve(lhs, rhs)
    except np.linalg.LinAlgError:
        raise UnsolvableError(
            "the sampled regulator equations are singular: the sampled plant has a "
            "transmission zero at 1 (no input holds the regulated output at its reference)"
        ) from None
    return solution[:n], solution[n:]


def solve_digital_regulation(
    problem: RegulationProblem,
    Q: ArrayLike,
    R: ArrayLike,
    h: float,
    *,
    input_delay: int = 0,
    cost: DigitalCost = "digital",
    integral_weight: ArrayLike | None = None,
    plant: tuple[ArrayLike, ArrayLike, ArrayLike] | None = None,
) -> ModelBasedSolution:
    """The optimal digital regulator of ``problem`` sampled at h with a delay of d samples.

    ``(X, U)`` solve the regulator equations (as :func:`solve_optimal_regulation`: E = 0,
    so they are those of continuous time and ``(Ad - I) X + Bd U + Ed = 0``). ``K`` and
    ``P`` are the DARE's of the augmented plant (:class:`~selftune.loop.SampledLoop`), whose
    state, the order of K's columns, is ``z_k = [xbar_k; ubar_(k-d); ...; ubar_(k-1)]``.

    Costs, with ``ubar_k`` the deviation of the voltage computed at sample k and
    ``abar_k`` that of the voltage applied over ``[t_k, t_(k+1))`` (``u_(k-d)``):

    - ``"digital"``: ``sum_k h (xbar_k' Q xbar_k + ubar_k' R ubar_k)``; augmented weights
      ``Qz = blockdiag(h Q, 0, ..., 0)``, ``Rz = h R``, no cross term.
    - ``"sampled"``: ``int (xbar'Q xbar + abar'R abar) dt``, exact over each sample
      (:func:`sampled_data_weights`), each stage charged d samples early, when its
      voltage is computed (``Rz = Rd``); that leaves out only the first d stages, which
      depend on ``z_0`` alone, so K is the optimum, and ``P`` adds their value. The
      weights and why the whole stage is shifted are in this module's notes.

    With ``integral_weight`` (``Q_i``) it is the optimal digital servo controller: the
    state is extended with the drive's integrator ``z_(k+1) = z_k + h C xbar_k`` and the
    cost with ``h z_k' Q_i z_k`` per sample, for both costs (for ``"sampled"`` that is the
    exact integral of ``z' Q_i z`` over the sample, z being held); the law carries
    ``K_i, C, F, h``. See the module's notes.

    Parameters
    ----------
    problem : RegulationProblem
        The continuous plant ``(A, B, D)`` with E = 0 and the regulated output ``(C, F)``
        (for the motor: x in A, u in V, t in s).
    Q : array_like, shape (n, n)
        Continuous state weight, symmetric positive semidefinite.
    R : array_like, shape (m, m)
        Continuous input weight, symmetric positive definite.
    h : float
        Sampling period, s (1e-4 s for a 10 kHz current loop).
    input_delay : int, optional
        d >= 0, the computation delay in samples (default 0; 1 on most drives).
    cost : {"digital", "sampled"}, optional
        The cost minimized (default ``"digital"``), see above.
    integral_weight : array_like, shape (r, r), optional
        ``Q_i``, the continuous weight of the integral of ``e``, symmetric positive
        definite; None (default): no integral action.
    plant : (Ad, Bd, Ed), optional
        The exact sampled plant when the input is not held in the problem's own frame
        (e.g. a PWM inverter's stationary-frame hold seen in dq:
        :meth:`selftune.model.SPMSM.sampled_plant`); default: the zero-order hold of
        ``(A, B, D)``. ``(X, U)`` then solve the sampled regulator equations
        ``(Ad - I) X + Bd U + Ed = 0``, ``C X + F = 0`` (square: r = m). Digital cost only.

    Returns
    -------
    ModelBasedSolution
        Of the sampled loop (``loop.h = h``, ``loop.input_delay = d``), with the sampled
        plant ``Ad, Bd, Ed``.

    Raises
    ------
    InputError
        If E is not zero, h is not a positive number, input_delay is not a whole number
        >= 0, cost is unknown, or Q, R, Q_i are not as required.
    UnsolvableError
        Naming the failing condition: the continuous problem is not solvable, or the
        sampled plant (with the integrator) is not stabilizable or not detected by the
        cost (names the eigenvalue; e.g. a sampling period at which a mode loses
        controllability, or the eigenvalue 1 of an integrator the inputs cannot drive).
    """
    Q_, R_ = check_weights(Q, R, problem.n, problem.m)
    period, delay = _check_arguments(problem, h, input_delay, cost)
    Q_i = None if integral_weight is None else check_integral_weight(integral_weight, problem.r)
    problem.check_solvable()
    if plant is None:
        X, U = problem.solve_regulator_equations(Q_ if is_positive_definite(Q_) else None, R_)
        sampled = discretize(problem.A, problem.B, period, D=problem.D)
        Ad, Bd, Ed = sampled.Ad, sampled.Bd, sampled.Ed
    else:
        if cost != "digital":
            raise InputError('plant: a given sampled plant supports cost = "digital" only')
        Ad, Bd, Ed = _sampled_plant(plant, problem)
        X, U = _sampled_regulator(problem, Ad, Bd, Ed)
    if Q_i is None:
        loop = SampledLoop(period, delay)
    else:
        loop = SampledLoop(period, delay, C=problem.C, F=problem.F, Q_i=Q_i)
    weights = loop.weights(Q_, R_, cost, plant=(Ad, Bd), continuous_plant=(problem.A, problem.B))
    K, P = loop.optimum((Ad, Bd), weights)
    for matrix in (P, Ad, Bd, Ed, Q_, R_):
        matrix.setflags(write=False)
    return ModelBasedSolution(
        law=loop.law(K, X, U),
        P=P,
        loop=loop,
        problem=problem,
        Q=Q_,
        R=R_,
        cost=cost,
        Ad=Ad,
        Bd=Bd,
        Ed=Ed,
    )
