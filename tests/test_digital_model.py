"""The discrete-time solvers and the model-based digital optimum against independent truth.

Oracles:

- python-control's ``dlqr`` with ``method="slycot"``: SLICOT's ``SG02AD`` (a generalized
  Schur method written independently of scipy's ``solve_discrete_are``);
- long simulated trajectories, summed stage by stage (the value of a policy);
- adaptive quadrature (``scipy.integrate.quad_vec``) of the continuous cost along the
  exact intra-sample trajectory (the sampled-data weights);
- :func:`selftune.core.discretize` (the inverse of ``continuous_from_discrete``);
- :func:`selftune.model.solve_optimal_regulation` (the continuous optimum, the limit of
  the digital one as h -> 0).

For the digital optimum with the ``"sampled"`` cost and a delay, SLICOT is given the
"shift-only-Rd" weights (the applied input's weight charged when it is computed, the
cross weight between x and the oldest delayed input in the state weight): a different,
indefinite, formulation from the one selftune solves, with the same optimal K.
"""

from __future__ import annotations

import control
import numpy as np
import pytest
import scipy.integrate
import scipy.linalg
from hypothesis import assume, example, given, target
from hypothesis import strategies as st

from example_counts import at_least
from selftune.core import (
    continuous_from_discrete,
    delay_augmented,
    discretize,
    dlqr,
    dpolicy_value,
    sampled_data_weights,
)
from selftune.errors import InputError, UnsolvableError
from selftune.model import (
    SPMSM,
    DigitalCost,
    ModelBasedSolution,
    RegulationProblem,
    solve_digital_regulation,
    solve_optimal_regulation,
)

Array = np.ndarray

#: Bar for agreement with SLICOT (relative Frobenius norm of the difference).
AGREEMENT = 1e-9
#: Systems whose DARE condition estimate exceeds this are not used for forward errors:
#: with a backward error of ~1e-16 the forward error is then at most ~1e-11.
MAX_DARE_CONDITION = 1e5

#: Policies whose Stein equation ``P = Acl' P Acl + S`` has a condition number above this
#: are not used for forward errors: a backward-stable solve is then accurate to ~1e-11.
#: (A strongly non-normal closed loop with spectral radius 0.6 can reach 2e9, and its
#: value is then right to only ~1e-9, while the simulated sum stays accurate.)
MAX_STEIN_CONDITION = 1e5

SEEDS = st.integers(min_value=0, max_value=2**32 - 1)
PAPER_Q, PAPER_R = 1e3 * np.eye(2), np.eye(2)


def _relative(actual: Array, expected: Array) -> float:
    return float(np.linalg.norm(actual - expected) / np.linalg.norm(expected))


def _slicot_dlqr(A: Array, B: Array, Q: Array, R: Array, N: Array) -> tuple[Array, Array]:
    K, P, _ = control.dlqr(A, B, Q, R, N, method="slycot")
    return np.asarray(K), np.asarray(P)


def _dare_residual(A: Array, B: Array, Q: Array, R: Array, N: Array, P: Array) -> float:
    coupling = A.T @ P @ B + N
    gain_term = coupling @ np.linalg.solve(R + B.T @ P @ B, coupling.T)
    residual = A.T @ P @ A - P - gain_term + Q
    scale = sum(np.linalg.norm(M) for M in (A.T @ P @ A, P, gain_term, Q))
    return float(np.linalg.norm(residual) / scale)


def _dare_condition(A: Array, B: Array, Q: Array, R: Array, N: Array, P: Array) -> float:
    """First-order relative condition estimate of the DARE at P: ``||L^-1||`` (L the
    closed-loop Stein operator ``X -> X - Acl' X Acl``) times the size of the data terms,
    over ``||P||``."""
    n = A.shape[0]
    K = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A + N.T)
    closed_loop = A - B @ K
    operator = np.eye(n * n) - np.kron(closed_loop.T, closed_loop.T)
    separation = float(np.linalg.svd(operator, compute_uv=False)[-1])
    size = float(np.linalg.norm(P, 2))
    data = (
        float(np.linalg.norm(A, 2)) ** 2 * size
        + float(np.linalg.norm(K.T @ (R + B.T @ P @ B) @ K, 2))
        + float(np.linalg.norm(Q, 2))
    )
    return data / (separation * size)


