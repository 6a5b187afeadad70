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

The costs, with ``ubar_k`` the deviation of the voltage *computed* at sample k and
``a_k = u_(k-d)`` the voltage *applied* over ``[t_k, t_(k+1))`` (``abar_k`` its deviation):

- ``"digital"``: ``sum_k h (xbar_k' Q xbar_k + ubar_k' R ubar_k)``, computable from
  samples alone; the augmented weights are ``Qz = blockdiag(h Q, 0, ..., 0)``,
  ``Rz = h R``, no cross term.
- ``"sampled"``: the continuous cost ``int (xbar'Q xbar + abar'R abar) dt`` integrated
  exactly over each sample with the voltage actually applied,
  ``sum_k [xbar_k; abar_k]' W [xbar_k; abar_k]``, ``W = [[Qd, N], [N', Rd]]``
  (:func:`sampled_data_weights`). For d = 0, ``a_k`` is the input. For d >= 1 it is the
  oldest delayed input in ``z_k``, and each stage is charged d samples early, when its
  voltage is computed: stage ``k + d`` is ``[xbar_(k+d); ubar_k]' W [xbar_(k+d); ubar_k]``
  with ``xbar_(k+d) = Cz z_k`` (``Cz``: the first n rows of ``Az^d``), so ``Rz = Rd``,
  ``Nz = Cz' N`` and ``Qz = Cz' Qd Cz``. The shift leaves out the first d stages, which
  depend on ``z_0`` alone and no decision changes, so K is the infinite-horizon optimum;
  ``P`` adds their value, so it is the value of the whole sampled cost. Shifting only the
  ``Rd`` term (state weight ``Qd`` on x and the cross ``N`` between x and the oldest
  delayed input, ``Rz = Rd``) gives the same K, but its joint weight is indefinite, outside
  the conditions under which the Riccati equation is known to have a stabilizing solution.

In both, ``P`` is the value: the optimal cost from ``z_0`` is ``z_0' P z_0``.

**Integral action** (the optimal digital servo controller, ``integral_weight = Q_i``):
the drive's integrator ``z_(k+1) = z_k + h e_k`` (:class:`ControlLaw`), with
``e_k = C x_k + F w_k = C xbar_k`` since ``C X + F = 0``, extends the augmented state to
``zeta_k = [xbar_k; ubar_(k-d); ...; ubar_(k-1); z_k]`` (:func:`integrator_augmented` of
the delay-augmented plant with ``[C, 0]``)::

    Az_i = [[Az, 0], [h [C, 0], I]],   Bz_i = [Bz; 0]

exactly the state and matrices of the learners (:mod:`selftune.learn`). The cost adds
``z' Q_i z``: ``"digital"``: ``sum_k h (xbar_k' Q xbar_k + ubar_k' R ubar_k + z_k' Q_i
z_k)``, so ``Qz = h blockdiag(Q, 0, ..., 0, Q_i)``, ``Rz = h R``. ``"sampled"``: the
integrator is a digital state, held over each sample, so ``int z' Q_i z dt`` over a sample
is exactly ``h z_k' Q_i z_k``: the weights of the sampled cost above, padded with
``h Q_i`` on z (no cross term), and the first d stages as before (they do not involve z).
The learner's identify-then-design minimizes the same two costs. ``K``'s last r columns
are ``K_i``; ``P`` is the value of the whole state: the optimal cost from ``zeta_0`` is
``zeta_0' P zeta_0``.
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
    check_weights,
    delay_augmented,
    discretize,
    dlqr,
    integrator_augmented,
    is_positive_definite,
    positive_finite,
    positive_integer,
    sampled_data_weights,
)
from ..errors import InputError, UnsolvableError
from ._optimum import check_integral_weight
from ._problem import RegulationProblem

__all__ = ["DigitalSolution", "solve_digital_regulation"]

#: The costs a digital optimum can minimize (see :func:`solve_digital_regulation`).
DigitalCost = Literal["digital", "sampled"]


@dataclass(frozen=True, eq=False)
class DigitalSolution(WithLaw):
    """The optimal digital regulator of a sampled plant with a computation delay.

    Attributes
    ----------
    law : ControlLaw
        The law a drive runs: ``K`` over ``z_k = [xbar_k; ubar_(k-d); ...; ubar_(k-1)]``
        (V/A on the state, V/V on the delayed inputs), ``X``, ``U`` and ``history = d``;
        with integral action also ``K_i`` (V/(A s) for the motor), ``C``, ``F`` and ``h``.
    P : ndarray, shape (n + d m + r_i, n + d m + r_i)
        Value matrix of the augmented state (the integrator's r_i = r states last with
        integral action, r_i = 0 without): the optimal cost from ``z_0`` is
        ``z_0' P z_0`` (for the motor in A^2 s times the unit of Q).
    h : float
        Sampling period, s.
    input_delay : int
        d: the voltage computed at sample k acts over ``[t_(k+d), t_(k+d+1))``.
    cost : {"digital", "sampled"}
        The cost minimized (see :func:`solve_digital_regulation`).
    Ad : ndarray, shape (n, n)
        ``expm(A h)`` (exact zero-order-hold discretization).
    Bd : ndarray, shape (n, m)
        Effect of the applied (held) voltage on ``x_(k+1)``, A/V for the motor.
    Ed : ndarray, shape (n, q)
        Effect of the held reference ``w_k`` on ``x_(k+1)``.
    Q : ndarray, shape (n, n)
        The continuous state weight given.
    R : ndarray, shape (m, m)
        The continuous input weight given.
    integral_weight : ndarray, shape (r, r), or None
        ``Q_i``, the weight of the integrator ``z``; None without integral action.
    """

    law: ControlLaw
    P: Array
    h: float
    input_delay: int
    cost: DigitalCost
    Ad: Array
    Bd: Array
    Ed: Array
    Q: Array
    R: Array
    integral_weight: Array | None = None


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


