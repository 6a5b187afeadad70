"""The model-based optimal servo controller (integral action), continuous and digital.

Oracles, all built here from the motor's A, B, C with scipy, independently of selftune:

- the plant sampled with a zero-order hold (``scipy.linalg.expm`` of ``[[A, B], [0, 0]] h``),
  augmented by hand with the computation delay and the drive's integrator
  ``z_(k+1) = z_k + h C xbar_k``;
- ``scipy.linalg.solve_discrete_are``: for the digital cost, and for the sampled cost
  given the "shift-only-Rd" weights (the applied input's weight charged when it is
  computed, its cross weight with x in the state weight: a different formulation from
  selftune's, with the same optimal K) and the one-sample weights by 24-point
  Gauss-Legendre quadrature of ``expm(F't) W expm(Ft)``. (SLICOT's SG02AD, used for the
  sampled cost in tests/test_digital_model.py, loses up to 3e-8 on these weights at
  small h, where scipy's solution keeps 1e-11, so it is not used here);
- ``scipy.linalg.solve_continuous_are`` (and python-control's ``lqr`` once) on
  ``[[A, 0], [C, 0]]``, ``[B; 0]``, ``blockdiag(Q, Q_i)``;
- the steady state of the sampled loop under a constant input disturbance, solved
  algebraically from the closed loop built here, and a simulated loop;
- the learner's identify-then-design on the exact discrete model (a different code path:
  :mod:`selftune.learn.learners._identify`).
"""

from __future__ import annotations

import control
import numpy as np
import pytest
import scipy.linalg
from hypothesis import given
from hypothesis import strategies as st

from example_counts import at_least
from selftune.core import ControlLaw, discretize, integrator_augmented
from selftune.errors import InputError, UnsolvableError
from selftune.learn import (
    DiscreteModel,
    LearningProblem,
    closed_loop_radius,
    design_continuous,
    design_digital,
)
from selftune.model import (
    SPMSM,
    RegulationProblem,
    solve_digital_regulation,
    solve_optimal_regulation,
)

Array = np.ndarray

Q, R = 1e3 * np.eye(2), np.eye(2)
PAPER_K0 = 20 * np.pi * np.eye(2)
#: Agreement with the independent Riccati solvers and the learner's design (relative).
AGREEMENT = 1e-9


def _relative(actual: Array, expected: Array) -> float:
    return float(np.linalg.norm(actual - expected) / np.linalg.norm(expected))


def _spectral_radius(M: Array) -> float:
    return float(np.max(np.abs(np.linalg.eigvals(M))))


class Case:
    """A random motor at a speed, a sampling period, a delay and an integral bandwidth."""

    def __init__(self, motor: SPMSM, speed: float, h: float, delay: int, bandwidth: float):
        self.motor, self.speed, self.h, self.delay = motor, speed, h, delay
        self.problem = motor.regulation_problem(speed)
        self.Q_i = bandwidth**2 * self.problem.C @ Q @ self.problem.C.T

    def __repr__(self) -> str:
        return f"Case({self.motor!r}, speed={self.speed!r}, h={self.h!r}, delay={self.delay})"


@st.composite
def cases(draw: st.DrawFn) -> Case:
    """Random SPMSMs (R_s 0.1-3 ohm, L_s 1-100 mH, phi 0.01-0.5 Wb, p 1-6) at 0-300 rad/s,
    h 10-200 us, delays 0-2 and an integral bandwidth of 50-1000 rad/s."""
    motor = SPMSM(
        R_s=draw(st.floats(min_value=0.1, max_value=3.0)),
        L_s=draw(st.floats(min_value=1e-3, max_value=0.1)),
        phi_pm=draw(st.floats(min_value=0.01, max_value=0.5)),
        p=draw(st.integers(min_value=1, max_value=6)),
    )
    return Case(
        motor,
        speed=draw(st.floats(min_value=0.0, max_value=300.0)),
        h=draw(st.floats(min_value=1e-5, max_value=2e-4)),
        delay=draw(st.integers(min_value=0, max_value=2)),
        bandwidth=draw(st.floats(min_value=50.0, max_value=1000.0)),
    )


# -- the truth, built here -------------------------------------------------------------------


