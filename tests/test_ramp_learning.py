"""Learning the motor from a log over several speeds
(:func:`selftune.learn.learn_over_speeds`, :func:`selftune.tuning.commission_ramp`), and
the schedule refused outside the speeds the data cover.

The fit is checked against the truth on hypothesis-drawn motors across the issue's range
(surface and interior, ``L_q / L_d`` up to 3, 25 uH to 100 mH, 2 to 20 pole pairs) from
1 s of a two-speed staircase at 5% and 100% of the rated speed on a drive with a
one-sample delay, 10 mA of noise and the stationary hold (average PWM, no dead time:
the dead-time model's refusals are another matter, measured in bench/_ramp.py): each
parameter within 4 standard errors, and the schedule designed on the identified motor
within 1% of the true motor's pointwise digital optimum at 50 speeds between its grid
speeds.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import Phase, given, settings
from hypothesis import strategies as st

from selftune.bench._interior import drawn_motor
from selftune.cli import main
from selftune.config import MotorConfig, load_learn_config, load_motor_config
from selftune.core import ControlLaw
from selftune.errors import DataFileError, InputError, SelftuneError
from selftune.learn import (
    LearningOptions,
    LearningProblem,
    Trajectory,
    learn_controller,
    learn_over_speeds,
    save_trajectory,
)
from selftune.learn._speeds import MIN_SEGMENT, speed_segments
from selftune.learn.verdict import _quality as verdict_quality
from selftune.model import (
    EXCESS,
    IPMSM,
    SPMSM,
    Motor,
    SpeedSchedule,
    design_schedule,
    excess_over,
)
from selftune.report import report_files
from selftune.report._digital_evaluation import true_motor
from selftune.sim import DriveSettings, constant, ramp_speeds, run_speed_profile
from selftune.tuning import TuningSettings, commission_ramp, tuning_settings

H = 1e-4
MOTOR = IPMSM(R_s=0.2, L_d=2e-3, L_q=5e-3, phi_pm=0.1, p=4)


def staircase_log(speeds: np.ndarray) -> Trajectory:
    """The drive over ``speeds`` (one per sample) under a small proportional law."""
    law = ControlLaw.regulator(
        0.2 * np.diag([MOTOR.L_d, MOTOR.L_q]) / H, np.zeros((2, 3)), np.zeros((2, 3))
    )
    record = run_speed_profile(
        MOTOR, speeds, H, DriveSettings(), law, constant([0.0, 0.0, 0.0]), exploration=None,
        seed=0,
    )  # fmt: skip
    return record.trajectory


def test_a_staircase_is_cut_at_its_speeds() -> None:
    speeds = ramp_speeds(10.0, 100.0, 1500, levels=3)
    segments = speed_segments(staircase_log(speeds))
    assert [(a, b) for a, b, _ in segments] == [(0, 500), (500, 1000), (1000, 1500)]
    np.testing.assert_allclose(
        [speed for _, _, speed in segments], [4 * 10.0, 4 * 55.0, 4 * 100.0], rtol=1e-9
    )


def test_a_speed_that_changes_every_sample_is_refused_saying_why() -> None:
    log = staircase_log(ramp_speeds(10.0, 100.0, 1500))
    with pytest.raises(InputError, match=r"changes every sample.*staircase"):
        speed_segments(log)
    short = ramp_speeds(10.0, 100.0, round(3 * MIN_SEGMENT / H), levels=6)
    with pytest.raises(InputError, match=f"at least {MIN_SEGMENT:g} s"):
        speed_segments(staircase_log(short))
    # a slower ramp's 10 ms blocks stay within the band for 70 ms at a time: they trend
    slow = staircase_log(ramp_speeds(10.0, 12.0, 3000))
    with pytest.raises(InputError, match=r"holds \(within .* without trending\).* \(a ramp\)"):
        speed_segments(slow)
    held = staircase_log(ramp_speeds(10.0, 100.0, 1500, levels=3))
    assert held.angle is not None
    degrees = dataclasses.replace(held, angle=np.degrees(np.angle(np.exp(1j * held.angle))))
    with pytest.raises(InputError, match=r"as an angle in degrees wraps; give it in rad"):
        speed_segments(degrees)


def test_speeds_the_data_do_not_cover_are_refused_by_name() -> None:
    Q, R = 1e3 * np.eye(2), np.eye(2)
    covered = (4 * 5.0, 4 * 100.0)  # electrical
    design = design_schedule(MOTOR, [5.0, 100.0], Q, R, H, covered=covered)
    assert design.schedule.covered == covered
    with pytest.raises(InputError, match=r"speeds: 4, 600 rad/s \(electrical\) outside the "
                       r"speeds the data cover, 20 to 400 rad/s"):  # fmt: skip
        design_schedule(MOTOR, [1.0, 50.0, 150.0], Q, R, H, covered=covered)


@st.composite
def drawn_motors(draw: st.DrawFn) -> tuple[Motor, float, float]:
    """A motor across the issue's range, its rated mechanical speed and torque."""
    L_d = 10 ** draw(st.floats(np.log10(25e-6), -1.0))
    ratio = draw(st.sampled_from([1.0, draw(st.floats(1.2, 3.0))]))
    tau = 10 ** draw(st.floats(-3.0, -1.0))  # L / R, s
    p = draw(st.integers(2, 20))
    w_e = 10 ** draw(st.floats(np.log10(300.0), np.log10(2000.0)))  # rated, rad/s
    phi = 60.0 / w_e  # 60 V of back-EMF at rated speed on a 540 V bus
    current = 0.5 * np.sqrt(1e-3 / L_d)  # from 0.5 A at 1 mH: the noise's 10 mA small
    if ratio == 1.0:
        motor: Motor = SPMSM(R_s=L_d / tau, L_s=L_d, phi_pm=phi, p=p)
    else:
        motor = IPMSM(R_s=L_d / tau, L_d=L_d, L_q=ratio * L_d, phi_pm=phi, p=p)
    return motor, w_e / p, 1.5 * p * phi * current


