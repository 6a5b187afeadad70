"""The simulator against independent truth: solve_ivp, closed forms, the motor model."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
import scipy.linalg
from hypothesis import given
from hypothesis import strategies as st
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from example_counts import examples
from selftune import SPMSM, InputError, solve_optimal_regulation
from selftune.learn import Trajectory
from selftune.sim import (
    Exploration,
    TrajectoryBatch,
    constant,
    discretize,
    exosystem,
    held,
    prbs,
    simulate,
    simulate_batch,
    steps,
    sum_of_sines,
    uniform,
)

Array = NDArray[np.float64]

RTOL_IVP = 1e-11


def random_plant(
    rng: np.random.Generator, n: int, m: int, q: int, shift: float = 0.0
) -> tuple[Array, Array, Array]:
    """A random plant ``A`` (eigenvalues moved right by ``shift``), ``B``, ``D``."""
    A = rng.normal(size=(n, n)) - (1.0 - shift) * np.eye(n)
    return A, rng.normal(size=(n, m)), rng.normal(size=(n, q))


def relative_error(actual: Array, expected: Array) -> float:
    return float(np.max(np.abs(actual - expected)) / max(1.0, float(np.max(np.abs(expected)))))


def closed_loop_ivp(
    A: Array,
    B: Array,
    D: Array,
    t: Array,
    x0: Array,
    policy: Callable[[int, Array, Array], Array],
    w0: Array,
    E: Array | None,
    held_w: Array | None = None,
) -> tuple[Array, Array]:
    """Integrate sample by sample with solve_ivp: the policy sees the ivp's own state.

    With ``E`` the exosystem is integrated jointly; otherwise ``held_w[k]`` is held.
    Returns the states (N + 1, n) and the exogenous values (N + 1, q).
    """
    n, q = A.shape[0], D.shape[1]
    x = [np.asarray(x0, dtype=float)]
    w = [np.asarray(w0, dtype=float) if E is not None else held_w[0]]  # type: ignore[index]
    for k in range(len(t) - 1):
        w_k = w[k] if E is not None else held_w[k]  # type: ignore[index]
        u_k = policy(k, x[k], w_k)

        def rhs(_: float, z: Array, u_k: Array = u_k, w_k: Array = w_k) -> Array:
            if E is None:
                return A @ z + B @ u_k + D @ w_k
            return np.concatenate([A @ z[:n] + B @ u_k + D @ z[n:], E @ z[n:]])

        z0 = x[k] if E is None else np.concatenate([x[k], w[k]])
        scale = max(1.0, float(np.max(np.abs(z0))))
        solution = solve_ivp(
            rhs, (t[k], t[k + 1]), z0, method="DOP853", rtol=RTOL_IVP, atol=1e-14 * scale
        )
        assert solution.success
        x.append(solution.y[:n, -1])
        w.append(solution.y[n:, -1] if E is not None else held_w[k + 1])  # type: ignore[index]
    return np.array(x), np.array(w).reshape(len(t), q)


# -- exactness against solve_ivp ----------------------------------------------------------


@pytest.mark.parametrize(("seed", "shift"), [(0, 0.0), (1, 0.0), (2, 2.5), (3, 2.5)])
def test_closed_loop_with_held_inputs_matches_solve_ivp(seed: int, shift: float) -> None:
    """Random stable (shift 0) and unstable (shift 2.5) plants, held reference, exploration."""
    rng = np.random.default_rng(seed)
    n, m, q = 3, 2, 2
    A, B, D = random_plant(rng, n, m, q, shift)
    K = 0.3 * rng.normal(size=(m, n))
    X = rng.normal(size=(n, q))
    U = rng.normal(size=(m, q))
    x0 = rng.normal(size=n)
    h, N = 0.07, 25

    def reference(t: Array) -> Array:
        return np.column_stack([np.sin(3.0 * t), 0.5 + np.cos(7.0 * t)])

    rho = rng.uniform(-1.0, 1.0, size=(N, m))
    data = simulate(
        A, B, D=D, exogenous=held(reference), K=K, X=X, U=U, exploration=rho, x0=x0, h=h,
        num_samples=N,
    )  # fmt: skip
    t = h * np.arange(N + 1)
    w_held = reference(t)

    def policy(k: int, x: Array, w: Array) -> Array:
        return -K @ (x - X @ w) + U @ w + rho[k]

    x_ivp, _ = closed_loop_ivp(A, B, D, t, x0, policy, w_held[0], None, w_held)
    assert np.max(np.abs(np.linalg.eigvals(A)).real) > 0  # sanity: plants are non-trivial
    assert relative_error(data.x, x_ivp) < 1e-9
    u_policy = np.array([policy(k, data.x[k], w_held[k]) for k in range(N)])
    assert relative_error(data.u, u_policy) < 1e-12
    np.testing.assert_allclose(data.w, w_held, rtol=0, atol=1e-15)
    np.testing.assert_allclose(data.t, t, rtol=1e-15)


def test_non_uniform_grid_matches_solve_ivp() -> None:
    rng = np.random.default_rng(7)
    A, B, D = random_plant(rng, 2, 1, 1, shift=1.2)
    K = rng.normal(size=(1, 2))
    t = np.concatenate([[0.0], np.cumsum(rng.uniform(0.01, 0.2, size=20))])
    x0 = np.array([1.0, -2.0])
    levels = np.array([[0.0], [1.0], [-2.0]])
    signal = steps([t[5], 0.5 * (t[12] + t[13])], levels)  # one on a sample, one between
    data = simulate(A, B, D=D, exogenous=signal, K=K, exploration=prbs(0.5), x0=x0, t=t, seed=3)
    w_held = signal.values(t)
    assert w_held[4, 0] == 0.0 and w_held[5, 0] == 1.0  # a step on a sample time counts there
    assert w_held[12, 0] == 1.0 and w_held[13, 0] == -2.0  # between samples: at the next one
    rho = data.u + data.x[:-1] @ K.T

    def policy(k: int, x: Array, w: Array) -> Array:
        return -K @ x + rho[k]

    x_ivp, _ = closed_loop_ivp(A, B, D, t, x0, policy, w_held[0], None, w_held)
    assert relative_error(data.x, x_ivp) < 1e-9
    np.testing.assert_allclose(np.abs(rho), 0.5, rtol=1e-12)


def test_exosystem_closed_loop_matches_solve_ivp() -> None:
    """w' = E w continuous inside the samples; the policy uses w(t_k)."""
    rng = np.random.default_rng(11)
    n, m = 3, 2
    E = np.array([[0.0, 4.0, 0.0], [-4.0, 0.0, 0.0], [0.0, 0.0, 0.0]])  # sinusoid and a constant
    A, B, D = random_plant(rng, n, m, 3, shift=0.5)
    K = 0.5 * rng.normal(size=(m, n))
    X = rng.normal(size=(n, 3))
    U = rng.normal(size=(m, 3))
    w0 = np.array([0.0, 1.0, 2.0])
    h, N = 0.05, 30
    rho = rng.uniform(-1.0, 1.0, size=(N, m))
    data = simulate(
        A, B, D=D, exogenous=exosystem(E, w0), K=K, X=X, U=U, exploration=rho, h=h, num_samples=N
    )
    t = h * np.arange(N + 1)

    def policy(k: int, x: Array, w: Array) -> Array:
        return -K @ (x - X @ w) + U @ w + rho[k]

    x_ivp, w_ivp = closed_loop_ivp(A, B, D, t, np.zeros(n), policy, w0, E)
    assert relative_error(data.x, x_ivp) < 1e-9
    assert relative_error(data.w, w_ivp) < 1e-9
    assert data.w.shape == (N + 1, 3)


