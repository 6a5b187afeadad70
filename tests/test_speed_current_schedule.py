"""The schedule over speed and current together, against independent truth.

A saturating interior motor whose q-axis inductance falls with ``i_q*`` (by up to 35%),
scheduled over 5-100% of its rated speed and 10-100% of its rated current. Oracles,
written here without selftune's solvers: the sampled plant by ``scipy.linalg.expm`` of
the continuous rotor-frame model (zero-order hold in the rotor frame), the delay and the
integrator stacked by hand; the pointwise optimum by scipy's ``solve_discrete_are``; a
law's cost by ``solve_discrete_lyapunov``; the bilinear interpolation by
``scipy.interpolate.RegularGridInterpolator``. The design checks lines through its
cells; the oracle judges random points anywhere inside them.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
from scipy.interpolate import RegularGridInterpolator

from selftune.core import ControlLaw
from selftune.errors import InputError, UnsolvableError
from selftune.learn._problem import INTEGRAL_BANDWIDTH
from selftune.model import (
    EXCESS,
    IPMSM,
    SpeedCurrentSchedule,
    design_speed_current_schedule,
)

Array = np.ndarray
H = 1e-4
DELAY = 1
Q, R = 1e3 * np.eye(2), np.eye(2)
Q_I = INTEGRAL_BANDWIDTH**2 * Q
P = 4
RATED_CURRENT = 20.0  # A
RATED_SPEED = 2000.0  # rad/s (electrical)


def motor_at(current: float) -> IPMSM:
    """The incremental motor at ``i_q* = current``: L_q falls 35% over the knee at 8 A."""
    L_q = 6e-3 * (1.0 - 0.35 * current**2 / (current**2 + 8.0**2))
    return IPMSM(R_s=0.15, L_d=2.5e-3, L_q=L_q, phi_pm=0.09, p=P)


def plant(current: float, electrical_speed: float):  # type: ignore[no-untyped-def]
    motor = motor_at(current)
    speed = electrical_speed / P
    return motor.regulation_problem(speed), motor.sampled_plant(speed, H, "rotor")


def augmented(current: float, electrical_speed: float) -> tuple[Array, Array, Array, Array]:
    """``(Az, Bz, Qz, Rz)`` of ``zeta = [xbar; ubar_(k-1); z]``, from scipy's expm of the
    rotor-frame model written here."""
    motor = motor_at(current)
    R_s, L_d, L_q, w = motor.R_s, motor.L_d, motor.L_q, electrical_speed
    A = np.array([[-R_s / L_d, w * L_q / L_d], [-w * L_d / L_q, -R_s / L_q]])
    B = np.diag([1.0 / L_d, 1.0 / L_q])
    M = np.zeros((4, 4))
    M[:2, :2], M[:2, 2:] = A * H, B * H
    E = scipy.linalg.expm(M)
    Az, Bz = np.zeros((6, 6)), np.zeros((6, 2))
    Az[:2, :2], Az[:2, 2:4], Bz[2:4] = E[:2, :2], E[:2, 2:], np.eye(2)
    Az[4:, :2], Az[4:, 4:] = H * np.eye(2), np.eye(2)
    Qz = np.zeros((6, 6))
    Qz[:2, :2], Qz[4:, 4:] = H * Q, H * Q_I
    return Az, Bz, Qz, H * R


def oracle_excess(current: float, electrical_speed: float, law: ControlLaw) -> float:
    """The worst-case excess of ``law`` there, from scipy's DARE and Lyapunov."""
    Az, Bz, Qz, Rz = augmented(current, electrical_speed)
    P_opt = scipy.linalg.solve_discrete_are(Az, Bz, Qz, Rz)
    assert law.K_i is not None
    K = np.hstack([law.K, law.K_i])
    closed = Az - Bz @ K
    if np.max(np.abs(np.linalg.eigvals(closed))) >= 1.0:
        return float("inf")
    P_law = scipy.linalg.solve_discrete_lyapunov(closed.T, Qz + K.T @ Rz @ K, method="bilinear")
    return float(scipy.linalg.eigh(P_law, P_opt, eigvals_only=True)[-1] - 1.0)


@pytest.fixture(scope="module")
def design():  # type: ignore[no-untyped-def]
    currents = [0.1 * RATED_CURRENT, RATED_CURRENT]
    speeds = [0.05 * RATED_SPEED, RATED_SPEED]
    return design_speed_current_schedule(
        plant, currents, speeds, Q, R, H, input_delay=DELAY, integral_weight=Q_I
    )


def test_the_grid_laws_are_the_pointwise_optima_of_scipy(design) -> None:  # type: ignore[no-untyped-def]
    schedule = design.schedule
    for i, current in enumerate(schedule.current):
        for j, speed in enumerate(schedule.electrical_speed):
            Az, Bz, Qz, Rz = augmented(current, speed)
            P_opt = scipy.linalg.solve_discrete_are(Az, Bz, Qz, Rz)
            K_opt = np.linalg.solve(Rz + Bz.T @ P_opt @ Bz, Bz.T @ P_opt @ Az)
            law = schedule.law(i, j)
            assert law.K_i is not None
            gain = np.hstack([law.K, law.K_i])
            assert np.linalg.norm(gain - K_opt) <= 1e-7 * np.linalg.norm(K_opt)