def _stein_condition(closed_loop: Array) -> float:
    """2-norm condition number of the Stein operator ``X -> X - Acl' X Acl``."""
    n = closed_loop.shape[0]
    return float(np.linalg.cond(np.eye(n * n) - np.kron(closed_loop.T, closed_loop.T)))


def _spectral_radius(M: Array) -> float:
    return float(np.max(np.abs(np.linalg.eigvals(M))))


# -- random data -----------------------------------------------------------------------------


def _random_spd(rng: np.random.Generator, size: int, floor: float) -> Array:
    G = rng.standard_normal((size, size))
    return G @ G.T / size + floor * np.eye(size)


def _random_dlqr_case(
    seed: int, n: int, m: int, radius: float, cross: bool
) -> tuple[Array, Array, Array, Array, Array]:
    """A, B Gaussian (A scaled to about ``radius``, some open-loop unstable), Q, R random
    positive definite, N = Q^(1/2) C R^(1/2) with ||C||_2 = 0.9 (the joint weight is then
    positive semidefinite: its Schur complement is Q^(1/2) (I - CC') Q^(1/2)) or zero."""
    rng = np.random.default_rng(seed)
    A = radius * rng.standard_normal((n, n)) / np.sqrt(n)
    B = rng.standard_normal((n, m))
    Q, R = _random_spd(rng, n, 0.1), _random_spd(rng, m, 0.5)
    N = np.zeros((n, m))
    if cross:
        C = rng.standard_normal((n, m))
        C *= 0.9 / np.linalg.norm(C, 2)
        N = np.real(scipy.linalg.sqrtm(Q) @ C @ scipy.linalg.sqrtm(R))
    return A, B, Q, R, N


@st.composite
def dlqr_cases(draw: st.DrawFn) -> tuple[Array, Array, Array, Array, Array]:
    n = draw(st.integers(min_value=1, max_value=6))
    m = draw(st.integers(min_value=1, max_value=3))
    radius = draw(st.floats(min_value=0.2, max_value=1.5))
    return _random_dlqr_case(draw(SEEDS), n, m, radius, draw(st.booleans()))


@st.composite
def motors(draw: st.DrawFn) -> tuple[SPMSM, float]:
    """A random motor (R_s 0.1-3 ohm, L_s 3-100 mH, phi 0.05-1 Wb, p 1-6) and a mechanical
    speed with an electrical speed up to 2000 rad/s."""
    motor = SPMSM(
        R_s=draw(st.floats(min_value=0.1, max_value=3.0)),
        L_s=draw(st.floats(min_value=3e-3, max_value=0.1)),
        phi_pm=draw(st.floats(min_value=0.05, max_value=1.0)),
        p=draw(st.integers(min_value=1, max_value=6)),
    )
    electrical_speed = draw(st.floats(min_value=0.0, max_value=2000.0))
    return motor, electrical_speed / motor.p


# -- dlqr --------------------------------------------------------------------------------------


@at_least(150)
@given(dlqr_cases())
@example(_random_dlqr_case(3, n=6, m=3, radius=1.5, cross=True))
def test_dlqr_agrees_with_slicot(case: tuple[Array, Array, Array, Array, Array]) -> None:
    A, B, Q, R, N = case
    K_slicot, P_slicot = _slicot_dlqr(A, B, Q, R, N)
    assume(_dare_condition(A, B, Q, R, N, P_slicot) <= MAX_DARE_CONDITION)

    K, P = dlqr(A, B, Q, R, N if np.any(N) else None)

    differences = [_relative(K, K_slicot), _relative(P, P_slicot)]
    target(max(differences), label="worst relative difference")
    assert max(differences) <= AGREEMENT, differences
    assert _dare_residual(A, B, Q, R, N, P) <= 1e-14
    assert _spectral_radius(A - B @ K) < 1.0
    np.testing.assert_array_equal(P, P.T)


