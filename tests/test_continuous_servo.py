"""The optimal servo controller (integral action) learned by continuous-time ADP.

Truth is independent of the learner: the LQR of the plant augmented with the integral of
the regulated error, ``[[A, 0], [C, 0]]``, solved by scipy's continuous Riccati solver
(checked once against python-control's ``lqr``) on the TRUE plant, and U from the
regulator equations. The discounted optimum of a rate gamma is the same Riccati equation
with ``A_a - gamma/2 I``.

Tolerances follow the quadrature of the data equation (:mod:`selftune.learn.learners._moments`):

- where the state is linear inside each sample (A = 0) the quadrature is exact, the
  integral state's quadratic included, so the learned controller equals the optimum to
  rounding: 1e-8;
- otherwise each row carries the error of integrating the state's linear interpolant,
  ``h^2/12`` times the second derivative, i.e. a relative ``(h omega)^2 / 12`` with
  omega the fastest rate of the data's loop; the learned unknowns inherit it through
  the regression's sensitivity (worse with the integrator, whose state is slow). The
  tolerances, ``2 (h omega)^2`` on well-excited random plants and ``3 (h omega)^2`` on
  random motors, allow a sensitivity of 24 and 36; calibration runs on 110 plants and
  120 motors (other draws than these tests') stayed below ``0.46 (h omega)^2`` and
  ``0.85 (h omega)^2``;
- on the paper's motor the order itself is measured: halving h divides the errors by
  about 4.6 (at least 2 is asserted), and at 10 us ``[K, K_i]`` and P are within
  ``error(2h) / 2`` and 3e-6 (measured: 1.1e-6), U within ``error(2h) / 2`` and 1e-5
  (measured: 4.1e-6).
"""

from __future__ import annotations

from functools import cache
from itertools import pairwise

import control
import numpy as np
import pytest
import scipy.linalg
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from learners import servo as learn_servo
from selftune import SPMSM, ExcitationError, InputError, RegulationProblem, lqr
from selftune.core import discretize
from selftune.learn import (
    IterationRecord,
    LearnedController,
    LearningOptions,
    LearningProblem,
    Trajectory,
    interval_moments,
    learn_controller,
)
from selftune.learn.learners._servo import FIRST_DISCOUNT
from selftune.sim import constant, held, prbs, simulate, steps, uniform

Q, R = 1e3 * np.eye(2), np.eye(2)
PAPER_K0 = 20 * np.pi * np.eye(2)


def relative(value: np.ndarray, truth: np.ndarray) -> float:
    return float(np.linalg.norm(value - truth) / np.linalg.norm(truth))


