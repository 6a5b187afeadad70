"""The bench section "on a realistic drive": its structure and the relations that must hold.

No measured number is hard-coded beyond the issue's own targets: the checks are what holds
whenever the study measures what it says (the optimum has no excess cost and no controller
beats it, every learned controller learns from the same batch, integral action leaves only
the drive's measurement floor in the torque, a wrong flux shows as exactly its error in the
torque, the PI is as fast as the controller it is compared with). The helpers are checked
against independent oracles (a PI's first-order loop, the seeded draws).
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from selftune.bench import BenchReport
from selftune.bench._drive_designs import (
    DriveCase,
    current_bandwidth,
    drive_cases,
    matched_pi,
    pi_law,
)
from selftune.bench._realistic_drive import (
    DC_VOLTAGE,
    REALISTIC_CONTROLLERS,
    RealisticDriveComparison,
    markdown_realistic_drive,
)
from selftune.bench._realistic_results import CONTROLLER_KNOWLEDGE, TORQUE_TARGET_PERCENT
from selftune.core import finite_or_null, to_jsonable
from selftune.model import SPMSM

#: The controllers with integral action and the measured flux: their steady torque error is
#: the drive's measurement floor, at tuning and after R_s +40%.
INTEGRAL_KNOWN_FLUX = (
    "selftune",
    "identify",
    "industrial_pi",
    "nominal_optimum",
    "nominal_pi",
    "optimum",
)


@pytest.fixture(scope="module")
def comparison(quick_bench: BenchReport) -> RealisticDriveComparison:
    """The quick bench's realistic drive (``measure_realistic_drive(quick=True)``), from the
    session's one quick bench."""
    return quick_bench.realistic_drive


def test_the_quick_run_has_every_controller_on_a_fast_motor(
    comparison: RealisticDriveComparison,
) -> None:
    assert comparison.quick is True
    assert len(comparison.motors) == 1 and len(comparison.seeds) >= 2
    motor = comparison.motors[0]
    assert motor.electrical_speed_rad_per_second >= 1000.0
    assert motor.electrical_speed_rad_per_second == pytest.approx(
        motor.pole_pairs_count * motor.speed_rad_per_second
    )
    assert len(motor.runs) == len(comparison.seeds)
    assert set(REALISTIC_CONTROLLERS) == set(CONTROLLER_KNOWLEDGE)
    for name in REALISTIC_CONTROLLERS:
        assert len(comparison.outcomes(name)) == len(comparison.seeds)
    # the true motor differs from the nameplate: heated, and within the tolerances
    assert motor.true_R_s_ohm != motor.nameplate_R_s_ohm
    assert abs(motor.true_L_s_henry / motor.nameplate_L_s_henry - 1) <= (
        comparison.tolerance_L_s_relative
    )
    assert comparison.wall_seconds > 0


def test_every_controller_is_made_and_stable(comparison: RealisticDriveComparison) -> None:
    for name in REALISTIC_CONTROLLERS:
        for outcome in comparison.outcomes(name):
            assert outcome.failure_text == "", (name, outcome.failure_text)
            assert outcome.excess_cost_percent is not None
            assert math.isfinite(outcome.excess_cost_percent), name
            assert outcome.bandwidth_rad_per_second is not None
            assert outcome.learn_seconds >= 0


def test_the_optimum_has_zero_excess_cost_and_none_beats_it(
    comparison: RealisticDriveComparison,
) -> None:
    for outcome in comparison.outcomes("optimum"):
        assert outcome.excess_cost_percent == pytest.approx(0.0, abs=1e-9)
    for name in REALISTIC_CONTROLLERS:
        for outcome in comparison.outcomes(name):
            assert outcome.excess_cost_percent is not None
            assert outcome.excess_cost_percent >= -1e-7, name


def test_every_learned_controller_is_given_the_same_data(
    comparison: RealisticDriveComparison,
) -> None:
    for run in comparison.runs():
        batch = run.selftune.data_seconds
        assert batch == pytest.approx(0.1)
        assert run.identify.data_seconds == batch
        assert run.industrial_pi.data_seconds == batch
        for name in ("nominal_optimum", "nominal_pi", "nominal_nameplate_flux", "optimum"):
            assert getattr(run, name).data_seconds == 0.0
        # Algorithm 3 does not know the flux: its own flux step, then its own batch
        assert run.flux_step_seconds == pytest.approx(0.2)
        assert run.algorithm3.data_seconds == pytest.approx(run.flux_step_seconds + batch)


def test_integral_action_leaves_only_the_measurement_floor(
    comparison: RealisticDriveComparison,
) -> None:
    for name in INTEGRAL_KNOWN_FLUX:
        for outcome in comparison.outcomes(name):
            assert outcome.torque_error_percent is not None
            assert outcome.hot_torque_error_percent is not None
            assert abs(outcome.torque_error_percent) <= TORQUE_TARGET_PERCENT, name
            assert abs(outcome.hot_torque_error_percent) <= TORQUE_TARGET_PERCENT, name