def test_dlqr_on_a_scalar_system_is_the_closed_form() -> None:
    # x+ = a x + u, cost x^2 + u^2: P = a^2 P / (1 + P) + 1, so P^2 - a^2 P - 1 = 0.
    a = 2.0
    P_exact = (a**2 + np.sqrt(a**4 + 4.0)) / 2.0
    K, P = dlqr([[a]], [[1.0]], [[1.0]], [[1.0]])
    assert P[0, 0] == pytest.approx(P_exact, rel=1e-15)
    assert K[0, 0] == pytest.approx(a * P_exact / (1.0 + P_exact), rel=1e-15)


@pytest.mark.parametrize(
    ("arguments", "error", "message"),
    [
        ((np.eye(2), np.ones((3, 1)), np.eye(2), np.eye(1)), InputError, "B: expected 2 rows"),
        ((np.eye(2), np.ones((2, 1)), np.eye(2), [[0.0]]), InputError, "R: must be symmetric"),
        ((np.eye(2), np.ones((2, 1)), -np.eye(2), [[1.0]]), InputError, "Q: must be positive"),
        ((np.eye(1), np.ones((1, 1)), [[1.0]], [[1.0]], [[2.0]]), InputError,
         r"\[\[Q, N\], \[N', R\]\]: must be positive semidefinite"),
        ((np.diag([1.5, 0.5]), np.array([[0.0], [1.0]]), np.eye(2), [[1.0]]),
         UnsolvableError, r"not stabilizable in discrete time: the mode at eigenvalue 1\.5"),
        ((np.diag([1.0, 0.5]), np.array([[1.0], [1.0]]), np.diag([0.0, 1.0]), [[1.0]]),
         UnsolvableError, r"\(A, Q\) is not detectable in discrete time: .* eigenvalue 1 "),
        ((np.eye(1), np.ones((1, 1)), [[np.nan]], [[1.0]]), InputError, "Q: contains NaN"),
    ],
)  # fmt: skip
def test_dlqr_rejects_bad_problems_by_name(
    arguments: tuple[object, ...], error: type[Exception], message: str
) -> None:
    with pytest.raises(error, match=message):
        dlqr(*arguments)  # type: ignore[arg-type]


# -- dpolicy_value -------------------------------------------------------------------------


def _trajectory_cost(closed_loop: Array, stage: Array, x0: Array, steps: int) -> float:
    total, x = 0.0, x0
    for _ in range(steps):
        total += float(x @ stage @ x)
        x = closed_loop @ x
    return total


@at_least(40)
@given(dlqr_cases(), SEEDS)
def test_dpolicy_value_is_the_cost_of_a_simulated_trajectory(
    case: tuple[Array, Array, Array, Array, Array], seed: int
) -> None:
    A, B, Q, R, N = case
    rng = np.random.default_rng(seed)
    # a stabilizing policy that is not the optimum: the LQR of other weights
    K, _ = dlqr(A, B, np.eye(A.shape[0]), _random_spd(rng, B.shape[1], 0.2))
    closed_loop = A - B @ K
    radius = _spectral_radius(closed_loop)
    assume(radius < 0.99 and _stein_condition(closed_loop) <= MAX_STEIN_CONDITION)
    steps = int(np.ceil(np.log(1e-20) / np.log(max(radius, 1e-3))))
    x0 = rng.standard_normal((A.shape[0],))

    P = dpolicy_value(A, B, K, Q, R, N)

    stage = Q - N @ K - K.T @ N.T + K.T @ R @ K
    expected = _trajectory_cost(closed_loop, stage, x0, steps)
    assert float(x0 @ P @ x0) == pytest.approx(expected, rel=1e-10)


def test_dpolicy_value_of_the_optimum_is_its_riccati_solution() -> None:
    A, B, Q, R, N = _random_dlqr_case(11, n=4, m=2, radius=1.2, cross=True)
    K, P = dlqr(A, B, Q, R, N)
    np.testing.assert_allclose(dpolicy_value(A, B, K, Q, R, N), P, rtol=1e-12, atol=0.0)


def test_dpolicy_value_of_an_unstable_policy_names_the_spectral_radius() -> None:
    with pytest.raises(UnsolvableError, match=r"spectral radius of A - BK is 1\.5 >= 1"):
        dpolicy_value([[2.0]], [[1.0]], [[0.5]], [[1.0]], [[1.0]])


# -- sampled_data_weights ------------------------------------------------------------------


