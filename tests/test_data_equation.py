"""The data equation's quadrature, checked against closed forms and exact simulation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from learners import regulator
from selftune import RegulationProblem, lqr, solve_optimal_regulation
from selftune.learn import (
    Trajectory,
    interval_moments,
    regression,
    solve_regression,
)
from selftune.learn.learners._moments import _holds, _quadratic_stencils
from selftune.sim import exosystem, simulate, sum_of_sines, uniform


@settings(max_examples=50)
@given(
    steps=st.lists(st.floats(0.1, 2.0), min_size=2, max_size=12),
    runs=st.lists(st.integers(1, 5), min_size=1, max_size=6),
    coefficients=st.tuples(st.floats(-3, 3), st.floats(-3, 3), st.floats(-3, 3)),
)
def test_hold_stencils_integrate_quadratics_exactly(
    steps: list[float], runs: list[int], coefficients: tuple[float, float, float]
) -> None:
    """On any grid, each sample's weights integrate a quadratic exactly over that sample."""
    count = len(steps)
    t = np.concatenate([[0.0], np.cumsum(steps)])
    run_of = np.repeat(np.arange(len(runs)), runs)[:count]
    run_of = np.concatenate([run_of, np.full(count - run_of.size, len(runs))])
    continues = run_of[1:] == run_of[:-1]
    in_hold, points, weights = _quadratic_stencils(t, continues)
    c0, c1, c2 = coefficients

    def antiderivative(s: np.ndarray) -> np.ndarray:
        return c0 * s + c1 * s**2 / 2 + c2 * s**3 / 3

    values = c0 + c1 * t + c2 * t**2
    for k in np.flatnonzero(in_hold):
        # the stencil lies in the sample's own hold
        assert set(run_of[np.minimum(points[k], count - 1)[:-1]]) <= {run_of[k]}
        exact = antiderivative(t[k + 1]) - antiderivative(t[k])
        approx = weights[k] @ values[points[k]]
        assert approx == pytest.approx(exact, rel=1e-9, abs=1e-9)
    lengths = np.bincount(run_of)[run_of]
    np.testing.assert_array_equal(in_hold, lengths >= 2)


def test_holds_are_read_off_equal_inputs() -> None:
    u = np.array([[1.0], [1.0], [2.0], [3.0], [3.0], [3.0]])
    data = Trajectory(t=np.arange(7.0), x=np.zeros((7, 1)), u=u)
    np.testing.assert_array_equal(_holds(data, held=True), [True, False, False, True, True])


def test_moments_are_exact_for_a_state_linear_in_time() -> None:
    """With A = 0 the state is linear in each sample: the moments are exact integrals."""
    t = np.linspace(0.0, 1.0, 11)
    u = np.sin(np.arange(10.0))[:, None]
    x = np.concatenate([[0.0], np.cumsum(u[:, 0] * 0.1)])[:, None]
    moments = interval_moments(Trajectory(t=t, x=x, u=u), interval=10)
    exact_xx = sum(
        0.1 * (x[k, 0] ** 2 + x[k, 0] * x[k + 1, 0] + x[k + 1, 0] ** 2) / 3 for k in range(10)
    )
    assert moments.zz[0, 0, 0] == pytest.approx(exact_xx, rel=1e-13)
    assert moments.zu[0, 0, 0] == pytest.approx(
        sum(0.05 * (x[k, 0] + x[k + 1, 0]) * u[k, 0] for k in range(10)), rel=1e-13
    )
    assert moments.dzz[0, 0, 0] == pytest.approx(x[-1, 0] ** 2 - x[0, 0] ** 2, rel=1e-13)


@pytest.mark.parametrize("hold", [1, 2, 4])
def test_simulated_holds_keep_inputs_and_replay_exactly(hold: int) -> None:
    rng = np.random.default_rng(hold)
    A, B = rng.normal(size=(3, 3)), rng.normal(size=(3, 2))
    K = lqr(A, B, np.eye(3), np.eye(2))[0]
    data = simulate(
        A,
        B,
        K=K,
        exploration=uniform(1.0),
        x0=[1.0, 0.0, -1.0],
        h=1e-2,
        num_samples=41,
        seed=3,
        input_hold=hold,
    )
    assert data.u.shape == (41, 2)
    for start in range(0, 41, hold):
        block = data.u[start : start + hold]
        assert np.all(block == block[0])
    replay = simulate(A, B, exploration=data.u, x0=data.x[0], h=1e-2, num_samples=41)
    np.testing.assert_allclose(data.x, replay.x, rtol=1e-12, atol=1e-12)
    # the controller acted on the state at its own update instants only
    rho = data.u[::hold] + data.x[:-1:hold] @ K.T
    coarse = simulate(
        A, B, K=K, exploration=rho, x0=data.x[0], h=hold * 1e-2, num_samples=rho.shape[0]
    )
    fine = data.x[::hold]
    common = min(fine.shape[0], coarse.x.shape[0])
    np.testing.assert_allclose(coarse.x[:common], fine[:common], rtol=1e-11, atol=1e-12)


def test_holding_the_input_gives_fourth_order() -> None:
    rng = np.random.default_rng(3)
    n = 3
    A, B = rng.normal(size=(n, n)), rng.normal(size=(n, n))
    C = np.eye(n) + 0.3 * rng.normal(size=(n, n))
    D, F = rng.normal(size=(n, 2)), rng.normal(size=(n, 2))
    E = np.array([[0.0, 3.0], [-3.0, 0.0]])
    problem = RegulationProblem(A=A, B=B, C=C, D=D, E=E, F=F)
    optimum = solve_optimal_regulation(problem, np.eye(n), np.eye(n))
    K0 = lqr(A, B, 10.0 * np.eye(n), np.eye(n))[0]
    exploration = sum_of_sines(1.0, rng.uniform(0.1, 3.0, size=8))
    periods, errors = [8e-3, 4e-3, 2e-3], []
    for h in periods:
        data = simulate(
            A,
            B,
            D=D,
            exogenous=exosystem(E, [1.0, 0.5]),
            K=K0,
            exploration=exploration,
            x0=[1.0, -1.0, 0.5],
            h=h,
            num_samples=round(10 / h),
            seed=1,
            input_hold=2,
        )
        learned = regulator(data, C, E, F, np.eye(n), np.eye(n), K0, interval=2 * round(0.01 / h))
        errors.append(np.linalg.norm(learned.theta - optimum.theta) / np.linalg.norm(optimum.theta))
    order = np.polyfit(np.log(periods), np.log(errors), 1)[0]
    assert 3.6 < order < 4.6, f"order {order:.2f}, errors {errors}"


def test_partially_known_theta_keeps_the_given_blocks() -> None:
    rng = np.random.default_rng(0)
    A, B = -np.eye(2) + 0.1 * rng.normal(size=(2, 2)), np.eye(2)
    data = simulate(A, B, exploration=uniform(1.0), x0=[1.0, 1.0], h=1e-2, num_samples=300, seed=1)
    moments = interval_moments(data, 5)
    problem = regression(moments, np.zeros((2, 2)), np.eye(2), np.eye(2))
    full = solve_regression(problem)
    known_P = full.theta[:3]
    partial = solve_regression(problem, known={"P": known_P})
    np.testing.assert_array_equal(partial.theta[:3], known_P)
    np.testing.assert_allclose(partial.theta[3:], full.theta[3:], rtol=1e-9, atol=1e-12)
