"""The speed schedule: the interpolated optimal digital law against independent truth.

Oracles, written here without selftune's solvers:

- the sampled plant: ``scipy.linalg.expm`` of the continuous motor (zero-order hold in
  the rotor frame), the delay and the integrator stacked by hand;
- the pointwise optimum: scipy's ``solve_discrete_are`` of that augmented plant;
- the cost of a law: scipy's ``solve_discrete_lyapunov`` of its closed loop;
- the interpolation: ``numpy.interp`` entry by entry.

The motors are drawn across the range of the issue: L_s 25 uH to 100 mH, 2-20 pole pairs,
the schedule over 5-100% of the rated speed, sampled at 10 kHz with a one-sample delay.
"""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import pytest
import scipy.linalg
from hypothesis import given
from hypothesis import strategies as st

from example_counts import examples
from selftune.core import ControlLaw
from selftune.errors import InputError, UnsolvableError
from selftune.learn._problem import INTEGRAL_BANDWIDTH
from selftune.model import (
    EXCESS,
    FINE_POINTS,
    SPMSM,
    SpeedSchedule,
    design_schedule,
    solve_digital_regulation,
    worst_excess,
)

Array = np.ndarray

H = 1e-4
DELAY = 1
Q, R = 1e3 * np.eye(2), np.eye(2)
Q_I = INTEGRAL_BANDWIDTH**2 * Q

#: Agreement of the DARE's gain with scipy's (relative Frobenius norm): both are
#: backward stable on these 6x6 Riccati equations, well conditioned at 10 kHz.
AGREEMENT = 1e-7


def augmented(motor: SPMSM, speed: float, integral: bool) -> tuple[Array, Array, Array, Array]:
    """``(Az, Bz, Qz, Rz)`` of ``zeta = [xbar; ubar_(k-1); z]`` from scipy's expm."""
    A, B = motor.torque_mode(speed)
    M = np.zeros((4, 4))
    M[:2, :2], M[:2, 2:] = A * H, B * H
    E = scipy.linalg.expm(M)
    Ad, Bd = E[:2, :2], E[:2, 2:]
    r = 2 if integral else 0
    size = 4 + r
    Az, Bz = np.zeros((size, size)), np.zeros((size, 2))
    Az[:2, :2], Az[:2, 2:4], Bz[2:4] = Ad, Bd, np.eye(2)
    Qz = np.zeros((size, size))
    Qz[:2, :2] = H * Q
    if integral:
        Az[4:, :2], Az[4:, 4:] = H * np.eye(2), np.eye(2)
        Qz[4:, 4:] = H * Q_I
    return Az, Bz, Qz, H * R


def gain(law: ControlLaw) -> Array:
    """``[K, K_i]`` over ``zeta``."""
    return law.K if law.K_i is None else np.hstack([law.K, law.K_i])


def reference_excess(motor: SPMSM, speed: float, law: ControlLaw, integral: bool) -> float:
    """The worst-case excess of ``law`` at ``speed`` from scipy's DARE and Lyapunov."""
    Az, Bz, Qz, Rz = augmented(motor, speed, integral)
    P_opt = scipy.linalg.solve_discrete_are(Az, Bz, Qz, Rz)
    K = gain(law)
    closed = Az - Bz @ K
    if np.max(np.abs(np.linalg.eigvals(closed))) >= 1.0:
        return float("inf")
    P = scipy.linalg.solve_discrete_lyapunov(closed.T, Qz + K.T @ Rz @ K, method="bilinear")
    return float(scipy.linalg.eigh(P, P_opt, eigvals_only=True)[-1] - 1.0)


@st.composite
def motors(draw: st.DrawFn) -> tuple[SPMSM, float]:
    """A motor of the issue's range and its rated mechanical speed (rad/s)."""

    def log_uniform(low: float, high: float) -> float:
        return float(np.exp(draw(st.floats(np.log(low), np.log(high)))))

    L_s = log_uniform(25e-6, 0.1)
    tau = log_uniform(1e-3, 0.1)
    p = draw(st.integers(2, 20))
    rated_electrical = log_uniform(300.0, 3000.0)
    motor = SPMSM(R_s=L_s / tau, L_s=L_s, phi_pm=log_uniform(0.01, 1.0), p=p)
    return motor, rated_electrical / p