def _quadrature_weights(A: Array, B: Array, Q: Array, R: Array, h: float) -> Array:
    """``int_0^h Phi(t)' blockdiag(Q, R) Phi(t) dt`` by adaptive quadrature, with
    ``[x(t); u] = Phi(t) [x_k; u_k]`` the exact intra-sample trajectory (input held)."""
    n, m = B.shape
    W = scipy.linalg.block_diag(Q, R)

    def integrand(t: float) -> Array:
        if t == 0.0:
            transition = np.eye(n + m)
        else:
            step = discretize(A, B, t)
            transition = np.block([[step.Ad, step.Bd], [np.zeros((m, n)), np.eye(m)]])
        return transition.T @ W @ transition

    integral, _ = scipy.integrate.quad_vec(integrand, 0.0, h, epsabs=0.0, epsrel=1e-13)
    return np.asarray(integral, dtype=np.float64)


@at_least(25)
@given(
    SEEDS,
    st.integers(min_value=1, max_value=4),
    st.integers(min_value=1, max_value=3),
    st.floats(min_value=1e-3, max_value=2.0),
)
def test_sampled_data_weights_equal_quadrature_of_the_continuous_cost(
    seed: int, n: int, m: int, time_constants: float
) -> None:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n)) * rng.uniform(0.1, 1e3)
    B = rng.standard_normal((n, m))
    Q, R = _random_spd(rng, n, 0.0), _random_spd(rng, m, 0.1) * rng.uniform(1e-3, 1e3)
    h = time_constants / float(np.linalg.norm(A, 2))

    Qd, Rd, N = sampled_data_weights(A, B, Q, R, h)

    expected = _quadrature_weights(A, B, Q, R, h)
    difference = _relative(np.block([[Qd, N], [N.T, Rd]]), expected)
    target(difference, label="relative difference from quadrature")
    assert difference <= 1e-12


def test_sampled_data_weights_match_their_taylor_series_for_a_short_period() -> None:
    motor = SPMSM.paper()
    A, B = motor.torque_mode(speed=10.0)
    h = 1e-6
    Qd, Rd, N = sampled_data_weights(A, B, PAPER_Q, PAPER_R, h)
    # int_0^h x'Qx dt with x = (I + A t) x_k + B t u_k, to the first neglected order
    assert _relative(Qd, h * PAPER_Q + h**2 / 2 * (A.T @ PAPER_Q + PAPER_Q @ A)) <= 1e-10
    assert _relative(N, h**2 / 2 * PAPER_Q @ B) <= 1e-5  # next term: h^3 A'QB / 3
    assert _relative(Rd, h * PAPER_R + h**3 / 3 * B.T @ PAPER_Q @ B) <= 1e-12


def test_sampled_data_weights_reject_a_bad_period() -> None:
    with pytest.raises(InputError, match="h: must be a positive finite number"):
        sampled_data_weights([[-1.0]], [[1.0]], [[1.0]], [[1.0]], -1e-4)


# -- continuous_from_discrete ----------------------------------------------------------------


@at_least(60)
@given(
    SEEDS,
    st.integers(min_value=1, max_value=6),
    st.integers(min_value=1, max_value=3),
    st.integers(min_value=0, max_value=2),
    st.floats(min_value=0.01, max_value=1.0),
)
def test_continuous_from_discrete_inverts_discretize(
    seed: int, n: int, m: int, q: int, fraction: float
) -> None:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n)) * rng.uniform(0.1, 1e3)
    B, D = rng.standard_normal((n, m)), rng.standard_normal((n, q))
    # h at most 1/||A||_2: |lambda| h <= 1, far below the aliasing limit |Im lambda| h = pi
    h = fraction / float(np.linalg.norm(A, 2))
    plant = discretize(A, B, h, D=D)

    A_back, B_back, D_back = continuous_from_discrete(plant.Ad, plant.Bd, h, plant.Ed)

    errors = [_relative(A_back, A), _relative(B_back, B)]
    if q:
        errors.append(_relative(D_back, D))
    target(max(errors), label="worst relative error")
    assert max(errors) <= 1e-10, errors
    assert D_back.shape == (n, q)


