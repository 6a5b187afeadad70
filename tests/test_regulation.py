"""The model-based optimum against independent truth.

Oracles:

- python-control's ``lqr`` and ``care``. Without slycot installed (as here) both call
  ``scipy.linalg.solve_continuous_are``, the same solver selftune calls, so they are
  also checked against a solver that shares nothing with it: the ordered real Schur form
  of the Hamiltonian matrix (stable invariant subspace), written out below.
- The regulator equations are rebuilt here by applying the map ``(X, U) -> (AX + BU - XE,
  CX)`` to unit matrices, not from the Kronecker formula; the min-trace pair of Remark 2
  is checked against the closed-form KKT solution ``z = W^-1 N' (N W^-1 N')^-1 c``, against
  scipy's SLSQP, and by moving along the null space of the constraints.
- Value matrices of policies are checked against a Kronecker-form linear solve of the
  Lyapunov equation (not scipy's Bartels-Stewart).

Random systems are drawn from a hypothesis-chosen seed (Gaussian entries, so they are
generic). Tests that compare *forward* errors at 1e-9 keep only systems whose Riccati
equation is well conditioned (see :func:`_care_condition`); the backward error (the ARE
residual) is checked on every system.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import control
import numpy as np
import pytest
import scipy.linalg
import scipy.optimize
from hypothesis import assume, example, given, target
from hypothesis import strategies as st
from numpy.typing import ArrayLike

from example_counts import at_least
from selftune import (
    InputError,
    RegulationProblem,
    UnsolvableError,
    lqr,
    policy_value,
    solve_optimal_regulation,
)
from selftune.core import unpack_theta

Array = np.ndarray

#: Bar for agreement with the oracles (relative Frobenius norm of the difference).
AGREEMENT = 1e-9
#: Bar for the regulator-equation residuals, relative to the norms of the terms.
RESIDUAL = 1e-10
#: Systems whose Riccati condition estimate exceeds this are not used for forward errors:
#: with a backward error of ~1e-16 the forward error is then at most ~1e-11.
MAX_CARE_CONDITION = 1e5

SEEDS = st.integers(min_value=0, max_value=2**32 - 1)


def _relative(actual: Array, expected: Array) -> float:
    return float(np.linalg.norm(actual - expected) / np.linalg.norm(expected))


# -- random data -----------------------------------------------------------------------------


def _random_spd(rng: np.random.Generator, size: int, floor: float) -> Array:
    G = rng.standard_normal((size, size))
    return G @ G.T / size + floor * np.eye(size)


@dataclass(frozen=True)
class LqrCase:
    A: Array
    B: Array
    Q: Array
    R: Array


def _random_lqr_case(seed: int, n: int, m: int, shift: float, q_floor: float) -> LqrCase:
    """A random ``(A, B, Q, R)``: A Gaussian with its spectrum shifted by ``shift`` (so some
    are open-loop unstable), B Gaussian (full rank), Q = GG'/n + q_floor I, R = HH'/m + I/2."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n)) / np.sqrt(n) + shift * np.eye(n)
    B = rng.standard_normal((n, m))
    Q = _random_spd(rng, n, q_floor)
    R = _random_spd(rng, m, 0.5)
    return LqrCase(A, B, Q, R)


@st.composite
def lqr_cases(draw: st.DrawFn, max_n: int = 8, max_m: int = 4) -> LqrCase:
    n = draw(st.integers(min_value=1, max_value=max_n))
    m = draw(st.integers(min_value=1, max_value=max_m))
    shift = draw(st.floats(min_value=-1.0, max_value=1.0))
    q_floor = draw(st.floats(min_value=1e-2, max_value=1.0))
    case = _random_lqr_case(draw(SEEDS), n, m, shift, q_floor)
    assume(np.linalg.matrix_rank(case.B) == min(n, m))
    return case


def _rotation(frequency: float) -> Array:
    return np.array([[0.0, frequency], [-frequency, 0.0]])


def _random_exosystem(rng: np.random.Generator, rotations: int, zero_modes: int) -> Array:
    """E = blockdiag(rotations [[0, w], [-w, 0]], zero block): eigenvalues +-jw and 0."""
    blocks = [_rotation(float(rng.uniform(0.2, 5.0))) for _ in range(rotations)]
    if zero_modes:
        blocks.append(np.zeros((zero_modes, zero_modes)))
    return scipy.linalg.block_diag(*blocks)


@dataclass(frozen=True)
class RegulationCase:
    problem: RegulationProblem
    Q: Array
    R: Array


def _random_regulation_case(
    seed: int, n: int, m: int, r: int, rotations: int, zero_modes: int, shift: float
) -> RegulationCase:
    lqr_case = _random_lqr_case(seed, n, m, shift, 0.1)
    rng = np.random.default_rng(seed + 1)
    E = _random_exosystem(rng, rotations, zero_modes)
    q = E.shape[0]
    problem = RegulationProblem(
        A=lqr_case.A,
        B=lqr_case.B,
        C=rng.standard_normal((r, n)),
        D=rng.standard_normal((n, q)),
        E=E,
        F=rng.standard_normal((r, q)),
    )
    return RegulationCase(problem, lqr_case.Q, lqr_case.R)