def _zoh(A: Array, B: Array, h: float) -> tuple[Array, Array]:
    n, m = B.shape
    M = scipy.linalg.expm(np.block([[A, B], [np.zeros((m, n + m))]]) * h)
    return M[:n, :n], M[:n, n:]


def _servo_plant(
    problem: RegulationProblem, h: float, delay: int, integrator: bool = True
) -> tuple[Array, Array]:
    """``[x; u_(k-d); ...; u_(k-1); z]`` with ``z_(k+1) = z_k + h C x_k`` (without z
    unless ``integrator``)."""
    Ad, Bd = _zoh(problem.A, problem.B, h)
    n, m, r = problem.n, problem.m, problem.r if integrator else 0
    size = n + delay * m + r
    A = np.zeros((size, size))
    B = np.zeros((size, m))
    A[:n, :n] = Ad
    if delay == 0:
        B[:n] = Bd
    else:
        A[:n, n : n + m] = Bd  # the oldest delayed input is applied
        for block in range(delay - 1):  # shift the delayed inputs up by one block
            start = n + block * m
            A[start : start + m, start + m : start + 2 * m] = np.eye(m)
        B[n + (delay - 1) * m : n + delay * m] = np.eye(m)
    if integrator:
        A[size - r :, :n] = h * problem.C
        A[size - r :, size - r :] = np.eye(r)
    return A, B


def _scipy_dlqr(
    A: Array, B: Array, Qz: Array, Rz: Array, Nz: Array | None = None
) -> tuple[Array, Array]:
    Nz = np.zeros(B.shape) if Nz is None else Nz
    P = scipy.linalg.solve_discrete_are(A, B, Qz, Rz, s=Nz)
    return np.linalg.solve(Rz + B.T @ P @ B, B.T @ P @ A + Nz.T), P


def _quadrature_weights(A: Array, B: Array, h: float) -> Array:
    """``int_0^h expm(F't) blockdiag(Q, R) expm(Ft) dt``, ``F = [[A, B], [0, 0]]``."""
    n, m = B.shape
    F = np.block([[A, B], [np.zeros((m, n + m))]])
    W = scipy.linalg.block_diag(Q, R)
    nodes, weights = np.polynomial.legendre.leggauss(24)
    total = np.zeros_like(W)
    for node, weight in zip(nodes, weights, strict=True):
        Phi = scipy.linalg.expm(F * 0.5 * h * (node + 1.0))
        total += 0.5 * h * weight * Phi.T @ W @ Phi
    return 0.5 * (total + total.T)


def _digital_weights(case: Case, size: int) -> Array:
    """``Qz = h blockdiag(Q, 0, Q_i)``."""
    Qz = np.zeros((size, size))
    Qz[:2, :2] = case.h * Q
    Qz[-2:, -2:] = case.h * case.Q_i
    return Qz


def _digital_truth(case: Case) -> tuple[Array, Array]:
    """``[K, K_i]`` and P: ``Qz = h blockdiag(Q, 0, Q_i)``, ``Rz = h R`` (scipy's DARE)."""
    A, B = _servo_plant(case.problem, case.h, case.delay)
    return _scipy_dlqr(A, B, _digital_weights(case, A.shape[0]), case.h * R)


def _dare_residual(case: Case, P: Array) -> float:
    """Relative residual of ``A'PA - P - A'PB (Rz + B'PB)^-1 B'PA + Qz`` (built here)."""
    A, B = _servo_plant(case.problem, case.h, case.delay)
    Qz, Rz = _digital_weights(case, A.shape[0]), case.h * R
    gain_term = A.T @ P @ B @ np.linalg.solve(Rz + B.T @ P @ B, B.T @ P @ A)
    residual = A.T @ P @ A - P - gain_term + Qz
    scale = sum(float(np.linalg.norm(M)) for M in (A.T @ P @ A, P, gain_term, Qz))
    return float(np.linalg.norm(residual)) / scale