def augmented(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``[[A, 0], [C, 0]]`` and ``[B; 0]``: the plant with the integral of ``C xbar``."""
    n, r, m = A.shape[0], C.shape[0], B.shape[1]
    A_a = np.block([[A, np.zeros((n, r))], [C, np.zeros((r, r))]])
    return A_a, np.vstack([B, np.zeros((r, m))])


def servo_optimum(
    A: np.ndarray, B: np.ndarray, C: np.ndarray, weights: tuple[np.ndarray, ...], gamma: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """``[K, K_i]`` and P of the servo LQR discounted at ``gamma`` (scipy's Riccati)."""
    Q_x, R_u, Q_i = weights
    A_a, B_a = augmented(A, B, C)
    A_a = A_a - 0.5 * gamma * np.eye(A_a.shape[0])
    P = scipy.linalg.solve_continuous_are(A_a, B_a, scipy.linalg.block_diag(Q_x, Q_i), R_u)
    return np.linalg.solve(R_u, B_a.T @ P), P


def feedforward(problem: RegulationProblem) -> np.ndarray:
    """U of the regulator equations (E = 0, C and B invertible): X = -C^-1 F."""
    X = -np.linalg.solve(problem.C, problem.F)
    return -np.linalg.solve(problem.B, problem.A @ X + problem.D)


def learned_gain(learned: LearnedController) -> np.ndarray:
    """``[K, K_i]``."""
    assert learned.law.K_i is not None
    return np.hstack([learned.K, learned.law.K_i])


def sampled_radius(problem: RegulationProblem, gain: np.ndarray, h: float) -> float:
    """Spectral radius of the plant's exact discretization under ``u = -K xbar - K_i z``,
    ``z_(k+1) = z_k + h C xbar_k`` (the drive's integrator)."""
    n = problem.n
    exact = discretize(problem.A, problem.B, h)
    K, K_i = gain[:, :n], gain[:, n:]
    loop = np.block(
        [[exact.Ad - exact.Bd @ K, -exact.Bd @ K_i], [h * problem.C, np.eye(problem.C.shape[0])]]
    )
    return float(np.max(np.abs(np.linalg.eigvals(loop))))


# -- the paper's motor: the pipeline, the order of the quadrature, the schedule --------------


@cache
def paper_data(h: float) -> tuple[RegulationProblem, Trajectory]:
    """30 ms of the paper's motor under K0 = 20 pi I, a 10 V PRBS held 0.2 ms (the same
    sequence at every h) and the paper's perturbed reference."""
    motor = SPMSM.paper()
    problem = motor.regulation_problem(10.0)
    base = motor.exogenous(10.0, 10.0)
    reference = held(lambda t: base + np.column_stack([np.sin(1000 * t), 0.1 * np.cos(3000 * t)]))
    data = simulate(
        problem.A, problem.B, D=problem.D, exogenous=reference, K=PAPER_K0,
        exploration=prbs(10.0, round(2e-4 / h)), h=h, num_samples=round(0.03 / h), seed=3,
    )  # fmt: skip
    return problem, data


def paper_knowledge(problem: RegulationProblem) -> LearningProblem:
    return LearningProblem(Q, R, C=problem.C, F=problem.F, integral_action=True)


def paper_weights(problem: RegulationProblem) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(Q, R, Q_i)`` with the default integral weight, ``(200 rad/s)^2 C Q C'``."""
    Q_i = paper_knowledge(problem).integral_weight
    assert Q_i is not None
    return Q, R, Q_i


@cache
def learn_paper_servo(h: float, discounts: tuple[float, ...] | None = None) -> LearnedController:
    """The servo learned from :func:`paper_data`, once per module (three tests read it)."""
    problem, data = paper_data(h)
    output = (problem.C, problem.E, problem.F)
    return learn_servo(data, output, paper_weights(problem), PAPER_K0, discounts=discounts)


def test_the_paper_motor_servo_is_learned_to_the_second_order_quadrature() -> None:
    problem, data = paper_data(1e-5)
    known = paper_knowledge(problem)
    weights = paper_weights(problem)
    K_star, P_star = servo_optimum(problem.A, problem.B, problem.C, weights)
    A_a, B_a = augmented(problem.A, problem.B, problem.C)
    K_control, _, _ = control.lqr(A_a, B_a, scipy.linalg.block_diag(Q, weights[2]), R)
    # the two oracles agree to their rounding: each solves the Riccati equation to a
    # residual of eps at its own scale, which the closed loop's Lyapunov operator (the
    # equation's derivative) turns into a relative error of eps times its condition number
    closed = A_a - B_a @ K_star
    identity = np.eye(closed.shape[0])
    lyapunov = np.kron(identity, closed.T) + np.kron(closed.T, identity)
    rounding = np.finfo(float).eps * np.linalg.cond(lyapunov)
    assert relative(K_control, K_star) < 2.0 * rounding
    U_star = feedforward(problem)
    # second order: the same continuous experiment at 2h and h
    coarse, fine = learn_paper_servo(2e-5), learn_paper_servo(1e-5)
    errors = [relative(learned_gain(result), K_star) for result in (coarse, fine)]
    U_errors = [relative(result.U, U_star) for result in (coarse, fine)]
    assert errors[1] < errors[0] / 2.0, errors
    assert U_errors[1] < U_errors[0] / 2.0, U_errors
    tolerance, U_tolerance = min(errors[0] / 2.0, 3e-6), min(U_errors[0] / 2.0, 1e-5)
    for noise in ("none", "smoothed", "instruments"):
        learned = learn_controller(data, known, PAPER_K0, LearningOptions(noise=noise))
        gain = learned_gain(learned)
        assert relative(gain, K_star) < tolerance, noise
        assert relative(learned.P, P_star) < tolerance, noise
        assert relative(learned.U, U_star) < U_tolerance, noise
        assert learned.state == ("x1", "x2", "z1", "z2")
        assert learned.law.h == 1e-5
        np.testing.assert_array_equal(learned.law.C, problem.C)
        np.testing.assert_array_equal(learned.law.F, problem.F)
        assert "K_i z_k" in learned.law.equations()
        assert np.max(np.linalg.eigvals(A_a - B_a @ gain).real) < 0.0
        assert sampled_radius(problem, gain, 1e-5) < 1.0
        assert learned.quality.stability_margin > 0.0
        assert learned.quality.K_relative_se < 1e-4  # includes the quadrature error
        assert learned.history[0].iteration == 0


def test_the_schedule_starts_from_K0_without_integral_gain_and_stays_stabilizing() -> None:
    problem, _ = paper_data(1e-5)
    Q_i = paper_weights(problem)[2]
    servo = learn_paper_servo(1e-5)
    discounts = servo.discounts
    assert discounts[-1] == 0.0 and all(b < a for a, b in pairwise(discounts))
    # the first discount: a tenth of the decay rate K0's loop certifies, on the true plant
    closed = problem.A - problem.B @ PAPER_K0
    W = Q + PAPER_K0.T @ R @ PAPER_K0
    P_K0 = scipy.linalg.solve_continuous_lyapunov(closed.T, -W)
    rate = float(scipy.linalg.eigh(W, P_K0, eigvals_only=True)[0])
    assert relative(np.array(discounts[0]), np.array(FIRST_DISCOUNT * rate)) < 1e-5
    # the first step evaluates [K0, 0] at that discount: P_zz = Q_i / gamma exactly
    A_a, B_a = augmented(problem.A, problem.B, problem.C)
    start = np.hstack([PAPER_K0, np.zeros((2, 2))])
    shifted = A_a - B_a @ start - 0.5 * discounts[0] * np.eye(4)
    value = scipy.linalg.solve_continuous_lyapunov(
        shifted.T, -(scipy.linalg.block_diag(Q, Q_i) + start.T @ R @ start)
    )
    first = servo.history[0]
    assert first.iteration == 0
    assert relative(first.P, value) < 1e-5
    assert relative(first.P[2:, 2:], Q_i / discounts[0]) < 1e-5
    # each discount's policy stabilizes the next one (the certified step), on the truth
    for stage, following in zip(servo.stages[:-1], discounts[1:], strict=True):
        assert np.max(np.linalg.eigvals(A_a - B_a @ stage.K).real) < 0.5 * following
    assert [stage.iterations for stage in servo.stages] == [
        sum(1 for _ in group) for group in _stages_of(servo.history)
    ]


def _stages_of(history: tuple[IterationRecord, ...]) -> list[list[IterationRecord]]:
    """The history split where the iteration count restarts (a new discount)."""
    groups: list[list[IterationRecord]] = []
    for record in history:
        if record.iteration == 0:
            groups.append([])
        groups[-1].append(record)
    return groups


def test_the_undiscounted_step_is_necessary() -> None:
    problem, _ = paper_data(1e-5)
    weights = paper_weights(problem)
    K_star, _ = servo_optimum(problem.A, problem.B, problem.C, weights)
    servo = learn_paper_servo(1e-5)
    last_discounted = servo.stages[-2]
    gamma = last_discounted.discount
    assert gamma > 0.0
    K_gamma, _ = servo_optimum(problem.A, problem.B, problem.C, weights, gamma)
    # the discounted stage learns the discounted optimum, which is not the servo optimum
    assert relative(last_discounted.K, K_gamma) < 1e-5
    assert relative(K_gamma, K_star) > 1e-2
    assert relative(learned_gain(servo), K_star) < 3e-6
    without_zero = learn_paper_servo(1e-5, discounts=servo.discounts[:-1])
    assert without_zero.discounts == servo.discounts[:-1]
    assert relative(learned_gain(without_zero), K_gamma) < 1e-5
    assert relative(learned_gain(without_zero), K_star) > 1e-2


# -- exact quadrature: A = 0 ----------------------------------------------------------------


@settings(max_examples=8)
@given(st.integers(0, 2**32 - 1), st.floats(0.3, 5.0))
def test_learning_is_exact_when_the_quadrature_is_exact(seed: int, integral: float) -> None:
    """With A = 0 and w held the state is linear and z quadratic inside each sample: the
    data equation is exact, so the servo optimum is learned to rounding."""
    rng = np.random.default_rng(seed)
    B = rng.normal(size=(2, 2))
    assume(np.linalg.cond(B) < 10.0)
    problem = RegulationProblem(
        A=np.zeros((2, 2)), B=B, C=np.eye(2) + 0.3 * rng.normal(size=(2, 2)),
        D=rng.normal(size=(2, 2)), E=np.zeros((2, 2)), F=rng.normal(size=(2, 2)),
    )  # fmt: skip
    weights = (np.eye(2), np.eye(2), integral * np.eye(2))
    K_star, P_star = servo_optimum(problem.A, B, problem.C, weights)
    K0 = lqr(problem.A, B, 5.0 * np.eye(2), np.eye(2))[0]
    h, count = 0.01, 1500
    times = np.sort(rng.uniform(0.0, count * h, 12))
    data = simulate(
        problem.A, B, D=problem.D, exogenous=steps(times, rng.normal(size=(13, 2))), K=K0,
        exploration=uniform(1.0), x0=rng.normal(size=2), h=h, num_samples=count, seed=seed,
    )  # fmt: skip
    servo = learn_servo(data, (problem.C, problem.E, problem.F), weights, K0, interval=5)
    assert relative(learned_gain(servo), K_star) < 1e-8
    assert relative(servo.P, P_star) < 1e-8
    assert relative(servo.U, feedforward(problem)) < 1e-8


def test_the_discounted_moments_with_the_integrator_are_exact_for_the_interpolant() -> None:
    """A = 0, no holds: x linear and z (the integral of e) quadratic inside each sample; the
    moments equal a fine quadrature of the discounted products, gamma = 0 included."""
    rng = np.random.default_rng(4)
    n, m, q, count, h, interval = 2, 2, 1, 30, 1e-3, 7
    B, D = rng.normal(size=(n, m)), rng.normal(size=(n, q))
    C, F = np.eye(n) + 0.2 * rng.normal(size=(n, n)), rng.normal(size=(n, q))
    t = np.arange(count + 1) * h
    u, w = rng.normal(size=(count, m)), rng.normal(size=(count + 1, q))
    x = np.zeros((count + 1, n))
    x[0] = rng.normal(size=n)
    for k in range(count):
        x[k + 1] = x[k] + h * (B @ u[k] + D @ w[k])
    data = Trajectory(t, x, u, w)
    s = np.linspace(0.0, h, 401)
    for gamma in (0.0, 300.0, 3000.0):
        moments = interval_moments(data, interval, integrator=(C, F), discount=gamma)
        assert (moments.n, moments.r, moments.discount) == (n + n, n, gamma)
        zz, zu = np.zeros_like(moments.zz), np.zeros_like(moments.zu)
        z_start = np.zeros(n)
        for k in range(count):
            x_s = x[k] + np.outer(s, B @ u[k] + D @ w[k])
            e_a, slope = C @ x[k] + F @ w[k], C @ (B @ u[k] + D @ w[k])
            z_s = z_start + np.outer(s, e_a) + 0.5 * np.outer(s**2, slope)
            z_start = z_s[-1]
            xi = np.hstack([x_s, z_s, np.tile(w[k], (s.size, 1))])
            weight = np.exp(-gamma * (t[k] + s - t[(k // interval) * interval]))
            outer = weight[:, None, None] * xi[:, :, None] * xi[:, None, :]
            zz[k // interval] += scipy.integrate.simpson(outer, x=s, axis=0)
            integral = scipy.integrate.simpson(weight[:, None] * xi, x=s, axis=0)
            zu[k // interval] += np.outer(integral, u[k])
        assert np.max(np.abs(moments.zz - zz)) < 1e-10 * np.max(np.abs(zz)), gamma
        assert np.max(np.abs(moments.zu - zu)) < 1e-10 * np.max(np.abs(zu)), gamma


# -- random plants and motors: second-order quadrature --------------------------------------


@settings(max_examples=8)
@given(st.integers(0, 2**32 - 1), st.floats(0.5, 5.0))
def test_random_stable_plants(seed: int, integral: float) -> None:
    rng = np.random.default_rng(seed)
    A = -np.diag(rng.uniform(0.5, 3.0, 2)) + 0.5 * rng.normal(size=(2, 2))
    B = rng.normal(size=(2, 2))
    assume(np.max(np.linalg.eigvals(A).real) < -0.2 and np.linalg.cond(B) < 10.0)
    problem = RegulationProblem(
        A=A, B=B, C=np.eye(2) + 0.3 * rng.normal(size=(2, 2)), D=rng.normal(size=(2, 2)),
        E=np.zeros((2, 2)), F=rng.normal(size=(2, 2)),
    )  # fmt: skip
    weights = (np.eye(2), np.eye(2), integral * np.eye(2))
    K_star, P_star = servo_optimum(A, B, problem.C, weights)
    K0 = lqr(A, B, 5.0 * np.eye(2), np.eye(2))[0]
    omega = float(np.max(np.abs(np.linalg.eigvals(A - B @ K0))))
    h, duration = 0.02 / omega, 10.0
    times = np.sort(rng.uniform(0.0, duration, 20))
    data = simulate(
        A, B, D=problem.D, exogenous=steps(times, rng.normal(size=(21, 2))), K=K0,
        exploration=prbs(1.0, 10), x0=rng.normal(size=2), h=h,
        num_samples=round(duration / h), seed=seed,
    )  # fmt: skip
    servo = learn_servo(data, (problem.C, problem.E, problem.F), weights, K0)
    tolerance = 2.0 * (h * omega) ** 2
    gain = learned_gain(servo)
    assert relative(gain, K_star) < tolerance
    assert relative(servo.P, P_star) < tolerance
    assert relative(servo.U, feedforward(problem)) < tolerance
    A_a, B_a = augmented(A, B, problem.C)
    assert np.max(np.linalg.eigvals(A_a - B_a @ gain).real) < 0.0


motors = st.builds(
    SPMSM,
    R_s=st.floats(0.1, 3.0),
    L_s=st.floats(1e-3, 0.1),
    phi_pm=st.floats(0.05, 1.0),
    p=st.integers(1, 6),
)


@pytest.mark.slow  # 6 motors; the paper motor's servo runs the same pipeline in a plain pytest
@settings(max_examples=6)
@given(motors, st.floats(0.05, 1.0), st.integers(0, 1000))
def test_random_motors_through_learn_controller(
    motor: SPMSM, speed_fraction: float, seed: int
) -> None:
    """At 10 us, electrical speeds up to 2000 rad/s; the data's controller closes the
    current loop near 1250 rad/s with a feedforward from parameters 10-20% off."""
    h = 1e-5
    speed = speed_fraction * 2000.0 / motor.p
    problem = motor.regulation_problem(speed)
    K0 = 1250.0 * motor.L_s * np.eye(2)
    X0 = -np.linalg.solve(problem.C, problem.F)
    nominal = SPMSM(
        R_s=1.2 * motor.R_s, L_s=0.85 * motor.L_s, phi_pm=1.1 * motor.phi_pm, p=motor.p
    ).regulation_problem(speed)
    U0 = -np.linalg.solve(nominal.B, nominal.A @ X0 + nominal.D)
    base = motor.exogenous(speed, 2.0)

    def perturbed(t: np.ndarray) -> np.ndarray:
        back_emf = 0.2 * base[0] * np.sin(700 * t)
        torque = np.sign(np.sin(2 * np.pi * 90 * t + 0.3)) + 0.5 * np.sin(2300 * t)
        return base + np.column_stack([back_emf, torque])

    reference = held(perturbed)
    data = simulate(
        problem.A, problem.B, D=problem.D, exogenous=reference, K=K0, X=X0, U=U0,
        exploration=prbs(2500.0 * motor.L_s, 20), h=h, num_samples=3000, seed=seed,
    )  # fmt: skip
    known = LearningProblem(Q, R, C=problem.C, F=problem.F, integral_action=True)
    learned = learn_controller(data, known, K0, LearningOptions(noise="none"))
    assert known.integral_weight is not None
    K_star, _ = servo_optimum(problem.A, problem.B, problem.C, (Q, R, known.integral_weight))
    omega = float(np.max(np.abs(np.linalg.eigvals(problem.A - problem.B @ K0))))
    tolerance = 3.0 * (h * omega) ** 2
    gain = learned_gain(learned)
    assert relative(gain, K_star) < tolerance
    assert relative(learned.U, feedforward(problem)) < tolerance
    assert sampled_radius(problem, gain, h) < 1.0


@pytest.mark.slow  # the smoothed and instrumental estimates also run in the paper servo test
def test_noisy_logs_learned_within_the_stated_standard_error() -> None:
    """0.1 mA of current noise: the smoothed states give the servo within 3 of the standard
    errors the verdict states; the noisier instrumental-variable estimate is refused."""
    problem, data = paper_data(1e-5)
    rng = np.random.default_rng(1)
    noisy = Trajectory(data.t, data.x + 1e-4 * rng.normal(size=data.x.shape), data.u, data.w)
    K_star, _ = servo_optimum(problem.A, problem.B, problem.C, paper_weights(problem))
    learned = learn_controller(noisy, paper_knowledge(problem), PAPER_K0)
    assert learned.quality.noise_handling == "smoothed"
    assert relative(learned_gain(learned), K_star) < 3.0 * learned.quality.K_relative_se
    assert relative(learned.U, feedforward(problem)) < 3.0 * learned.quality.U_relative_se
    with pytest.raises(ExcitationError, match=r"too little data for this noise level"):
        learn_controller(
            noisy, paper_knowledge(problem), PAPER_K0, LearningOptions(noise="instruments")
        )


# -- what the learner refuses ----------------------------------------------------------------


def test_a_constant_reference_is_refused_naming_the_exogenous_block() -> None:
    motor = SPMSM.paper()
    problem = motor.regulation_problem(10.0)
    data = simulate(
        problem.A, problem.B, D=problem.D, exogenous=constant(motor.exogenous(10.0, 10.0)),
        K=PAPER_K0, exploration=prbs(10.0, 20), h=1e-5, num_samples=3000, seed=0,
    )  # fmt: skip
    weights = paper_weights(problem)
    with pytest.raises(ExcitationError, match=r"the M block adds rank .*perturb the reference"):
        learn_servo(data, (problem.C, problem.E, problem.F), weights, PAPER_K0)
    with pytest.raises(ExcitationError, match=r"perturb the reference"):
        learn_controller(data, paper_knowledge(problem), PAPER_K0)


def test_too_short_data_are_refused_with_the_servo_count() -> None:
    problem, data = paper_data(1e-5)
    assert data.w is not None
    short = Trajectory(data.t[:21], data.x[:21], data.u[:20], data.w[:21])
    weights = paper_weights(problem)
    with pytest.raises(ExcitationError, match=r"only 20 regression intervals for the 26 unknowns"):
        learn_servo(short, (problem.C, problem.E, problem.F), weights, PAPER_K0, interval=1)


def test_an_output_that_does_not_fix_X_is_refused() -> None:
    problem, data = paper_data(1e-5)
    known = LearningProblem(Q, R, C=problem.C[1:], F=problem.F[1:], integral_action=True)
    with pytest.raises(InputError, match=r"needs a unique X from C X \+ F = 0.*'identify'"):
        learn_controller(data, known, PAPER_K0)