DRIVE = DriveSettings(current_noise=0.01, dc_voltage=540.0)


# a warning would make a command refuse the log as numerically meaningless (core._numerics):
# an unstable trial step of the fit overflowed here and warned
@pytest.mark.filterwarnings("error::RuntimeWarning")
@settings(max_examples=4, deadline=None, phases=[Phase.explicit, Phase.reuse, Phase.generate])
@given(drawn_motors(), st.integers(0, 1000))
def test_a_two_speed_log_gives_the_motor_and_its_schedule(
    drawn: tuple[Motor, float, float], seed: int
) -> None:
    motor, speed, torque = drawn
    config = MotorConfig(
        motor=motor, speed=speed, torque=torque, drive=DRIVE, drive_h=H,
        learning={"integral_action": True}, source="drawn",
    )  # fmt: skip
    tuning = tuning_settings(config, seed)  # (no shrinking: an example takes seconds)
    speeds = (0.05 * speed, speed)
    result = commission_ramp(motor, tuning, DRIVE, speeds, seed=seed, levels=2)
    np.testing.assert_allclose(result.covered, np.array(speeds) * motor.p, rtol=1e-9)
    # the back-EMF and the cross-coupling fed forward at each speed: the currents follow
    # their references on average at the top speed (under K0 alone the 60 V of back-EMF
    # drove a mean offset of 60 V / (R_s + K0), up to thousands of amperes), within a
    # fifth of the steps' scale and 4 standard errors of the mean (from 50 batch means:
    # the exploration's currents, tens of amperes on 25 uH, average out slowly)
    scale = 2.0 * torque / (3.0 * motor.p * motor.phi_pm)
    top = result.record_speeds == speeds[1]
    log = result.log
    assert log.w is not None
    references = log.w[:-1][top] @ -motor.regulation_problem(speeds[1]).F.T
    batches = np.array_split(log.x[:-1][top] - references, 50)
    means = np.array([batch.mean(axis=0) for batch in batches])
    offset, spread = means.mean(axis=0), means.std(axis=0, ddof=1) / np.sqrt(len(batches))
    assert np.all(np.abs(offset) <= 0.2 * scale + 4.0 * spread), (offset, spread, scale)
    for name, se in result.standard_errors.items():
        error = getattr(result.motor, name) - getattr(motor, name)
        assert abs(error) <= 4.0 * se, (name, error, se)
    designs = [
        design_schedule(
            model,
            speeds,
            tuning.Q,
            tuning.R,
            H,
            integral_weight=result.integral_weight,
            hold=DRIVE.voltage_hold,
        )
        for model in (result.motor, motor)
    ]
    assert float(np.max(designs[1].excess_of(designs[0].schedule))) <= EXCESS


