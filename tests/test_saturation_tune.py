"""``selftune tune`` of a motor file with a ``[saturation]`` table: the simulated motor
saturates, and the law is scheduled over the q-axis current it is learned at.

The JSON states the whole problem, so the current schedule is recomputed here from the
file alone (the levels' identified incremental models, the loop and the cost); the truth
(the analytic saturation's incremental inductances at each level's mean current) is the
simulator's, which the learner never sees. A bad table is one line naming its key."""

from __future__ import annotations

import json
import re
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import selftune.tuning._saturation as saturation_module
from selftune.bench import SaturationCase, SaturationStudy, markdown_saturation
from selftune.cli import main
from selftune.config import MotorConfig, load_motor_config
from selftune.errors import ModelMissesEffect
from selftune.learn import IncrementalStructure
from selftune.model import (
    IPMSM,
    SPMSM,
    RegulationProblem,
    design_current_schedule,
    design_speed_current_schedule,
)
from selftune.report import evaluate_current_schedule, report_files
from selftune.report._saturation_report import current_document, current_lines
from selftune.sim import DriveSettings, Saturation, SaturationModel
from selftune.tuning import TuningSettings, commission_over_current, tuning_settings
from selftune.tuning._resistance import (
    disagreeing_levels,
    kept_levels,
    left_out_text,
    small_levels,
)
from selftune.tuning._saturation import LEVEL_ATTEMPTS, incremental_theta

MOTOR = """[motor]
R_s = 0.3
L_d = 3e-3
L_q = 7e-3
phi_pm = 0.12
p = 3
[operating_point]
speed = 120.0
torque = 6.0
[learning]
integral_action = true
"""

DRIVE = """[drive]
switching_frequency = 10000.0
input_delay = 1
dc_voltage = 400.0
pwm = "average"
dead_time = 5e-7
current_noise = 0.01
adc_bits = 12
adc_range = 50.0
"""

SATURATION = """[saturation]
i_sat = 6.0
drop = 0.15
cross = 0.1
"""


