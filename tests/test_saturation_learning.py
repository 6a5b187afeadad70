"""A saturating motor learned about its operating current (the incremental structure) and
its law scheduled over the current (:mod:`selftune.tuning._saturation`)."""

from __future__ import annotations

from dataclasses import replace
from typing import Literal

import numpy as np
import pytest

from selftune.config import MotorConfig
from selftune.errors import InputError
from selftune.learn import IncrementalStructure, IpmsmStructure
from selftune.model import IPMSM, CurrentSchedule, RegulationProblem, design_current_schedule
from selftune.sim import DriveSettings, SaturationModel
from selftune.tuning import TuningSettings, tuning_settings
from selftune.tuning._interior import CURRENT_REFERENCE_F
from selftune.tuning._saturation import (
    incremental_theta,
    learn_level,
    level_plants,
    schedule_over_levels,
)

MOTOR = IPMSM(R_s=0.2, L_d=2e-3, L_q=6e-3, phi_pm=0.1, p=4)
SPEED, TORQUE, H = 100.0, 5.0, 1e-4
RATED = float(MOTOR.current_reference(TORQUE)[1])
#: L_qq falls 29 % from 10 % to 100 % of rated current (the study's first motor).
SATURATION = SaturationModel.of(MOTOR, i_sat=0.6 * RATED, drop=0.35, cross=0.1)
W_E = MOTOR.p * SPEED


@pytest.mark.parametrize("hold", ["stationary", "rotor"])
@pytest.mark.parametrize("dead_time", [False, True])
def test_without_cross_terms_it_is_the_interior_structure(
    hold: Literal["stationary", "rotor"], dead_time: bool
) -> None:
    """With L_dq = kappa_q = 0 the incremental structure's blocks are the interior
    structure's, to rounding (the same matrix exponentials of the same A, B, D, whose
    entries the two compute by different products)."""
    interior = IpmsmStructure(W_E, H, dead_time, hold)
    incremental = IncrementalStructure(W_E, H, dead_time, hold)
    theta = np.array([0.2, 2e-3, 6e-3, 0.97])
    extended = np.array([0.2, 2e-3, 6e-3, 0.0, 0.97, 0.0])
    if dead_time:
        theta, extended = np.append(theta, 1.3), np.append(extended, 1.3)
    for mine, theirs in zip(incremental(extended), interior(theta), strict=True):
        np.testing.assert_allclose(mine, theirs, rtol=1e-13, atol=1e-15 * np.max(np.abs(theirs)))
    assert IncrementalStructure.names(dead_time)[:6] == (
        "R_s", "L_d", "L_q", "L_dq", "kappa", "kappa_q",
    )  # fmt: skip
    # and a cross term changes them: the comparison can fail
    extended[3] = 1e-4
    assert not np.allclose(incremental(extended)[0], interior(theta)[0], rtol=1e-9, atol=0.0)


def _rate(current: np.ndarray, voltage: np.ndarray) -> np.ndarray:
    """The saturating motor's ``di/dt`` with the incremental inductance by central
    differences of its flux linkages (not the model's closed form)."""
    step = 1e-6 * RATED
    psi = np.array(SATURATION.flux(*current))
    L = np.empty((2, 2))
    for column in range(2):
        move = np.zeros(2)
        move[column] = step
        plus = np.array(SATURATION.flux(*(current + move)))
        minus = np.array(SATURATION.flux(*(current - move)))
        L[:, column] = (plus - minus) / (2 * step)
    J = np.array([[0.0, -1.0], [1.0, 0.0]])
    return np.linalg.solve(L, voltage - MOTOR.R_s * current - W_E * (J @ psi))


def test_the_continuous_model_is_the_saturating_motors_linearization() -> None:
    """At an equilibrium ``(i0, u0)`` of the saturating motor, the structure's ``A``, ``B``
    (of ``L = d psi / d i`` and ``c = psi(i0) - L i0``) are the Jacobians of its ``di/dt``
    (finite differences of psi), and ``A i0 + B u0 + D w = 0``."""
    i0 = MOTOR.current_reference(0.7 * TORQUE)
    J = np.array([[0.0, -1.0], [1.0, 0.0]])
    u0 = MOTOR.R_s * i0 + W_E * (J @ np.array(SATURATION.flux(*i0)))
    theta = incremental_theta(SATURATION, MOTOR.R_s, i0, MOTOR.phi_pm)
    assert abs(theta[3]) > 1e-5 and abs(theta[5]) > 1e-3  # cross-saturation, a q offset
    A, B, D = IncrementalStructure(W_E, H).continuous(theta)
    w = np.array([W_E * MOTOR.phi_pm, 0.0, 0.0])
    scale = np.max(np.abs(A @ i0))
    assert np.max(np.abs(A @ i0 + B @ u0 + D @ w)) < 1e-9 * scale
    assert np.max(np.abs(_rate(i0, u0))) < 1e-6 * scale
    delta = 1e-4 * RATED
    jacobian_i = np.column_stack([
        (_rate(i0 + delta * e, u0) - _rate(i0 - delta * e, u0)) / (2 * delta) for e in np.eye(2)
    ])  # fmt: skip
    jacobian_u = np.column_stack([
        (_rate(i0, u0 + e) - _rate(i0, u0 - e)) / 2.0 for e in np.eye(2)
    ])  # fmt: skip
    # central differences of central differences: the error is O(delta^2) of A's entries
    np.testing.assert_allclose(jacobian_i, A, rtol=1e-5, atol=1e-5 * np.max(np.abs(A)))
    np.testing.assert_allclose(jacobian_u, B, rtol=1e-5, atol=1e-5 * np.max(np.abs(B)))