@examples(full=12, quick=3)
@given(motors(), st.booleans())
def test_the_interpolated_schedule_is_within_one_percent_between_the_design_points(
    case: tuple[SPMSM, float], integral: bool
) -> None:
    motor, rated = case
    design = design_schedule(
        motor, [0.05 * rated, rated], Q, R, H, input_delay=DELAY,
        integral_weight=Q_I if integral else None,
    )  # fmt: skip
    schedule = design.schedule
    grid = schedule.electrical_speed
    assert grid[0] == pytest.approx(0.05 * rated * motor.p)
    assert grid[-1] == pytest.approx(rated * motor.p)
    worst = 0.0
    for low, high in pairwise(grid):
        for speed in np.linspace(low, high, FINE_POINTS + 2)[1:-1]:
            law = schedule.law_at(speed)
            for name in ("K", "U", "X") + (("K_i",) if integral else ()):
                table = np.array([getattr(each, name) for each in schedule.laws])
                flat = table.reshape(len(grid), -1)
                expected = [np.interp(speed, grid, flat[:, j]) for j in range(flat.shape[1])]
                expected = np.reshape(expected, table.shape[1:])
                np.testing.assert_allclose(getattr(law, name), expected, rtol=1e-12, atol=0)
            worst = max(worst, reference_excess(motor, speed / motor.p, law, integral))
    assert worst <= EXCESS
    assert worst == pytest.approx(float(np.max(design.check.excess)), rel=1e-3, abs=1e-9)


@pytest.mark.parametrize("integral", [False, True])
@pytest.mark.parametrize(
    "motor",
    [SPMSM(R_s=0.6, L_s=8e-3, phi_pm=0.35, p=3), SPMSM(R_s=0.01, L_s=25e-6, phi_pm=0.01, p=20)],
)
def test_the_grid_optima_are_the_dare_of_the_sampled_plant(motor: SPMSM, integral: bool) -> None:
    rated = 2000.0 / motor.p
    design = design_schedule(
        motor, [0.05 * rated, 0.5 * rated, rated], Q, R, H, input_delay=DELAY,
        integral_weight=Q_I if integral else None,
    )  # fmt: skip
    for electrical, law in zip(design.schedule.electrical_speed, design.schedule.laws, strict=True):
        Az, Bz, Qz, Rz = augmented(motor, electrical / motor.p, integral)
        P = scipy.linalg.solve_discrete_are(Az, Bz, Qz, Rz)
        K = np.linalg.solve(Rz + Bz.T @ P @ Bz, Bz.T @ P @ Az)
        error = np.linalg.norm(gain(law) - K) / np.linalg.norm(K)
        assert error <= AGREEMENT
        # the feedforward: the continuous steady state (E = 0, zero-order hold)
        x_e, u_e = motor.equilibrium(electrical / motor.p, 3.0)
        w = motor.exogenous(electrical / motor.p, 3.0)
        np.testing.assert_allclose(law.X @ w, x_e, rtol=1e-9, atol=1e-9 * np.abs(x_e).max())
        np.testing.assert_allclose(law.U @ w, u_e, rtol=1e-9, atol=1e-9 * np.abs(u_e).max())


def test_a_tighter_excess_refines_the_grid_and_is_met() -> None:
    motor = SPMSM(R_s=0.2, L_s=0.05, phi_pm=0.3, p=4)
    coarse = design_schedule(motor, [25.0, 500.0], Q, R, H, input_delay=DELAY)
    limit = 0.1 * float(np.max(coarse.check.excess))
    fine = design_schedule(motor, [25.0, 500.0], Q, R, H, input_delay=DELAY, excess=limit)
    assert fine.added
    assert len(fine.schedule.electrical_speed) == 2 + len(fine.added)
    assert float(np.max(fine.check.excess)) <= limit
    for speed in fine.added:
        assert speed in fine.schedule.electrical_speed
    with pytest.raises(UnsolvableError, match="max_points = 2"):
        design_schedule(motor, [25.0, 500.0], Q, R, H, excess=limit, max_points=2)


def test_the_single_speed_law_costs_more_away_from_its_speed() -> None:
    motor = SPMSM(R_s=0.2, L_s=0.05, phi_pm=0.3, p=4)
    design = design_schedule(motor, [25.0, 500.0], Q, R, H, input_delay=DELAY, integral_weight=Q_I)
    single = solve_digital_regulation(
        motor.regulation_problem(25.0), Q, R, H, input_delay=DELAY, integral_weight=Q_I,
        plant=motor.sampled_plant(25.0, H),
    ).law  # fmt: skip
    excess = design.excess_of(single)
    top = design.check.electrical_speed[-1] / motor.p
    assert excess[-1] == pytest.approx(reference_excess(motor, top, single, True), rel=1e-6)
    assert excess[-1] > 10 * EXCESS
    assert np.max(design.check.excess) <= EXCESS


def test_worst_excess_is_the_largest_ratio_over_initial_states() -> None:
    rng = np.random.default_rng(3)
    root = rng.normal(size=(4, 4))
    P_opt = root @ root.T + np.eye(4)
    P = P_opt + 0.3 * np.outer(root[0], root[0])
    ratios = [v @ P @ v / (v @ P_opt @ v) for v in rng.normal(size=(20000, 4))]
    assert max(ratios) <= 1.0 + float(worst_excess(P, P_opt)) + 1e-12
    assert max(ratios) >= 1.0 + 0.95 * float(worst_excess(P, P_opt))
    assert worst_excess(np.full((4, 4), np.inf), P_opt) == np.inf