def _sampled_truth(case: Case) -> tuple[Array, Array]:
    """``[K, K_i]`` and P of the sampled cost in the "shift-only-Rd" form (scipy): the
    applied input's weight charged when it is computed, its cross weight with x in the
    state weight; ``h Q_i`` on z (the held integrator)."""
    A, B = _servo_plant(case.problem, case.h, case.delay)
    W = _quadrature_weights(case.problem.A, case.problem.B, case.h)
    Qd, N, Rd = W[:2, :2], W[:2, 2:], W[2:, 2:]
    Qz = np.zeros_like(A)
    Nz = np.zeros((A.shape[0], 2))
    Qz[:2, :2] = Qd
    Qz[-2:, -2:] = case.h * case.Q_i
    if case.delay == 0:
        Nz[:2] = N
    else:
        Qz[:2, 2:4], Qz[2:4, :2] = N, N.T
    return _scipy_dlqr(A, B, Qz, Rd, Nz)


def _continuous_servo_plant(problem: RegulationProblem) -> tuple[Array, Array]:
    """``[[A, 0], [C, 0]]`` and ``[B; 0]``."""
    n, r, m = problem.n, problem.r, problem.m
    A = np.block([[problem.A, np.zeros((n, r))], [problem.C, np.zeros((r, r))]])
    return A, np.vstack([problem.B, np.zeros((r, m))])


def _continuous_truth(problem: RegulationProblem, Q_i: Array) -> tuple[Array, Array]:
    A, B = _continuous_servo_plant(problem)
    P = scipy.linalg.solve_continuous_are(A, B, scipy.linalg.block_diag(Q, Q_i), R)
    return np.linalg.solve(R, B.T @ P), P


def _care_residual(problem: RegulationProblem, Q_i: Array, P: Array) -> float:
    """Relative residual of ``A'P + PA - PBR^-1B'P + blockdiag(Q, Q_i)`` (built here)."""
    A, B = _continuous_servo_plant(problem)
    gain_term = P @ B @ np.linalg.solve(R, B.T @ P)
    Q_aug = scipy.linalg.block_diag(Q, Q_i)
    residual = A.T @ P + P @ A - gain_term + Q_aug
    scale = 2.0 * float(np.linalg.norm(A.T @ P)) + sum(
        float(np.linalg.norm(M)) for M in (gain_term, Q_aug)
    )
    return float(np.linalg.norm(residual)) / scale


def _gain(law: ControlLaw) -> Array:
    assert law.K_i is not None
    return np.hstack([law.K, law.K_i])


def _steady_error(case: Case, law: ControlLaw, disturbance: Array, w: Array) -> Array:
    """``e = C x + F w`` at the steady state of the sampled loop (built here) with a
    constant voltage error added to every applied input; ``law`` with or without K_i.

    With the state ``s = [x; u_(k-d); ...; u_(k-1) (; z)]`` the law is ``u_k = -K s + L w``,
    ``L = U + K_x X + sum_j K_j U`` (K_j on the delayed inputs), and the loop is
    ``s_(k+1) = (A - B K) s_k + g``: its steady state solves ``(I - A + B K) s = g``.
    """
    problem, d, n = case.problem, case.delay, case.problem.n
    integral = law.K_i is not None
    A, B = _servo_plant(problem, case.h, d, integrator=integral)
    size = A.shape[0]
    Ad, Bd = _zoh(problem.A, problem.B, case.h)
    Ed = np.linalg.solve(problem.A, Ad - np.eye(n)) @ problem.D  # A is invertible
    K = np.zeros((2, size))
    K[:, : law.K.shape[1]] = law.K
    K_history = np.zeros((2, 2))
    for j in range(d):
        K_history += law.K[:, n + 2 * j : n + 2 * j + 2]
    g = B @ (law.U + law.K_x @ law.X + K_history @ law.U) @ w
    g[:n] += Ed @ w + Bd @ disturbance
    if law.K_i is not None:
        K[:, size - 2 :] = law.K_i
        g[size - 2 :] += case.h * problem.F @ w
    closed = A - B @ K
    assert _spectral_radius(closed) < 1.0
    steady = np.linalg.solve(np.eye(size) - closed, g)
    return np.asarray(problem.C @ steady[:n] + problem.F @ w)


def _exact_model(case: Case) -> DiscreteModel:
    plant = discretize(case.problem.A, case.problem.B, case.h, D=case.problem.D)
    return DiscreteModel(plant.Ad, plant.Bd, plant.Ed, case.h, np.zeros(2), 0.0, 1.0, 0)


