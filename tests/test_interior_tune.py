"""``selftune tune`` of an interior PM motor on the realistic drive: identify R_s, L_d,
L_q and the flux, design the digital optimum, run MTPA of the identified motor, and
check the torque and the law against the truth."""

from __future__ import annotations

import json

import numpy as np
import pytest

from selftune.cli import main
from selftune.config import load_motor_config
from selftune.model import IPMSM, solve_digital_regulation
from selftune.report import LEARN_REPORT_FILES, report_files
from selftune.report._digital_evaluation import true_motor

DRIVE = """
[drive]
input_delay = 1
switching_frequency = 10000.0
pwm = "carrier"
dead_time = 3.7e-7
dc_voltage = {dc}
current_noise = 0.01
adc_bits = 12
adc_range = 50.0
temperature_rise = 20.0
"""


def _file(tmp_path, motor: str, speed: float, torque: float, dc: float = 540.0) -> str:  # type: ignore[no-untyped-def]
    path = tmp_path / "motor.toml"
    path.write_text(
        f"[motor]\n{motor}\n[operating_point]\nspeed = {speed}\ntorque = {torque}\n"
        "[learning]\nintegral_action = true\n" + DRIVE.format(dc=dc)
    )
    return str(path)


@pytest.mark.parametrize(
    ("motor", "speed", "torque", "dc"),
    [
        ("R_s = 0.2\nL_d = 2e-3\nL_q = 5e-3\nphi_pm = 0.1\np = 4", 100.0, 5.0, 540.0),
        ("R_s = 1.5\nL_d = 0.02\nL_q = 0.05\nphi_pm = 0.3\np = 3", 60.0, 8.0, 540.0),
    ],
)
def test_interior_motor_is_commissioned_within_its_errors(  # type: ignore[no-untyped-def]
    tmp_path, capsys, motor: str, speed: float, torque: float, dc: float
) -> None:
    """0.5 s of carrier-PWM data with 2 V of dead time, noise, ADC and a 20 K warmer motor: the
    identified parameters within 4 standard errors of the heated truth and L_d, L_q, the
    flux within 0.5%; the MTPA torque within 0.5% of T*; K within 4 of its standard
    errors of the true loop's digital optimum, recomputed here from the JSON alone."""
    path = _file(tmp_path, motor, speed, torque, dc)
    out = tmp_path / "result.json"
    # seed 2: of 4 seeds x 4 motors (25 uH-100 mH) 2 logs were refused by the consistency
    # test before its refit on the model's own dead-time signs, the rest learned as here
    report = tmp_path / "report"
    assert main(["tune", "--motor", path, "--json", str(out), "--seed", "2",
                 "--report", str(report)]) == 0  # fmt: skip
    printed = capsys.readouterr().out
    assert "Interior PM motor commissioned" in printed
    assert sorted(p.name for p in report.iterdir()) == sorted(LEARN_REPORT_FILES)
    assert "Interior PM motor commissioned" in (report / "report.html").read_text()
    document = json.loads(out.read_text())
    config = load_motor_config(path)
    assert isinstance(config.motor, IPMSM) and config.drive is not None
    truth = true_motor(config.motor, config.drive)
    identified = document["identified"]
    for name in ("R_s", "L_d", "L_q", "phi_pm"):
        value, se, true = identified[name], identified[f"{name}_se"], getattr(truth, name)
        assert abs(value - true) <= 4.0 * se, (name, value, true, se)
        if name != "R_s":
            assert abs(value - true) <= 5e-3 * true, (name, value, true)
    assert abs(document["steady_torque_error"]) <= 5e-3
    # the optimum of the stated problem from the file alone (motor, drive, cost, h, delay)
    h, cost = document["h"], document["cost"]
    motor_document = document["motor"]
    file_motor = IPMSM(**{key: motor_document[key] for key in ("R_s", "L_d", "L_q", "phi_pm", "p")})
    assert file_motor == config.motor
    optimum = solve_digital_regulation(
        truth.regulation_problem(speed), np.array(cost["Q"]), np.array(cost["R"]), h,
        input_delay=document["input_delay"], integral_weight=np.array(cost["Q_i"]),
        plant=truth.sampled_plant(speed, h, "stationary"),
    )  # fmt: skip
    K = np.array(document["control_law"]["K"])
    K_se = document["quality"]["K_relative_se"]
    error = np.linalg.norm(K - optimum.law.K) / np.linalg.norm(optimum.law.K)
    assert error <= 4.0 * K_se + 1e-9, (error, K_se)


