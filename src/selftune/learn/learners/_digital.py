"""The discrete-time ADP learner: the optimal digital controller, exact from samples.

The drive's loop as the controller sees it at sample k (delay d, optional integrator)::

    zeta_k = [xbar_k; u_(k-d); ...; u_(k-1); z_k],    xbar_k = x_k - X w_k
    zeta_(k+1)^- = Az zeta_k + Bz u_k + Gz w_k,        z_(k+1) = z_k + h C xbar_k

with ``u_k`` the voltage computed at sample k, ``X`` the unique solution of
``C X + F = 0`` and ``zeta_(k+1)^-`` built with ``w_k`` (the reference may step at the
sample instant; what it does after is the next transition's). Az, Bz, Gz are unknown. For
any policy ``u = -K_j zeta`` the value matrix ``P_j`` satisfies the discrete Lyapunov
equation, and along ANY applied inputs (off-policy; Bradtke, Ydstie & Barto 1994, Lewis &
Vrabie 2009, the discrete-time counterpart of Jiang & Jiang 2012), with
``e_k = u_k + K_j zeta_k``::

    gamma zeta^-' P zeta^- - zeta' P zeta = -zeta' (Qz + K_j' Rz K_j) zeta
        + 2 e' S_K zeta + e' S_uu e - 2 (K_j zeta)' S_uu e
        + 2 w' S_wz zeta + 2 u' S_wu w + w' S_ww w

which is linear in the unknowns ``P``, ``S_K = gamma Bz'P Az``, ``S_uu = gamma Bz'P Bz``,
``S_wz = gamma Gz'P Az``, ``S_wu = gamma Bz'P Gz`` and ``S_ww = gamma Gz'P Gz``: one row per
sample, no quadrature, so it is exact on noise-free data at any sampling period. Policy
improvement is ``K_(j+1) = (Rz + S_uu)^-1 S_K``. The digital cost is
``sum_k h (xbar_k' Q xbar_k + u_k' R u_k + z_k' Q_i z_k)``: ``Qz = h diag(Q, 0, Q_i)``,
``Rz = h R``.

The feedforward follows from the regulator identity ``Gz = [-Bd U; 0]`` (``E = 0``): with
``G = -Bd U`` the exogenous blocks give ``Bd' P_xx G = -(Bd' P_xx Bd) U`` for the positive
definite ``P_xx``; ``Bd' P_xx Bd`` and ``G' P_xx Bd`` are read off ``S_uu, S_wu`` (d = 0).
With a delay (d >= 1, the oldest delayed input enters the plant through Bd) the newest
delayed input's row of P gives ``P_lx Bd U = -P_lx G`` directly from ``S_K`` and
``S_wu`` (:func:`_feedforward`; ``Az' P Az`` from the Lyapunov identity where ``P_lx Bd``
is ill conditioned).

With integral action the initial policy ``[K0, 0, 0]`` leaves the integrator at the
stability limit, so policy iteration starts on the discounted cost (``gamma < 1``, for
which it is stabilizing) and raises ``gamma`` to 1 (Lamperski 2020).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from functools import partial

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ...core import (
    RANK_TOLERANCE,
    Array,
    unvec,
    unvecs,
    vec,
    vecs,
    vecs_hat,
    vecs_hat_from_outer,
)
from ...errors import InputError, PolicyIterationFailure, TooShort
from ...loop import LoopWeights, SampledLoop
from .._problem import LearningOptions, LearningProblem
from .._result import LearnedController
from ..data._trajectory import Trajectory
from ..evidence._alignment import applied_inputs
from ._continuous import solutions_of_output_equation
from ._policy_iteration import IterationRecord, PolicyStep, discounted_policy_iteration
from ._regression import Regression, RegressionSolution, solve_regression

__all__ = ["DigitalTransitions", "digital_transitions", "learn_digital_adp", "steady_state_map"]

#: The discounts of the schedule used when the initial policy does not stabilize the
#: integrator: each is run to convergence before the next.
DISCOUNTS = (0.9, 0.99, 0.999, 0.9999, 0.99999, 1.0)

#: The condition number of ``P_lx Bd`` below which the feedforward is read off the
#: regression directly (:func:`_feedforward`); 1 on the motors of the tests.
DIRECT_CONDITION = 1e6


@dataclass(frozen=True)
class DigitalTransitions:
    """The transitions of the controller's state, built from logs.

    Attributes
    ----------
    zeta : ndarray, shape (T, nz)
        ``[xbar_k; u_(k-d); ...; u_(k-1); z_k]`` at each transition's start.
    zeta_next : ndarray, shape (T, nz)
        The same at its end, built with ``w_k`` (``zeta_(k+1)^-``).
    command : ndarray, shape (T, m)
        ``u_k``, the voltage computed at sample k.
    w : ndarray, shape (T, q)
        The reference held over the sample.
    n, m, q, delay, r : int
        Dimensions: state, input, reference, the delay d and the integrator's r.
    h : float
        Sampling period, s.
    starts : ndarray of int
        The first transition of each regression row: consecutive transitions of one log
        are summed into one row (an interval), which keeps the identity exact and lets
        the state's change over the interval, not over one sample, stand against the
        measurement noise.
    instruments : DigitalTransitions or None
        The same transitions of noise-free states simulated from the same inputs (an
        output-error model's): the rows built from them are the instruments of an
        instrumental-variable solve, consistent under white measurement noise.
    """

    zeta: Array
    zeta_next: Array
    command: Array
    w: Array
    n: int
    m: int
    q: int
    delay: int
    r: int
    h: float
    starts: NDArray[np.intp]
    instruments: DigitalTransitions | None = None

    @property
    def nz(self) -> int:
        """Dimension of zeta, ``n + d m + r``."""
        return self.n + self.delay * self.m + self.r


def _episode_rows(
    episode: Trajectory, shift: int, delay: int, X: Array, integrator: Array | None
) -> tuple[Array, Array, Array, Array] | None:
    """The rows ``(zeta, zeta_next, command, w)`` of one log (None if too short)."""
    a, first = applied_inputs(episode, shift)
    count = a.shape[0] - delay  # transitions k = first .. first + count - 1
    count = min(count, episode.num_samples - first)
    if count < 1:
        return None
    q = X.shape[1]
    w_all = np.zeros((episode.num_samples, 0)) if episode.w is None else episode.w
    k = first + np.arange(count)
    w = w_all[k] if q else np.zeros((count, 0))
    xbar = episode.x[k] - w @ X.T
    xbar_next = episode.x[k + 1] - w @ X.T
    registers = [a[j : j + count] for j in range(delay)]
    registers_next = [a[j + 1 : j + 1 + count] for j in range(delay)]
    command = a[delay : delay + count]
    parts, parts_next = [xbar, *registers], [xbar_next, *registers_next]
    if integrator is not None:
        steps = episode.t[1:] - episode.t[:-1]
        error = xbar @ integrator.T * steps[k][:, None]  # h C xbar_k (C X + F = 0)
        z = np.cumsum(np.vstack([np.zeros((1, error.shape[1])), error]), axis=0)
        parts.append(z[:-1])
        parts_next.append(z[1:])
    return np.hstack(parts), np.hstack(parts_next), command, w


def digital_transitions(
    episodes: Sequence[Trajectory],
    X: Array,
    *,
    shift: int,
    delay: int,
    h: float,
    C: Array | None = None,
    interval: int = 1,
) -> DigitalTransitions:
    """The controller-state transitions of logs aligned with ``shift``.

    Parameters
    ----------
    episodes : sequence of Trajectory
        The logs (uniform sampling, ``w`` held).
    X : ndarray, shape (n, q)
        ``xbar = x - X w``.
    shift : int
        The voltage applied during sample k is in row ``k - shift`` of the log.
    delay : int
        d: the voltage computed at k is applied at ``k + d``.
    h : float
        Sampling period, s.
    C : ndarray, shape (r, n), optional
        With integral action: the integrator ``z_(k+1) = z_k + h C xbar_k`` is part of the
        state (it starts at 0 in each log).
    interval : int
        Transitions summed into each regression row (within a log).

    Returns
    -------
    DigitalTransitions
    """
    rows = [_episode_rows(episode, shift, delay, X, C) for episode in episodes]
    kept = [row for row in rows if row is not None]
    if not kept:
        raise TooShort("the logs are too short for the input delay and alignment")
    zeta, zeta_next, command, w = (np.concatenate([row[i] for row in kept]) for i in range(4))
    offsets = np.cumsum([0] + [row[0].shape[0] for row in kept])
    starts = np.concatenate(
        [np.arange(offsets[i], offsets[i + 1], interval) for i in range(len(kept))]
    )
    first = episodes[0]
    return DigitalTransitions(
        zeta=zeta,
        zeta_next=zeta_next,
        command=command,
        w=w,
        n=first.n,
        m=first.m,
        q=X.shape[1],
        delay=delay,
        r=0 if C is None else C.shape[0],
        h=h,
        starts=starts,
    )


def _regression(
    data: DigitalTransitions, K: Array, weights: LoopWeights, gamma: float
) -> Regression:
    """Rows of the discrete Bellman identity for the policy ``K`` (see the module), with
    the instruments' rows when the data carry them."""
    rows = _rows(data, K, weights, gamma)
    if data.instruments is None:
        return rows
    return replace(rows, instruments=_rows(data.instruments, K, weights, gamma).Psi)


#: Transitions whose regression rows are made at once: the rows of a long log (55 columns
#: of float64 for the servo problem) are summed per interval block by block, whole
#: intervals at a time (a 1,000,000-row log held 1.9 GB of rows at once).
ROW_BLOCK = 2**16


def _rows(data: DigitalTransitions, K: Array, weights: LoopWeights, gamma: float) -> Regression:
    nz, m, q = data.nz, data.m, data.q
    sizes = {"P": nz * (nz + 1) // 2, "K": m * nz, "Huu": m * (m + 1) // 2}
    if q:
        sizes.update({"M": q * nz, "Mu": m * q, "Mw": q * (q + 1) // 2})
    weight = weights.Qz + K.T @ weights.Rz @ K
    starts = data.starts
    # block edges: the first interval start in each ROW_BLOCK of transitions
    edges = starts[np.flatnonzero(np.diff(starts // ROW_BLOCK, prepend=-1))]
    ends = [*edges[1:], data.zeta.shape[0]]
    Psi, b = [], []
    for first, stop in zip(edges, ends, strict=True):
        block = slice(int(first), int(stop))
        local = starts[(starts >= first) & (starts < stop)] - first
        columns, values = _block_rows(
            (data.zeta[block], data.zeta_next[block], data.command[block], data.w[block]),
            K, weight, gamma, q,
        )  # fmt: skip
        Psi.append(np.add.reduceat(columns, local, axis=0))
        b.append(np.add.reduceat(values, local))
    return Regression(Psi=np.vstack(Psi), b=np.concatenate(b), block_sizes=sizes)


def _block_rows(
    transitions: tuple[Array, Array, Array, Array], K: Array, weight: Array, gamma: float, q: int
) -> tuple[Array, Array]:
    """The regression's rows and right-hand side of transitions ``(zeta, zeta_next, u,
    w)``, one per transition."""
    zeta, zeta_next, u, w = transitions
    a = zeta @ K.T
    e = u + a
    outer_e = e[:, :, None] * e[:, None, :] - a[:, :, None] * e[:, None, :]
    outer_e = outer_e - e[:, :, None] * a[:, None, :]
    columns = [
        gamma * vecs_hat(zeta_next) - vecs_hat(zeta),
        -2.0 * _vec_rows(e, zeta),
        -vecs_hat_from_outer(outer_e),
    ]
    if q:
        columns += [-2.0 * _vec_rows(w, zeta), -2.0 * _vec_rows(u, w), -vecs_hat(w)]
    return np.hstack(columns), -np.einsum("ka,ab,kb->k", zeta, weight, zeta)


def _vec_rows(left: Array, right: Array) -> Array:
    """``vec(left_k right_k')`` for each row k (column-major), shape (T, a * b)."""
    outer = left[:, :, None] * right[:, None, :]
    return outer.transpose(0, 2, 1).reshape(left.shape[0], -1)


@dataclass(frozen=True)
class _Blocks:
    P: Array
    S_K: Array
    S_uu: Array
    S_wz: Array
    S_wu: Array


def _blocks(solution: RegressionSolution, data: DigitalTransitions) -> _Blocks:
    nz, m, q = data.nz, data.m, data.q
    theta = solution.theta
    sizes = [nz * (nz + 1) // 2, m * nz, m * (m + 1) // 2, q * nz, m * q]
    edges = np.cumsum([0, *sizes])
    part = [theta[edges[i] : edges[i + 1]] for i in range(len(sizes))]
    return _Blocks(
        P=unvecs(part[0], nz),
        S_K=unvec(part[1], m, nz),
        S_uu=unvecs(part[2], m),
        S_wz=unvec(part[3], q, nz) if q else np.zeros((0, nz)),
        S_wu=unvec(part[4], m, q) if q else np.zeros((m, 0)),
    )


@dataclass(frozen=True)
class _Coordinates:
    """The regression's coordinates of the controller's state: ``zeta = T zeta~``, with
    ``zeta~`` of unit second moment over the data.

    The Bellman identity is the same in any coordinates (``P~ = T'P T``, ``S_K~ = S_K T``,
    ``S_wz~ = S_wz T``, ``K~ = K T``, ``Qz~ = T'Qz T``; ``S_uu``, ``S_wu``, ``S_ww`` as they
    are), but its regression is not as well conditioned in all: the columns of the
    quadratic monomials are scaled one by one, and on a stiff plant the logged states mix
    modes whose sizes differ by orders of magnitude, so that a slow mode's columns are a
    difference of much larger ones. Rounding then looks like a lack of rank (six states
    with poles from 1e-3 to 1e5 rad/s: singular values below 1e-9 of the largest in the
    states' own coordinates, 1e-7 in these). The identity's rows are built in ``zeta~``
    and every result is read back in ``zeta``.

    Attributes
    ----------
    T : ndarray, shape (nz, nz)
        ``zeta = T zeta~`` (the identity where the states' second moment is singular).
    data : DigitalTransitions
        The transitions in ``zeta~``.
    weights : LoopWeights
        The weights over ``zeta~``.
    """

    T: Array
    data: DigitalTransitions
    weights: LoopWeights


def _coordinates(data: DigitalTransitions, weights: LoopWeights) -> _Coordinates:
    """The coordinates of unit second moment (see :class:`_Coordinates`): ``T = R'`` of
    the triangular factor of the states ``zeta = Q R``."""
    scale = np.linalg.norm(data.zeta, axis=0)
    if np.any(scale == 0.0) or not np.all(np.isfinite(data.zeta)):
        T = np.eye(data.nz)
    else:
        factor = np.linalg.qr(data.zeta / scale, mode="r")
        if np.linalg.cond(factor) * RANK_TOLERANCE >= 1.0:
            T = np.eye(data.nz)
        else:
            T = (factor * scale[None, :] / np.sqrt(data.zeta.shape[0])).T
    inverse = np.linalg.inv(T)

    def moved(transitions: DigitalTransitions) -> DigitalTransitions:
        return replace(
            transitions,
            zeta=transitions.zeta @ inverse.T,
            zeta_next=transitions.zeta_next @ inverse.T,
            instruments=None if transitions.instruments is None else moved(transitions.instruments),
        )

    moved_weights = LoopWeights(
        Qz=T.T @ weights.Qz @ T,
        Rz=weights.Rz,
        Nz=T.T @ weights.Nz,
        first_stages=T.T @ weights.first_stages @ T,
    )
    return _Coordinates(T=T, data=moved(data), weights=moved_weights)


def _theta_back(theta: Array, data: DigitalTransitions, T: Array) -> Array:
    """The regression's unknowns solved in ``zeta~ = T^-1 zeta``, in ``zeta``'s."""
    nz, m, q = data.nz, data.m, data.q
    inverse = np.linalg.inv(T)
    sizes = [nz * (nz + 1) // 2, m * nz, m * (m + 1) // 2, q * nz, m * q]
    edges = np.cumsum([0, *sizes])
    P = inverse.T @ unvecs(theta[edges[0] : edges[1]], nz) @ inverse
    S_K = unvec(theta[edges[1] : edges[2]], m, nz) @ inverse
    parts = [vecs(0.5 * (P + P.T)), vec(S_K), theta[edges[2] : edges[3]]]
    if q:
        parts.append(vec(unvec(theta[edges[3] : edges[4]], q, nz) @ inverse))
    parts.append(theta[edges[4 if q else 3] :])
    return np.concatenate(parts)


def _step(
    data: DigitalTransitions,
    weights: LoopWeights,
    coordinates: _Coordinates,
    gamma: float,
    K: Array,
    iteration: int,
) -> IterationRecord:
    """Evaluate ``K`` (= K_j) on the data and improve it (the regression in
    ``coordinates``, the results in the data's)."""
    # S_ww, the value's part quadratic in w, is a nuisance no policy or feedforward uses:
    # its columns may be collinear (a constant w_1 beside the dead-time channels, whose
    # squares add up to a constant), and its minimum-norm part is then as good as any
    regression = _regression(coordinates.data, K @ coordinates.T, coordinates.weights, gamma)
    solution = solve_regression(regression, allow_deficient=("Mw",))
    solution = replace(solution, theta=_theta_back(solution.theta, data, coordinates.T))
    blocks = _blocks(solution, data)
    eigenvalues = np.linalg.eigvalsh(blocks.P)
    # P is positive semidefinite: delayed inputs the plant does not feel cost nothing
    if eigenvalues[-1] <= 0.0 or eigenvalues[0] < -RANK_TOLERANCE * eigenvalues[-1]:
        raise PolicyIterationFailure(
            f"digital policy iteration step {iteration}: the learned P is not positive "
            f"semidefinite (eigenvalues from {eigenvalues[0]:.3g} to {eigenvalues[-1]:.3g}); "
            "K0 may not stabilize the sampled loop with its delay, or the data are too "
            "noisy or too short",
            step=iteration,
            symptom="P not positive semidefinite",
        )
    K_next = np.asarray(np.linalg.solve(weights.Rz + blocks.S_uu, blocks.S_K), dtype=np.float64)
    return IterationRecord(
        iteration=iteration,
        P=blocks.P,
        K=K_next,
        theta=solution.theta,
        change=float("inf"),
        regression=solution,
        coordinates=coordinates.T,
    )


def _feedforward(
    data: DigitalTransitions, K: Array, blocks: _Blocks, weights: LoopWeights
) -> Array:
    """U from the exogenous blocks (see the module docstring).

    With a delay (d >= 1) the last delayed input's row of the value gives ``S_wu =
    gamma P_lx G`` and ``S_K[:, oldest] = gamma P_lx Bd`` (``P_lx`` the block of P between
    the newest delayed input and x; the oldest enters the plant through Bd), so ``P_lx Bd
    U = -P_lx G`` is read off the regression directly; where ``P_lx Bd`` is ill
    conditioned, ``Bd' P_xx Bd`` and ``G' P_xx Bd`` come from the Lyapunov identity (a
    difference of large terms, which loses digits: 1e-9 where the direct route gives
    3e-11 on the motors of the tests).
    """
    n, m = data.n, data.m
    if data.delay:
        direct = blocks.S_K[:, n : n + m]
        if np.linalg.cond(direct) < DIRECT_CONDITION:
            return np.asarray(-np.linalg.solve(direct, blocks.S_wu), dtype=np.float64)
    if data.delay == 0:
        B_P_B, G_P_B = blocks.S_uu, blocks.S_wu.T
    else:
        W = weights.Qz + K.T @ weights.Rz @ K
        A_P_A = blocks.P - W + K.T @ blocks.S_K + blocks.S_K.T @ K - K.T @ blocks.S_uu @ K
        oldest = slice(n, n + m)
        B_P_B, G_P_B = A_P_A[oldest, oldest], blocks.S_wz[:, oldest]
    B_P_B = 0.5 * (B_P_B + B_P_B.T)
    if np.min(np.linalg.eigvalsh(B_P_B)) <= 0.0:
        raise PolicyIterationFailure(
            "the learned Bd' P Bd is not positive definite: the inputs do not act "
            "independently on the state, so the feedforward U is not determined",
            step=None,
            symptom="Bd' P Bd not positive definite",
        )
    return np.asarray(-np.linalg.solve(B_P_B, G_P_B.T), dtype=np.float64)


def steady_state_map(problem: LearningProblem) -> Array:
    """X, the unique solution of ``C X + F = 0`` (n x 0 without regulation): the digital
    ADP learner builds ``xbar = x - X w`` with it.

    Parameters
    ----------
    problem : LearningProblem
        C and F.

    Raises
    ------
    InputError
        If X is not unique (C not of full column rank).
    """
    if problem.C is None or problem.F is None:
        return np.zeros((problem.n, 0))
    X, null_basis = solutions_of_output_equation(problem.C, problem.F)
    if null_basis:
        raise InputError(
            "C: the digital ADP learner needs a unique X from C X + F = 0 (C of full column "
            "rank); use method = 'identify' for this problem"
        )
    return X


def learn_digital_adp(
    data: DigitalTransitions,
    problem: LearningProblem,
    K0: ArrayLike,
    options: LearningOptions | None = None,
) -> LearnedController:
    """Off-policy policy iteration on the discrete Bellman identity, and the feedforward.

    Parameters
    ----------
    data : DigitalTransitions
        The controller-state transitions (:func:`digital_transitions`, built with the
        problem's :func:`steady_state_map` and, with integral action, its C).
    problem : LearningProblem
        The weights of the digital cost (Q, R and, with integral action, Q_i) and the
        regulated output (C, F) of the law's integrator.
    K0 : array_like, shape (m, n) or (m, nz)
        The stabilizing policy the data start from.
    options : LearningOptions, optional
        ``max_iterations`` and ``tolerance`` of each policy iteration.

    Returns
    -------
    LearnedController
        ``u_k = U w_k - K [xbar_k; ubar_(k-d); ...; ubar_(k-1)] - K_i z_k`` (history d),
        the value of the last policy evaluated (over zeta), every policy-iteration step
        (all discounts); B is not estimated (None), and there is no verdict.

    Raises
    ------
    ExcitationError, ConvergenceError, InputError
    """
    options = LearningOptions() if options is None else options
    m, r = data.m, data.r
    if (data.n, data.m, data.r) != (problem.n, problem.m, problem.r if r else 0):
        raise InputError(
            f"data: transitions of n = {data.n}, m = {data.m}, r = {data.r} do not fit the "
            f"problem's Q, R, C ({problem.n}, {problem.m}, {problem.r})"
        )
    if r:
        loop = SampledLoop(
            data.h, data.delay, C=problem.C, F=problem.F, Q_i=problem.integral_weight
        )
    else:
        loop = SampledLoop(data.h, data.delay)
    weights = loop.weights(problem.Q, problem.R)
    K = problem.initial_policy(K0, extra=data.nz - data.n)

    coordinates = _coordinates(data, weights)

    def step_at(gamma: float) -> PolicyStep:
        return partial(_step, data, weights, coordinates, gamma)

    schedule = DISCOUNTS if r else (1.0,)
    settings = (options.max_iterations, options.tolerance)
    history, stages = discounted_policy_iteration(step_at, K, settings, schedule)
    blocks = _blocks(history[-1].regression, data)
    U = _feedforward(data, stages[-1].evaluated, blocks, weights) if data.q else np.zeros((m, 0))
    return LearnedController(
        law=loop.law(history[-1].K, steady_state_map(problem), U),
        P=history[-1].P,
        B=None,
        history=tuple(history),
        target="digital",
        h=data.h,
        input_delay=data.delay,
    )
