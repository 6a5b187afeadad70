"""Logs as drives write them: the [log] table of CONFIG.toml, the phase frame, MAT files.

The done-when: a phase-frame log (phase currents in mA under the drive's own names, duty
cycles with the DC bus, the angle in degrees, time in ms) of the realistic drive gives
the controller its dq log gives, to the noise; every mistake is one line naming the
column and the row (exit 2 on the command line).
"""

from __future__ import annotations

import json
import runpy
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import scipy.io

import selftune
from selftune.cli import main
from selftune.config import LEARN_TABLES, load_log_format
from selftune.core import ControlLaw
from selftune.errors import DataFileError
from selftune.learn import Trajectory, load_log, load_trajectory, save_trajectory
from selftune.learn.data._io import trajectory_dimensions
from selftune.sim import DriveSettings, RealisticDrive, held, uniform

DATA = Path(__file__).resolve().parents[1] / "examples" / "data"
SCRIPT = runpy.run_path(str(DATA / "make_phase_log.py"))  # phase_columns, write_csv
MOTOR = selftune.SPMSM(R_s=0.6, L_s=8e-3, phi_pm=0.35, p=3)  # make_drive_log.py's
H = 1e-4


def drive_log(speed: float, settings: DriveSettings, samples: int = 2000) -> Trajectory:
    """make_drive_log.py's run (the torque reference stepping, exploration on both
    voltages, the back-EMF fed forward) at ``speed`` with ``settings``."""
    w = MOTOR.exogenous(speed, 5.0)
    F = MOTOR.regulation_problem(max(speed, 1.0)).F
    levels = np.array([1.0, 1.0 / 3.0, -1.0 / 3.0, -1.0])

    def reference(t: np.ndarray) -> np.ndarray:
        level = levels[np.floor(t / 0.01).astype(int) % levels.size]
        return np.column_stack([np.full_like(t, w[0]), level * 5.0])

    drive = RealisticDrive(MOTOR, speed, H, replace(settings, logged_input="commanded"))
    law = ControlLaw.regulator(np.eye(2), -F, np.array([[0.0, 0.0], [1.0, 0.0]]))
    return drive.run(law, held(reference), num_samples=samples, exploration=uniform(10.8), seed=7)


#: The realistic drive without its ADC: no phase current is exactly zero, so no sign of
#: one is decided by rounding (see test_the_example_phase_log_learns_the_same_controller).
NO_ADC = replace(DriveSettings.hardware_like(h=H), adc_bits=None, adc_range=None)


def learned(log: Path, config: Path, tmp_path: Path) -> dict[str, Any]:
    out = tmp_path / f"{log.stem}.json"
    assert main(["learn", str(log), "--config", str(config), "--json", str(out)]) == 0
    return json.loads(out.read_text())  # type: ignore[no-any-return]


def normalized_differences(one: dict[str, Any], other: dict[str, Any]) -> np.ndarray:
    """|K, K_i, U of one - of other| in units of one's standard errors."""
    gains = [np.hstack([np.array(d["K"]), np.array(d["K_i"])]) for d in (one, other)]
    feedforwards = [np.array(d["U"]) for d in (one, other)]
    quality = one["quality"]
    return np.concatenate([
        (np.abs(gains[0] - gains[1]) / np.array(quality["K_se"])).ravel(),
        (np.abs(feedforwards[0] - feedforwards[1]) / np.array(quality["U_se"])).ravel(),
    ])  # fmt: skip


def phase_config(tmp_path: Path, **edits: str | None) -> Path:
    """learn_phases.toml with [log] keys set to new values (None: the key dropped)."""
    head, log = (DATA / "learn_phases.toml").read_text().split("[log]\n")
    lines = []
    for line in log.splitlines():
        key = line.split("=")[0].strip()
        if key not in edits:
            lines.append(line)
        elif edits[key] is not None:
            lines.append(f"{key} = {edits[key]}")
    lines += [f"{key} = {value}" for key, value in edits.items() if value is not None
              and not any(line.startswith(f"{key} =") for line in lines)]  # fmt: skip
    config = tmp_path / "config.toml"
    config.write_text(head + "[log]\n" + "\n".join(lines) + "\n")
    return config


def test_a_phase_frame_log_gives_the_controller_of_its_dq_log(tmp_path: Path) -> None:
    """The same run of the realistic drive (carrier PWM, dead time, 10 mA of noise) as a
    dq log and as the drive's phase-frame log: the two learned controllers differ by
    the conversion's rounding (1e-13 V), far inside the standard errors; a conversion
    that misses the drive's angle compensation by one sample (advance 0.5 for 1.5) is
    not."""
    log = drive_log(50.0, NO_ADC)
    dq, phases = tmp_path / "dq.csv", tmp_path / "phases.csv"
    save_trajectory(log, dq)
    SCRIPT["write_csv"](SCRIPT["phase_columns"](log), phases)
    expected = learned(dq, DATA / "learn.toml", tmp_path)
    got = learned(phases, DATA / "learn_phases.toml", tmp_path)
    assert np.max(normalized_differences(expected, got)) < 1e-6
    late = learned(phases, phase_config(tmp_path, advance="0.5"), tmp_path)
    assert np.max(normalized_differences(expected, late)) > 10.0