def _knowledge(case: Case) -> LearningProblem:
    problem = case.problem
    return LearningProblem(
        Q, R, C=problem.C, F=problem.F, integral_action=True, integral_weight=case.Q_i
    )


# -- the digital servo optimum ---------------------------------------------------------------


@at_least(40)
@given(cases())
def test_digital_servo_is_the_riccati_solution_of_the_augmented_plant(case: Case) -> None:
    solution = solve_digital_regulation(
        case.problem, Q, R, case.h, input_delay=case.delay, integral_weight=case.Q_i
    )
    K_truth, P_truth = _digital_truth(case)

    assert solution.law.history == case.delay and solution.law.h == case.h
    assert solution.state[-2:] == ("z1", "z2")
    assert _relative(_gain(solution.law), K_truth) <= AGREEMENT
    assert _relative(solution.P, P_truth) <= AGREEMENT
    assert _dare_residual(case, solution.P) <= 1e-14
    np.testing.assert_array_equal(solution.K_i, solution.law.K_i)
    np.testing.assert_array_equal(solution.integral_weight, case.Q_i)
    assert closed_loop_radius(_exact_model(case), solution.law, case.delay) < 1.0


@at_least(25)
@given(cases())
def test_sampled_servo_gain_agrees_with_the_shift_only_rd_riccati(case: Case) -> None:
    solution = solve_digital_regulation(
        case.problem,
        Q,
        R,
        case.h,
        input_delay=case.delay,
        cost="sampled",
        integral_weight=case.Q_i,
    )
    K_truth, P_truth = _sampled_truth(case)

    assert _relative(_gain(solution.law), K_truth) <= AGREEMENT
    if case.delay == 0:  # the formulations' values differ by the first d stages
        assert _relative(solution.P, P_truth) <= AGREEMENT


@at_least(30)
@given(cases())
def test_identify_then_design_on_the_exact_model_agrees(case: Case) -> None:
    """The learner's design on the exact discrete model, for both costs. Its sampled cost
    with a delay uses the indefinite "shift-only-Rd" weights, which its dlqr refuses once
    their negative eigenvalue exceeds the semidefiniteness tolerance (h ~ 1e-4 s and up),
    so that combination is compared at d = 0 only."""
    model, known = _exact_model(case), _knowledge(case)
    for cost in ("digital", "sampled") if case.delay == 0 else ("digital",):
        solution = solve_digital_regulation(
            case.problem,
            Q,
            R,
            case.h,
            input_delay=case.delay,
            cost=cost,
            integral_weight=case.Q_i,
        )
        design = design_digital(model, known, case.delay, cost)
        assert _relative(_gain(design.law), _gain(solution.law)) <= AGREEMENT, cost
        assert _relative(design.law.U, solution.U) <= AGREEMENT, cost
        np.testing.assert_array_equal(design.law.C, solution.law.C)
        np.testing.assert_array_equal(design.law.F, solution.law.F)
        assert _relative(design.P, solution.P) <= AGREEMENT, cost

    continuous = solve_optimal_regulation(case.problem, Q, R, integral_weight=case.Q_i, h=case.h)
    design = design_continuous(model, known)
    assert _relative(_gain(design.law), _gain(continuous.law)) <= AGREEMENT
    assert _relative(design.P, continuous.P) <= AGREEMENT


@at_least(40)
@given(cases(), st.floats(-20.0, 20.0), st.floats(-20.0, 20.0))
def test_a_constant_input_disturbance_leaves_no_steady_state_error(
    case: Case, u_d: float, u_q: float
) -> None:
    disturbance = np.array([u_d, u_q])
    w = case.motor.exogenous(case.speed, torque=1.0)
    servo = solve_digital_regulation(
        case.problem, Q, R, case.h, input_delay=case.delay, integral_weight=case.Q_i
    )
    plain = solve_digital_regulation(case.problem, Q, R, case.h, input_delay=case.delay)

    error = _steady_error(case, servo.law, disturbance, w)
    without = _steady_error(case, plain.law, disturbance, w)
    # without integral action the disturbance moves the currents by about v / (R_s + K)
    scale = np.linalg.norm(disturbance) / (case.motor.R_s + np.linalg.norm(plain.K, 2))
    assert np.linalg.norm(without) >= 0.1 * scale
    assert np.linalg.norm(error) <= 1e-9 * max(scale, np.linalg.norm(plain.X @ w))