def test_exosystem_against_analytic_sinusoid() -> None:
    """x' = -a x + w_1 with w = [sin(omega t), cos(omega t)], x(0) = 0, in closed form."""
    a, omega, h, N = 3.0, 20.0, 0.013, 200
    data = simulate(
        [[-a]], [[1.0]], D=[[1.0, 0.0]],
        exogenous=exosystem([[0.0, omega], [-omega, 0.0]], [0.0, 1.0]), h=h, num_samples=N,
    )  # fmt: skip
    t = h * np.arange(N + 1)
    np.testing.assert_allclose(data.w[:, 0], np.sin(omega * t), rtol=0, atol=1e-12)
    np.testing.assert_allclose(data.w[:, 1], np.cos(omega * t), rtol=0, atol=1e-12)
    exact = (a * np.sin(omega * t) - omega * np.cos(omega * t) + omega * np.exp(-a * t)) / (
        a**2 + omega**2
    )
    np.testing.assert_allclose(data.x[:, 0], exact, rtol=0, atol=1e-13)
    assert data.u.shape == (N, 1) and np.all(data.u == 0.0)


def test_exosystem_on_a_non_uniform_grid_against_analytic_sinusoid() -> None:
    a, omega = 3.0, 20.0
    t = np.concatenate([[0.0], np.cumsum(np.random.default_rng(1).uniform(1e-3, 0.03, 150))])
    data = simulate(
        [[-a]], [[1.0]], D=[[1.0, 0.0]],
        exogenous=exosystem([[0.0, omega], [-omega, 0.0]], [0.0, 1.0]), t=t,
    )  # fmt: skip
    np.testing.assert_allclose(data.w, np.column_stack([np.sin(omega * t), np.cos(omega * t)]),
                               rtol=0, atol=1e-12)  # fmt: skip
    exact = (a * np.sin(omega * t) - omega * np.cos(omega * t) + omega * np.exp(-a * t)) / (
        a**2 + omega**2
    )
    np.testing.assert_allclose(data.x[:, 0], exact, rtol=0, atol=1e-13)


