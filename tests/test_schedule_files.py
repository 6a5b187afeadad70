"""The speed schedule through its files: MOTOR.toml's [schedule], the JSON, the C tables.

- ``[schedule]`` refusals are one line naming the file, the table and the key;
- ``selftune solve`` writes a JSON from which the schedule's pointwise optimum is
  recomputed with nothing but the file (the motor, the loop, the cost, the speeds);
- ``selftune export`` of that JSON compiles to C that runs the scheduled law as
  :meth:`selftune.model.SpeedSchedule.law_at` does, on grid speeds, between them, and
  clamped outside them (compared with the drives' stepper, to float32 rounding); and a
  ``current_schedule`` the same over ``i_q*``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from selftune.cli import main
from selftune.config import load_law_result, load_motor_config
from selftune.core import ControlLaw, to_jsonable
from selftune.errors import DataFileError
from selftune.model import (
    IPMSM,
    SPMSM,
    CurrentSchedule,
    SpeedSchedule,
    solve_digital_regulation,
)
from test_export import CompiledLaw, needs_compiler, rounding_bound, stepper_commands

MOTOR = """
[motor]
R_s = 0.6
L_s = 8e-3
phi_pm = 0.35
p = 3
[operating_point]
speed = 50.0
torque = 5.0
[learning]
h = 1e-4
integral_action = true
target = "digital"
"""


def motor_file(tmp_path: Path, schedule: str) -> Path:
    path = tmp_path / "motor.toml"
    path.write_text(MOTOR + "[schedule]\n" + schedule + "\n")
    return path


@pytest.mark.parametrize(
    ("schedule", "message"),
    [
        ("", "[schedule]: give exactly one of speeds"),
        ("speeds = [10.0, 20.0]\nspeed_range = [10.0, 20.0]", "[schedule] speed_range: give"),
        ("speeds = 10.0", "[schedule] speeds: must be a list"),
        ("speeds = []", "[schedule] speeds: must be a list"),
        ("speeds = [10.0]", "[schedule] speeds: needs at least two"),
        ("speeds = [10.0, 'fast']", "[schedule] speeds: entries must be numbers"),
        ("speeds = [10.0, true]", "[schedule] speeds: entries must be numbers"),
        ("speeds = [20.0, 10.0]", "[schedule] speeds: must increase strictly"),
        ("speeds = [10.0, 10.0]", "[schedule] speeds: must increase strictly"),
        ("speeds = [10.0, nan]", "[schedule] speeds: must be finite"),
        ("speeds = [10.0, 1e9]", "[schedule] speeds: "),
        ("speeds = [10.0, 20000.0]", "[schedule] speeds: 20000 rad/s is too fast"),
        ("speed_range = [10.0, 20.0, 30.0]", "[schedule] speed_range: must be [min, max]"),
        ("speed_range = [30.0, 20.0]", "[schedule] speed_range: must increase strictly"),
        ("speed = [10.0, 20.0]", "[schedule] speed: unknown key"),
    ],
)
def test_bad_schedule_tables_are_refused_in_one_line(
    tmp_path: Path, schedule: str, message: str
) -> None:
    with pytest.raises(DataFileError) as caught:
        load_motor_config(motor_file(tmp_path, schedule))
    text = str(caught.value)
    assert text.startswith(f"{tmp_path / 'motor.toml'}: ") and message in text, text
    assert "\n" not in text


def test_a_schedule_table_is_read_as_written(tmp_path: Path) -> None:
    config = load_motor_config(motor_file(tmp_path, "speeds = [-20, 10.0, 150]"))
    assert config.schedule is not None
    assert config.schedule.speeds == (-20.0, 10.0, 150.0) and not config.schedule.automatic
    config = load_motor_config(motor_file(tmp_path, "speed_range = [10, 150.0]"))
    assert config.schedule is not None and config.schedule.automatic
    assert load_motor_config(_without_schedule(tmp_path)).schedule is None


def _without_schedule(tmp_path: Path) -> Path:
    path = tmp_path / "plain.toml"
    path.write_text(MOTOR)
    return path


@pytest.fixture(scope="module")
def solved(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``selftune solve --json`` of a motor file with a three-speed schedule."""
    directory = tmp_path_factory.mktemp("schedule")
    path = directory / "motor.toml"
    path.write_text(MOTOR + "[schedule]\nspeeds = [10.0, 60.0, 200.0]\n")
    out = directory / "solve.json"
    assert main(["solve", "--motor", str(path), "--json", str(out)]) == 0
    return out