def test_the_simulated_sampled_loop_rejects_a_constant_voltage_error() -> None:
    """The paper's motor at 10 kHz with a one-sample delay, a 3 V / -2 V error on every
    applied voltage: with integral action e -> 0, without it e stays off."""
    motor, h, delay = SPMSM.paper(), 1e-4, 1
    problem = motor.regulation_problem(100.0)
    Q_i = 200.0**2 * Q
    plant = discretize(problem.A, problem.B, h, D=problem.D)
    w = motor.exogenous(100.0, torque=5.0)
    disturbance = np.array([3.0, -2.0])

    def final_error(law: ControlLaw, samples: int) -> Array:
        x, z, past = np.zeros(2), np.zeros(2), np.zeros((delay, 2))
        for _ in range(samples):
            u = law.command(x, w, past, z if law.K_i is not None else None)
            applied = past[0] + disturbance
            if law.K_i is not None:
                z = z + h * (problem.C @ x + problem.F @ w)
            x = plant.Ad @ x + plant.Bd @ applied + plant.Ed @ w
            past = np.vstack([past[1:], u])
        return np.asarray(problem.C @ x + problem.F @ w)

    servo = solve_digital_regulation(problem, Q, R, h, input_delay=delay, integral_weight=Q_i)
    plain = solve_digital_regulation(problem, Q, R, h, input_delay=delay)
    assert np.linalg.norm(final_error(servo.law, 3000)) < 1e-9
    assert np.linalg.norm(final_error(plain.law, 3000)) > 1e-2


# -- the continuous servo optimum ------------------------------------------------------------