def test_the_example_phase_log_learns_the_same_controller(tmp_path: Path) -> None:
    """examples/data: the phase log is make_phase_log.py's output, and learns drive_log.csv's
    controller to the conversion's rounding (3e-8 standard errors), although the drive's
    12-bit ADC puts 130 of the 6,000 phase currents at exactly 0 A: their signs in the
    dead-time model are 0 from either log, not the rounding's."""
    out = tmp_path / "phases.csv"
    SCRIPT["write_csv"](SCRIPT["phase_columns"](load_trajectory(DATA / "drive_log.csv")), out)
    committed = np.loadtxt(DATA / "drive_log_phases.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(
        np.loadtxt(out, delimiter=",", skiprows=1), committed, rtol=1e-12, atol=1e-9
    )
    expected = learned(DATA / "drive_log.csv", DATA / "learn.toml", tmp_path)
    got = learned(DATA / "drive_log_phases.csv", DATA / "learn_phases.toml", tmp_path)
    assert np.max(normalized_differences(expected, got)) < 1e-6


def phase_log(tmp_path: Path, log: Trajectory, **columns: np.ndarray) -> Path:
    values = SCRIPT["phase_columns"](log)
    values.update(columns)
    path = tmp_path / "phases.csv"
    SCRIPT["write_csv"](values, path)
    return path


def refusal(log: Path, config: Path) -> str:
    with pytest.raises(DataFileError) as info:
        load_log(log, load_log_format(config, LEARN_TABLES))
    message = str(info.value)
    assert "\n" not in message and message.startswith(str(log))
    return message


@pytest.fixture(scope="module")
def fast_log() -> Trajectory:
    return drive_log(50.0, NO_ADC, samples=1500)


@pytest.mark.parametrize(
    ("wrong", "why"),
    [
        (lambda angle: angle, "degrees declared as rad"),
        (lambda angle: -np.rad2deg(angle), "the wrong sign"),
        (lambda angle: np.rad2deg(angle) / 3.0, "the mechanical angle"),
        (lambda angle: np.rad2deg(np.angle(np.exp(1j * angle))) * 0.0, "a constant"),
    ],
)
def test_an_angle_that_does_not_follow_the_voltages_is_refused(
    tmp_path: Path, fast_log: Trajectory, wrong: Any, why: str
) -> None:
    log = phase_log(tmp_path, fast_log, theta_el_deg=wrong(np.unwrap(fast_log.angle)))
    message = refusal(log, DATA / "learn_phases.toml")
    assert "column 'theta_el_deg' ([log] angle), line 2: turns by" in message, why


@pytest.mark.parametrize("speed", [0.0, 1.0, 5.0, -50.0])
def test_the_angle_check_passes_good_logs_at_any_speed(tmp_path: Path, speed: float) -> None:
    """No false alarm: noise, dead time, carrier PWM and the 12-bit ADC, from standstill
    (where no line tells the angle) to speed, either direction."""
    log = drive_log(speed, DriveSettings.hardware_like(h=H), samples=1500)
    got = load_log(
        phase_log(tmp_path, log), load_log_format(DATA / "learn_phases.toml", LEARN_TABLES)
    )
    np.testing.assert_allclose(got.x, log.x, atol=1e-12)