def test_a_speed_outside_the_schedule_is_refused_with_the_range() -> None:
    motor = SPMSM(R_s=0.6, L_s=8e-3, phi_pm=0.35, p=3)
    schedule = design_schedule(motor, [10.0, 100.0], Q, R, H).schedule
    assert schedule.covered == (30.0, 300.0)
    for speed in (29.9, 300.5, -100.0):
        with pytest.raises(InputError, match=rf"{speed:g} rad/s is outside.* 30 to 300 rad/s"):
            schedule.law_at(speed)
    assert schedule.law_at(30.0) is schedule.laws[0]
    assert schedule.law_at(300.0) is schedule.laws[-1]


@pytest.mark.parametrize(
    ("speeds", "message"),
    [
        ([10.0], "at least two"),
        ([10.0, 10.0], "increase strictly"),
        ([50.0, 10.0], "increase strictly"),
        ([10.0, float("nan")], "finite"),
    ],
)
def test_bad_speed_grids_are_refused(speeds: list[float], message: str) -> None:
    motor = SPMSM(R_s=0.6, L_s=8e-3, phi_pm=0.35, p=3)
    with pytest.raises(InputError, match=f"speeds: .*{message}"):
        design_schedule(motor, speeds, Q, R, H)


def test_laws_of_different_structure_are_not_one_schedule() -> None:
    one = ControlLaw(np.eye(2), np.eye(2), np.eye(2))
    delayed = ControlLaw(np.ones((2, 4)), np.eye(2), np.eye(2), history=1)
    with pytest.raises(InputError, match="law 1 has"):
        SpeedSchedule([1.0, 2.0], [one, delayed])
    with pytest.raises(InputError, match="2 laws for 3 speeds"):
        SpeedSchedule([1.0, 2.0, 3.0], [one, one])


def test_the_figure_draws_the_interpolated_gains_and_both_excess_costs() -> None:
    from selftune.report import figure_schedule

    motor = SPMSM(R_s=0.2, L_s=0.05, phi_pm=0.3, p=4)
    design = design_schedule(motor, [25.0, 100.0, 500.0], Q, R, H, integral_weight=Q_I)
    single = design.pointwise_optimum(4 * 100.0).law
    single_excess = design.excess_of(single)
    figure = figure_schedule(design, single_excess, 400.0)
    gains, _, _, excess = figure.axes
    line = gains.get_lines()[0]
    speeds, values = line.get_xdata(), line.get_ydata()
    size = design.schedule.electrical_speed.size
    assert len(speeds) == size + FINE_POINTS * (size - 1)
    for speed, value in zip(speeds[::17], values[::17], strict=True):
        assert value == design.schedule.law_at(float(speed)).K[0, 0]
    drawn = {line.get_label(): line.get_ydata() for line in excess.get_lines()}
    np.testing.assert_array_equal(
        drawn["single-speed controller"], np.maximum(single_excess, 1e-12)
    )
    np.testing.assert_array_equal(
        drawn["interpolated schedule"], np.maximum(design.check.excess, 1e-12)
    )


#: The study of docs/schedule.md: seeded motors across the issue's range.
STUDY_MOTORS = 20


@pytest.mark.slow
def test_the_study_of_random_motors_meets_one_percent() -> None:
    """``pytest tests/test_schedule.py -k study -s`` prints docs/schedule.md's table."""
    rng = np.random.default_rng(2026)
    rows = []
    for index in range(STUDY_MOTORS):
        L_s = float(np.exp(rng.uniform(np.log(25e-6), np.log(0.1))))
        tau = float(np.exp(rng.uniform(np.log(1e-3), np.log(0.1))))
        p = int(rng.integers(2, 21))
        rated = float(np.exp(rng.uniform(np.log(300.0), np.log(3000.0)))) / p
        motor = SPMSM(R_s=L_s / tau, L_s=L_s, phi_pm=0.1, p=p)
        integral = index % 2 == 1
        design = design_schedule(
            motor, [0.05 * rated, rated], Q, R, H, input_delay=DELAY,
            integral_weight=Q_I if integral else None, hold="stationary",
        )  # fmt: skip
        single = design.pointwise_optimum(motor.p * 0.5 * rated).law
        single_excess = design.excess_of(single)
        worst = float(np.max(design.check.excess))
        assert worst <= EXCESS
        rows.append(
            f"| {L_s * 1e3:.3g} | {tau * 1e3:.3g} | {p} | {rated * p:.0f} | "
            f"{'yes' if integral else 'no'} | {design.schedule.electrical_speed.size} | "
            f"{worst:.2g} | {single_excess[-1]:.2g} |"
        )
    print("\n| L_s (mH) | L_s/R_s (ms) | p | rated omega_e (rad/s) | K_i | grid | "
          "worst excess | single-speed excess at top |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))