@pytest.mark.slow
def test_tune_schedules_a_saturating_motor_over_its_current(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The schedule within the issue's 2% of the true pointwise optimum from 10% to 100% of
    rated current; every level's identified L_dd, L_qq within 4 standard errors of the
    truth at its mean current; the tables recomputed from the JSON; the report draws the
    schedule over the current."""
    path = tmp_path / "motor.toml"
    path.write_text(MOTOR + DRIVE + SATURATION)
    out, report = tmp_path / "out.json", tmp_path / "report"
    assert main(["tune", "--motor", str(path), "--json", str(out), "--report", str(report)]) == 0
    assert "Saturating PM motor commissioned over its load" in capsys.readouterr().out
    assert sorted(p.name for p in report.iterdir()) == sorted(report_files(scheduled=True))
    assert '<figure id="schedule">' in (report / "report.html").read_text()
    document = json.loads(out.read_text())
    assert float(np.max(document["true_excess"]["schedule"])) <= 0.02
    config = load_motor_config(str(path))
    assert config.saturation is not None
    design = document["current_schedule_design"]
    levels = design["levels"]
    check_inductances(levels, config.saturation, config.motor, "share")
    structure = IncrementalStructure(
        config.motor.p * config.speed, document["h"], False,
        document["drive"]["settings"]["voltage_hold"],
    )  # fmt: skip
    check_recomputed(document, levels, structure, document["cost"], document["input_delay"])


@pytest.mark.slow
def test_tune_schedules_a_saturating_motor_over_speed_and_current(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """With a [schedule] the law is scheduled over speed and i_q* together: within the
    issue's 2% of the true pointwise optimum at 12 speeds over 5-100% of the range's top
    times 10-100% of rated current, where the schedule over i_q* alone (designed at the
    operating speed) is worse at the ends; the table recomputed from the JSON alone. The
    file is examples/saturating_motor.toml (this module's motor, drive and saturation,
    with speed_range = [12, 240] rad/s), run as docs/saturation.md runs it."""
    path = Path(__file__).resolve().parents[1] / "examples" / "saturating_motor.toml"
    config = load_motor_config(str(path))
    assert config.schedule is not None and config.schedule.speeds == (12.0, 240.0)
    out, report = tmp_path / "out.json", tmp_path / "report"
    assert main(["tune", "--motor", str(path), "--json", str(out), "--report", str(report)]) == 0
    assert "Speed and current schedule: the digital optimum at" in capsys.readouterr().out
    assert sorted(p.name for p in report.iterdir()) == sorted(report_files(scheduled=True))
    document = json.loads(out.read_text())
    true = document["true_excess"]
    both = np.array(true["speed_current_schedule"])
    alone = np.array(true["current_schedule_over_speed"])
    assert both.shape == alone.shape == (12, len(true["i_q"]))
    assert float(np.max(both)) <= 0.02
    assert float(np.max(alone)) > 10 * float(np.max(both))
    levels = document["current_schedule_design"]["levels"]
    currents = np.array([level["i_q"] for level in levels])
    thetas = np.array([level["theta"] for level in levels])
    structure = IncrementalStructure(
        0.0, document["h"], False, document["drive"]["settings"]["voltage_hold"]
    )
    F = np.array(document["control_law"]["F"])

    def plant(current: float, speed: float):  # type: ignore[no-untyped-def]
        theta = np.array([np.interp(current, currents, column) for column in thetas.T])
        at = replace(structure, electrical_speed=speed)
        A, B, D = at.continuous(theta)
        problem = RegulationProblem(A=A, B=B, C=np.eye(2), D=D, E=np.zeros((3, 3)), F=F)
        return problem, at(theta)

    cost = document["cost"]
    expected = design_speed_current_schedule(
        plant, currents, [3 * 12.0, 3 * 240.0], np.array(cost["Q"]), np.array(cost["R"]),
        document["h"], input_delay=document["input_delay"], integral_weight=np.array(cost["Q_i"]),
    )  # fmt: skip
    schedule = document["speed_current_schedule"]
    np.testing.assert_allclose(schedule["current"], expected.schedule.current)
    np.testing.assert_allclose(schedule["electrical_speed"], expected.schedule.electrical_speed)
    for name in ("K", "K_i", "U", "X"):
        np.testing.assert_allclose(
            schedule[name], expected.schedule.table(name), rtol=1e-9, atol=1e-12, err_msg=name
        )


def check_inductances(
    levels: list[dict[str, Any]], saturation: Saturation, motor: IPMSM | SPMSM, name: str
) -> None:
    """Every level's identified L_dd, L_qq within 4 standard errors of the truth at its
    mean current (a failure names the level by its key ``name``)."""
    for level in levels:
        truth = incremental_theta(
            saturation, motor.R_s, np.array(level["mean_current"]), motor.phi_pm
        )
        for k in (1, 2):
            error = level["theta"][k] - truth[k]
            assert abs(error) <= 4.0 * level["theta_se"][k], (level[name], k)


def saturating_case(
    motor: IPMSM, drive: DriveSettings, speed: float, torque: float, seed: int, share: float,
    drop: float,
) -> tuple[TuningSettings, SaturationModel]:  # fmt: skip
    """The settings of a commissioning at ``speed`` (rad/s) with rated ``torque`` (N m) and
    integral action, and the motor's saturation at ``share`` of its rated q current with
    ``drop`` (cross-saturation 0.1)."""
    rated = float(motor.current_reference(torque)[1])
    saturation = SaturationModel.of(motor, i_sat=share * rated, drop=drop, cross=0.1)
    config = MotorConfig(
        motor=motor, speed=speed, torque=torque, drive=drive, drive_h=1e-4,
        learning={"integral_action": True}, source=f"{type(motor).__name__} saturating",
        saturation=saturation,
    )  # fmt: skip
    return tuning_settings(config, seed), saturation


def check_recomputed(
    document: dict[str, Any],
    levels: list[dict[str, Any]],
    structure: IncrementalStructure,
    cost: dict[str, Any],
    input_delay: int,
) -> None:
    """The JSON's ``current_schedule`` is the design on its levels' identified models
    (interpolated in ``i_q*``), the structure's loop, the cost and the delay the file
    states: recomputed here from the file alone."""
    currents = np.array([level["i_q"] for level in levels])
    thetas = np.array([level["theta"] for level in levels])
    F = np.array(document["control_law"]["F"])

    def plant(current: float):  # type: ignore[no-untyped-def]
        theta = np.array([np.interp(current, currents, column) for column in thetas.T])
        A, B, D = structure.continuous(theta)
        problem = RegulationProblem(A=A, B=B, C=np.eye(2), D=D, E=np.zeros((3, 3)), F=F)
        return problem, structure(theta)

    expected = design_current_schedule(
        plant, currents, np.array(cost["Q"]), np.array(cost["R"]), structure.h,
        input_delay=input_delay, integral_weight=np.array(cost["Q_i"]),
    )  # fmt: skip
    schedule = document["current_schedule"]
    np.testing.assert_allclose(schedule["current"], expected.schedule.current)
    for name in ("K", "K_i", "U", "X"):
        np.testing.assert_allclose(
            schedule[name], expected.schedule.table(name), rtol=1e-9, atol=1e-12, err_msg=name
        )


@pytest.mark.parametrize(
    ("text", "said"),
    [
        (MOTOR + SATURATION, "[saturation]: a saturating motor runs on a realistic drive"),
        (
            MOTOR + DRIVE + "temperature_rise = 20.0\n" + SATURATION,
            "[saturation]: [drive] temperature_rise = 20 K: a heated saturating motor",
        ),
        (MOTOR + DRIVE + SATURATION.replace("0.15", "1.5"), "[saturation] drop: expected a share"),
        (MOTOR + DRIVE + SATURATION.replace("6.0", "-6.0"), "[saturation] i_sat: must be positive"),
        (MOTOR + DRIVE + "[saturation]\ndrop = 0.2\n", "[saturation] i_sat: "),
        (  # a knee at a microampere: no iron's, and a simulation that would not end
            MOTOR + DRIVE + SATURATION.replace("6.0", "1e-6"),
            "[saturation] i_sat: 1e-06 A is below 1% of the motor's characteristic current "
            "phi_pm / L_d = 40 A",
        ),
        (MOTOR + DRIVE + SATURATION + "knee = 1.0\n", "[saturation] knee"),
    ],
)
def test_a_bad_saturation_table_is_one_line_naming_the_key(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, said: str
) -> None:
    path = tmp_path / "motor.toml"
    path.write_text(text)
    assert main(["tune", "--motor", str(path)]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert captured.out == "" and len(err) == 1 and said in err[0], err


def test_the_online_tuner_refuses_a_saturating_motor_and_solve_says_whose_optimum(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path, profile = tmp_path / "motor.toml", tmp_path / "profile.toml"
    path.write_text(MOTOR.replace("L_d = 3e-3\nL_q = 7e-3", "L_s = 5e-3") + DRIVE + SATURATION)
    profile.write_text("[online]\nduration = 1.0\n")
    assert main(["tune", "--motor", str(path), "--online", str(profile)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "[saturation]: the online tuner follows a surface motor's" in err[0]
    assert main(["solve", "--motor", str(path)]) == 0
    assert "this is the optimum of the unsaturated [motor]" in capsys.readouterr().out


def _flux_map_table(i_d: np.ndarray, i_q: np.ndarray) -> str:
    """A ``[saturation]`` flux map: the analytic table's model sampled on the grid (A)."""
    from selftune.sim import FluxMap, SaturationModel

    config_motor = load_motor_config_text(MOTOR + DRIVE).motor
    table = FluxMap.sampled(SaturationModel.of(config_motor, i_sat=6.0, drop=0.15, cross=0.1),
                            i_d, i_q)  # fmt: skip

    def rows(values: np.ndarray) -> str:
        return "[" + ", ".join("[" + ", ".join(f"{v!r}" for v in row) + "]" for row in values) + "]"

    return (
        "[saturation]\n"
        f"i_d = {[float(v) for v in i_d]}\ni_q = {[float(v) for v in i_q]}\n"
        f"psi_d = {rows(table.psi_d.tolist())}\npsi_q = {rows(table.psi_q.tolist())}\n"
    )


def load_motor_config_text(text: str):  # type: ignore[no-untyped-def]
    """The motor file of ``text``."""
    import tempfile

    with tempfile.TemporaryDirectory() as directory:
        path = Path(directory) / "motor.toml"
        path.write_text(text)
        return load_motor_config(str(path))


#: The flux map's grid, A: the commissioning's currents stay inside it.
GRID_D = np.linspace(-40.0, 20.0, 9)
GRID_Q = np.linspace(-40.0, 40.0, 11)


def test_a_flux_map_table_is_the_simulated_motors_saturation() -> None:
    """A flux map in ``[saturation]`` is loaded as that map: its grid, and the incremental
    inductances of the map built from the same numbers."""
    from selftune.sim import FluxMap, SaturationModel

    config = load_motor_config_text(MOTOR + DRIVE + _flux_map_table(GRID_D, GRID_Q))
    assert isinstance(config.saturation, FluxMap)
    np.testing.assert_array_equal(config.saturation.i_q, GRID_Q)
    model = SaturationModel.of(config.motor, i_sat=6.0, drop=0.15, cross=0.1)
    direct = FluxMap.sampled(model, GRID_D, GRID_Q)
    for current in ([-3.0, 7.5], [0.0, 0.0], [-12.0, 25.0]):
        np.testing.assert_array_equal(
            config.saturation.incremental(*current), direct.incremental(*current)
        )


@pytest.mark.parametrize(
    ("change", "said"),
    [
        (lambda text: text + "i_sat = 6.0\n", "[saturation] i_sat: the analytic model's keys"),
        (
            lambda text: text.replace("\ni_d = [", "\ni_d = [-50.0, "),
            "[saturation] psi_d: expected shape (10, 11)",
        ),
        (
            lambda text: text.replace("\ni_q = [", "\ni_q = [50.0, "),
            "[saturation] i_q: expected finite, strictly increasing",
        ),
        (lambda text: text.replace("psi_q", "psi_x"), "[saturation] psi_x"),
        (
            lambda text: re.sub(r"\ni_d = \[[^\]]*\]", '\ni_d = "a"', text),
            "[saturation] i_d: must be a list of numbers",
        ),
    ],
)
def test_a_bad_flux_map_is_one_line_naming_the_key(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], change: object, said: str
) -> None:
    path = tmp_path / "motor.toml"
    path.write_text(MOTOR + DRIVE + change(_flux_map_table(GRID_D, GRID_Q)))  # type: ignore[operator]
    assert main(["tune", "--motor", str(path)]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert captured.out == "" and len(err) == 1 and said in err[0], err


@pytest.mark.slow
def test_tune_schedules_a_motor_of_a_flux_map_over_its_current(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The same motor as a flux map: the schedule within the issue's 2% of the map's
    pointwise optimum, and the JSON states the map."""
    path = tmp_path / "motor.toml"
    path.write_text(MOTOR + DRIVE + _flux_map_table(GRID_D, GRID_Q))
    out = tmp_path / "out.json"
    assert main(["tune", "--motor", str(path), "--json", str(out)]) == 0
    assert "Saturating PM motor commissioned over its load" in capsys.readouterr().out
    document = json.loads(out.read_text())
    assert float(np.max(document["true_excess"]["schedule"])) <= 0.02
    np.testing.assert_array_equal(document["saturation"]["i_d"], GRID_D)
    assert np.array(document["saturation"]["psi_q"]).shape == (GRID_D.size, GRID_Q.size)


def test_a_flux_map_the_currents_leave_is_one_line_naming_its_grid(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The commissioning drives the currents beyond a map of +-5 A: one line, exit 2."""
    small = np.linspace(-5.0, 5.0, 5)
    path = tmp_path / "motor.toml"
    path.write_text(MOTOR + DRIVE + _flux_map_table(small, small))
    assert main(["tune", "--motor", str(path)]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert captured.out == "" and len(err) == 1, err
    assert "is outside the flux map's grid [-5, 5] x [-5, 5] A" in err[0], err


def test_a_level_whose_resistance_disagrees_with_the_highest_is_left_out() -> None:
    """R_s does not depend on the current: a level 25% and 5 standard errors from the
    highest level's R_s is left out (the 0.29 A motor's 31 ohm at 10% of rated current,
    against 0.93), one within either bound is kept, and the sentence names each."""
    thetas = np.zeros((5, 6))
    errors = np.full((5, 6), 1e-3)
    thetas[:, 0] = [30.97, 1.5, 0.95, 0.2, 0.93]
    errors[:, 0] = [1.6, 0.05, 0.01, 0.2, 0.5]
    # 30.97: 18.8 se and far beyond 25%; 1.5: 1.14 se only; 0.95: 2% only; 0.2: 1.3 se
    assert disagreeing_levels(thetas, errors) == [0]
    errors[1, 0] = 0.01  # now 1.14 over sqrt(0.01^2 + 0.5^2): still within 5 se
    assert disagreeing_levels(thetas, errors) == [0]
    errors[:, 0] = 0.01
    assert disagreeing_levels(thetas, errors) == [0, 1, 3]  # 0.95 stays: within 25%
    text = left_out_text(["10%", "40%", "70%", "85%", "100%"], thetas, errors, [0, 1, 3])
    assert "10%: 30.97 ohm" in text and "85%: 0.2 ohm" in text and "0.93 ohm" in text


@pytest.mark.slow
def test_a_small_current_motor_leaves_out_the_levels_the_dead_time_misleads() -> None:
    """A motor rated 0.29 A on 540 V (2 V of dead time, 24 mA ADC steps): at the lowest
    levels the fit takes the dead time near zero current for resistance (tens of ohms
    against 0.8). Those levels are left out, saying so, and the schedule on the others
    (its first law held below them, as the firmware does) is within the issue's 2% of the
    true pointwise optimum from 10% to 100% of rated current; with them it was 78% off at
    10% (docs/saturation.md)."""
    motor = IPMSM(R_s=0.8, L_d=25e-3, L_q=75e-3, phi_pm=0.26, p=2)
    drive = replace(DriveSettings.hardware_like(dc_voltage=540.0), pwm="average")
    settings, saturation = saturating_case(motor, drive, 105.0, 0.23, 113, 0.57, 0.25)
    result = commission_over_current(motor, saturation, settings, drive, seed=113)
    assert result.left_out and "R_s far from" in result.left_out_text
    assert all(level.theta[0] > 1.25 * result.levels[-1].theta[0] for level in result.left_out)
    evaluation = evaluate_current_schedule(result, motor, saturation, settings)
    assert float(np.max(evaluation.schedule_excess)) <= 0.02


def test_levels_far_from_the_nameplate_resistance_are_left_out_or_refused() -> None:
    """With a nameplate, a level whose R_s is beyond twice or half of it, by enough to move
    the sampled plant's pole 1%, is left out too (a 0.74 A motor's 10% level found 2.19 ohm
    against 0.513, within 5 standard errors of the highest level's); where the highest
    level is among them (a 0.21 A motor: every level 7-21 times the nameplate's 0.186 ohm),
    there is no schedule, and the refusal says why; a gap that moves the pole 0.4% counts
    for nothing. Without a nameplate (learning from logs) only the levels' agreement
    counts."""
    names = ["10%", "40%", "70%", "100%"]
    thetas = np.zeros((4, 6))
    errors = np.zeros((4, 6))
    thetas[:, 0] = [2.19, 0.52, 0.50, 0.51]
    thetas[:, 1:3] = 3.9e-3  # H: at 10 kHz the 10% level's R_s moves the pole by 4.3%
    errors[:, 0] = [0.4, 0.01, 0.01, 0.01]
    assert kept_levels(names, thetas, errors) == ([0, 1, 2, 3], "")
    kept, why = kept_levels(names, thetas, errors, nameplate=0.513, h=1e-4)
    assert kept == [1, 2, 3] and "10%: 2.19 ohm" in why and "nameplate's 0.513 ohm" in why
    thetas[:, 0] = [3.86, 3.39, 2.48, 1.29]
    thetas[:, 1:3] = 4.1e-3
    errors[:, 0] = [0.77, 0.78, 0.85, 0.41]
    assert kept_levels(names, thetas, errors)[0] == [0, 1, 2, 3]
    with pytest.raises(ModelMissesEffect, match="too few levels agree on R_s") as refusal:
        kept_levels(names, thetas, errors, nameplate=0.186, h=1e-4)
    assert "100%: 1.29 ohm" in str(refusal.value)
    assert "[operating_point] torque" not in str(refusal.value)  # not the tuner's levels
    # the tuner's levels: the refusal names the user's torque and the highest current
    small = small_levels(0.21, 0.05)
    with pytest.raises(ModelMissesEffect, match="too few levels agree on R_s") as refusal:
        kept_levels(names, thetas, errors, nameplate=0.186, h=1e-4, small=small)
    assert "its 0.21 A may be too small" in str(refusal.value)
    assert "[operating_point] torque = 0.05 N m" in str(refusal.value)
    # twice the nameplate's R_s on a 40 uH motor moves the pole by 0.4%: kept
    thetas[:, 0] = [3.3e-3, 3.2e-3, 3.3e-3, 3.26e-3]
    thetas[:, 1:3] = 40e-6
    errors[:, 0] = 1e-4
    assert kept_levels(names, thetas, errors, nameplate=1.5e-3, h=1e-4) == ([0, 1, 2, 3], "")


#: The learner of one level, as the module has it.
LEARN_LEVEL = saturation_module.learn_level


def _refusing(monkeypatch: pytest.MonkeyPatch, refused: tuple[float, ...]) -> None:
    """Every log of the levels ``refused`` (shares of rated torque) refused by the learner
    (the others learned as they are)."""

    def learn_level(*args: Any, **kwargs: Any) -> Any:
        if any(abs(args[4] - share) < 1e-9 for share in refused):
            raise ModelMissesEffect(
                "the model cannot explain the data: a test's refusal",
                statistic=2.0, threshold=1.0, causes=("a test",),
            )  # fmt: skip
        return LEARN_LEVEL(*args, **kwargs)

    monkeypatch.setattr(saturation_module, "learn_level", learn_level)


@pytest.mark.slow
def test_a_lowest_level_whose_logs_are_all_refused_is_left_out_saying_so(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Every log of the 10% level refused (as on motors rated under 1 A with a 50 A ADC,
    docs/saturation.md): levels halfway towards the lowest learned (40%) are tried, 25%
    and then 17.5%, the schedule starts at the lowest level learned, the printout and
    the JSON say which level was not learned and why, each of its logs is among the
    refusals, and the first law held below is within the issue's 2% there. A refused
    halfway level is itself halved towards 40%. A refused level above one learned, or
    fewer than two learned, still refuses the commissioning."""
    path = tmp_path / "motor.toml"
    path.write_text(MOTOR + DRIVE + SATURATION)
    config = load_motor_config(str(path))
    assert config.saturation is not None and config.drive is not None
    assert isinstance(config.motor, IPMSM)
    settings = tuning_settings(config, 0)
    _refusing(monkeypatch, (0.1,))
    result = commission_over_current(config.motor, config.saturation, settings, config.drive)
    assert result.unlearned == (0.1,)
    assert [level.share for level in result.levels[:3]] == pytest.approx([0.175, 0.25, 0.4])
    assert [share for share, _ in result.refusals] == [0.1] * LEVEL_ATTEMPTS
    assert "10% not learned, all 3 logs of each refused (the last: the model cannot" in (
        result.left_out_text
    )
    evaluation = evaluate_current_schedule(result, config.motor, config.saturation, settings)
    assert float(np.max(evaluation.schedule_excess)) <= 0.02
    lines = current_lines("motor.toml", result, evaluation, config.drive)
    assert any(line.startswith("  note: levels 10% not learned") for line in lines)
    document = current_document(
        config.motor, config.saturation, settings, result, evaluation, config.drive
    )
    assert document["current_schedule_design"]["unlearned"] == [0.1]
    _refusing(monkeypatch, (0.1, 0.25))
    result = commission_over_current(config.motor, config.saturation, settings, config.drive)
    assert result.unlearned == (0.1, 0.25) and result.levels[0].share == pytest.approx(0.325)
    assert "10%, 25% not learned" in result.left_out_text
    for refused, level in (((0.4,), "40%"), ((0.1, 0.4, 0.7), "70%")):
        _refusing(monkeypatch, refused)
        with pytest.raises(
            ModelMissesEffect,
            match=rf"^the level at {level} of rated torque \(i_q\* = [0-9.]+ A\), all 3 of its "
            "logs refused; the last: the model cannot explain the data: a test's refusal",
        ):
            commission_over_current(config.motor, config.saturation, settings, config.drive)


def test_the_saturation_studys_table_states_its_pwm_and_calibration() -> None:
    """The study's markdown says which PWM it ran on and how many inductance errors fell
    within one standard error (a refused case's none counted)."""
    learned = SaturationCase(
        "1: IPMSM 2/6 mH", 0, "", 29.0, 9, 0, 0.088, 19.9, 16.4, (0.5, -1.5), (0.1, 0.2), 58.0
    )
    refused = replace(learned, seed=1, refusal_text="too little data", z=(), errors_percent=())
    lines = markdown_saturation(SaturationStudy((learned, refused), 99.0, "carrier"))
    assert "on carrier PWM" in lines[2] and "standard error of the truth: 50% of 2" in lines[2]
    assert "refused: too little data" in lines[-1]