@st.composite
def regulation_cases(
    draw: st.DrawFn, max_n: int = 6, max_m: int = 4, max_blocks: int = 2, m_above_r: bool = False
) -> RegulationCase:
    """A random, generically solvable problem: E with rotations and/or zero modes,
    r <= min(m, n) (r < m when ``m_above_r``: the regulator solution is then not unique)."""
    n = draw(st.integers(min_value=1, max_value=max_n))
    m = draw(st.integers(min_value=2 if m_above_r else 1, max_value=max_m))
    r_max = min(m - 1 if m_above_r else m, n)
    r = draw(st.integers(min_value=1, max_value=r_max))
    rotations = draw(st.integers(min_value=0, max_value=max_blocks))
    zero_modes = draw(st.integers(min_value=0 if rotations else 1, max_value=max_blocks))
    shift = draw(st.floats(min_value=-1.0, max_value=1.0))
    return _random_regulation_case(draw(SEEDS), n, m, r, rotations, zero_modes, shift)


def _problem(
    A: ArrayLike, B: ArrayLike, C: ArrayLike, D: ArrayLike, E: ArrayLike, F: ArrayLike
) -> RegulationProblem:
    """A problem from hand-written matrices (the dataclass fields are typed as arrays)."""
    matrices = (np.asarray(M, dtype=float) for M in (A, B, C, D, E, F))
    return RegulationProblem(*matrices)


# -- independent oracles -----------------------------------------------------------------------


def _hamiltonian_care(A: Array, B: Array, Q: Array, R: Array) -> Array:
    """Stabilizing ARE solution from the stable invariant subspace of the Hamiltonian."""
    n = A.shape[0]
    H = np.block([[A, -B @ np.linalg.solve(R, B.T)], [-Q, -A.T]])
    _, Z, stable = scipy.linalg.schur(H, sort="lhp")
    assert stable == n
    P = np.linalg.solve(Z[:n, :n].T, Z[n:, :n].T).T
    return 0.5 * (P + P.T)


def _lyapunov_by_kronecker(closed_loop: Array, weight: Array) -> Array:
    """Solve ``closed_loop' P + P closed_loop + weight = 0`` as one linear system."""
    n = closed_loop.shape[0]
    operator = np.kron(np.eye(n), closed_loop.T) + np.kron(closed_loop.T, np.eye(n))
    P = np.linalg.solve(operator, -weight.ravel(order="F")).reshape((n, n), order="F")
    return 0.5 * (P + P.T)


def _care_condition(A: Array, B: Array, Q: Array, R: Array, P: Array) -> float:
    """First-order relative condition estimate of the ARE at its solution P:
    ||L^-1|| (2||A|| ||P|| + ||BR^-1B'|| ||P||^2 + ||Q||) / ||P||, L the closed-loop
    Lyapunov operator."""
    n = A.shape[0]
    S = B @ np.linalg.solve(R, B.T)
    closed_loop = A - S @ P
    operator = np.kron(np.eye(n), closed_loop.T) + np.kron(closed_loop.T, np.eye(n))
    separation = float(np.linalg.svd(operator, compute_uv=False)[-1])
    size = float(np.linalg.norm(P, 2))
    data = (
        2.0 * float(np.linalg.norm(A, 2)) * size
        + float(np.linalg.norm(S, 2)) * size**2
        + float(np.linalg.norm(Q, 2))
    )
    return data / (separation * size)


def _are_relative_residual(A: Array, B: Array, Q: Array, R: Array, P: Array) -> float:
    S = B @ np.linalg.solve(R, B.T)
    residual = A.T @ P + P @ A - P @ S @ P + Q
    scale = (
        2.0 * np.linalg.norm(A) * np.linalg.norm(P)
        + np.linalg.norm(P) ** 2 * np.linalg.norm(S)
        + np.linalg.norm(Q)
    )
    return float(np.linalg.norm(residual) / scale)


def _regulator_operator(problem: RegulationProblem) -> tuple[Array, Array]:
    """``N z = c`` of the regulator equations, built column by column from the map itself:
    ``z = [vec X; vec U]`` (column-major), rows ``[vec(AX + BU - XE); vec(CX)]``."""
    n, m, q = problem.n, problem.m, problem.q
    A, B, C, D, E, F = (problem.A, problem.B, problem.C, problem.D, problem.E, problem.F)
    columns = []
    for k in range((n + m) * q):
        z = np.zeros((n + m) * q)
        z[k] = 1.0
        X = z[: n * q].reshape((n, q), order="F")
        U = z[n * q :].reshape((m, q), order="F")
        image = np.concatenate([(A @ X + B @ U - X @ E).ravel(order="F"), (C @ X).ravel(order="F")])
        columns.append(image)
    c = -np.concatenate([D.ravel(order="F"), F.ravel(order="F")])
    return np.column_stack(columns), c


def _weight(problem: RegulationProblem, Q: Array, R: Array) -> Array:
    """W with z'Wz = Tr(X'QX + U'RU) for z = [vec X; vec U]."""
    identity = np.eye(problem.q)
    return scipy.linalg.block_diag(np.kron(identity, Q), np.kron(identity, R))