def test_the_json_states_the_schedule_and_its_whole_problem(solved: Path) -> None:
    """From the file alone: the motor, the loop (h, delay, hold), the cost with Q_i and
    the speeds give each grid law again (solve_digital_regulation at that speed)."""
    document = json.loads(solved.read_text())
    schedule, design = document["schedule"], document["schedule_design"]
    assert set(schedule) >= {"electrical_speed", "K", "K_i", "U", "X"}
    motor = SPMSM(**{key: document["motor"][key] for key in ("R_s", "L_s", "phi_pm", "p")})
    assert schedule["electrical_speed"][0] == pytest.approx(10.0 * motor.p)
    cost, h = design["cost"], design["h"]
    assert cost["Q_i"] is not None and design["speeds"] == [10.0, 60.0, 200.0]
    for index, electrical in enumerate(schedule["electrical_speed"]):
        speed = electrical / motor.p
        law = solve_digital_regulation(
            motor.regulation_problem(speed),
            cost["Q"],
            cost["R"],
            h,
            input_delay=design["input_delay"],
            integral_weight=cost["Q_i"],
            plant=motor.sampled_plant(speed, h, design["hold"]),
        ).law
        for name in ("K", "K_i", "U", "X"):
            np.testing.assert_allclose(schedule[name][index], getattr(law, name), rtol=1e-12)
    check = design["check"]
    assert len(check["electrical_speed"]) >= 50 * (len(schedule["electrical_speed"]) - 1)
    assert max(check["excess"]) <= design["excess_limit"] == 0.01
    # the single-speed law (the file's control_law) costs more at the top of the range
    assert check["single_speed_excess"][-1] > max(check["excess"])
    result = load_law_result(solved)
    assert result.schedule is not None and result.h == h and result.input_delay == 1
    loaded = result.schedule
    for index, law in enumerate(loaded.laws):  # the JSON's numbers, bit for bit
        for name in ("K", "K_i", "U", "X"):
            np.testing.assert_array_equal(getattr(law, name), schedule[name][index])
    middle = 0.5 * (schedule["electrical_speed"][0] + schedule["electrical_speed"][1])
    halfway = 0.5 * (np.array(schedule["K"][0]) + np.array(schedule["K"][1]))
    np.testing.assert_allclose(loaded.law_at(middle).K, halfway, rtol=1e-15, atol=1e-15)
    assert loaded.laws[0].C is not None and loaded.laws[0].h == h