class Ramp:
    """A user-defined held signal through the protocol: w(t) = slope t."""

    E = None

    def __init__(self, slope: float) -> None:
        self.slope = slope

    def values(self, t: Array) -> Array:
        return self.slope * np.asarray(t)[:, None]


class Alternating:
    """A user-defined exploration through the protocol: +a, -a, +a, ..."""

    def __init__(self, amplitude: float, shape: tuple[int, ...] | None = None) -> None:
        self.amplitude, self.shape = amplitude, shape

    def sample(
        self, t: Array, m: int, rng: np.random.Generator, batch: tuple[int, ...] = ()
    ) -> Array:
        signs = (-1.0) ** np.arange(len(t) - 1)
        values = self.amplitude * np.broadcast_to(signs[:, None], (len(t) - 1, m))
        return values if self.shape is None else np.zeros(self.shape)


def test_user_defined_signal_and_exploration() -> None:
    data = simulate(
        [[-1.0]], [[1.0]], D=[[2.0]], exogenous=Ramp(3.0), exploration=Alternating(0.5),
        h=0.1, num_samples=8,
    )  # fmt: skip
    np.testing.assert_allclose(data.w[:, 0], 3.0 * 0.1 * np.arange(9))
    np.testing.assert_array_equal(data.u[:, 0], 0.5 * (-1.0) ** np.arange(8))
    with pytest.raises(InputError, match=r"exploration.sample: expected shape \(8, 1\)"):
        simulate([[-1.0]], [[1.0]], exploration=Alternating(0.5, (8, 2)), h=0.1, num_samples=8)


def test_exosystem_with_zero_E_equals_held_constant() -> None:
    rng = np.random.default_rng(5)
    A, B, D = random_plant(rng, 3, 1, 2)
    K = rng.normal(size=(1, 3))
    common = {"K": K, "exploration": rng.normal(size=(40, 1)), "h": 0.1, "num_samples": 40}
    held_run = simulate(A, B, D=D, exogenous=constant([1.0, -2.0]), **common)  # type: ignore[arg-type]
    exo_run = simulate(A, B, D=D, exogenous=exosystem(np.zeros((2, 2)), [1.0, -2.0]), **common)  # type: ignore[arg-type]
    assert relative_error(exo_run.x, held_run.x) < 1e-13
    np.testing.assert_array_equal(exo_run.w, held_run.w)


# -- closed forms -------------------------------------------------------------------------


@pytest.mark.parametrize("a", [-2.0, 1.5])
def test_scalar_plant_closed_form(a: float) -> None:
    """x' = a x + b u, u_k = -k x_k + rho_k held: x_{k+1} = phi x_k + gamma (rho_k - k x_k)."""
    b, k_gain, h, N, x0 = 0.7, 0.4, 0.05, 60, 1.3
    rho = np.sin(np.arange(N))
    data = simulate(
        [[a]], [[b]], K=[[k_gain]], exploration=rho[:, None], x0=[x0], h=h, num_samples=N
    )
    phi = np.exp(a * h)
    gamma = (np.exp(a * h) - 1.0) / a * b
    x = [x0]
    for k in range(N):
        x.append(phi * x[k] + gamma * (rho[k] - k_gain * x[k]))
    np.testing.assert_allclose(data.x[:, 0], x, rtol=1e-12)
    # open loop with a constant input from x0: x(t) = e^{at} x0 + (e^{at} - 1)/a b u
    u = 0.8
    open_loop = simulate([[a]], [[b]], exploration=np.full((N, 1), u), x0=[x0], h=h, num_samples=N)
    t = h * np.arange(N + 1)
    exact = np.exp(a * t) * x0 + (np.exp(a * t) - 1.0) / a * b * u
    np.testing.assert_allclose(open_loop.x[:, 0], exact, rtol=1e-12)


def test_discretize_against_closed_form() -> None:
    rng = np.random.default_rng(2)
    A, B, D = random_plant(rng, 4, 2, 3)
    h = 0.2
    d = discretize(A, B, h, D=D)
    Phi = scipy.linalg.expm(A * h)
    np.testing.assert_allclose(d.Ad, Phi, rtol=1e-12, atol=1e-14)
    integral = np.linalg.solve(A, Phi - np.eye(4))  # int_0^h expm(A s) ds, A invertible
    np.testing.assert_allclose(d.Bd, integral @ B, rtol=1e-10, atol=1e-13)
    np.testing.assert_allclose(d.Ed, integral @ D, rtol=1e-10, atol=1e-13)
    np.testing.assert_array_equal(d.Ew, np.eye(3))
    E = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -0.5]])
    np.testing.assert_allclose(discretize(A, B, h, D=D, E=E).Ew, scipy.linalg.expm(E * h))
    assert d.h == h