def _stack(X: Array, U: Array) -> Array:
    return np.concatenate([X.ravel(order="F"), U.ravel(order="F")])


def _relative_residuals(problem: RegulationProblem, X: Array, U: Array) -> tuple[float, float]:
    """The residuals of eq. 7 relative to the norms of their terms:
    ||AX + BU + D - XE|| / (||A|| ||X|| + ||B|| ||U|| + ||D|| + ||X|| ||E||) and
    ||CX + F|| / (||C|| ||X|| + ||F||) (Frobenius norms), computed here and by
    :meth:`RegulationProblem.regulator_residuals` (the two must agree)."""
    A, B, C, D, E, F = (problem.A, problem.B, problem.C, problem.D, problem.E, problem.F)
    first = np.linalg.norm(A @ X + B @ U + D - X @ E)
    second = np.linalg.norm(C @ X + F)
    reported = problem.regulator_residuals(X, U)
    np.testing.assert_allclose(reported, (first, second), rtol=1e-12, atol=1e-300)

    def size(M: Array) -> float:
        return float(np.linalg.norm(M))

    scale_first = size(A) * size(X) + size(B) * size(U) + size(D) + size(X) * size(E)
    scale_second = size(C) * size(X) + size(F)
    return float(first) / scale_first, float(second) / max(scale_second, 1e-300)


def _condition(M: Array) -> float:
    singular_values = np.linalg.svd(M, compute_uv=False)
    return float(singular_values[0] / singular_values[-1])


# -- 1. K and P against python-control and the Hamiltonian ----------------------------------------


@at_least(150)
@given(lqr_cases())
@example(_random_lqr_case(seed=8, n=8, m=4, shift=0.5, q_floor=0.1))
@example(_random_lqr_case(seed=1, n=8, m=1, shift=-0.5, q_floor=0.1))
def test_lqr_agrees_with_python_control_and_the_hamiltonian(case: LqrCase) -> None:
    A, B, Q, R = case.A, case.B, case.Q, case.R
    K_control, P_control, _ = control.lqr(A, B, Q, R)
    P_care, _, _ = control.care(A, B, Q, R)
    assume(_care_condition(A, B, Q, R, P_control) <= MAX_CARE_CONDITION)
    P_hamiltonian = _hamiltonian_care(A, B, Q, R)
    K_hamiltonian = np.linalg.solve(R, B.T @ P_hamiltonian)

    K, P = lqr(A, B, Q, R)

    differences = [
        _relative(K, K_control),
        _relative(P, P_control),
        _relative(P, P_care),
        _relative(P, P_hamiltonian),
        _relative(K, K_hamiltonian),
    ]
    target(max(differences), label="worst relative difference")
    assert max(differences) <= AGREEMENT, differences


@at_least(100)
@given(regulation_cases(max_n=8, max_m=4))
@example(_random_regulation_case(6, n=8, m=4, r=3, rotations=2, zero_modes=1, shift=0.4))
def test_solve_optimal_regulation_feedback_agrees_with_python_control(
    case: RegulationCase,
) -> None:
    problem = case.problem
    A, B, Q, R = problem.A, problem.B, case.Q, case.R
    K_control, P_control, _ = control.lqr(A, B, Q, R)
    assume(_care_condition(A, B, Q, R, P_control) <= MAX_CARE_CONDITION)
    P_hamiltonian = _hamiltonian_care(A, B, Q, R)

    solution = solve_optimal_regulation(problem, Q, R)

    differences = [
        _relative(solution.K, K_control),
        _relative(solution.P, P_control),
        _relative(solution.P, P_hamiltonian),
    ]
    target(max(differences), label="worst relative difference")
    assert max(differences) <= AGREEMENT, differences


@at_least(100)
@given(
    st.builds(
        _random_lqr_case,
        seed=SEEDS,
        n=st.integers(min_value=1, max_value=8),
        m=st.integers(min_value=1, max_value=4),
        shift=st.floats(min_value=-1.0, max_value=2.0),
        q_floor=st.floats(min_value=1e-3, max_value=1.0),
    )
)
def test_lqr_backward_error_is_tiny_even_when_ill_conditioned(case: LqrCase) -> None:
    # No conditioning filter here: whatever the forward error, P nearly solves the ARE.
    K, P = lqr(case.A, case.B, case.Q, case.R)
    residual = _are_relative_residual(case.A, case.B, case.Q, case.R, P)
    target(residual, label="relative ARE residual")
    # Schur-vector ARE solvers (scipy's, hence selftune's) are not strictly backward
    # stable: the residual grows with cond(U11) ~ ||P||. The worst seen over thousands of
    # these systems is ~2e-13 (n = 1, B tiny, A unstable, P ~ 1e4); a wrong formula gives O(1).
    assert residual <= 1e-11
    np.testing.assert_allclose(K, np.linalg.solve(case.R, case.B.T @ P), rtol=1e-12, atol=0)


# -- 5. invariants of the optimum and of policy values -----------------------------------------