def learn_config(path: Path, tuning: TuningSettings, extra: str) -> Path:
    """A learning configuration of the interior experiment's log: identify-then-design
    with the interior structure, digital target, one sample of delay, integral action."""
    F = MOTOR.regulation_problem(1.0).F
    rows = lambda M: "[" + ", ".join(str(list(map(float, row))) for row in M) + "]"  # noqa: E731
    path.write_text(
        f"""[cost]
Q = {rows(tuning.Q)}
R = {rows(tuning.R)}
[policy]
K0 = {rows(tuning.K0)}
[regulation]
C = [[1.0, 0.0], [0.0, 1.0]]
E = {rows(np.zeros((3, 3)))}
F = {rows(F)}
[learning]
target = "digital"
method = "identify"
structure = "ipmsm"
input_delay = 1
integral_action = true
{extra}"""
    )
    return path


def two_speed_log(tmp_path: Path, speed: float) -> tuple[TuningSettings, Any, Path]:
    """The interior motor's two-speed ramp log (5 rad/s and ``speed``, 1 s, seed 3) of
    ``commission_ramp``, its settings and the log saved as NPZ."""
    config = MotorConfig(
        motor=MOTOR, speed=speed, torque=5.0, drive=DRIVE, drive_h=H,
        learning={"integral_action": True}, source="motor",
    )  # fmt: skip
    tuning = tuning_settings(config, 3)
    result = commission_ramp(MOTOR, tuning, DRIVE, (5.0, speed), seed=3, levels=2)
    log = tmp_path / "ramp.npz"
    save_trajectory(result.log, log)
    return tuning, result, log