@at_least(40)
@given(cases())
def test_continuous_servo_is_the_lqr_of_the_plant_with_the_integral(case: Case) -> None:
    solution = solve_optimal_regulation(case.problem, Q, R, integral_weight=case.Q_i, h=case.h)
    K_truth, P_truth = _continuous_truth(case.problem, case.Q_i)

    assert solution.K_i is not None and solution.K.shape == (2, 2)
    assert _relative(np.hstack([solution.K, solution.K_i]), K_truth) <= AGREEMENT
    assert _relative(solution.P, P_truth) <= AGREEMENT
    assert _care_residual(case.problem, case.Q_i, solution.P) <= 1e-12
    A_aug, B_aug = integrator_augmented(case.problem.A, case.problem.B, case.problem.C)
    assert np.max(np.linalg.eigvals(A_aug - B_aug @ K_truth).real) < 0.0
    X, U = case.problem.solve_regulator_equations(Q, R)
    np.testing.assert_allclose(solution.X, X, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(solution.U, U, rtol=1e-12, atol=1e-12)
    G = case.problem.D + case.problem.A @ X
    assert _relative(solution.exogenous_block, G.T @ P_truth[:2]) <= AGREEMENT


def test_continuous_servo_on_the_paper_motor_agrees_with_python_control() -> None:
    problem = SPMSM.paper().regulation_problem(100.0)
    Q_i = 200.0**2 * Q
    A, B = _continuous_servo_plant(problem)
    K_truth, P_truth, _ = control.lqr(A, B, scipy.linalg.block_diag(Q, Q_i), R)

    solution = solve_optimal_regulation(problem, Q, R, integral_weight=Q_i, h=1e-4)

    # python-control (SLICOT's SB02MD) leaves 5e-9 in K's zero off-diagonal entries here
    # (up to 6e-6 on random motors), where selftune's Riccati residual is 1e-14: a looser
    # bar, on this motor only
    assert _relative(_gain(solution.law), np.asarray(K_truth)) <= 1e-8
    assert _relative(solution.P, np.asarray(P_truth)) <= 1e-8
    law = solution.law
    assert law.h == 1e-4 and law.K_i is not None
    np.testing.assert_array_equal(law.C, problem.C)
    assert solution.theta.shape == (10 + 8 + 8,)


def test_without_integral_action_nothing_changes() -> None:
    problem = SPMSM.paper().regulation_problem(100.0)
    continuous = solve_optimal_regulation(problem, Q, R)
    P = scipy.linalg.solve_continuous_are(problem.A, problem.B, Q, R)
    assert continuous.K_i is None and continuous.integral_weight is None
    assert continuous.P.shape == (2, 2) and _relative(continuous.P, P) <= AGREEMENT
    assert continuous.law.K_i is None and continuous.h == 0.0 and continuous.cost == "continuous"
    digital = solve_digital_regulation(problem, Q, R, 1e-4, input_delay=1)
    assert type(digital) is type(continuous)  # one model-based solution type
    assert digital.h == 1e-4 and digital.input_delay == 1 and digital.cost == "digital"
    with pytest.raises(InputError, match="theta: "):
        digital.theta  # noqa: B018
    with pytest.raises(InputError, match="sampled_plant: "):
        continuous.sampled_plant  # noqa: B018
    assert digital.K_i is None and digital.integral_weight is None
    assert digital.P.shape == (4, 4) and digital.law.h is None


# -- the shared augmentation and the errors --------------------------------------------------


def test_integrator_augmented_in_continuous_and_digital_form() -> None:
    A, B, C = np.array([[1.0, 2.0], [3.0, 4.0]]), np.array([[5.0], [6.0]]), np.array([[7.0, 8.0]])
    A_c, B_c = integrator_augmented(A, B, C)
    A_d, B_d = integrator_augmented(A, B, C, h=0.5)
    np.testing.assert_array_equal(A_c, [[1, 2, 0], [3, 4, 0], [7, 8, 0]])
    np.testing.assert_array_equal(A_d, [[1, 2, 0], [3, 4, 0], [3.5, 4, 1]])
    np.testing.assert_array_equal(B_c, [[5], [6], [0]])
    np.testing.assert_array_equal(B_d, B_c)
    with pytest.raises(InputError, match="C: expected 2 columns"):
        integrator_augmented(A, B, np.ones((1, 3)))
    with pytest.raises(InputError, match="h: "):
        integrator_augmented(A, B, C, h=0.0)


def _solvers() -> list[object]:
    return [
        lambda problem, Q_i: solve_optimal_regulation(problem, Q, R, integral_weight=Q_i, h=1e-4),
        lambda problem, Q_i: solve_digital_regulation(
            problem, Q, R, 1e-4, input_delay=1, integral_weight=Q_i
        ),
        lambda problem, Q_i: solve_digital_regulation(
            problem, Q, R, 1e-4, cost="sampled", integral_weight=Q_i
        ),
    ]


@pytest.mark.parametrize("solve", _solvers())
@pytest.mark.parametrize(
    ("Q_i", "message"),
    [
        (np.eye(3), "integral_weight: expected 2 rows"),
        (np.diag([1.0, -1.0]), "integral_weight: must be symmetric positive definite"),
        (np.array([[1.0, 2.0], [0.0, 1.0]]), "integral_weight: must be symmetric"),
    ],
)
def test_a_bad_integral_weight_is_named(solve: object, Q_i: Array, message: str) -> None:
    problem = SPMSM.paper().regulation_problem(100.0)
    with pytest.raises(InputError, match=message):
        solve(problem, Q_i)  # type: ignore[operator]


@pytest.mark.parametrize("solve", _solvers())
def test_more_regulated_outputs_than_inputs_cannot_be_integrated(solve: object) -> None:
    A, B = SPMSM.paper().torque_mode(100.0)
    C = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])  # three errors, two voltages
    problem = RegulationProblem(A, B, C, np.zeros((2, 0)), np.zeros((0, 0)), np.zeros((3, 0)))
    with pytest.raises(UnsolvableError, match=r"not stabilizable.*eigenvalue (0|1)"):
        solve(problem, np.eye(3))  # type: ignore[operator]


def test_the_continuous_servo_optimum_needs_the_drive_sampling_period() -> None:
    problem = SPMSM.paper().regulation_problem(100.0)
    with pytest.raises(InputError, match="h: "):
        solve_optimal_regulation(problem, Q, R, integral_weight=200.0**2 * Q)