@at_least(100)
@given(lqr_cases(), SEEDS)
def test_optimum_invariants_and_policy_values(case: LqrCase, seed: int) -> None:
    A, B, Q, R = case.A, case.B, case.Q, case.R
    K_star, P_star = lqr(A, B, Q, R)
    assume(_care_condition(A, B, Q, R, P_star) <= MAX_CARE_CONDITION)

    np.testing.assert_array_equal(P_star, P_star.T)
    assert np.min(np.linalg.eigvalsh(P_star)) > 0.0
    assert np.max(np.linalg.eigvals(A - B @ K_star).real) < 0.0
    assert _are_relative_residual(A, B, Q, R, P_star) <= 1e-13

    # The value of the optimal policy is P* (Lyapunov equation, solved two ways).
    assert _relative(policy_value(A, B, K_star, Q, R), P_star) <= AGREEMENT
    weight = Q + K_star.T @ R @ K_star
    assert _relative(_lyapunov_by_kronecker(A - B @ K_star, weight), P_star) <= AGREEMENT

    # A stabilizing, non-optimal policy: K* plus a random perturbation, halved until the
    # closed loop keeps a stability margin.
    rng = np.random.default_rng(seed)
    perturbation = rng.standard_normal(K_star.shape) * (1.0 + np.linalg.norm(K_star))
    for _ in range(60):
        K = K_star + perturbation
        if np.max(np.linalg.eigvals(A - B @ K).real) < -1e-2:
            break
        perturbation *= 0.5
    P_K = policy_value(A, B, K, Q, R)
    P_K_reference = _lyapunov_by_kronecker(A - B @ K, Q + K.T @ R @ K)
    assert _relative(P_K, P_K_reference) <= AGREEMENT
    # Loewner order: P_K - P* is the value of the gain error, (A-BK)'G + G(A-BK) +
    # (K-K*)'R(K-K*) = 0, hence positive semidefinite.
    gap = P_K - P_star
    scale = float(np.linalg.norm(P_K, 2))
    assert np.min(np.linalg.eigvalsh(gap)) >= -1e-9 * scale
    gain_error = K - K_star
    expected_gap = _lyapunov_by_kronecker(A - B @ K, gain_error.T @ R @ gain_error)
    assert np.linalg.norm(gap - expected_gap) <= AGREEMENT * scale


def test_policy_value_rejects_a_destabilizing_policy() -> None:
    A = np.array([[1.0, 0.0], [0.0, -1.0]])
    B = np.eye(2)
    with pytest.raises(UnsolvableError, match="does not stabilize"):
        policy_value(A, B, np.zeros((2, 2)), np.eye(2), np.eye(2))
    # The same plant with a stabilizing gain has a finite cost.
    P = policy_value(A, B, np.diag([2.0, 0.0]), np.eye(2), np.eye(2))
    np.testing.assert_allclose(P, np.diag([2.5, 0.5]), rtol=1e-12)


def test_policy_value_names_a_bad_argument() -> None:
    A, B = -np.eye(2), np.eye(2)[:, :1]
    with pytest.raises(InputError, match=r"K: expected 2 columns"):
        policy_value(A, B, np.zeros((1, 3)), np.eye(2), np.eye(1))
    with pytest.raises(InputError, match=r"K: expected 1 rows"):
        policy_value(A, B, np.zeros((2, 2)), np.eye(2), np.eye(1))
    with pytest.raises(InputError, match=r"Q: must be symmetric"):
        policy_value(A, B, np.zeros((1, 2)), [[1.0, 1.0], [0.0, 1.0]], np.eye(1))
    with pytest.raises(InputError, match=r"K: contains NaN"):
        policy_value(A, B, [[np.nan, 0.0]], np.eye(2), np.eye(1))


def test_scalar_lqr_has_the_closed_form() -> None:
    # Scalar ARE 2aP - b^2 P^2 / r + q = 0, positive root P = (a + sqrt(a^2 + b^2 q / r)) r / b^2.
    a, b, q, r = 1.0, 2.0, 3.0, 4.0
    P_expected = (a + np.sqrt(a**2 + b**2 * q / r)) * r / b**2
    K, P = lqr([[a]], [[b]], [[q]], [[r]])
    np.testing.assert_allclose(P, [[P_expected]], rtol=1e-14)
    np.testing.assert_allclose(K, [[b * P_expected / r]], rtol=1e-14)


@at_least(60)
@given(regulation_cases())
def test_theta_unpacks_to_p_k_and_the_exogenous_block(case: RegulationCase) -> None:
    problem = case.problem
    solution = solve_optimal_regulation(problem, case.Q, case.R)
    P, K, M = unpack_theta(solution.theta, problem.n, problem.m, problem.q)
    np.testing.assert_array_equal(P, solution.P)
    np.testing.assert_array_equal(K, solution.K)
    A, D, E, X = problem.A, problem.D, problem.E, solution.X
    expected = (D + A @ X - X @ E).T @ solution.P
    np.testing.assert_allclose(M, expected, rtol=0, atol=1e-12 * float(np.linalg.norm(expected)))
    np.testing.assert_allclose(solution.L, solution.U + solution.K @ solution.X, rtol=0, atol=1e-13)


# -- 2. regulator-equation residuals -------------------------------------------------------------