def test_a_broken_schedule_in_a_json_is_refused_in_one_line(
    solved: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    document = json.loads(solved.read_text())
    over_current = {"control_law": document["control_law"]}  # the same tables over i_q*
    over_current["current_schedule"] = dict(document["schedule"])
    over_current["current_schedule"]["current"] = over_current["current_schedule"].pop(
        "electrical_speed"
    )
    both = {"control_law": document["control_law"]}  # two rows of the speed tables
    both["speed_current_schedule"] = {
        **document["schedule"],
        "current": [1.0, 2.0],
        **{name: [document["schedule"][name]] * 2 for name in ("K", "K_i", "U", "X")},
    }
    for key, change, message in [
        (
            "speed_current_schedule",
            lambda s: s.pop("current"),
            "speed_current_schedule.current: missing",
        ),
        (
            "speed_current_schedule",
            lambda s: s["K"].pop(),
            "K: must list one row of matrices per current (2)",
        ),
        (
            "speed_current_schedule",
            lambda s: s["U"][1].pop(),
            "speed_current_schedule (current 1).U: must list one matrix per speed (3)",
        ),
        (
            "speed_current_schedule",
            lambda s: s.update(current=[2.0, 1.0]),
            "current: must increase strictly",
        ),
        (
            "speed_current_schedule",
            lambda s: None,
            "looks i_q* up in w[2] of the current references",
        ),
        (
            "speed_current_schedule",
            lambda s: s.pop("K_i"),
            "speed_current_schedule: its first law has (n, m, q, r, d) = (2, 2, 2, 0, 1), "
            "control_law (2, 2, 2, 2, 1): a schedule's laws have the form of control_law",
        ),
        ("schedule", lambda s: s.pop("K_i"), "schedule: its first law has (n, m, q, r, d)"),
        ("schedule", lambda s: s.update(h=2 * s["h"]), "schedule: its first law has h = "),
        ("schedule", lambda s: s.pop("K"), "schedule.K: missing"),
        ("schedule", lambda s: s["U"].pop(), "schedule.U: must list one matrix per speed (3)"),
        ("schedule", lambda s: s.update(electrical_speed=[1.0, 0.5, 2.0]), "increase strictly"),
        ("current_schedule", lambda s: s.pop("current"), "current_schedule.current: missing"),
        ("current_schedule", lambda s: s["X"].pop(), "X: must list one matrix per current (3)"),
        ("current_schedule", lambda s: None, "looks i_q* up in w[2] of the current references"),
    ]:
        source = {"current_schedule": over_current, "speed_current_schedule": both}
        broken = json.loads(json.dumps(source.get(key, document)))
        change(broken[key])
        path = tmp_path / "broken.json"
        path.write_text(json.dumps(broken))
        assert main(["export", str(path), "--out", str(tmp_path / "out"), "--u-max", "100"]) == 2
        error = capsys.readouterr().err
        assert message in error and error.count("\n") == 1, error
        assert not (tmp_path / "out").exists()


def envelope(first: ControlLaw, second: ControlLaw) -> ControlLaw:
    """The law whose every gain is the larger magnitude of two neighbours': the float32
    rounding of an interpolated gain is bounded by that of the larger of the two."""

    def big(name: str) -> np.ndarray:
        return np.maximum(np.abs(getattr(first, name)), np.abs(getattr(second, name)))

    return ControlLaw(
        big("K"), big("X"), big("U"), first.history, big("K_i"), first.C, first.F, first.h
    )


def _agrees(
    schedule: SpeedSchedule | CurrentSchedule, inside: float, compiled: CompiledLaw,
    x: np.ndarray, w: np.ndarray, omega: np.ndarray, u_max: float,
) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Assert that the C law fed ``x``, ``w``, ``omega`` returns the stepper's commands of
    ``law_at(inside)`` within the float32 rounding bound of the neighbours' envelope;
    those commands and the bound."""
    expected = stepper_commands(schedule.law_at(inside), x, w, u_max)
    u = compiled.run(x, w, omega)
    grid = schedule.grid
    index = min(int(np.searchsorted(grid, inside, side="right")) - 1, grid.size - 2)
    bound = rounding_bound(
        envelope(schedule.laws[index], schedule.laws[index + 1]), x, w, expected, u_max
    )
    error = np.hypot(*(u - expected).T)
    assert np.all(error <= bound), (inside, float(np.max(error / bound)))
    return expected, bound


@needs_compiler
def test_the_exported_tables_run_the_law_at_every_speed(solved: Path, tmp_path: Path) -> None:
    """On grid speeds, between them and outside them (clamped), the C law returns what
    the stepper computes with ``law_at`` of the float32 speed, within float32 rounding."""
    result = load_law_result(solved)
    schedule = result.schedule
    assert schedule is not None
    grid = schedule.electrical_speed
    speeds = [*grid, 0.5 * (grid[0] + grid[1]), grid[1] + 0.1 * (grid[2] - grid[1]),
              grid[0] - 5.0, grid[-1] + 50.0]  # fmt: skip
    u_max = 150.0
    compiled = CompiledLaw(solved, u_max, tmp_path)
    rng = np.random.default_rng(7)
    count = 4000
    law0 = schedule.laws[0]
    for speed in speeds:
        omega = float(np.float32(speed))
        inside = float(np.clip(omega, grid[0], grid[-1]))
        w = np.repeat(np.c_[np.full(count // 500, 0.35 * omega), rng.normal(0, 5.0, count // 500)],
                      500, axis=0)  # fmt: skip
        x = w @ law0.X.T + rng.normal(0, 1.0, (count, 2))
        expected, bound = _agrees(schedule, inside, compiled, x, w, np.full(count, omega), u_max)
    # a law away from the speed it runs at differs by far more than the rounding
    wrong = stepper_commands(schedule.laws[0], x, w, u_max)
    assert np.max(np.hypot(*(wrong - expected).T)) > 1e3 * np.max(bound)


def test_solve_writes_the_schedules_figure_as_one_set(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``solve --report DIR`` writes schedule.png and schedule.svg (a PNG and an SVG,
    nothing else); without a [schedule] table it refuses in one line and writes
    nothing."""
    path = motor_file(tmp_path, "speed_range = [10.0, 200.0]")
    report = tmp_path / "report"
    assert main(["solve", "--motor", str(path), "--report", str(report)]) == 0
    assert sorted(item.name for item in report.iterdir()) == ["schedule.png", "schedule.svg"]
    assert (report / "schedule.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "<svg" in (report / "schedule.svg").read_text()
    capsys.readouterr()
    other = tmp_path / "other"
    assert main(["solve", "--report", str(other)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--report: the figure is a speed schedule's" in err[0]
    assert not other.exists()


@needs_compiler
def test_a_current_schedule_runs_in_c_at_the_reference_current(tmp_path: Path) -> None:
    """A JSON's ``current_schedule`` (``tune`` with ``[saturation]``) exports as tables over
    ``IQ_REF`` looked up at ``i_q* = w[2]``: on grid currents, between them and clamped
    outside, the C law returns what the stepper computes with ``law_at`` of the float32
    current, within float32 rounding; ``omega_e`` is unused."""
    motor = IPMSM(R_s=0.3, L_d=3e-3, L_q=7e-3, phi_pm=0.12, p=3)
    Q_i = np.diag([4e6, 4e6])
    laws = [  # four different laws of the current-reference form, one per grid current
        solve_digital_regulation(
            motor.regulation_problem(speed),
            1e3 * np.eye(2),
            np.eye(2),
            1e-4,
            input_delay=1,
            integral_weight=Q_i,
            plant=motor.sampled_plant(speed, 1e-4, "stationary"),
        ).law
        for speed in (20.0, 60.0, 120.0, 200.0)
    ]
    schedule = CurrentSchedule([1.0, 3.0, 6.0, 10.0], laws)
    path = tmp_path / "saturating.json"
    document = {"control_law": laws[-1].document(), "current_schedule": schedule.document(),
                "h": 1e-4, "input_delay": 1}  # fmt: skip
    path.write_text(json.dumps(to_jsonable(document)))
    result = load_law_result(path)
    assert isinstance(result.schedule, CurrentSchedule) and result.scheduled
    u_max = 150.0
    compiled = CompiledLaw(path, u_max, tmp_path)
    assert "IQ_REF[SELFTUNE_CURRENTS]" in compiled.files.source
    grid = schedule.current
    rng = np.random.default_rng(3)
    count = 2000
    for current in [*grid, 2.0, 4.7, 0.2, 14.0]:
        i_q = float(np.float32(current))
        inside = float(np.clip(i_q, grid[0], grid[-1]))
        law = schedule.law_at(inside)
        w = np.c_[np.full(count, 36.0), np.full(count, -0.2 * i_q), np.full(count, i_q)]
        x = w @ law.X.T + rng.normal(0, 0.5, (count, 2))
        omega = rng.uniform(-500.0, 500.0, count)  # unused
        expected, bound = _agrees(schedule, inside, compiled, x, w, omega, u_max)
    wrong = stepper_commands(schedule.laws[0], x, w, u_max)
    assert np.max(np.hypot(*(wrong - expected).T)) > 1e3 * np.max(bound)


@needs_compiler
def test_a_speed_and_current_schedule_runs_in_c_at_both(tmp_path: Path) -> None:
    """A JSON's ``speed_current_schedule`` (``tune`` with ``[saturation]`` and
    ``[schedule]``) exports as tables over ``IQ_REF`` times ``OMEGA_E``, looked up at
    ``i_q* = w[2]`` and ``omega_e``: on grid points, inside cells and clamped outside
    either grid, the C law returns what the stepper computes with ``law_at`` of the
    float32 values, within float32 rounding of the four neighbours' envelope."""
    from selftune.model import SpeedCurrentSchedule

    Q_i = np.diag([4e6, 4e6])
    speeds, currents = [60.0, 300.0, 900.0], [1.0, 4.0, 10.0]

    def law(current: float, speed: float) -> ControlLaw:  # a different motor per current
        motor = IPMSM(R_s=0.3, L_d=3e-3, L_q=7e-3 * (1.0 - 0.03 * current), phi_pm=0.12, p=3)
        return solve_digital_regulation(
            motor.regulation_problem(speed / 3), 1e3 * np.eye(2), np.eye(2), 1e-4,
            input_delay=1, integral_weight=Q_i,
            plant=motor.sampled_plant(speed / 3, 1e-4, "stationary"),
        ).law  # fmt: skip

    schedule = SpeedCurrentSchedule(
        speeds, currents, [[law(c, s) for s in speeds] for c in currents]
    )
    path = tmp_path / "saturating.json"
    document = {"control_law": schedule.law(2, 0).document(), "h": 1e-4, "input_delay": 1,
                "current_schedule": {"broken": True},
                "speed_current_schedule": schedule.document()}  # fmt: skip
    path.write_text(json.dumps(to_jsonable(document)))
    # every table the file states is read, the one not exported too
    with pytest.raises(DataFileError, match=r"current_schedule\.current: missing"):
        load_law_result(path)
    del document["current_schedule"]
    path.write_text(json.dumps(to_jsonable(document)))
    result = load_law_result(path)
    assert isinstance(result.schedule, SpeedCurrentSchedule) and result.scheduled
    u_max = 150.0
    compiled = CompiledLaw(path, u_max, tmp_path)
    assert "K_TABLE[SELFTUNE_CURRENTS][SELFTUNE_SPEEDS][2][4]" in compiled.files.source
    rng = np.random.default_rng(5)
    count = 1000
    points = [(900.0, 4.0), (180.0, 2.5), (600.0, 7.0), (30.0, 5.0), (2000.0, 0.2), (500.0, 14.0)]
    for speed, current in points:
        omega, i_q = float(np.float32(speed)), float(np.float32(current))
        inside = (float(np.clip(omega, 60.0, 900.0)), float(np.clip(i_q, 1.0, 10.0)))
        at = schedule.law_at(*inside)
        w = np.c_[np.full(count, 0.36 * omega), np.full(count, -0.2 * i_q), np.full(count, i_q)]
        x = w @ at.X.T + rng.normal(0, 0.5, (count, 2))
        expected = stepper_commands(at, x, w, u_max)
        u = compiled.run(x, w, np.full(count, omega))
        c = min(int(np.searchsorted(currents, inside[1], side="right")) - 1, 1)
        g = min(int(np.searchsorted(speeds, inside[0], side="right")) - 1, 1)
        corners = [schedule.law(i, j) for i in (c, c + 1) for j in (g, g + 1)]
        bound = rounding_bound(
            envelope(envelope(corners[0], corners[1]), envelope(corners[2], corners[3])),
            x, w, expected, u_max,
        )  # fmt: skip
        error = np.hypot(*(u - expected).T)
        assert np.all(error <= bound), (speed, current, float(np.max(error / bound)))
    wrong = stepper_commands(schedule.law(0, 0), x, w, u_max)
    assert np.max(np.hypot(*(wrong - expected).T)) > 1e3 * np.max(bound)