def test_the_schedule_is_within_one_percent_anywhere_inside_its_cells(design) -> None:  # type: ignore[no-untyped-def]
    """Random points of every cell, off the lines the design checked: the oracle's excess
    of the interpolated law stays within the design's limit."""
    schedule, check = design.schedule, design.check
    assert np.all(check.passed) and check.excess.size > 0
    rng = np.random.default_rng(7)
    worst = 0.0
    for c0, c1 in zip(schedule.current[:-1], schedule.current[1:], strict=True):
        for (s0, s1) in zip(schedule.electrical_speed[:-1], schedule.electrical_speed[1:],
                            strict=True):  # fmt: skip
            for _ in range(3):
                current, speed = rng.uniform(c0, c1), rng.uniform(s0, s1)
                worst = max(worst, oracle_excess(current, speed, schedule.law_at(speed, current)))
    assert worst <= EXCESS
    # the design had to refine: the inductance's knee and the speed both move the optimum
    assert design.added_speeds or design.added_currents


def test_the_interpolation_is_bilinear(design) -> None:  # type: ignore[no-untyped-def]
    schedule = design.schedule
    table = schedule.table("K")
    interpolator = RegularGridInterpolator(
        (schedule.current, schedule.electrical_speed), table, method="linear"
    )
    rng = np.random.default_rng(3)
    for _ in range(20):
        current = rng.uniform(*schedule.covered[1])
        speed = rng.uniform(*schedule.covered[0])
        expected = interpolator([[current, speed]])[0]
        np.testing.assert_allclose(schedule.law_at(speed, current).K, expected, rtol=1e-12)
    assert schedule.law_at(schedule.electrical_speed[1], schedule.current[0]) is schedule.law(0, 1)


def test_the_document_states_every_law_indexed_current_then_speed(design) -> None:  # type: ignore[no-untyped-def]
    schedule = design.schedule
    document = schedule.document()
    K = np.asarray(document["K"])
    assert K.shape == (schedule.current.size, schedule.electrical_speed.size, 2, 4)
    np.testing.assert_array_equal(K[-1, 0], schedule.law(schedule.current.size - 1, 0).K)
    assert np.asarray(document["K_i"]).shape[:2] == K.shape[:2]
    assert "indexed [current][speed]" in str(document["equations"])


def test_outside_the_grid_and_bad_grids_are_refused(design) -> None:  # type: ignore[no-untyped-def]
    schedule = design.schedule
    (low, high), (lowest, highest) = schedule.covered
    with pytest.raises(InputError, match="electrical_speed"):
        schedule.law_at(2 * high, lowest)
    with pytest.raises(InputError, match="current"):
        schedule.law_at(low, 2 * highest)
    with pytest.raises(InputError, match="currents: must increase strictly"):
        design_speed_current_schedule(plant, [5.0, 1.0], [100.0, 200.0], Q, R, H)
    with pytest.raises(InputError, match="electrical_speeds: needs at least two"):
        design_speed_current_schedule(plant, [1.0, 5.0], [100.0], Q, R, H)
    with pytest.raises(UnsolvableError, match="max_points = 2"):
        design_speed_current_schedule(
            plant, [2.0, 20.0], [100.0, 2000.0], Q, R, H, integral_weight=Q_I, max_points=2
        )
    laws = [[schedule.law(0, 0), schedule.law(0, 1)]]
    with pytest.raises(InputError, match="at least two"):
        SpeedCurrentSchedule(schedule.electrical_speed[:2], [1.0], laws)


def test_the_figure_draws_each_grid_current_against_speed(design) -> None:  # type: ignore[no-untyped-def]
    """One line per grid current on the gains' panels, their dots the grid laws' entries;
    the excess panel the two true-motor curves given."""
    from selftune.report._schedule_figure import figure_speed_current

    schedule = design.schedule
    speeds = np.linspace(*schedule.covered[0], 5)
    both, alone = np.full((5, 3), 1e-4), np.full((5, 3), 0.05)
    figure = figure_speed_current(design, speeds, both, alone)
    gains, integral, rate, excess = figure.axes
    dots = [line for line in gains.lines if line.get_marker() == "o"]
    assert len(dots) == 2 * schedule.current.size  # d on d and q on q per current
    np.testing.assert_allclose(dots[0].get_ydata(), schedule.table("K")[0, :, 0, 0])
    np.testing.assert_allclose(dots[1].get_ydata(), schedule.table("K")[0, :, 1, 1])
    integral_dots = [line for line in integral.lines if line.get_marker() == "o"]
    np.testing.assert_allclose(integral_dots[-1].get_ydata(), schedule.table("K_i")[-1, :, 1, 1])
    curves_of_rate = [line for line in rate.lines if len(line.get_xdata()) > 2]  # not the grid's
    assert len(curves_of_rate) == 2 * schedule.current.size
    curves = {line.get_label(): line for line in excess.lines}
    np.testing.assert_allclose(curves["schedule over $i_q^*$ alone, true motor"].get_ydata(), 0.05)