def test_continuous_from_discrete_of_the_paper_motor_at_10_khz() -> None:
    problem = SPMSM.paper().regulation_problem(speed=10.0)
    plant = discretize(problem.A, problem.B, 1e-4, D=problem.D)
    A, B, D = continuous_from_discrete(plant.Ad, plant.Bd, 1e-4, Ed=plant.Ed)
    for actual, expected in ((A, problem.A), (B, problem.B), (D, problem.D)):
        assert _relative(actual, expected) <= 1e-12


@pytest.mark.parametrize(
    ("Ad", "message"),
    [
        ([[-0.5]], "eigenvalue -0.5 on the closed negative real axis"),
        ([[0.0, 1.0], [0.0, 0.0]], "eigenvalue 0 on the closed negative real axis"),
    ],
)
def test_continuous_from_discrete_without_a_real_logarithm(
    Ad: list[list[float]], message: str
) -> None:
    n = len(Ad)
    with pytest.raises(UnsolvableError, match=message):
        continuous_from_discrete(Ad, np.ones((n, 1)), 1e-3)


def test_continuous_from_discrete_says_when_sampling_is_too_slow() -> None:
    h = 1e-3
    rotation = np.pi / h  # a mode with |Im lambda| h = pi: Ad = -I
    plant = discretize([[0.0, rotation], [-rotation, 0.0]], [[0.0], [1.0]], h)
    with pytest.raises(UnsolvableError, match=r"sampling is too slow .*\|Im lambda\(A\)\| h >= pi"):
        continuous_from_discrete(plant.Ad, plant.Bd, h)


# -- delay_augmented -------------------------------------------------------------------------


@given(
    SEEDS,
    st.integers(min_value=1, max_value=4),
    st.integers(min_value=1, max_value=3),
    st.integers(min_value=0, max_value=3),
)
def test_delay_augmented_is_the_plant_with_a_delay_line(seed: int, n: int, m: int, d: int) -> None:
    rng = np.random.default_rng(seed)
    Ad, Bd = rng.standard_normal((n, n)), rng.standard_normal((n, m))
    Az, Bz = delay_augmented(Ad, Bd, d)
    computed = rng.standard_normal((6 + d, m))  # u_(-d) .. u_5, oldest first
    x = rng.standard_normal(n)
    z = np.concatenate([x, *computed[:d]])
    for k in range(6):
        u = computed[k + d]  # the voltage computed at k
        x = Ad @ x + Bd @ computed[k]  # the voltage applied over [t_k, t_(k+1)): u_(k-d)
        z = Az @ z + Bz @ u
        np.testing.assert_allclose(z, np.concatenate([x, *computed[k + 1 : k + 1 + d]]),
                                   rtol=1e-13, atol=1e-13)  # fmt: skip


def test_delay_augmented_without_delay_is_the_plant_and_names_a_bad_delay() -> None:
    Ad, Bd = np.diag([0.5, 0.25]), np.ones((2, 1))
    Az, Bz = delay_augmented(Ad, Bd, 0)
    np.testing.assert_array_equal(Az, Ad)
    np.testing.assert_array_equal(Bz, Bd)
    for bad in (-1, 1.5, True):
        with pytest.raises(InputError, match="d: expected a whole number >= 0"):
            delay_augmented(Ad, Bd, bad)  # type: ignore[arg-type]


# -- the digital optimum -----------------------------------------------------------------------

PERIODS = st.sampled_from([1e-4, 5e-5])  # 10 and 20 kHz
DELAYS = st.integers(min_value=0, max_value=2)
COSTS: st.SearchStrategy[DigitalCost] = st.sampled_from(["digital", "sampled"])


