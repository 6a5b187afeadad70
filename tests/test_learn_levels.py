"""``selftune learn`` of several logs: a saturating motor's current levels, its law
scheduled over ``i_q*``.

The logs are the realistic drive's at four loads of a saturating motor (the levels
``selftune tune`` logs, :func:`selftune.tuning._saturation.level_log`), written as CSV;
the learner sees only them and the configuration. The truth (the analytic saturation's
incremental inductances at each log's mean current, and the true pointwise digital
optimum from 10% to 100% of rated current) is the simulator's. The schedule is
recomputed from the JSON alone. A configuration or a set of logs that cannot give a
current schedule is one line naming the file and the key or column."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from selftune.cli import main
from selftune.config import load_law_result, load_motor_config
from selftune.learn import IncrementalStructure, Trajectory
from selftune.learn.data._io import save_trajectory
from selftune.model import excess_over
from selftune.report._saturation_report import judged_references, true_current_optima
from selftune.tuning import tuning_settings
from selftune.tuning._saturation import level_log
from test_saturation_tune import DRIVE, SATURATION, check_inductances, check_recomputed
from test_saturation_tune import MOTOR as NAMEPLATE

#: The saturating motor and drive of ``selftune tune``'s test.
MOTOR = NAMEPLATE + DRIVE + SATURATION

#: What the learner is told: the cost, a stabilizing K0, the current-reference form, how
#: the drive logs, and the electrical speed (3 pole pairs at 120 rad/s).
CONFIG = """[cost]
Q = [[1000.0, 0.0], [0.0, 1000.0]]
R = [[1.0, 0.0], [0.0, 1.0]]
[policy]
K0 = [[0.375, 0.0], [0.0, 0.875]]
[regulation]
C = [[1.0, 0.0], [0.0, 1.0]]
E = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]
F = [[0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]
[learning]
target = "digital"
method = "identify"
structure = "incremental"
electrical_speed = 360.0
input_delay = 1
logged_input = "applied"
dead_time = true
integral_action = true
"""

SHARES = (0.1, 0.4, 0.7, 1.0)


def _levels(tmp_path: Path, seed: int) -> list[str]:
    """The four level logs of the motor, written as CSV (in an order not by current)."""
    motor_file = tmp_path / "motor.toml"
    motor_file.write_text(MOTOR)
    config = load_motor_config(motor_file)
    assert config.saturation is not None and config.drive is not None
    settings = tuning_settings(config, 0, "digital")
    paths = []
    for index, share in enumerate(SHARES):
        log, _ = level_log(
            config.motor, config.saturation, settings, config.drive, share, seed=seed + index
        )
        path = tmp_path / f"load_{share:.0%}.csv".replace("%", "pc")
        save_trajectory(log, path)
        paths.append(str(path))
    return [paths[2], paths[0], paths[3], paths[1]]


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 10])
def test_learn_schedules_a_saturating_motor_over_its_logs_current_levels(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], seed: int
) -> None:
    """Every level's L_dd, L_qq within 4 standard errors of the truth at its mean current;
    the schedule recomputed from the JSON alone; within the issue's 2% of the true
    pointwise optimum from 10% to 100% of rated current; exported for firmware."""
    paths = _levels(tmp_path, seed)
    config_file, out = tmp_path / "learn.toml", tmp_path / "out.json"
    config_file.write_text(CONFIG)
    assert main(["learn", *paths, "--config", str(config_file), "--json", str(out)]) == 0
    assert "learned at 4 current levels" in capsys.readouterr().out
    document = json.loads(out.read_text())
    design = document["current_schedule_design"]
    levels = design["levels"]
    currents = np.array([level["i_q"] for level in levels])
    assert np.all(np.diff(currents) > 0.0)
    assert [Path(level["source"]).name for level in levels] == [
        "load_10pc.csv", "load_40pc.csv", "load_70pc.csv", "load_100pc.csv"
    ]  # fmt: skip
    motor = load_motor_config(tmp_path / "motor.toml")
    assert motor.saturation is not None
    check_inductances(levels, motor.saturation, motor.motor, "source")

    # the schedule from the file alone: the levels' models, speed, period, delay, cost
    h, cost = design["h"], design["cost"]
    structure = IncrementalStructure(design["electrical_speed"], h, False, design["hold"])
    check_recomputed(document, levels, structure, cost, design["input_delay"])
    weights = (np.array(cost["Q"]), np.array(cost["R"]), np.array(cost["Q_i"]))

    # against the true motor's pointwise optimum, 10% to 100% of rated torque's current
    result = load_law_result(out)
    assert result.schedule is not None
    references = judged_references(motor.motor, motor.torque)
    optima = true_current_optima(
        motor.motor, motor.saturation, motor.speed, h, references, weights, design["input_delay"]
    )  # fmt: skip
    # the firmware holds the end laws outside the levels' currents (the lowest log's mean
    # i_q* may lie a little above 10% of rated's)
    low, high = result.schedule.covered
    laws = [result.schedule.law_at(float(np.clip(q, low, high))) for q in references[:, 1]]
    assert float(np.max(excess_over(optima, laws))) <= 0.02
    firmware = tmp_path / "firmware"
    assert main(["export", str(out), "--out", str(firmware), "--u-max", "230"]) == 0
    assert "#define SELFTUNE_CURRENTS 4 " in (firmware / "selftune_law.h").read_text()


def _tiny_logs(tmp_path: Path) -> tuple[Path, Path]:
    """Two short logs in the current-reference form (not learned: the checks before
    learning refuse them), at two levels of i_q*."""
    rng = np.random.default_rng(0)
    t = np.arange(200) * 1e-4
    paths = []
    for level in (2.0, 5.0):
        w = np.column_stack([np.full(t.size, 43.2), np.zeros(t.size), np.full(t.size, level)])
        log = Trajectory(t=t, x=rng.normal(size=(t.size, 2)), u=rng.normal(size=(t.size, 2)), w=w)
        path = tmp_path / f"level_{level:g}.csv"
        save_trajectory(log, path)
        paths.append(path)
    return paths[0], paths[1]


def _rewritten(path: Path, to: Path, column: str, factor: float) -> Path:
    """A copy of a CSV log with one column scaled."""
    lines = path.read_text().splitlines()
    index = lines[0].split(",").index(column)
    rows = [lines[0]]
    for line in lines[1:]:
        cells = line.split(",")
        cells[index] = repr(float(cells[index]) * factor)
        rows.append(",".join(cells))
    to.write_text("\n".join(rows) + "\n")
    return to


FLIPPED = CONFIG.replace(
    "F = [[0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]", "F = [[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]"
)


@pytest.mark.parametrize(
    ("config", "logs", "said"),
    [
        (CONFIG.replace('"incremental"', '"ipmsm"'), "ab", "[learning] structure: several logs"),
        (CONFIG.replace('"digital"', '"continuous"'), "ab", "[learning] target: "),
        (FLIPPED.replace("C = [[1.0", "C = [[-1.0"), "ab", "[regulation] C: the current schedule"),
        (FLIPPED, "ab", "[regulation] F: the current schedule"),
        (CONFIG.replace("= 360.0", "= 0.0"), "ab", "[learning] electrical_speed: the levels"),
        (
            CONFIG + "[schedule]\nspeeds = [10.0, 100.0]\npole_pairs = 3\n",
            "ab",
            "[schedule]: a speed schedule is learned from one log over several held speeds",
        ),
        (CONFIG, "aa", "level_2.csv: given twice (as"),
        (CONFIG, "an", "near.csv: w3: its mean i_q* reference (2.01 A) is within 1% of"),
        (CONFIG, "af", "flux.csv: w1: its mean is 47.52, "),
        (CONFIG, "at", "period.csv: t: sampled every 0.0002 s"),
        (CONFIG, "aq", "two.csv: its columns are n, m, q = (2, 2, 2) (x, u, w)"),
    ],
)
def test_several_logs_that_cannot_be_current_levels_are_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], config: str, logs: str, said: str
) -> None:
    """Said before any log is learned, naming the file and the key or column."""
    a, b = _tiny_logs(tmp_path)
    two = Trajectory(t=np.arange(50) * 1e-4, x=np.ones((50, 2)), u=np.ones((50, 2)),
                     w=np.ones((50, 2)))  # fmt: skip
    save_trajectory(two, tmp_path / "two.csv")
    files = {
        "a": a,
        "b": b,
        "f": _rewritten(b, tmp_path / "flux.csv", "w1", 1.1),
        "n": _rewritten(a, tmp_path / "near.csv", "w3", 1.005),
        "t": _rewritten(b, tmp_path / "period.csv", "t", 2.0),
        "q": tmp_path / "two.csv",
    }
    config_file = tmp_path / "learn.toml"
    config_file.write_text(config)
    arguments = [str(files[key]) for key in logs]
    assert main(["learn", *arguments, "--config", str(config_file)]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert captured.out == "" and len(err) == 1 and said in err[0], err