def _digital_weights(Q: Array, R: Array, h: float, size: int) -> tuple[Array, Array, Array]:
    """``Qz = blockdiag(h Q, 0)``, ``Rz = h R``, no cross weight."""
    n, m = Q.shape[0], R.shape[0]
    Qz = np.zeros((size, size))
    Qz[:n, :n] = h * Q
    return Qz, h * R, np.zeros((size, m))


def _sampled_weights(
    problem: RegulationProblem, Q: Array, R: Array, h: float, Az: Array, delay: int
) -> tuple[tuple[Array, Array, Array], Array]:
    """The sampled cost's weights on ``(z_k, u_k)``, charged d samples early, and the value
    of the first d stages (which no decision changes) as a quadratic form in ``z_0``.

    The stage of sample ``k + d`` is ``[x_(k+d); u_k]' W [x_(k+d); u_k]`` with
    ``x_(k+d) = Cz z_k`` (``Cz`` the first n rows of ``Az^d``): ``Qz = Cz' Qd Cz``,
    ``Nz = Cz' N``, ``Rz = Rd``.
    """
    n = problem.n
    Qd, Rd, N = sampled_data_weights(problem.A, problem.B, Q, R, h)
    W = np.block([[Qd, N], [N.T, Rd]])
    ahead = np.linalg.matrix_power(Az, delay)
    Cz = ahead[:n]
    weights = (Cz.T @ Qd @ Cz, Rd, Cz.T @ N)
    first_stages = np.zeros_like(Az)
    power = np.eye(Az.shape[0])
    for _ in range(delay):  # stage j: [x_j; u_(j-d)] = (first n + m rows of Az^j) z_0
        selected = power[: n + problem.m]
        first_stages += selected.T @ W @ selected
        power = Az @ power
    return weights, first_stages


def _with_integral_action(
    problem: RegulationProblem,
    Q_i: Array,
    h: float,
    plant: tuple[Array, Array],
    weights: tuple[Array, Array, Array],
    first_stages: Array,
) -> tuple[tuple[Array, Array], tuple[Array, Array, Array], Array]:
    """The delay-augmented plant, its weights and first stages extended with the digital
    integrator ``z_(k+1) = z_k + h C xbar_k``, weighted by ``h Q_i`` (no cross term)."""
    Az, Bz = plant
    Qz, Rz, Nz = weights
    size, r = Az.shape[0], problem.r
    C_full = np.zeros((r, size))
    C_full[:, : problem.n] = problem.C
    augmented = integrator_augmented(Az, Bz, C_full, h)
    Qz_i = np.zeros((size + r, size + r))
    Qz_i[:size, :size] = Qz
    Qz_i[size:, size:] = h * Q_i
    padded = np.zeros((size + r, size + r))
    padded[:size, :size] = first_stages
    return augmented, (Qz_i, Rz, np.vstack([Nz, np.zeros((r, Nz.shape[1]))])), padded


def _law(
    problem: RegulationProblem,
    K: Array,
    steady: tuple[Array, Array],
    delay: int,
    integral: tuple[Array | None, float],
) -> ControlLaw:
    """The law of a gain over ``[xbar; delayed inputs (; z)]``: the last r columns are
    ``K_i`` under integral action."""
    X, U = steady
    Q_i, h = integral
    if Q_i is None:
        return ControlLaw(K, X, U, history=delay)
    width = problem.n + delay * problem.m
    return ControlLaw(
        K[:, :width], X, U, history=delay, K_i=K[:, width:], C=problem.C, F=problem.F, h=h
    )


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
) -> DigitalSolution:
    """The optimal digital regulator of ``problem`` sampled at h with a delay of d samples.

    ``(X, U)`` solve the regulator equations (as :func:`solve_optimal_regulation`: E = 0,
    so they are those of continuous time and ``(Ad - I) X + Bd U + Ed = 0``). ``K`` and
    ``P`` are the DARE's of the delay-augmented plant (:func:`delay_augmented`), whose
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
    DigitalSolution

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
    Az, Bz = delay_augmented(Ad, Bd, delay)
    if cost == "digital":
        weights = _digital_weights(Q_, R_, period, Az.shape[0])
        first_stages = np.zeros_like(Az)
    else:
        weights, first_stages = _sampled_weights(problem, Q_, R_, period, Az, delay)
    if Q_i is not None:
        (Az, Bz), weights, first_stages = _with_integral_action(
            problem, Q_i, period, (Az, Bz), weights, first_stages
        )
    try:
        K, P = dlqr(Az, Bz, *weights)
    except UnsolvableError as exc:
        integrator = "" if Q_i is None else " and an integrator"
        raise UnsolvableError(
            f"the plant sampled at h = {period:g} s with a delay of {delay} samples"
            f"{integrator}: {exc}"
        ) from None
    P = P + first_stages
    P = 0.5 * (P + P.T)
    for matrix in (P, Ad, Bd, Ed, Q_, R_):
        matrix.setflags(write=False)
    if Q_i is not None:
        Q_i.setflags(write=False)
    return DigitalSolution(
        law=_law(problem, K, (X, U), delay, (Q_i, period)),
        P=P,
        h=period,
        input_delay=delay,
        cost=cost,
        Ad=Ad,
        Bd=Bd,
        Ed=Ed,
        Q=Q_,
        R=R_,
        integral_weight=Q_i,
    )