@at_least(150)
@given(regulation_cases())
@example(_random_regulation_case(3, n=6, m=4, r=2, rotations=2, zero_modes=0, shift=0.3))
@example(_random_regulation_case(4, n=6, m=3, r=3, rotations=0, zero_modes=2, shift=0.3))
@example(_random_regulation_case(5, n=5, m=4, r=1, rotations=1, zero_modes=1, shift=-0.2))
def test_regulator_residuals_are_tiny(case: RegulationCase) -> None:
    problem = case.problem
    N, c = _regulator_operator(problem)
    # The Kronecker form selftune builds is the map itself.
    N_selftune, c_selftune = problem.regulator_system()
    np.testing.assert_allclose(N_selftune, N, rtol=0, atol=1e-14 * np.max(np.abs(N)))
    np.testing.assert_array_equal(c_selftune, c)

    residuals = [
        _relative_residuals(problem, X, U)
        for X, U in (
            problem.solve_regulator_equations(),
            problem.solve_regulator_equations(case.Q, case.R),
        )
    ]
    worst = max(max(pair) for pair in residuals)
    target(worst, label="relative regulator residual")
    assert worst <= RESIDUAL, residuals


@at_least(60)
@given(
    st.integers(min_value=1, max_value=6).flatmap(
        lambda n: st.tuples(
            st.just(n),
            st.integers(min_value=1, max_value=min(n, 4)),
            st.integers(min_value=0, max_value=2),
            st.integers(min_value=0, max_value=2),
            st.floats(min_value=-1.0, max_value=1.0),
            SEEDS,
        )
    )
)
def test_square_regulator_equations_have_the_unique_solution(
    dims: tuple[int, int, int, int, float, int],
) -> None:
    # m = r: N is square and (generically) invertible, so the solution is the plain solve.
    n, m, rotations, zero_modes, shift, seed = dims
    assume(rotations + zero_modes > 0)
    case = _random_regulation_case(seed, n, m, m, rotations, zero_modes, shift)
    problem = case.problem
    N, c = _regulator_operator(problem)
    assume(_condition(N) <= 1e6)
    expected = np.linalg.solve(N, c)
    X, U = problem.solve_regulator_equations()
    assert _relative(_stack(X, U), expected) <= AGREEMENT


# -- 3. the min-trace (X, U) of Remark 2 -----------------------------------------------------------


def _kkt_minimizer(N: Array, c: Array, W: Array) -> Array:
    """argmin z'Wz subject to Nz = c, from the Lagrange (KKT) conditions
    ``W z + N' lambda = 0, N z = c``.

    Eliminating lambda gives the closed form ``z = W^-1 N' (N W^-1 N')^-1 c``; evaluated
    that way it squares cond(N) (errors up to ~3e-9 were measured on these problems), so the
    same conditions are solved here as one augmented linear system.
    """
    constraints = N.shape[0]
    kkt = np.block([[W, N.T], [N, np.zeros((constraints, constraints))]])
    right_side = np.concatenate([np.zeros(W.shape[0]), c])
    return np.linalg.solve(kkt, right_side)[: W.shape[0]]


def test_kkt_oracle_matches_the_closed_form_on_a_well_conditioned_case() -> None:
    # The oracle itself, against z = W^-1 N' (N W^-1 N')^-1 c where that is accurate.
    rng = np.random.default_rng(0)
    N = rng.standard_normal((3, 6))
    c = rng.standard_normal(3)
    W = _random_spd(rng, 6, 1.0)
    W_inverse_N_T = np.linalg.solve(W, N.T)
    closed_form = W_inverse_N_T @ np.linalg.solve(N @ W_inverse_N_T, c)
    assert _relative(_kkt_minimizer(N, c, W), closed_form) <= 1e-13


@at_least(100)
@given(regulation_cases(max_n=5, max_m=4, m_above_r=True), st.booleans())
def test_min_trace_pair_is_the_kkt_solution(case: RegulationCase, weighted: bool) -> None:
    problem = case.problem
    Q, R = (case.Q, case.R) if weighted else (np.eye(problem.n), np.eye(problem.m))
    N, c = _regulator_operator(problem)
    W = _weight(problem, Q, R)
    assume(_condition(N) <= 1e5)
    expected = _kkt_minimizer(N, c, W)

    X, U = (
        problem.solve_regulator_equations(Q, R) if weighted else problem.solve_regulator_equations()
    )
    z = _stack(X, U)
    assert _relative(z, expected) <= AGREEMENT

    # The same pair from the full solution (it weights X, U with the cost's Q, R).
    solution = solve_optimal_regulation(problem, Q, R)
    assert _relative(_stack(solution.X, solution.U), expected) <= AGREEMENT

    # Optimality along the null space of the constraints (its basis from our own SVD):
    # the gradient Wz is orthogonal to it, and no step along it lowers the cost.
    _, singular_values, right = np.linalg.svd(N)
    rank = int(np.sum(singular_values > 1e-10 * singular_values[0]))
    null_basis = right[rank:].T
    assert null_basis.shape[1] == (problem.m - problem.r) * problem.q
    gradient = W @ z
    assert np.linalg.norm(null_basis.T @ gradient) <= 1e-10 * np.linalg.norm(gradient)
    cost = float(z @ W @ z)
    rng = np.random.default_rng(problem.n * 1000 + problem.q)
    for _ in range(5):
        direction = null_basis @ rng.standard_normal(null_basis.shape[1])
        for step in (1e-4, -1e-4, 1e-2, -1.0, 3.0):
            moved = z + step * direction
            assert np.linalg.norm(N @ moved - c) <= 1e-9 * (1.0 + np.linalg.norm(c))
            assert float(moved @ W @ moved) >= cost * (1.0 - 1e-14)