def _stated_weights(
    problem: RegulationProblem, h: float, d: int, cost: DigitalCost
) -> tuple[Array, Array, Array]:
    """The augmented weights, built here from their definition (for "sampled" with a
    delay, the shift-only-Rd form the docstring of ``solve_digital_regulation`` states).

    "digital": ``Qz = blockdiag(h Q, 0)``, ``Rz = h R``. "sampled": ``[[Qd, N], [N', Rd]]``
    on ``[x_k; u_k]`` for d = 0; for d >= 1, ``Qd`` on x and ``N`` between x and the
    oldest delayed input (the applied one) in Qz, and ``Rz = Rd`` (the applied input's
    weight charged when it is computed), no cross weight with the input.
    """
    n, m = problem.n, problem.m
    size = n + d * m
    Qz, Nz = np.zeros((size, size)), np.zeros((size, m))
    if cost == "digital":
        Qz[:n, :n] = h * PAPER_Q
        return Qz, h * PAPER_R, Nz
    Qd, Rd, N = sampled_data_weights(problem.A, problem.B, PAPER_Q, PAPER_R, h)
    Qz[:n, :n] = Qd
    if d == 0:
        return Qz, Rd, N
    Qz[:n, n : n + m], Qz[n : n + m, :n] = N, N.T
    return Qz, Rd, Nz


def _simulated_cost(solution: ModelBasedSolution, problem: RegulationProblem, z0: Array) -> float:
    """The cost of the closed loop from ``z0`` (deviations), summed over a long simulation:
    "digital", ``sum h (x'Qx + u'Ru)`` with u the computed voltage; "sampled",
    ``sum [x; a]' W [x; a]`` with a the voltage applied during the sample."""
    n, m, d, h = problem.n, problem.m, solution.input_delay, solution.h
    Az, Bz = delay_augmented(solution.Ad, solution.Bd, d)
    W, _ = _sampled_weight(problem, h)
    total, z = 0.0, z0
    radius = _spectral_radius(Az - Bz @ solution.K)
    for _ in range(int(np.ceil(np.log(1e-20) / np.log(radius))) + 10):
        u = -solution.K @ z
        x = z[:n]
        if solution.cost == "digital":
            total += h * float(x @ PAPER_Q @ x + u @ PAPER_R @ u)
        else:
            applied = u if d == 0 else z[n : n + m]
            stage = np.concatenate([x, applied])
            total += float(stage @ W @ stage)
        z = Az @ z + Bz @ u
    return total


def _sampled_weight(problem: RegulationProblem, h: float) -> tuple[Array, Array]:
    """``W = [[Qd, N], [N', Rd]]`` and ``Rd``."""
    Qd, Rd, N = sampled_data_weights(problem.A, problem.B, PAPER_Q, PAPER_R, h)
    return np.block([[Qd, N], [N.T, Rd]]), Rd


def _check_digital_optimum(
    problem: RegulationProblem, h: float, d: int, cost: DigitalCost, seed: int
) -> list[float]:
    """(a) Schur stability, (b) K and P against SLICOT with the stated weights, (d) P
    against a simulated cost; returns the relative differences of (b)."""
    solution = solve_digital_regulation(problem, PAPER_Q, PAPER_R, h, input_delay=d, cost=cost)
    Az, Bz = delay_augmented(solution.Ad, solution.Bd, d)
    assert solution.K.shape == (problem.m, problem.n + d * problem.m)
    assert _spectral_radius(Az - Bz @ solution.K) < 1.0  # (a)

    Qz, Rz, Nz = _stated_weights(problem, h, d, cost)
    K_slicot, P_slicot = _slicot_dlqr(Az, Bz, Qz, Rz, Nz)
    if cost == "sampled" and d:
        # the shift-only-Rd sum leaves out Rd of the d inputs computed before k = 0,
        # which the sampled cost charges while they are applied
        _, Rd = _sampled_weight(problem, h)
        P_slicot = P_slicot + scipy.linalg.block_diag(np.zeros((problem.n,) * 2), *[Rd] * d)
    differences = [_relative(solution.K, K_slicot), _relative(solution.P, P_slicot)]  # (b)

    z0 = np.random.default_rng(seed).standard_normal((Az.shape[0],))  # (d)
    value = float(z0 @ solution.P @ z0)
    assert value == pytest.approx(_simulated_cost(solution, problem, z0), rel=1e-10)
    return differences


def test_the_digital_optimum_of_the_paper_motor() -> None:
    problem = SPMSM.paper().regulation_problem(speed=10.0)
    worst = 0.0
    for h in (1e-4, 5e-5):
        for d in (0, 1, 2):
            for cost in ("digital", "sampled"):
                worst = max(worst, *_check_digital_optimum(problem, h, d, cost, seed=d))
    assert worst <= AGREEMENT