# -- the paper's motor ----------------------------------------------------------------------


def test_motor_currents_match_the_motor_model_and_reach_the_reference() -> None:
    motor = SPMSM.paper()
    speed, torque = 10.0, 10.0
    problem = motor.regulation_problem(speed)
    solution = solve_optimal_regulation(problem, 1e3 * np.eye(2), np.eye(2))
    w = motor.exogenous(speed, torque)
    h, N = 1e-5, 10_000
    data = simulate(
        problem.A, problem.B, D=problem.D, exogenous=constant(w), K=solution.K, X=solution.X,
        U=solution.U, h=h, num_samples=N,
    )  # fmt: skip
    # steady state: the current reference, zero tracking error
    x_ref = motor.current_reference(torque)
    np.testing.assert_allclose(data.x[-1], x_ref, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(data.x[-1], solution.X @ w, rtol=1e-9, atol=1e-9)
    _, u_e = motor.equilibrium(speed, torque)
    np.testing.assert_allclose(data.u[-1], u_e, rtol=1e-7)
    # the first 200 samples against the motor's own equations (held u), by solve_ivp
    x = [np.zeros(2)]
    for k in range(200):
        solution_k = solve_ivp(
            lambda _, i, u=data.u[k]: motor.full_model([i[0], i[1], speed], u)[:2],
            (data.t[k], data.t[k + 1]), x[k], method="DOP853", rtol=RTOL_IVP, atol=1e-12,
        )  # fmt: skip
        x.append(solution_k.y[:, -1])
    assert relative_error(data.x[:201], np.array(x)) < 1e-9


def test_paper_settings_example() -> None:
    """The usage of the paper's Sec. V: K0 = 20 pi I, uniform 1 V, held w_base + w_d(t)."""
    motor = SPMSM.paper()
    problem = motor.regulation_problem(speed=10.0)
    w_base = motor.exogenous(speed=10.0, torque=10.0)
    reference = held(lambda t: w_base + np.column_stack([np.sin(1000 * t), 0.1 * np.cos(3000 * t)]))
    data = simulate(
        problem.A, problem.B, D=problem.D, exogenous=reference, K=20 * np.pi * np.eye(2),
        exploration=uniform(1.0), h=1e-5, num_samples=500, seed=0,
    )  # fmt: skip
    assert isinstance(data, Trajectory)
    assert (data.num_samples, data.n, data.m, data.q) == (500, 2, 2, 2)
    w_d_end = np.array([np.sin(5e-3 * 1000), 0.1 * np.cos(3000 * 5e-3)])
    np.testing.assert_allclose(data.w[-1], w_base + w_d_end)
    rho = data.u + 20 * np.pi * data.x[:-1]
    assert np.all(np.abs(rho) <= 1.0) and np.max(np.abs(rho)) > 0.99


# -- batches ------------------------------------------------------------------------------


def test_batch_equals_single_runs() -> None:
    rng = np.random.default_rng(21)
    P, n, m, q, N = 6, 3, 2, 2, 57
    plants = [random_plant(rng, n, m, q, shift=1.0) for _ in range(P)]
    A, B, D = (np.stack(parts) for parts in zip(*plants, strict=True))
    K = 0.3 * rng.normal(size=(P, m, n))
    X = rng.normal(size=(n, q))  # shared
    x0 = rng.normal(size=(P, n))
    rho = rng.uniform(-1.0, 1.0, size=(P, N, m))
    w0 = rng.normal(size=(P, q))
    E = np.array([[0.0, 2.0], [-2.0, 0.0]])
    for signal in (held(lambda t: np.column_stack([np.sin(t), np.cos(t)])), exosystem(E, w0)):
        batch = simulate_batch(
            A, B, D=D, exogenous=signal, K=K, X=X, exploration=rho, x0=x0, h=0.03, num_samples=N
        )
        assert isinstance(batch, TrajectoryBatch) and len(batch) == P
        assert batch.x.shape == (P, N + 1, n) and batch.u.shape == (P, N, m)
        assert batch.w is not None and batch.w.shape == (P, N + 1, q)
        for i in range(P):
            signal_i = signal if not hasattr(signal, "w0") else exosystem(E, w0[i])
            single = simulate(
                A[i], B[i], D=D[i], exogenous=signal_i, K=K[i], X=X, exploration=rho[i],
                x0=x0[i], h=0.03, num_samples=N,
            )  # fmt: skip
            batch_i = batch.trajectory(i)
            assert relative_error(batch_i.x, single.x) < 1e-12
            assert relative_error(batch_i.u, single.u) < 1e-12
            np.testing.assert_allclose(batch_i.w, single.w, rtol=1e-12, atol=1e-14)
        assert len(batch.trajectories()) == P


def test_batch_of_motors_equals_single_runs_on_a_non_uniform_grid() -> None:
    rng = np.random.default_rng(4)
    motors = [
        SPMSM(R_s=0.439 * f_r, L_s=0.0601 * f_l, phi_pm=0.46, p=2)
        for f_r, f_l in rng.uniform(0.7, 1.3, size=(4, 2))
    ]
    problems = [motor.regulation_problem(10.0) for motor in motors]
    A = np.stack([p.A for p in problems])
    B = np.stack([p.B for p in problems])
    D = np.stack([p.D for p in problems])
    w = np.stack([motor.exogenous(10.0, 10.0) for motor in motors])
    t = np.concatenate([[0.0], np.cumsum(rng.choice([1e-5, 2e-5, 1.5e-5], size=80))])
    K = 20 * np.pi * np.eye(2)
    batch = simulate_batch(
        A, B, D=D, exogenous=constant(w), K=K, exploration=uniform(1.0), t=t, seed=1
    )
    for i in range(len(motors)):
        single = simulate(
            A[i], B[i], D=D[i], exogenous=constant(w[i]), K=K,
            exploration=batch.exploration[i], t=t,
        )  # fmt: skip
        assert relative_error(batch.trajectory(i).x, single.x) < 1e-12


def test_batch_shared_plant_with_num_plants_draws_independent_exploration() -> None:
    batch = simulate_batch(
        [[-1.0, 0.0], [0.0, -2.0]], np.eye(2), exploration=uniform(1.0), h=0.01, num_samples=30,
        num_plants=4, seed=9,
    )  # fmt: skip
    assert batch.x.shape == (4, 31, 2) and batch.w is None
    assert not np.allclose(batch.u[0], batch.u[1])
    assert batch.trajectory(-1).w is None
    # a shared plant and reference, exploration per plant, on a non-uniform grid
    t = np.cumsum(np.concatenate([[0.0], np.random.default_rng(0).uniform(0.01, 0.1, 30)]))
    common = {"D": [[1.0]], "exogenous": constant([1.0]), "t": t}
    batch = simulate_batch(
        [[-1.0]],
        [[1.0]],
        exploration=uniform(1.0),
        num_plants=3,
        seed=0,
        **common,  # type: ignore[arg-type]
    )
    for i in range(3):
        single = simulate([[-1.0]], [[1.0]], exploration=batch.exploration[i], **common)  # type: ignore[arg-type]
        assert relative_error(batch.x[i], single.x) < 1e-13


# -- seeding and exploration --------------------------------------------------------------


@pytest.mark.parametrize("exploration", [uniform(1.0), prbs(2.0, 5), sum_of_sines(0.5, [50.0, 70])])
def test_seeding_is_reproducible(exploration: Exploration) -> None:
    def run(seed: int | np.random.Generator) -> Trajectory:
        return simulate(
            [[-1.0, 1.0], [0.0, -1.0]], [[1.0, 0.0], [0.0, 1.0]], K=np.eye(2),
            exploration=exploration, h=1e-3, num_samples=200, seed=seed,
        )  # fmt: skip

    np.testing.assert_array_equal(run(5).u, run(5).u)
    np.testing.assert_array_equal(run(5).x, run(5).x)
    assert not np.allclose(run(5).u, run(6).u)
    generator = np.random.default_rng(5)
    first, second = run(generator), run(generator)
    np.testing.assert_array_equal(first.u, run(5).u)
    assert not np.allclose(first.u, second.u)


def test_uniform_bounds_per_channel() -> None:
    rng = np.random.default_rng(0)
    t = np.arange(5001) * 1e-4
    rho = uniform([1.0, 3.0]).sample(t, 2, rng)
    assert rho.shape == (5000, 2)
    for channel, amplitude in enumerate([1.0, 3.0]):
        assert np.all(np.abs(rho[:, channel]) <= amplitude)
        assert np.max(np.abs(rho[:, channel])) > 0.99 * amplitude
        assert abs(float(np.mean(rho[:, channel]))) < 0.1 * amplitude
    assert len(np.unique(rho[:, 0])) == 5000  # a new value every sample
    assert uniform(1.0).sample(t, 3, rng, (4,)).shape == (4, 5000, 3)


def run_lengths(sequence: Array) -> list[int]:
    changes = np.flatnonzero(np.diff(sequence) != 0.0)
    edges = np.concatenate([[0], changes + 1, [len(sequence)]])
    return [int(length) for length in np.diff(edges)]


@pytest.mark.parametrize("hold", [1, 4, 7])
def test_prbs_levels_and_minimum_hold(hold: int) -> None:
    rng = np.random.default_rng(hold)
    t = np.arange(1001) * 1e-3
    rho = prbs(1.5, hold).sample(t, 2, rng, (3,))
    assert rho.shape == (3, 1000, 2)
    assert set(np.unique(rho)) == {-1.5, 1.5}
    for sequence in rho.reshape(3, 1000, 2).transpose(0, 2, 1).reshape(6, 1000):
        lengths = run_lengths(sequence)
        assert min(lengths[:-1]) >= hold  # the last run may be cut by the end
        # switches only on block boundaries
        assert np.all(np.flatnonzero(np.diff(sequence) != 0.0) % hold == hold - 1)
        if hold == 1:
            assert len(lengths) > 300  # switches often


def test_sum_of_sines_is_bounded_and_has_the_given_frequencies() -> None:
    rng = np.random.default_rng(3)
    t = np.arange(2001) * 1e-4
    frequencies = [30.0, 110.0, 250.0]
    rho = sum_of_sines(2.0, frequencies).sample(t, 2, rng)
    assert rho.shape == (2000, 2)
    assert np.all(np.abs(rho) <= 2.0)
    # exactly a combination of sin and cos at the frequencies, with amplitude 2/3 each
    basis = np.column_stack(
        [f(2 * np.pi * nu * t[:-1]) for nu in frequencies for f in (np.sin, np.cos)]
    )
    coefficients, *_ = np.linalg.lstsq(basis, rho, rcond=None)
    np.testing.assert_allclose(basis @ coefficients, rho, atol=1e-10)
    amplitudes = np.hypot(coefficients[0::2], coefficients[1::2])
    np.testing.assert_allclose(amplitudes, 2.0 / 3.0, rtol=1e-9)
    assert not np.allclose(rho[:, 0], rho[:, 1])  # independent phases per input


# -- signals and shapes -------------------------------------------------------------------


def test_held_signals_store_all_sample_times() -> None:
    N, h = 10, 0.1
    t = h * np.arange(N + 1)
    data = simulate(
        [[-1.0]], [[1.0]], D=[[1.0, 1.0]], exogenous=steps([N * h], [[0.0, 1.0], [5.0, 1.0]]),
        h=h, num_samples=N,
    )  # fmt: skip
    assert data.w is not None and data.w.shape == (N + 1, 2)
    np.testing.assert_array_equal(data.w[:-1, 0], 0.0)
    assert data.w[-1, 0] == 5.0  # w(t_N), sampled; never drives the plant
    assert data.x[-1, 0] == pytest.approx(1.0 - np.exp(-N * h), rel=1e-12)
    function_run = simulate(
        [[-1.0]], [[1.0]], D=[[1.0]], exogenous=held(lambda t: t**2), h=h, num_samples=N
    )
    np.testing.assert_allclose(function_run.w[:, 0], t**2, rtol=1e-15)
    array_run = simulate(
        [[-1.0]], [[1.0]], D=[[1.0]], exogenous=t[:, None] ** 2, h=h, num_samples=N
    )
    np.testing.assert_array_equal(array_run.x, function_run.x)


def test_uniform_time_array_equals_period_form() -> None:
    rng = np.random.default_rng(8)
    A, B, D = random_plant(rng, 2, 2, 1)
    rho = rng.normal(size=(1000, 2))
    common = {"D": D, "exogenous": constant([1.0]), "K": np.eye(2), "exploration": rho}
    by_period = simulate(A, B, h=1e-3, num_samples=1000, **common)  # type: ignore[arg-type]
    by_times = simulate(A, B, t=np.linspace(0.0, 1.0, 1001), **common)  # type: ignore[arg-type]
    assert relative_error(by_times.x, by_period.x) < 1e-12
    shifted = simulate(A, B, t=5.0 + np.linspace(0.0, 1.0, 1001), **common)  # type: ignore[arg-type]
    assert relative_error(shifted.x, by_period.x) < 1e-10


def test_long_run_agrees_with_step_by_step_recursion() -> None:
    """The two-level propagation against the plain recursion, with a ragged last chunk."""
    rng = np.random.default_rng(12)
    A, B, D = random_plant(rng, 3, 2, 1)
    K = 0.2 * rng.normal(size=(2, 3))
    h, N = 2e-3, 9973
    data = simulate(
        A, B, D=D, K=K, exogenous=held(lambda t: np.sin(40 * t)), exploration=uniform(0.3),
        x0=[1.0, 0.0, -1.0], h=h, num_samples=N, seed=1,
    )  # fmt: skip
    d = discretize(A, B, h, D=D)
    x = np.empty((N + 1, 3))
    x[0] = data.x[0]
    for k in range(N):
        x[k + 1] = d.Ad @ x[k] + d.Bd @ data.u[k] + d.Ed @ data.w[k]
    assert relative_error(data.x, x) < 1e-11


# -- hypothesis: random sizes -------------------------------------------------------------


@st.composite
def plant_cases(draw: st.DrawFn) -> dict[str, object]:
    n = draw(st.integers(1, 6))
    m = draw(st.integers(1, 3))
    q = draw(st.integers(1, 3))
    N = draw(st.integers(1, 40))
    plants = draw(st.integers(1, 3))
    seed = draw(st.integers(0, 2**31))
    h = draw(st.sampled_from([1e-5, 1e-3, 0.05]))
    exo = draw(st.booleans())
    return {"n": n, "m": m, "q": q, "N": N, "P": plants, "seed": seed, "h": h, "exo": exo}


@examples(60, quick=15)
@given(plant_cases())
def test_random_sizes_agree_with_the_plain_recursion(case: dict[str, int]) -> None:
    n, m, q, N, P = case["n"], case["m"], case["q"], case["N"], case["P"]
    rng = np.random.default_rng(case["seed"])
    h = float(case["h"])
    A = rng.normal(size=(P, n, n)) - np.eye(n)
    B = rng.normal(size=(P, n, m))
    D = rng.normal(size=(P, n, q))
    K = 0.3 * rng.normal(size=(P, m, n))
    X = rng.normal(size=(n, q))
    U = rng.normal(size=(m, q))
    x0 = rng.normal(size=(P, n))
    E = rng.normal(size=(q, q)) - rng.normal(size=(q, q)).T if case["exo"] else None
    w0 = rng.normal(size=q)
    signal = (
        exosystem(E, w0) if E is not None else held(lambda t: np.cos(np.outer(t, np.arange(q))))
    )
    batch = simulate_batch(
        A, B, D=D, exogenous=signal, K=K, X=X, U=U, exploration=uniform(1.0), x0=x0,
        h=h, num_samples=N, seed=case["seed"],
    )  # fmt: skip
    assert batch.x.shape == (P, N + 1, n) and batch.u.shape == (P, N, m)
    assert batch.w is not None and batch.w.shape == (P, N + 1, q)
    for i in range(P):
        d = discretize(A[i], B[i], h, D=D[i], E=E)
        x = np.empty((N + 1, n))
        w = np.empty((N + 1, q))
        x[0], w[0] = x0[i], batch.w[i, 0]
        for k in range(N):
            w[k + 1] = d.Ew @ w[k] if E is not None else batch.w[i, k + 1]
            u = -K[i] @ (x[k] - X @ w[k]) + U @ w[k] + batch.exploration[i, k]
            x[k + 1] = d.Ad @ x[k] + d.Bd @ u + d.Ed @ w[k]
        assert relative_error(batch.x[i], x) < 1e-10
        assert relative_error(batch.w[i], w) < 1e-10
        assert np.all(np.abs(batch.exploration[i]) <= 1.0)
        single = simulate(
            A[i], B[i], D=D[i], exogenous=signal, K=K[i], X=X, U=U,
            exploration=batch.exploration[i], x0=x0[i], h=h, num_samples=N,
        )  # fmt: skip
        assert relative_error(single.x, batch.x[i]) < 1e-12


# -- validation ---------------------------------------------------------------------------

A2 = np.array([[-1.0, 0.0], [0.0, -2.0]])
B2 = np.eye(2)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"A": np.ones((2, 3))}, r"A: expected a square matrix \(n, n\), got shape \(2, 3\)"),
        ({"A": [[np.nan, 0.0], [0.0, 1.0]]}, "A: contains NaN"),
        ({"B": np.ones((3, 2))}, r"B: expected shape \(2, any\)"),
        ({"K": np.ones((2, 3))}, r"K: expected shape \(2, 2\)"),
        ({"x0": [1.0, 2.0, 3.0]}, r"x0: expected shape \(2,\)"),
        ({"A": np.ones((3, 2, 2))}, "use simulate_batch"),
        ({"K": np.ones((3, 2, 2))}, "use simulate_batch"),
        ({"A": [[1.0, 2.0], [3.0]]}, "A: not numeric"),
        ({"D": np.ones((2, 1))}, "exogenous: D has 1 columns"),
        ({"exogenous": constant([1.0])}, r"exogenous: given, but .* \(D is None\)"),
        ({"X": np.ones((2, 1))}, r"X: given, but .* \(D is None\)"),
        ({"D": np.ones((2, 1)), "exogenous": constant([1.0, 2.0])}, "2 channels, but D has 1"),
        (
            {"D": np.ones((2, 1)), "exogenous": constant([1.0]), "U": np.ones((2, 2))},
            r"U: expected",
        ),
        ({"D": np.ones((2, 1)), "exogenous": held(lambda t: t[:-1])}, r"held: function\(t\)"),
        ({"D": np.ones((2, 1)), "exogenous": np.ones((5, 1))}, r"exogenous: expected shape \(11"),
        ({"exploration": np.ones((10, 3))}, r"exploration: .* shape \(10, 2\)"),
        ({"exploration": uniform([1.0, 2.0, 3.0])}, "uniform: amplitude: expected 2"),
        ({"exploration": "uniform"}, "exploration: not numeric"),
        ({"h": -1.0}, "h: must be a positive"),
        ({"h": None}, "give the sampling period h"),
        ({"num_samples": 0}, "num_samples: expected a whole number >= 1"),
        ({"num_samples": 2.5}, "num_samples: expected a whole number >= 1"),
        ({"num_samples": True}, "num_samples: expected a whole number >= 1"),
        ({"t": [0.0, 1.0]}, "not both"),
        ({"h": None, "num_samples": None, "t": [0.0, 1.0, 1.0]}, r"strictly increasing.*t\[2\]"),
        ({"h": None, "num_samples": None, "t": [0.0]}, "at least 2 sample times"),
        ({"seed": 1.5}, "seed: expected an integer"),
        ({"seed": -1}, "seed: must be non-negative"),
        ({"A": [[50.0, 0.0], [0.0, -1.0]], "h": 10.0}, "overflows at sample"),
    ],
)
def test_validation_errors_name_the_argument(kwargs: dict[str, object], match: str) -> None:
    arguments: dict[str, object] = {"A": A2, "B": B2, "h": 0.1, "num_samples": 10}
    arguments.update(kwargs)
    with pytest.raises(InputError, match=match):
        simulate(**arguments)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("factory", "match"),
    [
        (lambda: uniform(-1.0), "uniform: amplitude: amplitudes must be positive"),
        (lambda: uniform(np.ones((2, 2))), "uniform: amplitude: expected a number or a vector"),
        (lambda: prbs(1.0, 0), "prbs: hold_samples: expected a whole number >= 1"),
        (lambda: prbs(1.0, 1.5), "prbs: hold_samples"),
        (lambda: sum_of_sines(1.0, [10.0, -5.0]), "frequencies: must be positive"),
        (lambda: sum_of_sines(1.0, []), "frequencies: expected a non-empty"),
        (lambda: steps([1.0, 0.5], [[0.0], [1.0], [2.0]]), "times: must be strictly increasing"),
        (lambda: steps([1.0], [[0.0]]), r"values: expected shape \(2, q\)"),
        (lambda: exosystem(np.ones((2, 3)), [1.0, 1.0]), "E: expected a square matrix"),
        (lambda: exosystem(np.eye(2), [1.0]), r"w0: expected shape \(2,\)"),
        (lambda: constant(np.ones((2, 2, 2))), r"constant: w: expected shape \(q,\)"),
        (lambda: held(3.0), "held: function: expected a callable"),  # type: ignore[arg-type]
        (lambda: discretize(A2, B2, 0.0), "h: must be a positive"),
    ],
)
def test_signal_and_exploration_validation(factory: Callable[[], object], match: str) -> None:
    with pytest.raises(InputError, match=match):
        factory()


def test_batch_validation() -> None:
    with pytest.raises(InputError, match="K: a batch of 3 plants, but A gives 2"):
        simulate_batch(np.stack([A2, A2]), B2, K=np.ones((3, 2, 2)), h=0.1, num_samples=5)
    with pytest.raises(InputError, match="x0: a batch of 2 plants, but num_plants gives 4"):
        simulate_batch(A2, B2, x0=np.ones((2, 2)), num_plants=4, h=0.1, num_samples=5)
    with pytest.raises(
        InputError, match=r"A: expected a square matrix \(n, n\) or a batch \(P, n, n\)"
    ):
        simulate_batch(np.ones((2, 2, 2, 2)), B2, h=0.1, num_samples=5)
    batch = simulate_batch(A2, B2, h=0.1, num_samples=5)
    with pytest.raises(InputError, match=r"index: must be in \[-1, 1\)"):
        batch.trajectory(1)
    with pytest.raises(InputError, match="exogenous: expected shape"):
        simulate(
            A2, B2, D=np.ones((2, 1)), exogenous=constant(np.ones((3, 1))), h=0.1, num_samples=5
        )