@at_least(20)
@given(regulation_cases(max_n=3, max_m=3, max_blocks=1, m_above_r=True))
def test_min_trace_pair_agrees_with_slsqp(case: RegulationCase) -> None:
    problem = case.problem
    N, c = _regulator_operator(problem)
    W = _weight(problem, case.Q, case.R)
    assume(_condition(N) <= 1e4)
    # Start SLSQP from the least-squares feasible point and scale the cost to ~1 there, so
    # its stopping test (ftol on the cost) is relative.
    start = np.linalg.lstsq(N, c, rcond=None)[0]
    cost_scale = float(start @ W @ start)
    ftol = 1e-13
    result = scipy.optimize.minimize(
        lambda z: float(z @ W @ z) / cost_scale,
        start,
        jac=lambda z: 2.0 * W @ z / cost_scale,
        constraints=[{"type": "eq", "fun": lambda z: N @ z - c, "jac": lambda z: N}],
        method="SLSQP",
        options={"ftol": ftol, "maxiter": 500},
    )
    assert result.success, result.message
    X, U = problem.solve_regulator_equations(case.Q, case.R)
    z = _stack(X, U)
    # SLSQP stops when the (scaled) cost changes by less than ftol, so its point is only
    # accurate to about sqrt(ftol) (~3e-7); the exact check is the KKT test above.
    assert _relative(z, result.x) <= 30.0 * np.sqrt(ftol)
    # And selftune's feasible pair is never worse than what SLSQP found.
    assert float(z @ W @ z) <= float(result.x @ W @ result.x) * (1.0 + 1e-9)


def test_min_trace_pair_in_a_case_solved_by_hand() -> None:
    # x' = -x + u1 + u2 + w, e = x - w, w' = 0: X = 1, u1 + u2 = 0 -> min u1^2 + u2^2 at U = 0.
    problem = _problem(A=[[-1.0]], B=[[1.0, 1.0]], C=[[1.0]], D=[[1.0]], E=[[0.0]], F=[[-1.0]])
    X, U = problem.solve_regulator_equations()
    np.testing.assert_allclose(X, [[1.0]], rtol=1e-14)
    np.testing.assert_allclose(U, [[0.0], [0.0]], atol=1e-14)
    # With D = 3: u1 + u2 = -2, min u1^2 + 4 u2^2 -> u1 = -8/5, u2 = -2/5.
    problem = _problem(A=[[-1.0]], B=[[1.0, 1.0]], C=[[1.0]], D=[[3.0]], E=[[0.0]], F=[[-1.0]])
    X, U = problem.solve_regulator_equations(np.eye(1), np.diag([1.0, 4.0]))
    np.testing.assert_allclose(U, [[-1.6], [-0.4]], rtol=1e-13)


# -- 4. unsolvable problems --------------------------------------------------------------------


def _numbers_in(message: str) -> list[complex]:
    values = []
    for token in re.split(r"[\s(),;:\[\]]+", message):
        try:
            value = complex(token)
        except ValueError:
            continue
        if np.isfinite(value):
            values.append(value)
    return values


def _assert_names_eigenvalue(message: str, eigenvalue: complex) -> None:
    """The message says "eigenvalue" and prints ``eigenvalue`` (or its conjugate) to 6 digits."""
    assert "eigenvalue" in message, message
    tolerance = 1e-5 * max(1.0, abs(eigenvalue))
    assert any(
        min(abs(value - eigenvalue), abs(value - np.conj(eigenvalue))) <= tolerance
        for value in _numbers_in(message)
    ), f"{eigenvalue} not named in: {message}"


def _unstabilizable() -> tuple[Array, Array]:
    # Modes 1.5 (uncontrollable, unstable), -1 (controllable), 0.25 +- 2j (controllable).
    A = scipy.linalg.block_diag([[1.5]], [[-1.0]], [[0.25, 2.0], [-2.0, 0.25]])
    B = np.array([[0.0], [1.0], [1.0], [0.5]])
    return A, B


def test_lqr_rejects_an_unstabilizable_pair_and_names_the_eigenvalue() -> None:
    A, B = _unstabilizable()
    with pytest.raises(UnsolvableError, match="stabilizable") as info:
        lqr(A, B, np.eye(4), np.eye(1))
    _assert_names_eigenvalue(str(info.value), 1.5)


def test_an_uncontrollable_but_stable_mode_is_accepted() -> None:
    A, B = _unstabilizable()
    A = A.copy()
    A[0, 0] = -1.5
    K, P = lqr(A, B, np.eye(4), np.eye(1))
    K_control, P_control, _ = control.lqr(A, B, np.eye(4), np.eye(1))
    assert _relative(P, P_control) <= AGREEMENT
    assert _relative(K, K_control) <= AGREEMENT