@at_least(40)
@given(motors(), PERIODS, DELAYS, COSTS, SEEDS)
def test_the_digital_optimum_of_random_motors(
    motor_and_speed: tuple[SPMSM, float], h: float, d: int, cost: DigitalCost, seed: int
) -> None:
    motor, speed = motor_and_speed
    problem = motor.regulation_problem(speed=speed)
    differences = _check_digital_optimum(problem, h, d, cost, seed)
    target(max(differences), label="worst relative difference from SLICOT")
    assert max(differences) <= AGREEMENT, differences


@given(motors(), PERIODS)
def test_the_digital_feedforward_is_the_continuous_one(
    motor_and_speed: tuple[SPMSM, float], h: float
) -> None:
    motor, speed = motor_and_speed
    problem = motor.regulation_problem(speed=speed)
    solution = solve_digital_regulation(problem, PAPER_Q, PAPER_R, h, input_delay=1)
    continuous = solve_optimal_regulation(problem, PAPER_Q, PAPER_R)
    np.testing.assert_array_equal(solution.X, continuous.X)
    np.testing.assert_array_equal(solution.U, continuous.U)
    residual = (solution.Ad - np.eye(2)) @ solution.X + solution.Bd @ solution.U + solution.Ed
    size = np.linalg.norm(solution.Ad) * np.linalg.norm(solution.X) + np.linalg.norm(solution.Ed)
    assert np.linalg.norm(residual) <= 1e-13 * size


@pytest.mark.parametrize(
    ("motor", "speed", "periods"),
    [
        (SPMSM.paper(), 10.0, (1e-4, 5e-5, 2.5e-5)),
        # a fast motor (L_s = 3 mH, 2000 rad/s electrical): closed-loop bandwidth ~1e4 rad/s
        (SPMSM(R_s=3.0, L_s=3e-3, phi_pm=0.05, p=1), 2000.0, (1e-5, 5e-6, 2.5e-6)),
    ],
)
def test_the_digital_optimum_converges_to_the_continuous_one_at_first_order(
    motor: SPMSM, speed: float, periods: tuple[float, ...]
) -> None:
    problem = motor.regulation_problem(speed=speed)
    continuous = solve_optimal_regulation(problem, PAPER_Q, PAPER_R)
    errors = []
    for h in periods:
        digital = solve_digital_regulation(problem, PAPER_Q, PAPER_R, h)
        errors.append([_relative(digital.K, continuous.K), _relative(digital.P, continuous.P)])
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    orders = np.log(ratios) / np.log(np.array(periods[:-1]) / np.array(periods[1:]))[:, None]
    # measured: 0.990-1.009 (paper's motor), 0.982-1.019 (fast motor)
    assert np.all(np.abs(orders - 1.0) <= 0.03), orders
    assert max(errors[-1]) <= 0.02  # and close: 0.7% (paper's motor), 1.5% (fast motor)


def test_the_law_drives_the_plant_to_the_reference_with_the_computed_cost() -> None:
    """(e) ControlLaw.command, run on the sampled plant with its delay line and a nonzero
    reference, gives the deviations of the augmented closed loop, and their digital cost
    is the value z0' P z0."""
    motor = SPMSM.paper()
    problem = motor.regulation_problem(speed=10.0)
    h, d = 1e-4, 1
    solution = solve_digital_regulation(problem, PAPER_Q, PAPER_R, h, input_delay=d)
    law, w = solution.law, motor.exogenous(speed=10.0, torque=10.0)
    x, past = np.array([1.0, -2.0]), np.array([[3.0, 4.0]])  # x_0 in A, u_(-1) in V
    z0 = np.concatenate([x - law.X @ w, past[0] - law.U @ w])
    Az, Bz = delay_augmented(solution.Ad, solution.Bd, d)
    closed_loop, z, cost = Az - Bz @ solution.K, z0, 0.0
    for _ in range(1500):
        u = law.command(x, w, past)
        deviation = np.concatenate([x - law.X @ w, past[0] - law.U @ w])
        np.testing.assert_allclose(deviation, z, rtol=0, atol=1e-11)
        np.testing.assert_allclose(u, law.U @ w - solution.K @ deviation, rtol=1e-13, atol=1e-12)
        cost += h * float(deviation[:2] @ PAPER_Q @ deviation[:2])
        cost += h * float((u - law.U @ w) @ PAPER_R @ (u - law.U @ w))
        x = solution.Ad @ x + solution.Bd @ past[0] + solution.Ed @ w  # u_(k-1) applied
        past = np.array([u])
        z = closed_loop @ z
    np.testing.assert_allclose(x, law.X @ w, rtol=0, atol=1e-12)  # i_q -> i_q* = 7.2464 A
    assert cost == pytest.approx(float(z0 @ solution.P @ z0), rel=1e-10)
    assert solution.state == ("x1", "x2", "u1[k-1]", "u2[k-1]")


