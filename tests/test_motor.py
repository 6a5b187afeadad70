"""The SPMSM model against the published numbers, closed forms and physics.

Expected values:

- PAPER_NOTES.md section 2 (erratum 1): the numbers the paper prints, reproduced by
  ``SPMSM.paper()`` at 10 rad/s, 10 N m, Q = 1e3 I, R = I. They are hard-coded here as
  published (4 decimals, so compared to half a unit in the last printed place).
- Closed forms: the equilibrium of eq. 3 (corrected sign), and the scalar Riccati equation
  the motor's LQR reduces to (A = -gamma I + skew, B = I / L_s, Q = q I, R = I, so
  P = s I with -2 gamma s - s^2 / L_s^2 + q = 0).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from example_counts import at_least
from selftune import SPMSM, InputError, ModelBasedSolution, solve_optimal_regulation
from selftune.core import unpack_theta

SPEED = 10.0  # rad/s, mechanical
TORQUE = 10.0  # N m
Q_PAPER = 1e3 * np.eye(2)
R_PAPER = np.eye(2)

#: Half a unit in the 4th decimal: "equal to 4 decimals" as printed.
FOUR_DECIMALS = 5e-5
#: Half a unit in the 3rd decimal.
THREE_DECIMALS = 5e-4

# PAPER_NOTES.md section 2, erratum 1 (the published values, reconciled parameters).
PUBLISHED_X_E = [0.0, 7.2464]
PUBLISHED_U_E = [-8.7101, 12.3812]
PUBLISHED_P = 1.8743 * np.eye(2)
PUBLISHED_K = 31.1868 * np.eye(2)
PUBLISHED_X = [[0.0, 0.0], [0.0, 0.7246]]
PUBLISHED_U = [[0.0, -0.8710], [1.0, 0.3181]]
PUBLISHED_THETA = [
    1.8743,
    1.8743,
    0.0,
    31.1868,
    0.0,
    0.0,
    31.1868,
    0.0,
    27.1642,
    -31.1868,
    -9.9210,
]


def _assert_to_decimals(actual: object, published: object, half_unit: float) -> None:
    difference = np.abs(np.asarray(actual, dtype=float) - np.asarray(published, dtype=float))
    # 1e-12 absorbs the binary representation of the printed decimal.
    assert np.all(difference <= half_unit + 1e-12), (actual, published)


#: Agreement bar for solved quantities, relative to the norms involved. The regulator
#: equations of a fast motor with a small L_s are badly scaled (cond(N) ~ 1e4-1e5), so
#: their unscaled solution carries relative errors up to ~1e-10.
AGREEMENT = 1e-9


def _assert_close(actual: object, expected: object, scale: float) -> None:
    """||actual - expected|| <= AGREEMENT * scale (Frobenius / Euclidean norms)."""
    difference = np.asarray(actual, dtype=float) - np.asarray(expected, dtype=float)
    assert float(np.linalg.norm(difference)) <= AGREEMENT * scale, (actual, expected)


@pytest.fixture(scope="module")
def paper_solution() -> ModelBasedSolution:
    motor = SPMSM.paper()
    return solve_optimal_regulation(motor.regulation_problem(SPEED), Q_PAPER, R_PAPER)


motors = st.builds(
    SPMSM,
    R_s=st.floats(min_value=0.01, max_value=10.0),
    L_s=st.floats(min_value=1e-4, max_value=0.5),
    phi_pm=st.floats(min_value=0.01, max_value=2.0),
    p=st.integers(min_value=1, max_value=12),
    J=st.floats(min_value=1e-4, max_value=1.0),
)
speeds = st.floats(min_value=-1000.0, max_value=1000.0)
torques = st.floats(min_value=-100.0, max_value=100.0)
currents = st.floats(min_value=-100.0, max_value=100.0)
voltages = st.floats(min_value=-600.0, max_value=600.0)


# -- 7a. the published numbers -------------------------------------------------------------------


def test_paper_operating_point_matches_the_published_values() -> None:
    x_e, u_e = SPMSM.paper().equilibrium(SPEED, TORQUE)
    _assert_to_decimals(x_e, PUBLISHED_X_E, FOUR_DECIMALS)
    _assert_to_decimals(u_e, PUBLISHED_U_E, FOUR_DECIMALS)


def test_paper_optimum_matches_the_published_values(
    paper_solution: ModelBasedSolution,
) -> None:
    _assert_to_decimals(paper_solution.P, PUBLISHED_P, FOUR_DECIMALS)
    _assert_to_decimals(paper_solution.K, PUBLISHED_K, FOUR_DECIMALS)
    _assert_to_decimals(paper_solution.X, PUBLISHED_X, FOUR_DECIMALS)
    _assert_to_decimals(paper_solution.U, PUBLISHED_U, FOUR_DECIMALS)
    _assert_to_decimals(paper_solution.theta, PUBLISHED_THETA, FOUR_DECIMALS)
    motor = SPMSM.paper()
    w = motor.exogenous(SPEED, TORQUE)
    _assert_to_decimals(paper_solution.X @ w, PUBLISHED_X_E, FOUR_DECIMALS)
    _assert_to_decimals(paper_solution.U @ w, PUBLISHED_U_E, FOUR_DECIMALS)


def test_the_printed_feedforward_is_not_an_exact_solution(
    paper_solution: ModelBasedSolution,
) -> None:
    # Erratum 1: the paper's U* = [[0.0028, -0.8660], [0.9999, 0.3181]] leaves a residual
    # in AX + BU + D = 0 far above the rounding of the exact U*.
    problem = SPMSM.paper().regulation_problem(SPEED)
    printed = np.array([[0.0028, -0.8660], [0.9999, 0.3181]])
    printed_residual, _ = problem.regulator_residuals(paper_solution.X, printed)
    exact_residual, output_residual = problem.regulator_residuals(
        paper_solution.X, paper_solution.U
    )
    # Rounding level: C X + F with X = -F solved from the regulator equations is exact to a
    # few units in the last place of F.
    rounding = 16 * np.finfo(float).eps * float(np.linalg.norm(problem.F))
    assert exact_residual <= 1e-12 and output_residual <= rounding
    assert printed_residual > 0.05


def test_theta_recovers_the_model_as_in_the_notes(
    paper_solution: ModelBasedSolution,
) -> None:
    # PAPER_NOTES.md section 3: B = (R K P^-1)', D + A X* = P^-1 M', U = -B^-1 (D + A X*).
    motor = SPMSM.paper()
    P, K, M = unpack_theta(paper_solution.theta, n=2, m=2, q=2)
    B = (R_PAPER @ K @ np.linalg.inv(P)).T
    np.testing.assert_allclose(B, np.eye(2) / motor.L_s, rtol=1e-12, atol=1e-12)
    drift = np.linalg.solve(P, M.T)
    U = -np.linalg.solve(B, drift)
    np.testing.assert_allclose(U, paper_solution.U, rtol=1e-12, atol=1e-14)


def test_table_parameters_with_the_texts_weight_give_the_numbers_in_the_notes() -> None:
    # Erratum 1: Table II (L_s = 0.0615 H, phi_pm = 0.5 Wb) with Q = 1e4 I gives
    # P* = 6.1231 I and K* = 99.562 I, not the paper's printed results.
    motor = SPMSM.paper_table()
    assert (motor.L_s, motor.phi_pm) == (0.0615, 0.5)
    solution = solve_optimal_regulation(motor.regulation_problem(SPEED), 1e4 * np.eye(2), R_PAPER)
    _assert_to_decimals(solution.P, 6.1231 * np.eye(2), FOUR_DECIMALS)
    _assert_to_decimals(solution.K, 99.562 * np.eye(2), THREE_DECIMALS)


# -- 7b. closed forms for random motors -----------------------------------------------------------


@at_least(100)
@given(motors, speeds, torques)
def test_closed_form_equilibrium_is_the_regulation_solution(
    motor: SPMSM, speed: float, torque: float
) -> None:
    x_e, u_e = motor.equilibrium(speed, torque)
    problem = motor.regulation_problem(speed)
    X, U = problem.solve_regulator_equations()
    w = motor.exogenous(speed, torque)
    w_norm = float(np.linalg.norm(w))
    _assert_close(X @ w, x_e, float(np.linalg.norm(X)) * w_norm)
    _assert_close(U @ w, u_e, float(np.linalg.norm(U)) * w_norm)
    # e = C x + F w = 0: the current is the reference, so the torque is the reference.
    torque_per_ampere = 1.5 * motor.p * motor.phi_pm
    np.testing.assert_allclose(motor.torque(x_e[1]), torque, rtol=1e-12, atol=1e-300)
    x_norm = float(np.linalg.norm(X))
    _assert_close(motor.torque((X @ w)[1]), torque, torque_per_ampere * x_norm * w_norm)
    np.testing.assert_array_equal(x_e, motor.current_reference(torque))


@at_least(100)
@given(motors, speeds, torques)
def test_equilibrium_is_a_rest_point_of_the_full_model(
    motor: SPMSM, speed: float, torque: float
) -> None:
    # With the load torque equal to the reference, nothing moves: currents and speed hold.
    x_e, u_e = motor.equilibrium(speed, torque)
    derivative = motor.full_model([x_e[0], x_e[1], speed], u_e, load_torque=torque)
    electrical_speed = abs(motor.p * speed)
    current_rate_scale = (
        motor.gamma * abs(x_e[1])
        + electrical_speed * abs(x_e[1])
        + electrical_speed * motor.phi_pm / motor.L_s
        + np.max(np.abs(u_e)) / motor.L_s
    )
    np.testing.assert_allclose(derivative[:2], 0.0, atol=1e-12 * current_rate_scale + 1e-300)
    assert motor.J is not None
    assert abs(derivative[2]) <= 1e-12 * abs(torque) / motor.J + 1e-300


@at_least(100)
@given(
    motors,
    speeds,
    torques,
    st.tuples(currents, currents),
    st.tuples(voltages, voltages),
)
def test_full_model_currents_at_constant_speed_are_the_regulation_form(
    motor: SPMSM,
    speed: float,
    torque: float,
    current: tuple[float, float],
    voltage: tuple[float, float],
) -> None:
    # Physical consistency: x' = A x + B u + D w with w = [p speed phi_pm, T*], whatever T*.
    x = np.array(current)
    u = np.array(voltage)
    problem = motor.regulation_problem(speed)
    w = motor.exogenous(speed, torque)
    linear = problem.A @ x + problem.B @ u + problem.D @ w
    derivative = motor.full_model([x[0], x[1], speed], u)
    scale = (
        (motor.gamma + abs(motor.p * speed)) * np.max(np.abs(x))
        + np.max(np.abs(u)) / motor.L_s
        + abs(motor.p * speed) * motor.phi_pm / motor.L_s
    )
    np.testing.assert_allclose(derivative[:2], linear, rtol=0, atol=1e-13 * scale + 1e-300)
    # The torque-mode (A, B) is the same pair.
    A, B = motor.torque_mode(speed)
    np.testing.assert_array_equal(A, problem.A)
    np.testing.assert_array_equal(B, problem.B)
    # The speed equation: J speed' = T_e - T_L.
    assert motor.J is not None
    np.testing.assert_allclose(
        derivative[2], 1.5 * motor.p * motor.phi_pm * x[1] / motor.J, rtol=1e-12, atol=1e-300
    )


@at_least(60)
@given(motors, speeds, st.floats(min_value=1.0, max_value=1e5))
def test_motor_lqr_is_the_scalar_riccati_solution(
    motor: SPMSM, speed: float, q_weight: float
) -> None:
    # P = s I with -2 gamma s - s^2 / L_s^2 + q = 0 (the skew part of A cancels).
    gamma, L_s = motor.gamma, motor.L_s
    s = L_s**2 * (-gamma + math.sqrt(gamma**2 + q_weight / L_s**2))
    solution = solve_optimal_regulation(
        motor.regulation_problem(speed), q_weight * np.eye(2), np.eye(2)
    )
    np.testing.assert_allclose(solution.P, s * np.eye(2), rtol=1e-9, atol=1e-9 * s)
    np.testing.assert_allclose(solution.K, s / L_s * np.eye(2), rtol=1e-9, atol=1e-9 * s / L_s)
    # K = sqrt(R_s^2 + q) - R_s: independent of L_s (hence the same K* for both parameter sets).
    expected_gain = math.sqrt(motor.R_s**2 + q_weight) - motor.R_s
    np.testing.assert_allclose(np.diag(solution.K), expected_gain, rtol=1e-9)


# -- the two problems are solvable -----------------------------------------------------------------


@at_least(40)
@given(motors, speeds, torques)
def test_known_flux_problem_is_solvable(motor: SPMSM, speed: float, torque: float) -> None:
    problem = motor.regulation_problem(speed)
    problem.check_solvable()
    solution = solve_optimal_regulation(problem, 1e3 * np.eye(2), np.eye(2))
    _assert_close(solution.X, -problem.F, float(np.linalg.norm(problem.F)))
    A, B, D, F = problem.A, problem.B, problem.D, problem.F
    _assert_close(
        solution.U, -np.linalg.solve(B, A @ solution.X + D), float(np.linalg.norm(solution.U))
    )
    # Residuals relative to the norms of their terms (as in test_regulation).
    first, second = problem.regulator_residuals(solution.X, solution.U)
    norm = np.linalg.norm
    assert first <= 1e-10 * (norm(A) * norm(solution.X) + norm(B) * norm(solution.U) + norm(D))
    assert second <= 1e-10 * (norm(solution.X) + norm(F))


@at_least(40)
@given(motors, speeds)
def test_no_load_problem_is_solvable_with_zero_x(motor: SPMSM, speed: float) -> None:
    problem = motor.no_load_problem(speed)
    assert (problem.n, problem.m, problem.q, problem.r) == (2, 2, 1, 2)
    problem.check_solvable()
    solution = solve_optimal_regulation(problem, 1e3 * np.eye(2), np.eye(2))
    # u = U* p speed must cancel the back EMF: X* = 0, U* = [[0], [phi_pm]].
    _assert_close(solution.X, 0.0, motor.phi_pm)
    _assert_close(solution.U, [[0.0], [motor.phi_pm]], motor.phi_pm)
    w = motor.no_load_exogenous(speed)
    np.testing.assert_allclose(w, [motor.p * speed], rtol=1e-15)
    derivative = motor.full_model([0.0, 0.0, speed], solution.U @ w, load_torque=0.0)
    # The voltage error (<= AGREEMENT phi_pm |w|) divided by L_s.
    back_emf_rate = abs(motor.p * speed) * motor.phi_pm / motor.L_s
    assert float(np.linalg.norm(derivative)) <= AGREEMENT * back_emf_rate + 1e-300
    # Algorithm 3's recovery (PAPER_NOTES.md section 5): L_s = 1/B_ii, D = P^-1 (D'P)',
    # phi_pm = -D_2 L_s, from Theta = [vecs(P); vec(K); vec(D'P)].
    P, K, M = unpack_theta(solution.theta, n=2, m=2, q=1)
    B = (K @ np.linalg.inv(P)).T
    L_s = 1.0 / B[0, 0]
    D = np.linalg.solve(P, M.T)
    np.testing.assert_allclose(L_s, motor.L_s, rtol=1e-9)
    np.testing.assert_allclose(-D[1, 0] * L_s, motor.phi_pm, rtol=1e-9)
    # The feedback is that of the known-flux problem (same A, B).
    known_flux = solve_optimal_regulation(
        motor.regulation_problem(speed), 1e3 * np.eye(2), np.eye(2)
    )
    np.testing.assert_array_equal(solution.K, known_flux.K)


# -- validation ------------------------------------------------------------------------------------

_VALID: dict[str, Any] = {"R_s": 0.439, "L_s": 0.0601, "phi_pm": 0.46, "p": 2, "J": 0.0163}


_BAD_VALUES = [0.0, -1.0, -1e-300, math.nan, math.inf, -math.inf, "abc", True]


@pytest.mark.parametrize(
    ("field", "bad"),
    [(field, bad) for field in _VALID for bad in _BAD_VALUES]
    # J = None means "not given" (valid); the other fields are required.
    + [(field, None) for field in _VALID if field != "J"],
    ids=repr,
)
def test_invalid_parameters_are_named(field: str, bad: object) -> None:
    with pytest.raises(ValueError, match=rf"^{field}:") as info:
        SPMSM(**{**_VALID, field: bad})
    assert isinstance(info.value, InputError)


@pytest.mark.parametrize("p", [2.5, 0.5, 1.0000001])
def test_a_fractional_number_of_pole_pairs_is_named(p: float) -> None:
    with pytest.raises(ValueError, match=r"^p: .*whole number"):
        SPMSM(**{**_VALID, "p": p})


def test_a_whole_float_number_of_pole_pairs_becomes_an_int() -> None:
    motor = SPMSM(**{**_VALID, "p": 4.0})
    assert motor.p == 4 and isinstance(motor.p, int)


def test_inertia_is_optional_except_for_the_full_model() -> None:
    motor = SPMSM(R_s=0.439, L_s=0.0601, phi_pm=0.46, p=2)
    assert motor.J is None
    motor.regulation_problem(SPEED)  # torque mode needs no inertia
    with pytest.raises(ValueError, match=r"^J:"):
        motor.full_model([0.0, 0.0, SPEED], [0.0, 0.0])


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_non_finite_operating_conditions_are_named(bad: float) -> None:
    motor = SPMSM.paper()
    with pytest.raises(ValueError, match=r"^speed:"):
        motor.regulation_problem(bad)
    with pytest.raises(ValueError, match=r"^torque:"):
        motor.equilibrium(SPEED, bad)
    with pytest.raises(ValueError, match=r"^load_torque:"):
        motor.full_model([0.0, 0.0, SPEED], [0.0, 0.0], load_torque=bad)