def test_solve_optimal_regulation_rejects_an_unstabilizable_complex_mode() -> None:
    # An uncontrollable pair 0.5 +- 3j.
    A = scipy.linalg.block_diag([[0.5, 3.0], [-3.0, 0.5]], [[-2.0]])
    B = np.array([[0.0], [0.0], [1.0]])
    problem = _problem(A=A, B=B, C=[[0.0, 0.0, 1.0]], D=np.ones((3, 1)), E=[[0.0]], F=[[1.0]])
    with pytest.raises(UnsolvableError, match="stabilizable") as info:
        solve_optimal_regulation(problem, np.eye(3), np.eye(1))
    _assert_names_eigenvalue(str(info.value), 0.5 + 3.0j)


@at_least(40)
@given(
    SEEDS,
    st.integers(min_value=1, max_value=4),
    st.floats(min_value=0.0, max_value=2.0),
    st.floats(min_value=0.0, max_value=3.0),
)
def test_unstabilizable_modes_are_found_in_any_coordinates(
    seed: int, controllable: int, real: float, imaginary: float
) -> None:
    # blockdiag(controllable part, unstable uncontrollable part) in random coordinates T.
    rng = np.random.default_rng(seed)
    A_c = rng.standard_normal((controllable, controllable)) - np.eye(controllable)
    if imaginary > 0.1:
        A_u, eigenvalue = (
            np.array([[real, imaginary], [-imaginary, real]]),
            complex(real, imaginary),
        )
    else:
        A_u, eigenvalue = np.array([[real]]), complex(real)
    n = controllable + A_u.shape[0]
    m = int(rng.integers(1, 3))
    T = np.eye(n) + 0.3 * rng.standard_normal((n, n))
    assume(_condition(T) <= 100.0)
    A = T @ scipy.linalg.block_diag(A_c, A_u) @ np.linalg.inv(T)
    B = T @ np.vstack([rng.standard_normal((controllable, m)), np.zeros((A_u.shape[0], m))])
    with pytest.raises(UnsolvableError, match="stabilizable") as info:
        lqr(A, B, np.eye(n), np.eye(m))
    _assert_names_eigenvalue(str(info.value), eigenvalue)


def _siso_companion(denominator: list[float], numerator: list[float]) -> tuple[Array, Array, Array]:
    """Controllable canonical form of numerator(s) / denominator(s), denominator monic of
    degree n (coefficients highest power first, leading 1 omitted), numerator of degree < n
    (lowest power first, length n)."""
    n = len(denominator)
    A = np.zeros((n, n))
    A[:-1, 1:] = np.eye(n - 1)
    A[-1, :] = -np.array(denominator[::-1])
    B = np.zeros((n, 1))
    B[-1, 0] = 1.0
    return A, B, np.array([numerator])


def test_a_transmission_zero_at_an_eigenvalue_of_e_is_named() -> None:
    # (s^2 + 4) / (s^3 + 2 s^2 + 3 s + 1): zeros at +-2j; E rotates at 2 rad/s.
    A, B, C = _siso_companion([2.0, 3.0, 1.0], [4.0, 0.0, 1.0])
    problem = _problem(A=A, B=B, C=C, D=np.ones((3, 2)), E=_rotation(2.0), F=[[1.0, 0.0]])
    with pytest.raises(UnsolvableError, match="Remark 1") as info:
        problem.check_solvable()
    _assert_names_eigenvalue(str(info.value), 2.0j)
    with pytest.raises(UnsolvableError) as info:
        solve_optimal_regulation(problem, np.eye(3), np.eye(1))
    _assert_names_eigenvalue(str(info.value), 2.0j)
    # At another frequency the same plant can track.
    other = _problem(A=A, B=B, C=C, D=np.ones((3, 2)), E=_rotation(3.0), F=[[1.0, 0.0]])
    X, U = other.solve_regulator_equations()
    first, second = _relative_residuals(other, X, U)
    assert max(first, second) <= RESIDUAL


def test_a_zero_at_the_origin_blocks_constant_references() -> None:
    # s (s + 1) / (s^3 + 2 s^2 + 3 s + 1): zero DC gain, E = 0.
    A, B, C = _siso_companion([2.0, 3.0, 1.0], [0.0, 1.0, 1.0])
    problem = _problem(A=A, B=B, C=C, D=np.ones((3, 1)), E=[[0.0]], F=[[1.0]])
    with pytest.raises(UnsolvableError, match="Remark 1") as info:
        problem.solve_regulator_equations()
    _assert_names_eigenvalue(str(info.value), 0.0)


@pytest.mark.parametrize("E", [np.zeros((1, 1)), _rotation(1.7)])
def test_more_outputs_than_inputs_is_unsolvable(E: Array) -> None:
    A = np.array([[-1.0, 0.2, 0.0], [0.0, -2.0, 1.0], [0.3, 0.0, -0.5]])
    q = E.shape[0]
    problem = _problem(
        A=A, B=[[0.0], [0.0], [1.0]], C=np.eye(3)[:2], D=np.ones((3, q)), E=E, F=np.ones((2, q))
    )
    with pytest.raises(UnsolvableError, match="Remark 1") as info:
        solve_optimal_regulation(problem, np.eye(3), np.eye(1))
    _assert_names_eigenvalue(str(info.value), complex(np.linalg.eigvals(E)[0]))