def _settings(seed: int = 0) -> tuple[TuningSettings, DriveSettings]:
    drive = replace(DriveSettings.hardware_like(dc_voltage=540.0), pwm="average")
    config = MotorConfig(
        motor=MOTOR, speed=SPEED, torque=TORQUE, drive=drive, drive_h=H,
        learning={"integral_action": True}, source="saturating test motor",
        saturation=SATURATION,
    )  # fmt: skip
    return tuning_settings(config, seed), drive


def test_a_learned_incremental_inductance_is_within_its_standard_errors() -> None:
    """0.2 s at 70 % of rated torque on the realistic drive (average PWM, dead time,
    noise, ADC): L_dd, L_qq, L_dq against the true ``d psi / d i`` at the log's mean
    current, within 3.5 standard errors (a 1-in-2000 event per parameter if the errors
    mean what they say), and the nameplate's unsaturated L_q well outside them."""
    settings, drive = _settings()
    level = learn_level(MOTOR, SATURATION, settings, drive, 0.7, seconds=0.2, seed=0)
    truth = incremental_theta(SATURATION, MOTOR.R_s, level.mean_current, MOTOR.phi_pm)
    z = (level.theta - truth) / level.standard_errors
    assert np.all(np.abs(z[1:4]) < 3.5), z
    # the motor has saturated: its unsaturated L_q is many standard errors away
    assert abs(MOTOR.L_q - level.theta[2]) > 20.0 * level.standard_errors[2]
    estimate = level.learned.quality.motor  # type: ignore[union-attr]
    assert estimate is not None and estimate.L_dq is not None and estimate.phi_q is not None
    assert "L_dq = " in estimate.text() and "phi_q = " in estimate.text()


def _plant(current: float) -> tuple[RegulationProblem, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The true incremental plant on the MTPA path at the torque share ``current /
    RATED`` (``i_q*`` near ``current``)."""
    torque = current / RATED * TORQUE
    reference = MOTOR.current_reference(torque)
    structure = IncrementalStructure(W_E, H)
    theta = incremental_theta(SATURATION, MOTOR.R_s, reference, MOTOR.phi_pm)
    A, B, D = structure.continuous(theta)
    problem = RegulationProblem(
        A=A, B=B, C=np.eye(2), D=D, E=np.zeros((3, 3)), F=CURRENT_REFERENCE_F
    )
    return problem, structure(theta)


def test_the_current_schedule_refuses_a_current_outside_its_levels() -> None:
    """The schedule over i_q* is designed between its levels, checked between them, and
    refuses a current outside them, naming it and the range."""
    settings, _ = _settings()
    low, high = 0.4 * RATED, RATED
    design = design_current_schedule(
        _plant, [low, high], settings.Q, settings.R, H, input_delay=1,
        fine_points=5,
    )  # fmt: skip
    schedule = design.schedule
    assert isinstance(schedule, CurrentSchedule)
    assert np.all(design.check.passed)
    assert schedule.law_at(0.5 * (low + high)).K.shape == design.optima[0].law.K.shape
    with pytest.raises(
        InputError,
        match=r"^current: 9\.5 A is outside the schedule, which"
        r" covers 3\.\d+ to 7\.\d+ A \(i_q\*\)",
    ):
        schedule.law_at(9.5)
    with pytest.raises(InputError, match=r"^current: 0\.5 A is outside"):
        schedule.law_at(0.5)


def test_a_negative_torques_levels_are_scheduled_in_rising_current() -> None:
    """Levels learned by rising share of a negative torque have falling ``i_q*``: the
    schedule's grid and the interpolation between the levels take them rising (before,
    ``tune`` with ``torque = -6.0`` and a ``[saturation]`` stopped at ``currents: must
    increase strictly``, and ``np.interp`` over falling currents would have read the
    wrong level's model). The same levels in either order give the same schedule."""
    settings, _ = _settings()
    currents = -np.array([0.1, 0.55, 1.0]) * RATED  # by rising share: falling
    thetas = np.array(
        [incremental_theta(SATURATION, MOTOR.R_s, np.array([0.0, c]), MOTOR.phi_pm)
         for c in currents]
    )  # fmt: skip
    structure = IncrementalStructure(W_E, H, False, "stationary")
    falling, rising = (
        schedule_over_levels(
            c, t, structure, settings.Q, settings.R, input_delay=1, integral_weight=None
        )
        for c, t in ((currents, thetas), (currents[::-1], thetas[::-1]))
    )
    np.testing.assert_array_equal(falling.schedule.current, np.sort(currents))
    np.testing.assert_array_equal(falling.schedule.table("K"), rising.schedule.table("K"))
    plant = level_plants(currents, thetas, structure)
    middle = 0.5 * (currents[0] + currents[1])  # between the two lowest shares' levels
    expected = replace(structure, electrical_speed=W_E)(0.5 * (thetas[0] + thetas[1]))
    for got, want in zip(plant(middle, W_E)[1], expected, strict=True):
        np.testing.assert_allclose(got, want, rtol=1e-12)