# -- errors ----------------------------------------------------------------------------------


def _rotating_problem(rotation: float, growth: float, E: Array | None = None) -> RegulationProblem:
    """A two-state plant ``x' = [[g, w], [-w, g]] x + [0; 1] u`` (controllable), e = x1."""
    A = np.array([[growth, rotation], [-rotation, growth]])
    E = np.zeros((1, 1)) if E is None else E
    q = E.shape[0]
    return RegulationProblem(
        A=A, B=np.array([[0.0], [1.0]]), C=np.array([[1.0, 0.0]]), D=np.ones((2, q)), E=E,
        F=np.ones((1, q)),
    )  # fmt: skip


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        ({"h": 0.0}, "h: must be a positive finite number, got 0.0"),
        ({"h": -1e-4}, "h: must be a positive finite number"),
        ({"h": float("nan")}, "h: must be a positive finite number"),
        ({"h": "1e-4"}, "h: must be a positive number, got '1e-4'"),
        ({"input_delay": -1}, "input_delay: expected a whole number >= 0, got -1"),
        ({"input_delay": 1.0}, "input_delay: expected a whole number >= 0, got 1.0"),
        ({"input_delay": True}, "input_delay: expected a whole number >= 0, got True"),
        ({"cost": "continuous"}, "cost: expected 'digital' or 'sampled', got 'continuous'"),
        ({"Q": -np.eye(2)}, "Q: must be positive semidefinite"),
    ],
)
def test_bad_arguments_are_named(arguments: dict[str, object], message: str) -> None:
    problem = SPMSM.paper().regulation_problem(speed=10.0)
    values: dict[str, object] = {"Q": PAPER_Q, "R": PAPER_R, "h": 1e-4, **arguments}
    with pytest.raises(InputError, match=message):
        solve_digital_regulation(problem, **values)  # type: ignore[arg-type]


def test_a_moving_reference_is_refused() -> None:
    problem = _rotating_problem(10.0, -1.0, E=np.array([[0.0, 5.0], [-5.0, 0.0]]))
    with pytest.raises(InputError, match=r"E: digital regulation needs E = 0 \(the reference"):
        solve_digital_regulation(problem, np.eye(2), [[1.0]], 1e-3)


def test_an_unstabilizable_plant_is_named() -> None:
    problem = RegulationProblem(
        A=np.diag([1.0, -1.0]), B=[[0.0], [1.0]], C=[[0.0, 1.0]], D=np.ones((2, 1)),
        E=np.zeros((1, 1)), F=[[1.0]],
    )  # fmt: skip
    with pytest.raises(UnsolvableError, match=r"\(A, B\) is not stabilizable"):
        solve_digital_regulation(problem, np.eye(2), [[1.0]], 1e-3)


def test_a_sampling_period_that_hides_a_mode_is_named() -> None:
    # controllable in continuous time; sampled at one full turn of the unstable rotating
    # mode, Ad = exp(g h) I and rank [Ad - lambda I, Bd] = 1: not stabilizable
    rotation, growth = 2 * np.pi * 100.0, 1.0
    problem = _rotating_problem(rotation, growth)
    solve_digital_regulation(problem, np.eye(2), [[1.0]], 1e-3)  # 10 samples a turn: fine
    with pytest.raises(
        UnsolvableError,
        match=r"sampled at h = 0\.01 s with a delay of 1 samples: \(A, B\) is not stabilizable in"
        r" discrete time: the mode at eigenvalue 1\.01005 ",
    ):
        solve_digital_regulation(problem, np.eye(2), [[1.0]], 1e-2, input_delay=1)