def test_learn_writes_the_schedule_of_the_motor_learned_over_speeds(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``selftune learn`` on a two-speed log with a [schedule] table: the JSON's schedule
    is the one designed on the motor it states (recomputed from the file), that motor is
    the truth within 4 of the standard errors ``commission_ramp`` gives on the same log,
    the schedule covers the log's speeds and the report draws it; a speed beyond them is
    refused, named."""
    speed = 100.0
    tuning, result, log = two_speed_log(tmp_path, speed)
    toml = learn_config(
        tmp_path / "learn.toml", tuning,
        "[schedule]\npole_pairs = 4\nspeed_range = [5.0, 100.0]\n",
    )  # fmt: skip
    out, report = tmp_path / "out.json", tmp_path / "report"
    args = ["learn", str(log), "--config", str(toml), "--json", str(out), "--report", str(report)]
    assert main(args) == 0
    files = report_files(scheduled=True)  # the report draws the schedule
    assert sorted(path.name for path in report.iterdir()) == sorted(files)
    assert f"wrote {report}/ ({', '.join(files)})" in capsys.readouterr().out
    assert '<figure id="schedule">' in (report / "report.html").read_text()
    document = json.loads(out.read_text())
    design = document["schedule_design"]
    learned = IPMSM(**{key: value for key, value in design["motor"].items() if key != "J"})
    for name, se in result.standard_errors.items():  # the same log's motor, and its errors
        assert abs(getattr(learned, name) - getattr(MOTOR, name)) <= 4.0 * se, name
    expected = design_schedule(
        learned, [5.0, speed], tuning.Q, tuning.R, H, integral_weight=result.integral_weight,
        hold=DRIVE.voltage_hold,
    )  # fmt: skip
    schedule = document["schedule"]
    np.testing.assert_allclose(schedule["electrical_speed"], expected.schedule.electrical_speed)
    for name in ("K", "K_i", "U", "X"):  # recomputed from the file: rounding apart
        np.testing.assert_allclose(
            schedule[name], expected.schedule.table(name), rtol=1e-9, atol=1e-12, err_msg=name
        )
    assert document["schedule_design"]["covered"] == pytest.approx([20.0, 400.0], rel=1e-9)
    wide = learn_config(
        tmp_path / "wide.toml", tuning, "[schedule]\npole_pairs = 4\nspeeds = [5.0, 150.0]\n"
    )
    capsys.readouterr()
    assert main(["learn", str(log), "--config", str(wide), "--json", str(out)]) != 0
    said = capsys.readouterr().err
    assert "wide.toml: [schedule] speeds: 600 rad/s (electrical) outside the speeds" in said


def test_learn_by_adp_schedules_the_laws_learned_at_the_held_speeds(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """``method = "adp"`` with a [schedule]: the grid is the log's held speeds, each law
    the one ADP learned from its part alone; against the TRUE motor's pointwise digital
    optimum (designed on the model, only to judge) the schedule is within the issue's 1%
    at the fine speeds between them, where the law learned at the top speed alone is not;
    a [schedule] speed the log does not hold is refused, named, with the held ones."""
    speed = 100.0
    tuning, result, log = two_speed_log(tmp_path, speed)
    adp = 'method = "adp"\n'
    toml = learn_config(
        tmp_path / "learn.toml", tuning, "[schedule]\npole_pairs = 4\nspeed_range = [5.0, 100.0]\n"
    )
    toml.write_text(toml.read_text().replace('method = "identify"\nstructure = "ipmsm"\n', adp))
    out, report = tmp_path / "out.json", tmp_path / "report"
    args = ["learn", str(log), "--config", str(toml), "--json", str(out), "--report", str(report)]
    assert main(args) == 0
    assert "Speed schedule of the laws learned at 2 held speeds" in capsys.readouterr().out
    assert sorted(path.name for path in report.iterdir()) == sorted(report_files(scheduled=True))
    document = json.loads(out.read_text())
    assert document["schedule_design"]["method"] == "adp"
    table = document["schedule"]
    np.testing.assert_allclose(table["electrical_speed"], [20.0, 400.0], rtol=1e-6)
    laws = [
        ControlLaw(table["K"][k], table["X"][k], table["U"][k], table["history"],
                   table["K_i"][k], table["C"], table["F"], table["h"])
        for k in range(2)
    ]  # fmt: skip
    truth = design_schedule(
        MOTOR, [5.0, speed], tuning.Q, tuning.R, H, integral_weight=result.integral_weight,
        hold=DRIVE.voltage_hold,
    )  # fmt: skip
    fine = truth.check.points[(truth.check.points > 20.0) & (truth.check.points < 400.0)]
    schedule = SpeedSchedule([20.0, 400.0], laws)
    optima = [truth.pointwise_optimum(float(w)) for w in fine]
    ours = excess_over(optima, [schedule.law_at(float(w)) for w in fine])
    alone = excess_over(optima, laws[1])
    assert float(np.max(ours)) <= EXCESS < float(np.max(alone))
    wide = toml.parent / "wide.toml"
    wide.write_text(toml.read_text().replace("speed_range = [5.0, 100.0]", "speeds = [5.0, 50.0]"))
    assert main(["learn", str(log), "--config", str(wide)]) == 2
    said = capsys.readouterr().err
    assert (
        "wide.toml: [schedule] speeds: 200 rad/s (electrical) is no held speed of the log" in said
    )
    # where the interpolated laws fail the check (here: a limit of 1e-12), ADP cannot add
    # a grid speed without data: refused, naming the speed to log
    import selftune.commands._adp_schedule as adp_schedule

    monkeypatch.setattr(adp_schedule, "EXCESS", 1e-12)
    assert main(["learn", str(log), "--config", str(toml)]) == 2
    said = capsys.readouterr().err
    assert "between the held speeds 20 and 400 rad/s (electrical)" in said
    assert "log a held speed near 210 rad/s" in said and said.count("\n") == 1


@pytest.mark.parametrize(
    ("learning", "schedule", "said"),
    [
        ('method = "identify"\n', "pole_pairs = 4\nspeeds = [5.0, 100.0]\n",
         'bad.toml: [schedule]: identify-then-design schedules the motor learned: set '
         '[learning] structure = "spmsm" or "ipmsm" (or method = "adp"'),
        ('method = "identify"\nstructure = "ipmsm"\n', "speeds = [5.0, 100.0]\n",
         "bad.toml: [schedule] pole_pairs: missing"),
        ('method = "identify"\nstructure = "ipmsm"\n', "pole_pairs = 4\nspeeds = [100.0, 5.0]\n",
         "bad.toml: [schedule] speeds: must increase strictly"),
    ],
    ids=["identify without a structure", "no pole pairs", "decreasing"],
)  # fmt: skip
def test_a_bad_schedule_table_is_one_line_naming_the_key(
    tmp_path: Path, learning: str, schedule: str, said: str
) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(
        "[cost]\nQ = [[1.0, 0.0], [0.0, 1.0]]\nR = [[1.0, 0.0], [0.0, 1.0]]\n"
        "[policy]\nK0 = [[1.0, 0.0], [0.0, 1.0]]\n"
        "[regulation]\nC = [[1.0, 0.0], [0.0, 1.0]]\nE = [[0.0]]\nF = [[0.0], [-1.0]]\n"
        f"[learning]\n{learning}[schedule]\n{schedule}"
    )
    with pytest.raises(DataFileError) as caught:
        load_learn_config(path, 2, 2, 1)
    assert str(caught.value).startswith(f"{path}: {said.removeprefix('bad.toml: ')}")


def test_a_part_below_the_top_speed_too_imprecise_for_its_own_law_counts_by_its_variance(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """At 5% of the rated speed an 80 mH motor's part gives its own law's feedforward
    beyond the precision limit (TooLittleData); the top speed's part passes, so the low
    part is learned again with that gate open, says so in a note, and the combined motor
    is the truth's within 4 standard errors, its schedule within 1% of the optimum.

    The low part's U has a relative standard error of 20% (25.5% when the signs' bias was
    measured on the replayed voltages, beyond the servo's 25% limit; the experiment re-run
    under the drive's law narrowed it), the top part's 0.13%: the limit is set to 15%."""
    monkeypatch.setattr(verdict_quality, "SERVO_FEEDFORWARD_LIMIT", 0.15)
    motor, speed = SPMSM(R_s=0.84, L_s=0.08, phi_pm=0.16, p=4), 95.0
    drive = dataclasses.replace(
        DriveSettings.hardware_like(dc_voltage=540.0), temperature_rise=20.0
    )
    config = MotorConfig(
        motor=motor, speed=speed, torque=0.85, drive=drive, drive_h=H,
        learning={"integral_action": True}, source="80 mH",
    )  # fmt: skip
    tuning = tuning_settings(config, 1)
    speeds = (0.05 * speed, speed)
    result = commission_ramp(motor, tuning, drive, speeds, seed=1, levels=2)
    (low, low_part), (_, top_part) = sorted(result.segments, key=lambda part: part[0])
    assert low == pytest.approx(0.05 * speed * motor.p)
    assert low_part.quality is not None and top_part.quality is not None
    assert any("own law is too imprecise" in note for note in low_part.quality.notes)
    assert not any("own law is too imprecise" in note for note in top_part.quality.notes)
    truth = true_motor(motor, drive)
    for name, se in result.standard_errors.items():
        error = getattr(result.motor, name) - getattr(truth, name)
        assert abs(error) <= 4.0 * se, (name, error, se)
    designs = [
        design_schedule(
            model, speeds, tuning.Q, tuning.R, H, input_delay=drive.input_delay,
            integral_weight=result.integral_weight, hold=drive.voltage_hold,
        )
        for model in (result.motor, truth)
    ]  # fmt: skip
    assert float(np.max(designs[1].excess_of(designs[0].schedule))) <= EXCESS


def test_the_drawn_motors_span_the_issues_range() -> None:
    """The ramp study's random motors (:func:`selftune.bench._interior.drawn_motor`): surface
    and interior, ``L_q / L_d`` up to 3, 25 uH to 100 mH, 2 to 20 pole pairs, within the
    bus's voltage at rated torque and speed."""
    rng = np.random.default_rng(0)
    draws = [drawn_motor(rng) for _ in range(500)]
    kinds = {type(motor) for motor, *_ in draws}
    assert kinds == {SPMSM, IPMSM}
    for motor, speed, torque, bus, adc_range in draws:
        assert 25e-6 <= motor.L_d <= 0.1 and 1.0 <= motor.L_q / motor.L_d <= 3.0 + 1e-12
        assert 2 <= motor.p <= 20 and torque > 0.0 and adc_range >= 50.0
        current = torque / (1.5 * motor.p * motor.phi_pm)
        w_e = motor.p * speed
        steady = np.hypot(w_e * motor.phi_pm + motor.R_s * current, w_e * motor.L_q * current)
        assert steady <= bus / np.sqrt(3.0)
    smallest = min(motor.L_d for motor, *_ in draws)
    largest = max(motor.L_d for motor, *_ in draws)
    assert smallest < 50e-6 and largest > 0.05  # both ends of the range are drawn


SURFACE_FILE = """[motor]
R_s = 0.35
L_s = 4e-3
phi_pm = 0.08
p = 5
[operating_point]
speed = 120.0
torque = 3.0
[learning]
integral_action = true
[drive]
switching_frequency = 10000.0
input_delay = 1
dc_voltage = 540.0
pwm = "carrier"
dead_time = 3.7e-7
current_noise = 0.01
adc_bits = 12
adc_range = 50.0
temperature_rise = 20.0
"""


def test_tune_commissions_a_surface_motor_over_its_schedules_speeds(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``selftune tune`` of a surface motor with a [schedule] table runs the staircase over
    the schedule's speeds on the file's drive: the JSON's schedule is the one designed on
    the motor it states (recomputed from the file alone), that motor is the heated truth
    within 4 standard errors, the schedule within the 1% excess of the true pointwise
    optimum at every speed checked, and the report draws it."""
    path = tmp_path / "motor.toml"
    path.write_text(SURFACE_FILE + "[schedule]\nspeed_range = [10.0, 150.0]\n")
    out, report = tmp_path / "out.json", tmp_path / "report"
    args = ["tune", "--motor", str(path), "--json", str(out), "--report", str(report)]
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert "Surface PM motor commissioned over a speed ramp" in printed
    assert sorted(p.name for p in report.iterdir()) == sorted(report_files(scheduled=True))
    document = json.loads(out.read_text())
    design = document["schedule_design"]
    assert design["designed_on"] == "the identified motor"
    assert design["covered"] == pytest.approx([50.0, 750.0], rel=1e-9)
    learned = SPMSM(**{key: value for key, value in design["motor"].items() if key != "J"})
    config = load_motor_config(str(path))
    assert config.drive is not None
    truth = true_motor(config.surface_motor(), config.drive)
    for name in ("R_s", "L_s", "phi_pm"):
        se = document["identified"][f"{name}_se"]
        assert abs(getattr(learned, name) - getattr(truth, name)) <= 4.0 * se, name
    cost = design["cost"]
    expected = design_schedule(
        learned, design["speed_range"], np.array(cost["Q"]), np.array(cost["R"]), design["h"],
        input_delay=design["input_delay"], integral_weight=np.array(cost["Q_i"]),
        hold=design["hold"],
    )  # fmt: skip
    for name in ("K", "K_i", "U", "X"):  # recomputed from the file: rounding apart
        np.testing.assert_allclose(
            document["schedule"][name], expected.schedule.table(name), rtol=1e-9, atol=1e-12
        )
    on_truth = design_schedule(
        truth, design["speed_range"], np.array(cost["Q"]), np.array(cost["R"]), design["h"],
        input_delay=design["input_delay"], integral_weight=np.array(cost["Q_i"]),
        hold=design["hold"],
    )  # fmt: skip
    excess = on_truth.excess_of(expected.schedule)
    assert float(np.max(excess)) <= EXCESS
    np.testing.assert_allclose(document["true_schedule_excess"]["schedule"], excess, rtol=1e-6)


@pytest.mark.parametrize(
    ("change", "said"),
    [
        (
            lambda text: text.split("[drive]")[0],
            "is commissioned on a realistic drive: add a [drive]",
        ),
        (lambda text: text, "--algorithm: a surface motor with a [schedule] table is"),
    ],
)
def test_a_surface_schedule_tune_without_its_drive_or_with_an_algorithm_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], change: Any, said: str
) -> None:
    path = tmp_path / "motor.toml"
    path.write_text(change(SURFACE_FILE) + "[schedule]\nspeed_range = [10.0, 150.0]\n")
    extra = ["--algorithm", "1"] if "algorithm" in said else []
    assert main(["tune", "--motor", str(path), *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and said in err[0]


def test_a_refused_part_names_the_speeds_the_others_cover() -> None:
    """A refusal of one held speed says where the others were learned; when the refused
    ones are the lowest, from which speed a schedule is covered without them."""
    from selftune.errors import Refusal
    from selftune.learn._speeds import _others

    refusal = Refusal("the model cannot explain the data")
    low = _others([300.0, 600.0], [(30.0, refusal)])
    assert low.endswith("(300, 600 rad/s): a schedule from 300 rad/s (electrical) up is covered"
                        " without it")  # fmt: skip
    middle = _others([30.0, 600.0], [(300.0, refusal), (400.0, refusal)])
    assert middle == " (and at 1 more); learned at 30, 600 rad/s (electrical)"
    assert _others([], [(30.0, refusal)]) == ""


def _hardware_like(seed: int) -> tuple[DriveSettings, TuningSettings]:
    """The hardware-like drive (carrier PWM, dead time) on 540 V, and the settings of the
    test motor at 100 rad/s, 5 N m, with integral action."""
    drive = DriveSettings.hardware_like(dc_voltage=540.0)
    config = MotorConfig(
        motor=MOTOR, speed=100.0, torque=5.0, drive=drive, drive_h=H,
        learning={"integral_action": True}, source="motor",
    )  # fmt: skip
    return drive, tuning_settings(config, seed)


def test_a_learn_files_dc_voltage_gives_bars_that_hold_the_pulses(tmp_path: Path) -> None:
    """A carrier-PWM log with dead time: with ``[learning] dc_voltage`` the learner reports
    the fit on the next sample's signs, its standard errors holding the carrier's pulses
    (and says both in notes), every parameter within 3 of them; without it neither note."""
    drive, tuning = _hardware_like(0)
    result = commission_ramp(MOTOR, tuning, drive, (5.0, 100.0), seed=0, levels=2)
    log = tmp_path / "ramp.npz"
    save_trajectory(result.log, log)
    schedule = "[schedule]\npole_pairs = 4\nspeed_range = [5.0, 100.0]\n"
    documents = []
    for name, bus in (("bare", ""), ("bus", "dc_voltage = 540.0\n")):
        toml = learn_config(tmp_path / f"{name}.toml", tuning, f"dead_time = true\n{bus}{schedule}")
        out = tmp_path / f"{name}.json"
        assert main(["learn", str(log), "--config", str(toml), "--json", str(out)]) == 0
        documents.append(json.loads(out.read_text()))
    bare, bus = documents
    truth = true_motor(MOTOR, drive)
    motor = bus["quality"]["motor"]
    for name in ("R_s", "L_d", "L_q", "phi_pm"):
        assert abs(motor[name] - getattr(truth, name)) <= 3.0 * motor[f"{name}_se"], name
    for document, count in ((bare, 0), (bus, 1)):
        notes = document["quality"]["notes"]
        assert sum("the carrier's pulses" in note for note in notes) == count
        assert sum("as the next sample shows them" in note for note in notes) == count


def test_a_ramp_from_standstill_covers_it_without_learning_it(tmp_path: Path) -> None:
    """A staircase from standstill: the part at zero speed has no back-EMF (its w_1 is
    zero, and the data's rank refused it before 2026-11-26), so it is not learned; the
    motor learned at the other speeds (within 4 standard errors of the heated truth) is
    the plant there too, and the schedule covers standstill. A log at standstill only is
    refused, saying why."""
    drive, tuning = _hardware_like(1)
    result = commission_ramp(MOTOR, tuning, drive, (0.0, 100.0), seed=1, levels=3)
    assert result.standstill and result.covered[0] == 0.0 and len(result.segments) == 2
    truth = true_motor(MOTOR, drive)
    for name, se in result.standard_errors.items():
        assert abs(getattr(result.motor, name) - getattr(truth, name)) <= 4.0 * se, name
    design = design_schedule(
        result.motor, [0.0, 100.0], tuning.Q, tuning.R, H, covered=result.covered,
        integral_weight=result.integral_weight, hold=drive.voltage_hold,
    )  # fmt: skip
    assert design.schedule.electrical_speed[0] == 0.0
    standing = staircase_log(np.zeros(600))
    with pytest.raises(InputError, match="standstill only"):
        options = LearningOptions(method="identify", structure="ipmsm", electrical_speed=1.0)
        learn_over_speeds(standing, LearningProblem(tuning.Q, tuning.R), tuning.K0, options)


def test_a_rotor_turning_backwards_is_learned_and_an_angle_of_the_other_sense_refused() -> None:
    """A staircase at -5 and -100 rad/s (``w_1`` negative with the speed) is learned, the
    motor within 4 standard errors of the truth; the same log with its angle negated turns
    against its back-EMF reference and is refused, naming the angle column and w1 (before
    2026-11-28 it was refused as a model that cannot explain the data, whose likely causes
    named the dead time and the log's alignment, not the angle); so is one speed's part
    learned with its speed stated at the other sign, naming ``electrical_speed``. A
    mechanical angle is refused by the model's test at every part, saying that the parts'
    speeds are the angle column's, which must be the electrical angle, and not suggesting
    ``structure = 'none'``, which a log over several speeds cannot take."""
    config = MotorConfig(
        motor=MOTOR, speed=100.0, torque=5.0, drive=DRIVE, drive_h=H,
        learning={"integral_action": True}, source="motor",
    )  # fmt: skip
    tuning = tuning_settings(config, 3)
    result = commission_ramp(MOTOR, tuning, DRIVE, (-5.0, -100.0), seed=3, levels=2)
    assert result.covered == pytest.approx((-400.0, -20.0), rel=1e-9)
    for name, se in result.standard_errors.items():
        assert abs(getattr(result.motor, name) - getattr(MOTOR, name)) <= 4.0 * se, name
    assert result.log.angle is not None
    other = dataclasses.replace(result.log, angle=-result.log.angle)
    options = LearningOptions(method="identify", structure="ipmsm", electrical_speed=1.0)
    with pytest.raises(InputError, match=r"^angle: turns at 20 rad/s .* w1 .* -2: .* opposite"):
        learn_over_speeds(other, LearningProblem(tuning.Q, tuning.R), tuning.K0, options)
    # a mechanical angle: every part's cross-coupling 4 times too slow; the refusal says
    # where the speed came from
    mechanical = dataclasses.replace(
        result.log, angle=np.angle(np.exp(1j * np.unwrap(result.log.angle) / MOTOR.p))
    )
    problem = LearningProblem(
        tuning.Q, tuning.R, C=np.eye(2), F=MOTOR.regulation_problem(1.0).F,
        integral_action=True, integral_weight=tuning.Q_i,
    )  # fmt: skip
    with pytest.raises(
        SelftuneError, match=r"^at -5 rad/s .* the electrical angle \(p times"
    ) as caught:
        learn_over_speeds(mechanical, problem, tuning.K0, options)
    assert "structure = 'none'" not in str(caught.value)  # which a log over speeds refuses
    # one speed's part, stated at the other sign
    half = result.log.num_samples // 2  # the second half: -100 rad/s, -400 electrical
    log = result.log
    assert log.w is not None
    part = Trajectory(t=log.t[half:], x=log.x[half:], u=log.u[half:], w=log.w[half:])
    stated = dataclasses.replace(options, electrical_speed=400.0)
    with pytest.raises(InputError, match=r"^electrical_speed: says 400 rad/s, .* w1 .* -40: "):
        learn_controller(part, LearningProblem(tuning.Q, tuning.R), tuning.K0, stated)


def test_an_encoders_angle_is_read_as_the_speeds_it_holds(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A drive logs its encoder's angle, in whole counts: the speed over one sample is 0, 1
    or 2 counts, never the speed held. The two-speed log with its angle rounded to a
    4,096-count encoder (1.5 mrad electrical a count on 4 pole pairs; at 20 rad/s the
    angle moves 2 mrad a sample) is cut at the same sample into the same two speeds
    (each to a count over its part), and ``selftune learn`` gives the motor within 4
    standard errors of the truth, as on the exact angle; the angle's median step (one
    count) read 15 rad/s at 20 rad/s before, and the speeds' exact changes a part a
    sample."""
    tuning, result, _ = two_speed_log(tmp_path, 100.0)
    exact = speed_segments(result.log)
    count = 2 * np.pi * MOTOR.p / 4096  # one count, electrical rad
    angle = result.log.angle
    assert angle is not None
    encoder = dataclasses.replace(result.log, angle=np.round(angle / count) * count)
    steps = np.unique(np.round(np.diff(encoder.angle[:100]) / count))
    assert set(steps.tolist()) <= {0.0, 1.0, 2.0}  # whole counts at 20 rad/s
    segments = speed_segments(encoder)
    assert [(a, b) for a, b, _ in segments] == [(a, b) for a, b, _ in exact]
    for (first, last, speed), (_, _, truth) in zip(segments, exact, strict=True):
        length = float(encoder.t[last] - encoder.t[first])  # read to a count over the part
        assert abs(speed - truth) <= count / length, (speed, truth)
    log = tmp_path / "encoder.npz"
    save_trajectory(encoder, log)
    toml = learn_config(
        tmp_path / "learn.toml", tuning, "[schedule]\npole_pairs = 4\nspeed_range = [5.0, 100.0]\n"
    )
    out = tmp_path / "out.json"
    assert main(["learn", str(log), "--config", str(toml), "--json", str(out)]) == 0, (
        capsys.readouterr().err
    )
    design = json.loads(out.read_text())["schedule_design"]
    learned = IPMSM(**{key: value for key, value in design["motor"].items() if key != "J"})
    for name, se in result.standard_errors.items():
        assert abs(getattr(learned, name) - getattr(MOTOR, name)) <= 4.0 * se, name


def test_the_changes_between_held_speeds_are_left_out() -> None:
    """A staircase whose speed ramps for 5 ms between its steps (a speed loop's
    transition) is cut into its held speeds, the ramps left out; a log that is mostly
    ramp is refused."""
    held = ramp_speeds(10.0, 100.0, 1500, levels=3)
    speeds = held.copy()
    for edge in (500, 1000):  # 5 ms of linear change, ending at the edge
        speeds[edge - 50 : edge] = np.linspace(held[edge - 51], held[edge], 52)[1:-1]
    segments = speed_segments(staircase_log(speeds))
    assert len(segments) == 3
    for (first, last, speed), level in zip(segments, [10.0, 55.0, 100.0], strict=True):
        assert np.all(speeds[first:last] == level) and speed == pytest.approx(4 * level)
    assert sum(last - first for first, last, _ in segments) >= 1500 - 2 * 100