def test_interior_tune_asks_for_a_drive_and_the_right_options(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    path = tmp_path / "motor.toml"
    path.write_text("[motor]\nR_s = 0.2\nL_d = 2e-3\nL_q = 5e-3\nphi_pm = 0.1\np = 4\n")
    assert main(["tune", "--motor", str(path)]) == 2
    assert "add a [drive] table" in capsys.readouterr().err
    drive_file = _file(tmp_path, "R_s = 0.2\nL_d = 2e-3\nL_q = 5e-3\nphi_pm = 0.1\np = 4", 100, 5)
    assert main(["tune", "--motor", drive_file, "--algorithm", "2"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--algorithm: an interior PM motor" in err[0]


def test_an_exact_drive_is_commissioned_exactly(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    """A [drive] table with no noise, dead time, ADC or heating (the simulator's exact
    drive) gives the motor to the rounding. Its one-step residuals are the rounding's, with
    the log's angle or without: the angle's check refused it before 2026-11-26 ("theta
    explains the data worse than no angle at all", 3629% above)."""
    path = tmp_path / "motor.toml"
    path.write_text(
        "[motor]\nR_s = 0.2\nL_d = 2e-3\nL_q = 5e-3\nphi_pm = 0.1\np = 4\n"
        "[operating_point]\nspeed = 100.0\ntorque = 5.0\n[learning]\nintegral_action = true\n"
        "[drive]\nswitching_frequency = 10000.0\ninput_delay = 1\ndc_voltage = 540.0\n"
    )
    out = tmp_path / "result.json"
    assert main(["tune", "--motor", str(path), "--json", str(out)]) == 0
    identified = json.loads(out.read_text())["identified"]
    for name, value in (("R_s", 0.2), ("L_d", 2e-3), ("L_q", 5e-3), ("phi_pm", 0.1)):
        assert identified[name] == pytest.approx(value, rel=1e-9), name


def test_tune_schedules_the_identified_motor_never_the_files(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    """An interior motor's schedule is designed on the motor its tune identified (the
    JSON says so and states it), and its report draws it (a surface motor's:
    tests/test_ramp_learning.py)."""
    motor = "R_s = 0.2\nL_d = 2e-3\nL_q = 5e-3\nphi_pm = 0.1\np = 4"
    path = _file(tmp_path, motor, 100.0, 5.0)
    with open(path, "a") as handle:
        handle.write("[schedule]\nspeed_range = [20.0, 200.0]\n")
    out, report = tmp_path / "result.json", tmp_path / "report"
    assert main(["tune", "--motor", path, "--json", str(out), "--seed", "2",
                 "--report", str(report)]) == 0  # fmt: skip
    files = report_files(scheduled=True)
    assert sorted(p.name for p in report.iterdir()) == sorted(files)
    assert f"wrote {report}/ ({', '.join(files)})" in capsys.readouterr().out
    assert '<figure id="schedule">' in (report / "report.html").read_text()
    document = json.loads(out.read_text())
    design = document["schedule_design"]
    assert design["designed_on"] == "the identified motor"
    for name in ("R_s", "L_d", "L_q", "phi_pm"):
        assert design["motor"][name] == document["identified"][name]
    assert design["motor"]["L_d"] != 2e-3  # identified, not the file's


def test_the_online_tuner_refuses_an_interior_motor_in_one_line(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    path = _file(tmp_path, "R_s = 0.2\nL_d = 2e-3\nL_q = 5e-3\nphi_pm = 0.1\np = 4", 100, 5)
    profile = tmp_path / "profile.toml"
    profile.write_text(
        "[online]\nduration = 1.0\n[[online.profile]]\ntime = 0.0\nR_s = 1.0\nphi_pm = 1.0\n"
        "[[online.profile]]\ntime = 1.0\nR_s = 1.1\nphi_pm = 1.0\n"
    )
    assert main(["tune", "--motor", path, "--online", str(profile)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "has no online tuner yet" in err[0]
