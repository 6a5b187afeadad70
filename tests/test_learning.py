"""The learners against the model-based optimum, on plants built here with known optima.

Truth is independent of the learner: K*, P* from the Riccati equation and (X*, U*) from
the regulator equations (themselves checked against python-control in test_regulation).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from example_counts import examples
from learners import regulator
from selftune import (
    ConvergenceError,
    ExcitationError,
    InputError,
    RegulationProblem,
    UnsolvableError,
    lqr,
    solve_optimal_regulation,
)
from selftune.learn import LearningOptions, LearningProblem, Trajectory, learn_lqr
from selftune.sim import constant, exosystem, prbs, simulate, steps, sum_of_sines


def relative(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(a - b) / max(np.linalg.norm(b), 1e-300))


def random_problem(
    rng: np.random.Generator, n: int, m: int, r: int, q: int, rotating: bool, A_zero: bool = False
) -> RegulationProblem:
    A = np.zeros((n, n)) if A_zero else rng.normal(size=(n, n))
    B = rng.normal(size=(n, m))
    C = np.eye(n) + 0.3 * rng.normal(size=(n, n)) if r == n else rng.normal(size=(r, n))
    D = rng.normal(size=(n, q))
    F = rng.normal(size=(r, q))
    if rotating:
        frequencies = rng.uniform(1.0, 4.0, size=(q + 1) // 2)
        E = np.zeros((q, q))
        for index, frequency in enumerate(frequencies):
            if 2 * index + 1 < q:
                E[2 * index, 2 * index + 1] = frequency
                E[2 * index + 1, 2 * index] = -frequency
    else:
        E = np.zeros((q, q))
    return RegulationProblem(A=A, B=B, C=C, D=D, E=E, F=F)


def rich_exploration(rng: np.random.Generator, m: int) -> object:
    return sum_of_sines(1.0, rng.uniform(0.1, 3.0, size=8))


def record(
    problem: RegulationProblem,
    K0: np.ndarray,
    h: float,
    duration: float,
    seed: int,
    *,
    exploration: object | None = None,
) -> Trajectory:
    """Data from the plant under K0 with exploration and an exciting exogenous signal."""
    rng = np.random.default_rng(seed)
    q = problem.q
    if np.any(problem.E):
        reference = exosystem(problem.E, rng.normal(size=q) + 1.0)
    else:
        times = np.unique(rng.uniform(0.0, duration, size=12))
        reference = steps(times, rng.normal(size=(times.size + 1, q)) * 2.0)
    return simulate(
        problem.A,
        problem.B,
        D=problem.D,
        exogenous=reference,
        K=K0,
        exploration=rich_exploration(rng, problem.m) if exploration is None else exploration,
        x0=rng.normal(size=problem.n),
        h=h,
        num_samples=round(duration / h),
        seed=seed,
    )


def check_against_optimum(learned, optimum, tolerance: float) -> None:  # type: ignore[no-untyped-def]
    for name in ("K", "P", "X", "U"):
        error = relative(getattr(learned, name), getattr(optimum, name))
        assert error < tolerance, f"{name}: relative error {error:.3g} >= {tolerance:.3g}"
    assert relative(learned.theta, optimum.theta) < tolerance


# -- exact quadrature: A = 0 makes the state linear inside each sample --------------------


@settings(max_examples=25)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(1, 4),
    extra_inputs=st.integers(0, 1),
    q=st.integers(1, 2),
    h=st.sampled_from([1e-3, 1e-2, 5e-2]),
)
def test_learning_is_exact_when_the_quadrature_is_exact(
    seed: int, n: int, extra_inputs: int, q: int, h: float
) -> None:
    """With A = 0 and w held, x is linear in each sample: the data equation is exact, so
    the learned controller equals the optimum to rounding, at any sampling period."""
    rng = np.random.default_rng(seed)
    m = n + extra_inputs
    problem = random_problem(rng, n, m, n, q, rotating=False, A_zero=True)
    assume(np.linalg.matrix_rank(problem.C) == n)
    Q, R = np.eye(n), np.diag(rng.uniform(0.5, 2.0, size=m))
    optimum = solve_optimal_regulation(problem, Q, R)
    K0 = lqr(problem.A, problem.B, 5.0 * np.eye(n), np.eye(m))[0]
    data = record(problem, K0, h, duration=400 * h, seed=seed, exploration=prbs(1.0, 3))
    learned = regulator(data, problem.C, problem.E, problem.F, Q, R, K0, interval=4)
    check_against_optimum(learned, optimum, 1e-7)


# -- several sizes, m > r, rotating exosystem: 1e-6 at fine sampling -------------------------


CASES = [
    # (n, m, r, q, rotating): the customized path needs r = n <= m; m > r is non-unique.
    (1, 1, 1, 1, False),
    (2, 2, 2, 2, False),
    (3, 3, 3, 2, True),
    (2, 3, 2, 2, True),
    (3, 2, 1, 2, True),
    (4, 2, 1, 1, False),
]


@pytest.mark.parametrize(("n", "m", "r", "q", "rotating"), CASES)
def test_learned_controller_matches_optimum_at_fine_sampling(
    n: int, m: int, r: int, q: int, rotating: bool
) -> None:
    rng = np.random.default_rng(1000 * n + 100 * m + 10 * r + q)
    for _ in range(50):
        problem = random_problem(rng, n, m, r, q, rotating)
        try:
            optimum = solve_optimal_regulation(problem, np.eye(n), np.eye(m))
            break
        except UnsolvableError:
            continue
    K0 = lqr(problem.A, problem.B, 10.0 * np.eye(n), np.eye(m))[0]
    closed_loop = np.max(np.abs(np.linalg.eigvals(problem.A - problem.B @ K0)))
    h = 2e-4 / closed_loop
    data = record(problem, K0, h, duration=4.0, seed=n + m + r + q)
    learned = regulator(
        data, problem.C, problem.E, problem.F, np.eye(n), np.eye(m), K0, interval=50
    )
    assert learned.formulation == ("customized" if r == n else "general")
    check_against_optimum(learned, optimum, 1e-6)


def test_min_trace_pair_is_learned_when_regulator_solution_is_not_unique() -> None:
    rng = np.random.default_rng(7)
    problem = random_problem(rng, 3, 3, 1, 2, rotating=True)
    Q, R = np.diag([1.0, 2.0, 3.0]), np.diag([1.0, 0.5, 2.0])
    optimum = solve_optimal_regulation(problem, Q, R)
    K0 = lqr(problem.A, problem.B, 10.0 * np.eye(3), np.eye(3))[0]
    h = 2e-4 / np.max(np.abs(np.linalg.eigvals(problem.A - problem.B @ K0)))
    data = record(problem, K0, h, duration=8.0, seed=3)
    learned = regulator(data, problem.C, problem.E, problem.F, Q, R, K0, interval=50)
    assert learned.formulation == "general"
    check_against_optimum(learned, optimum, 1e-6)
    residuals = problem.regulator_residuals(learned.X, learned.U)
    assert max(residuals) < 1e-5 * np.linalg.norm(problem.D)


# -- the quadrature's order -------------------------------------------------------------------


@pytest.mark.parametrize("method", ["customized", "general"])
def test_error_shrinks_at_second_order(method: str) -> None:
    """Smooth exploration gives data with a continuous-time limit; halving h must divide
    the error by about 4 (the linear-interpolation quadrature is second order)."""
    rng = np.random.default_rng(3)
    problem = random_problem(rng, 3, 3, 3, 2, rotating=True)
    optimum = solve_optimal_regulation(problem, np.eye(3), np.eye(3))
    K0 = lqr(problem.A, problem.B, 10.0 * np.eye(3), np.eye(3))[0]
    exploration = sum_of_sines(1.0, rng.uniform(0.1, 3.0, size=8))
    periods = [4e-3, 2e-3, 1e-3, 5e-4]
    errors = []
    for h in periods:
        data = simulate(
            problem.A,
            problem.B,
            D=problem.D,
            exogenous=exosystem(problem.E, [1.0, 0.5]),
            K=K0,
            exploration=exploration,
            x0=[1.0, -1.0, 0.5],
            h=h,
            num_samples=round(10.0 / h),
            seed=11,
        )
        learned = regulator(
            data,
            problem.C,
            problem.E,
            problem.F,
            np.eye(3),
            np.eye(3),
            K0,
            interval=round(0.02 / h),
            formulation=method,  # type: ignore[arg-type]
        )
        errors.append(relative(learned.theta, optimum.theta))
    order = np.polyfit(np.log(periods), np.log(errors), 1)[0]
    assert 1.8 < order < 2.3, f"observed order {order:.2f}, errors {errors}"


# -- plain LQR ----------------------------------------------------------------------------


@examples(15, quick=5)  # 40,000 samples each
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 5), m=st.integers(1, 3))
def test_learn_lqr_matches_riccati_and_recovers_B(seed: int, n: int, m: int) -> None:
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    B = rng.normal(size=(n, m))
    assume(
        np.linalg.matrix_rank(np.hstack([np.linalg.matrix_power(A, k) @ B for k in range(n)])) == n
    )
    Q, R = np.eye(n), np.eye(m)
    K_star, P_star = lqr(A, B, Q, R)
    K0 = lqr(A, B, 20.0 * np.eye(n), np.eye(m))[0]
    h = 2e-4 / np.max(np.abs(np.linalg.eigvals(A - B @ K0)))
    data = simulate(
        A,
        B,
        K=K0,
        exploration=rich_exploration(rng, m),
        x0=rng.normal(size=n),
        h=h,
        num_samples=round(8.0 / h),
        seed=seed,
    )
    learned = learn_lqr(data, LearningProblem(Q, R), K0, LearningOptions(interval=50))
    assert relative(learned.K, K_star) < 1e-6
    assert relative(learned.P, P_star) < 1e-6
    assert relative(learned.B, B) < 1e-6
    assert np.allclose(learned.P, learned.P.T)
    assert np.min(np.linalg.eigvalsh(learned.P)) > 0


def test_off_policy_result_does_not_depend_on_the_initial_policy() -> None:
    rng = np.random.default_rng(5)
    problem = random_problem(rng, 2, 2, 2, 2, rotating=False)
    optimum = solve_optimal_regulation(problem, np.eye(2), np.eye(2))
    K_gather = lqr(problem.A, problem.B, 10.0 * np.eye(2), np.eye(2))[0]
    data = record(problem, K_gather, 1e-4, duration=6.0, seed=5)
    results = [
        regulator(data, problem.C, problem.E, problem.F, np.eye(2), np.eye(2), K0, interval=50)
        for K0 in (K_gather, lqr(problem.A, problem.B, 300.0 * np.eye(2), np.eye(2))[0])
    ]
    assert relative(results[0].K, results[1].K) < 1e-9
    check_against_optimum(results[1], optimum, 1e-6)


def test_episodes_add_their_intervals() -> None:
    rng = np.random.default_rng(9)
    problem = random_problem(rng, 2, 2, 2, 1, rotating=False)
    K0 = lqr(problem.A, problem.B, 10.0 * np.eye(2), np.eye(2))[0]
    episodes = [record(problem, K0, 1e-3, 1.0, seed) for seed in (1, 2, 3)]
    together = regulator(
        episodes, problem.C, problem.E, problem.F, np.eye(2), np.eye(2), K0, interval=10
    )
    assert together.rows == 300


# -- errors: never a silent wrong answer ------------------------------------------------------


def motor_like_problem() -> RegulationProblem:
    A = np.array([[-7.3, 20.0], [-20.0, -7.3]])
    return RegulationProblem(
        A=A,
        B=np.eye(2) / 0.06,
        C=np.eye(2),
        D=np.array([[0.0, 0.0], [-16.6, 0.0]]),
        E=np.zeros((2, 2)),
        F=np.array([[0.0, 0.0], [0.0, -0.72]]),
    )


def test_constant_reference_is_an_excitation_error_naming_the_block() -> None:
    problem = motor_like_problem()
    K0 = 60.0 * np.eye(2)
    data = simulate(
        problem.A,
        problem.B,
        D=problem.D,
        exogenous=constant([9.2, 10.0]),
        K=K0,
        exploration=prbs(1.0, 2),
        h=1e-5,
        num_samples=500,
        seed=0,
    )
    with pytest.raises(ExcitationError) as error:
        regulator(data, problem.C, problem.E, problem.F, 1e3 * np.eye(2), np.eye(2), K0)
    message = str(error.value)
    assert "rank 9 of 11" in message
    assert "M block" in message
    assert "perturb the reference" in message


def test_no_exploration_is_an_excitation_error_naming_the_input_block() -> None:
    A = np.array([[0.0, 1.0], [-2.0, -0.5]])
    B = np.array([[0.0], [1.0]])
    K0 = np.array([[1.0, 1.0]])
    data = simulate(A, B, K=K0, x0=[1.0, 0.0], h=1e-2, num_samples=500)
    with pytest.raises(ExcitationError) as error:
        learn_lqr(data, LearningProblem(np.eye(2), np.eye(1)), K0)
    assert "K block" in str(error.value)
    assert "exploration" in str(error.value)


def test_too_few_samples_is_an_excitation_error() -> None:
    problem = motor_like_problem()
    data = record(problem, 60.0 * np.eye(2), 1e-5, 5e-4, seed=0)
    with pytest.raises(ExcitationError, match="intervals"):
        regulator(
            data,
            problem.C,
            problem.E,
            problem.F,
            1e3 * np.eye(2),
            np.eye(2),
            60.0 * np.eye(2),
            interval=10,
        )


def test_destabilizing_initial_policy_is_a_convergence_error() -> None:
    A = np.array([[1.0, 0.5], [0.0, 2.0]])
    B = np.eye(2)
    K0 = np.zeros((2, 2))  # A is unstable: K0 = 0 does not stabilize
    data = simulate(
        A, B, K=K0, exploration=prbs(1.0, 5), x0=[0.1, 0.1], h=1e-3, num_samples=2000, seed=1
    )
    with pytest.raises(ConvergenceError, match="not positive definite"):
        learn_lqr(data, LearningProblem(np.eye(2), np.eye(2)), K0)


def test_wrong_shapes_are_named() -> None:
    problem = motor_like_problem()
    data = record(problem, 60.0 * np.eye(2), 1e-5, 5e-3, seed=0)
    with pytest.raises(InputError, match="K0"):
        regulator(data, problem.C, problem.E, problem.F, np.eye(2), np.eye(2), np.eye(3))
    with pytest.raises(InputError, match="F"):
        I2 = np.eye(2)
        regulator(data, problem.C, np.zeros((3, 3)), np.zeros((2, 3)), I2, I2, I2)
    with pytest.raises(InputError, match="exogenous"):
        learn_lqr(data, LearningProblem(np.eye(2), np.eye(2)), 60.0 * np.eye(2))
    with pytest.raises(InputError, match="interval"):
        regulator(
            data, problem.C, problem.E, problem.F, np.eye(2), np.eye(2), np.eye(2), interval=0
        )


def test_exosystem_data_need_every_sample_of_w() -> None:
    rng = np.random.default_rng(2)
    problem = random_problem(rng, 2, 2, 2, 2, rotating=True)
    data = record(problem, lqr(problem.A, problem.B, np.eye(2), np.eye(2))[0], 1e-3, 1.0, 0)
    held_only = Trajectory(t=data.t, x=data.x, u=data.u, w=data.w[:-1])
    with pytest.raises(InputError, match="exosystem"):
        regulator(held_only, problem.C, problem.E, problem.F, np.eye(2), np.eye(2), np.eye(2))


def test_the_learners_earlier_arguments_still_work_and_warn() -> None:
    """``learn_output_regulation(data, C, E, F, Q, R, K0)`` and
    ``learn_controller(data, LearningProblem(..., K0=K0), options)`` (the README's of
    earlier releases) give what the new order gives, with a deprecation warning."""
    from selftune.errors import SelftuneDeprecationWarning
    from selftune.learn import learn_controller, learn_output_regulation, learn_regulator

    rng = np.random.default_rng(4)
    problem = random_problem(rng, 2, 2, 2, 2, rotating=False, A_zero=True)
    Q, R = np.eye(2), np.eye(2)
    K0 = lqr(problem.A, problem.B, 5.0 * np.eye(2), np.eye(2))[0]
    data = record(problem, K0, 1e-2, duration=4.0, seed=4, exploration=prbs(1.0, 3))
    known = LearningProblem(Q, R, C=problem.C, E=problem.E, F=problem.F)
    new = learn_regulator(data, known, K0, LearningOptions(interval=4))
    with pytest.warns(SelftuneDeprecationWarning, match="call learn_regulator"):
        old = learn_output_regulation(data, problem.C, problem.E, problem.F, Q, R, K0, interval=4)
    np.testing.assert_array_equal(old.K, new.K)
    np.testing.assert_array_equal(old.U, new.U)
    options = LearningOptions(interval=4, noise="none")
    with pytest.warns(SelftuneDeprecationWarning, match=r"LearningProblem\(K0=...\)"):
        with_K0 = LearningProblem(Q, R, C=problem.C, E=problem.E, F=problem.F, K0=K0)
    with pytest.warns(SelftuneDeprecationWarning, match="learn_controller.data, problem, K0"):
        old_order = learn_controller(data, with_K0, options)
    np.testing.assert_array_equal(old_order.K, learn_controller(data, known, K0, options).K)
    with pytest.raises(InputError, match="K0: missing"):
        learn_controller(data, known, options)