def test_a_wrong_flux_shows_as_its_error_in_the_torque(
    comparison: RealisticDriveComparison,
) -> None:
    """The integrator drives i_q to 2 T* / (3 p phi_assumed): the torque is T* phi / phi_assumed."""
    motor = comparison.motors[0]
    nameplate_error = 100 * (motor.true_phi_pm_weber / motor.nameplate_phi_pm_weber - 1)
    assert abs(nameplate_error) > 10 * TORQUE_TARGET_PERCENT  # the study has a wrong flux
    for run in motor.runs:
        wrong = run.nominal_nameplate_flux
        assert wrong.torque_error_percent == pytest.approx(nameplate_error, abs=0.05)
        assert wrong.hot_torque_error_percent == pytest.approx(nameplate_error, abs=0.05)
        assert run.phi_pm_relative_error is not None
        identified = 100 * (1 / (1 + run.phi_pm_relative_error) - 1)
        assert run.algorithm3.torque_error_percent == pytest.approx(identified, abs=0.05)


def test_the_pi_is_as_fast_as_the_controller_it_is_compared_with(
    comparison: RealisticDriveComparison,
) -> None:
    """Matched on the identified model, the two loops are about equally fast on the true one."""
    for run in comparison.runs():
        tuned, pi = (
            run.selftune.bandwidth_rad_per_second,
            run.industrial_pi.bandwidth_rad_per_second,
        )
        assert tuned is not None and pi is not None
        assert 0.8 <= pi / tuned <= 1.25
        assert run.industrial_w_c_rad_per_second is not None
        assert run.industrial_w_c_rad_per_second < tuned  # the delay makes a PI faster than w_c
        assert run.fitted_L_s_relative_error is not None
        assert abs(run.fitted_L_s_relative_error) < 0.1


def test_targets_and_markdown(comparison: RealisticDriveComparison) -> None:
    targets = comparison.targets()
    assert [target.name_text for target in targets] == [
        "torque error, integral action",
        "excess cost",
        "flux",
    ]
    for target in targets:
        assert target.met in (True, False, None) and target.value_text and target.why_text
    lines = markdown_realistic_drive(comparison)
    text = "\n".join(lines)
    assert lines[0].startswith("## ")
    for title, _ in CONTROLLER_KNOWLEDGE.values():
        assert f"| {title} |" in text
    assert text.count("**met**") + text.count("**MISSED**") + text.count("**not measured**") == 3


def test_the_results_are_json(comparison: RealisticDriveComparison) -> None:
    document = finite_or_null(to_jsonable(dataclasses.asdict(comparison)))
    again = json.loads(json.dumps(document, allow_nan=False))
    assert again["motors"][0]["runs"][0]["selftune"]["data_seconds"] == pytest.approx(0.1)


def test_the_motors_are_drawn_reproducibly() -> None:
    three = drive_cases(3, DC_VOLTAGE)
    assert drive_cases(3, DC_VOLTAGE) == three
    assert drive_cases(1, DC_VOLTAGE) == three[:1]
    assert three[0].nameplate.p * three[0].speed >= 1000.0
    assert len({case.nameplate for case in three}) == 3


def _case(speed: float = 100.0) -> DriveCase:
    motor = SPMSM(R_s=0.5, L_s=4e-3, phi_pm=0.1, p=4)
    return DriveCase("test", motor, motor, speed, 2.0)


def test_a_pi_without_delay_has_the_bandwidth_w_c() -> None:
    """k_p = w_c L, k_i = w_c R with exact decoupling: the loop is w_c / (s + w_c)."""
    case = _case()
    h, w_c = 1e-7, 1000.0
    Ad, Bd, _ = case.nameplate.sampled_plant(case.speed, h, "rotor")
    law = pi_law(case.nameplate.R_s, case.nameplate.L_s, w_c, case, case.nameplate.phi_pm, h)
    bandwidth = current_bandwidth((Ad, Bd), law, h)
    assert bandwidth == pytest.approx(w_c, rel=1e-3)


def test_matched_pi_reaches_the_bandwidth_asked_for() -> None:
    case = _case(speed=250.0)
    h = 1e-4
    Ad, Bd, _ = case.nameplate.sampled_plant(case.speed, h, "stationary")
    matched = matched_pi((Ad, Bd), 0.5, 4e-3, 3000.0, case, 0.1, h)
    assert matched is not None
    law, w_c = matched
    assert current_bandwidth((Ad, Bd), law, h) == pytest.approx(3000.0, rel=1e-6)
    assert w_c < 3000.0
    # an unstable loop has no bandwidth
    assert current_bandwidth((Ad, Bd), pi_law(0.5, 4e-3, 4e4, case, 0.1, h), h) is None
    assert np.isfinite(w_c)