@at_least(40)
@given(SEEDS, st.integers(min_value=2, max_value=5), st.integers(min_value=1, max_value=2))
def test_a_random_transmission_zero_at_an_eigenvalue_of_e_is_named(
    seed: int, n: int, m: int
) -> None:
    assume(m < n)
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n)) / np.sqrt(n)
    B = rng.standard_normal((n, m))
    C = rng.standard_normal((m, n))
    # Invariant zeros: finite generalized eigenvalues of the Rosenbrock pencil.
    pencil = np.block([[A, B], [C, np.zeros((m, m))]])
    mass = scipy.linalg.block_diag(np.eye(n), np.zeros((m, m)))
    zeros = scipy.linalg.eigvals(pencil, mass)
    zeros = zeros[np.isfinite(zeros) & (np.abs(zeros) < 1e3)]
    assume(zeros.size > 0)
    zero = complex(zeros[np.argmin(np.abs(zeros))])
    rosenbrock = np.block([[A - zero * np.eye(n), B], [C, np.zeros((m, m))]])
    singular_values = np.linalg.svd(rosenbrock, compute_uv=False)
    assume(singular_values[-1] <= 1e-12 * singular_values[0])  # a well-computed zero
    if abs(zero.imag) > 1e-6:
        E = np.array([[zero.real, zero.imag], [-zero.imag, zero.real]])
    else:
        E = np.array([[zero.real]])
    q = E.shape[0]
    problem = _problem(
        A=A, B=B, C=C, D=rng.standard_normal((n, q)), E=E, F=rng.standard_normal((m, q))
    )
    with pytest.raises(UnsolvableError, match="Remark 1") as info:
        problem.check_solvable()
    _assert_names_eigenvalue(str(info.value), zero)


def test_undetectable_unstable_mode_is_named() -> None:
    A = np.diag([0.8, -1.0, -2.0])
    Q = np.diag([0.0, 1.0, 1.0])
    with pytest.raises(UnsolvableError, match="detectable") as info:
        lqr(A, np.eye(3), Q, np.eye(3))
    _assert_names_eigenvalue(str(info.value), 0.8)
    problem = _problem(
        A=A, B=np.eye(3), C=np.eye(3), D=np.ones((3, 1)), E=[[0.0]], F=np.ones((3, 1))
    )
    with pytest.raises(UnsolvableError, match="detectable") as info:
        solve_optimal_regulation(problem, Q, np.eye(3))
    _assert_names_eigenvalue(str(info.value), 0.8)


def test_undetectable_mode_on_the_imaginary_axis_is_named() -> None:
    A = scipy.linalg.block_diag([[0.0, 2.5], [-2.5, 0.0]], [[-1.0]])
    Q = np.diag([0.0, 0.0, 1.0])
    with pytest.raises(UnsolvableError, match="detectable") as info:
        lqr(A, np.eye(3), Q, np.eye(3))
    _assert_names_eigenvalue(str(info.value), 2.5j)


@at_least(30)
@given(SEEDS, st.integers(min_value=1, max_value=3), st.floats(min_value=0.05, max_value=2.0))
def test_undetectable_modes_are_found_in_any_coordinates(
    seed: int, observed: int, unstable: float
) -> None:
    # Q is blind to the unstable mode u of A = T blockdiag(A_o, u) T^-1.
    rng = np.random.default_rng(seed)
    n = observed + 1
    T = np.eye(n) + 0.3 * rng.standard_normal((n, n))
    assume(_condition(T) <= 100.0)
    T_inverse = np.linalg.inv(T)
    A_o = rng.standard_normal((observed, observed))
    A = T @ scipy.linalg.block_diag(A_o, [[unstable]]) @ T_inverse
    Q = T_inverse.T @ scipy.linalg.block_diag(np.eye(observed), [[0.0]]) @ T_inverse
    Q = 0.5 * (Q + Q.T)
    with pytest.raises(UnsolvableError, match="detectable") as info:
        lqr(A, np.eye(n), Q, np.eye(n))
    _assert_names_eigenvalue(str(info.value), unstable)


def test_a_stable_unobserved_mode_is_accepted() -> None:
    A = np.diag([-0.8, 1.0])
    Q = np.diag([0.0, 1.0])
    K, P = lqr(A, np.eye(2), Q, np.eye(2))
    P_control = control.care(A, np.eye(2), Q, np.eye(2))[0]
    np.testing.assert_allclose(P, P_control, rtol=1e-12, atol=1e-14)
    # Q = 0 on the first state and the mode is stable: no feedback on it.
    np.testing.assert_allclose(K[:, 0], 0.0, atol=1e-14)


def test_bad_weights_are_input_errors() -> None:
    A = -np.eye(2)
    with pytest.raises(InputError, match="R: must be symmetric positive definite"):
        lqr(A, np.eye(2), np.eye(2), np.diag([1.0, 0.0]))
    with pytest.raises(InputError, match="Q: must be positive semidefinite"):
        lqr(A, np.eye(2), np.diag([1.0, -1.0]), np.eye(2))
    with pytest.raises(InputError, match="B: expected 2 rows"):
        lqr(A, np.eye(3), np.eye(2), np.eye(3))