def test_every_mistake_is_one_line_naming_the_column_and_the_row(
    tmp_path: Path, fast_log: Trajectory, capsys: pytest.CaptureFixture[str]
) -> None:
    config = DATA / "learn_phases.toml"
    percent = SCRIPT["phase_columns"](fast_log)["PWM_B"] * 100.0
    message = refusal(phase_log(tmp_path, fast_log, PWM_B=percent), config)
    assert "column 'PWM_B' ([log] d_b), line 2: duty cycle" in message and '"%"' in message
    moved = phase_config(tmp_path, i_b='{column = "Ib", unit = "mA"}')
    message = refusal(phase_log(tmp_path, fast_log), moved)
    assert "no column 'Ib' ([log] i_b); the header has 'time_ms', 'Ia_mA'" in message
    times = SCRIPT["phase_columns"](fast_log)["time_ms"].copy()
    times[40] = times[39]
    message = refusal(phase_log(tmp_path, fast_log, time_ms=times), config)
    assert "column 'time_ms' ([log] time), line 42: time" in message
    # NaN: a CSV names its line and column; an NPZ or MAT column its row
    path = phase_log(tmp_path, fast_log)
    lines = path.read_text().splitlines()
    lines[7] = lines[7].replace(lines[7].split(",")[1], "nan", 1)
    path.write_text("\n".join(lines) + "\n")
    assert "line 8, column 2 (Ia_mA): not a finite number: 'nan'" in refusal(path, config)
    columns = SCRIPT["phase_columns"](fast_log)
    columns["Ia_mA"][6] = np.nan
    archive = tmp_path / "phases.npz"
    np.savez(archive, **columns)
    assert "column 'Ia_mA' ([log] i_a), row 6: not a finite number" in refusal(archive, config)
    matlab = tmp_path / "phases.mat"
    scipy.io.savemat(matlab, columns)
    assert "column 'Ia_mA' ([log] i_a), row 7: not a finite number" in refusal(matlab, config)
    # and on the command line: one line, exit 2
    assert main(["learn", str(archive), "--config", str(config)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "row 6" in err[0] and "Traceback" not in err[0]


@pytest.mark.parametrize(
    ("edit", "expected"),
    [
        (
            {"i_a": '{column = "Ia_mA", unit = "amps"}'},
            '[log] i_a.unit: must be one of "A", "mA", "counts"',
        ),
        ({"i_a": '{colum = "Ia_mA"}'}, "[log] i_a.colum: unknown key"),
        ({"i_a": '{column = "Ia_mA", scale = 2.0}'}, '[log] i_a.scale: only with unit = "counts"'),
        ({"advance": None}, "[log] advance: missing"),
        ({"angle": None}, "[log] angle: missing"),
        ({"u_dc": None}, "[log] u_dc: missing"),
        ({"d_c": None}, "[log] d_c: missing"),
        ({"i_q": '"Iq"'}, "currents: two frames mixed"),
        ({"angel": '"x"'}, "[log] angel: unknown key"),
        ({"w2": None, "w3": '"x"'}, "[log] w3: given without w2"),
    ],
)
def test_log_table_mistakes_name_the_key(
    tmp_path: Path, edit: dict[str, str | None], expected: str
) -> None:
    with pytest.raises(DataFileError) as info:
        load_log_format(phase_config(tmp_path, **edit), LEARN_TABLES)
    assert expected in str(info.value), str(info.value)
    assert "\n" not in str(info.value)


def test_counts_with_a_scale_and_an_offset(tmp_path: Path, fast_log: Trajectory) -> None:
    """An ADC's counts: SI = (count - offset) * scale."""
    columns = SCRIPT["phase_columns"](fast_log)
    columns["Ia_mA"] = columns["Ia_mA"] / 24.4140625 + 2048.0  # 24.4 mA per count, 0 A at 2048
    config = phase_config(
        tmp_path, i_a='{column = "Ia_mA", unit = "counts", scale = 0.0244140625, offset = 2048}'
    )
    path = tmp_path / "phases.csv"
    SCRIPT["write_csv"](columns, path)
    got = load_log(path, load_log_format(config, LEARN_TABLES))
    np.testing.assert_allclose(got.x, fast_log.x, atol=1e-9)


def test_mat_files_round_trip_and_v73_is_refused(tmp_path: Path, fast_log: Trajectory) -> None:
    columns = SCRIPT["phase_columns"](fast_log)
    matlab = tmp_path / "phases.mat"
    scipy.io.savemat(matlab, {**columns, "notes": "other variables are not read"})
    got = load_log(matlab, load_log_format(DATA / "learn_phases.toml", LEARN_TABLES))
    np.testing.assert_allclose(got.x, fast_log.x, atol=1e-12)
    np.testing.assert_allclose(got.u, fast_log.u, atol=1e-9)
    own = tmp_path / "own.mat"  # selftune's own arrays, as in an NPZ
    scipy.io.savemat(
        own,
        {
            "t": fast_log.t,
            "x": fast_log.x,
            "u": fast_log.u,
            "w": fast_log.w,
            "angle": fast_log.angle,
        },
    )
    again = load_trajectory(own)
    for name in ("t", "x", "u", "w", "angle"):
        np.testing.assert_array_equal(getattr(again, name), getattr(fast_log, name).copy())
    assert trajectory_dimensions(own) == (2, 2, 2)
    hdf5 = tmp_path / "v73.mat"
    header = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, HDF5 schema 1.00 .".ljust(116)
    hdf5.write_bytes(header + b"\x00" * 8 + b"\x00\x02" + b"IM" + b"\x00" * 512)
    for action in (
        lambda: load_trajectory(hdf5),
        lambda: load_log(hdf5, load_log_format(DATA / "learn_phases.toml", LEARN_TABLES)),
    ):
        with pytest.raises(DataFileError) as info:
            action()
        assert "v7.3 (HDF5)" in str(info.value) and "-v7" in str(info.value)
