"""The ``selftune`` command line: published values, JSON output, and clean failures."""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import selftune
from example_counts import examples
from selftune import commands
from selftune.cli import main

ROOT = Path(__file__).resolve().parents[1]

MOTOR_TOML = """\
[motor]
R_s = 0.439
L_s = 0.0601
phi_pm = 0.46
p = 2
[operating_point]
speed = 10.0
torque = 10.0
[cost]
Q = [[1000.0, 0.0], [0.0, 1000.0]]
R = [[1.0, 0.0], [0.0, 1.0]]
"""

#: PAPER_NOTES.md section 2, erratum 1: the published values, to 4 decimals.
PUBLISHED = {
    "x_e": "[0.0000, 7.2464]",
    "u_e": "[-8.7101, 12.3812]",
    "theta": (
        "[1.8743, 1.8743, 0.0000, 31.1868, 0.0000, 0.0000, 31.1868, 0.0000,"
        " 27.1642, -31.1868, -9.9210]"
    ),
}
PUBLISHED_MATRICES = {
    "K*": ("u_d", "u_q", [[31.1868, 0.0], [0.0, 31.1868]]),
    "P*": ("i_d", "i_q", [[1.8743, 0.0], [0.0, 1.8743]]),
    "X*": ("i_d", "i_q", [[0.0, 0.0], [0.0, 0.7246]]),
    "U*": ("u_d", "u_q", [[0.0, -0.8710], [1.0, 0.3181]]),
}


def run(argv: list[str]) -> tuple[int, str, str]:
    """Run ``main`` in-process; return the exit code, stdout and stderr."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    return code, out.getvalue(), err.getvalue()


def assert_clean_failure(code: int, err: str, *names: str) -> str:
    """Exit code 2 and exactly one line ``selftune: error: ...`` naming each of ``names``."""
    assert code == 2
    assert "Traceback" not in err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("selftune: error: "), err
    for name in names:
        assert name in lines[0], (name, err)
    return lines[0]


def matrix_rows(output: str, title: str) -> list[tuple[str, list[float]]]:
    """The labelled rows of the matrix printed under a line starting with ``title``."""
    lines = output.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith(title + " "))
    rows = []
    for line in lines[start + 2 : start + 4]:
        label, *values = line.split()
        rows.append((label, [float(value) for value in values]))
    return rows


def write_motor(directory: Path, text: str = MOTOR_TOML) -> Path:
    path = directory / "motor.toml"
    path.write_text(text, encoding="utf-8")
    return path


# -- the published values ---------------------------------------------------------------


def test_solve_prints_the_published_values() -> None:
    code, out, err = run(["solve"])
    assert (code, err) == (0, "")
    assert f"x_e = X* w = {PUBLISHED['x_e']} A" in out
    assert f"u_e = U* w = {PUBLISHED['u_e']} V" in out
    assert f"  {PUBLISHED['theta']}\n" in out
    for title, (first_row, _, expected) in PUBLISHED_MATRICES.items():
        rows = matrix_rows(out, title)
        assert rows[0][0] == first_row
        assert [values for _, values in rows] == expected, title
    assert "-0.0000" not in out
    assert "paper preset" in out


def test_solve_prints_every_number_with_four_decimals() -> None:
    _, out, _ = run(["solve"])
    results = out[out.index("K*  ") :]
    numbers = re.findall(r"-?\d+\.\d+", results)
    assert len(numbers) == 4 * 4 + 11 + 2 + 2
    assert all(len(number.split(".")[1]) == 4 for number in numbers)


def test_the_documented_motor_file_gives_the_published_values(tmp_path: Path) -> None:
    code, out, err = run(["solve", "--motor", str(write_motor(tmp_path))])
    assert (code, err) == (0, "")
    assert str(tmp_path / "motor.toml") in out
    assert f"x_e = X* w = {PUBLISHED['x_e']} A" in out
    assert f"  {PUBLISHED['theta']}\n" in out


def test_solve_json_has_the_results(tmp_path: Path) -> None:
    path = tmp_path / "solution.json"
    code, out, err = run(["solve", "--json", str(path)])
    assert (code, err) == (0, "")
    assert f"wrote {path}" in out
    data = json.loads(path.read_text())
    assert {"K", "P", "X", "U", "theta", "x_e", "u_e"} <= set(data)
    np.testing.assert_allclose(data["K"], 31.1868 * np.eye(2), atol=5e-5)
    np.testing.assert_allclose(data["P"], 1.8743 * np.eye(2), atol=5e-5)
    np.testing.assert_allclose(data["X"], [[0.0, 0.0], [0.0, 0.7246]], atol=5e-5)
    np.testing.assert_allclose(data["U"], [[0.0, -0.8710], [1.0, 0.3181]], atol=5e-5)
    np.testing.assert_allclose(
        data["theta"],
        [1.8743, 1.8743, 0, 31.1868, 0, 0, 31.1868, 0, 27.1642, -31.1868, -9.9210],
        atol=5e-5,
    )
    np.testing.assert_allclose(data["x_e"], [0.0, 7.2464], atol=5e-5)
    np.testing.assert_allclose(data["u_e"], [-8.7101, 12.3812], atol=5e-5)
    assert data["operating_point"] == {"speed": 10.0, "torque": 10.0}
    assert data["motor"]["L_s"] == 0.0601
    assert not list(tmp_path.glob(".solution.json.*"))


def test_json_matches_the_library_exactly(tmp_path: Path) -> None:
    path = tmp_path / "solution.json"
    assert run(["solve", "--speed", "120", "--torque", "-4", "--json", str(path)])[0] == 0
    data = json.loads(path.read_text())
    motor = selftune.SPMSM.paper()
    solution = selftune.solve_optimal_regulation(
        motor.regulation_problem(120.0), 1e3 * np.eye(2), np.eye(2)
    )
    for key in ("K", "P", "X", "U"):
        np.testing.assert_array_equal(data[key], getattr(solution, key))
    np.testing.assert_array_equal(data["theta"], solution.theta)


def test_the_solve_json_states_the_whole_problem(tmp_path: Path) -> None:
    """The optimum recomputed from the JSON alone (motor, operating point, Q, R, Q_i, h,
    delay: the continuous optimum, h = 0 and no delay) is the one it states."""
    path = tmp_path / "solution.json"
    motor = tmp_path / "motor.toml"
    motor.write_text(
        "[motor]\nR_s = 0.8\nL_s = 0.02\nphi_pm = 0.15\np = 3\n"
        "[cost]\nQ = [[300.0, 0.0], [0.0, 500.0]]\nR = [[2.0, 0.0], [0.0, 1.0]]\n"
    )
    assert run(["solve", "--motor", str(motor), "--speed", "80", "--json", str(path)])[0] == 0
    data = json.loads(path.read_text())
    assert data["cost"]["Q_i"] is None and (data["h"], data["input_delay"]) == (0.0, 0)
    stated = selftune.SPMSM(**{k: v for k, v in data["motor"].items() if v is not None})
    solution = selftune.solve_optimal_regulation(
        stated.regulation_problem(data["operating_point"]["speed"]), data["cost"]["Q"],
        data["cost"]["R"],
    )  # fmt: skip
    for key in ("K", "P", "X", "U"):
        np.testing.assert_array_equal(data[key], getattr(solution, key))


@pytest.mark.parametrize(("speed", "torque"), [(10.0, 10.0), (150.0, -3.0), (0.0, 5.0)])
def test_operating_point_agrees_with_the_closed_form(
    tmp_path: Path, speed: float, torque: float
) -> None:
    """x_e = X* w and u_e = U* w equal eq. (3) (corrected sign), i_d = 0, torque met."""
    path = tmp_path / "solution.json"
    argv = ["solve", "--speed", str(speed), "--torque", str(torque), "--json", str(path)]
    assert run(argv)[0] == 0
    data = json.loads(path.read_text())
    motor = selftune.SPMSM.paper()
    x_e, u_e = motor.equilibrium(speed, torque)
    np.testing.assert_allclose(data["x_e"], x_e, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(data["u_e"], u_e, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(motor.torque(data["x_e"][1]), torque, rtol=1e-10, atol=1e-12)


def test_options_override_the_file(tmp_path: Path) -> None:
    path = write_motor(tmp_path)
    code, out, _ = run(["solve", "--motor", str(path), "--speed", "20", "--torque", "5"])
    assert code == 0
    assert "speed = 20 rad/s (mechanical), torque = 5 N m" in out
    x_e, _ = selftune.SPMSM.paper().equilibrium(20.0, 5.0)
    assert f"x_e = X* w = [0.0000, {x_e[1]:.4f}] A" in out


def test_version_and_help() -> None:
    code, out, _ = run(["--version"])
    assert code == 0
    assert out.strip() == f"selftune {selftune.__version__}"
    code, out, _ = run(["solve", "--help"])
    assert code == 0
    for option in ("--motor", "--speed", "--torque", "--json"):
        assert option in out


# -- bad input ----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("old", "new", "key"),
    [
        ("L_s = 0.0601\n", "", "[motor] L_s: missing"),
        ("L_s =", "Ls =", "[motor] Ls: unknown key"),
        ("R = [[1.0, 0.0], [0.0, 1.0]]", "R = [[1.0, 0.0]]", "[cost] R: must be a 2x2 matrix"),
        ("R_s = 0.439", "R_s = -0.439", "[motor] R_s: must be positive"),
        ("phi_pm = 0.46", "phi_pm = 0", "[motor] phi_pm: must be positive"),
        ("L_s = 0.0601", "L_s = nan", "[motor] L_s: must be finite"),
        ("torque = 10.0", "torque = nan", "[operating_point] torque: must be finite"),
        ("Q = [[1000.0, 0.0], [0.0, 1000.0]]", "Q = [[1.0, 2.0], [0.0, 1.0]]", "[cost] Q:"),
        ("R = [[1.0, 0.0], [0.0, 1.0]]", "R = [[1.0, 0.0], [0.0, -1.0]]", "[cost] R:"),
        ("p = 2", "p = 1.5", "[motor] p: must be a whole number"),
        ("[cost]", "[costs]", "costs: unknown table"),
        ("speed = 10.0", "speed = 10.0.0", "not a valid TOML file"),
    ],
)
def test_bad_motor_file_fails_cleanly(tmp_path: Path, old: str, new: str, key: str) -> None:
    assert old in MOTOR_TOML
    path = write_motor(tmp_path, MOTOR_TOML.replace(old, new, 1))
    output = tmp_path / "out.json"
    code, out, err = run(["solve", "--motor", str(path), "--json", str(output)])
    line = assert_clean_failure(code, err, str(path), key)
    if "symmetric" not in key and key.endswith(":"):
        assert "symmetric positive definite" in line
    assert out == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == ["motor.toml"]


def test_unreadable_motor_file_fails_cleanly(tmp_path: Path) -> None:
    missing = tmp_path / "absent.toml"
    code, _, err = run(["solve", "--motor", str(missing)])
    assert_clean_failure(code, err, str(missing), "cannot read")
    code, _, err = run(["solve", "--motor", str(tmp_path)])
    assert_clean_failure(code, err, str(tmp_path), "cannot read")
    binary = tmp_path / "binary.toml"
    binary.write_bytes(bytes(range(256)))
    code, _, err = run(["solve", "--motor", str(binary)])
    assert_clean_failure(code, err, str(binary), "not a TOML file")


def test_unwritable_json_fails_cleanly(tmp_path: Path) -> None:
    target = tmp_path / "no such directory" / "out.json"
    code, _, err = run(["solve", "--json", str(target)])
    assert_clean_failure(code, err, str(target), "cannot write")
    code, _, err = run(["solve", "--json", str(tmp_path)])
    assert_clean_failure(code, err, str(tmp_path), "cannot write")
    assert list(tmp_path.iterdir()) == []


def test_failed_solve_leaves_an_existing_json_untouched(tmp_path: Path) -> None:
    output = tmp_path / "out.json"
    output.write_text("previous")
    path = write_motor(tmp_path, MOTOR_TOML.replace("p = 2", "p = 0"))
    code, _, err = run(["solve", "--motor", str(path), "--json", str(output)])
    assert_clean_failure(code, err, "[motor] p")
    assert output.read_text() == "previous"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["motor.toml", "out.json"]


def test_numerical_trouble_is_an_error_not_wrong_numbers(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Values that pass every check but overflow in the solver give exit 2, not output."""

    def overflowing(*args: object, **kwargs: object) -> object:
        warnings.warn("overflow encountered in matmul", RuntimeWarning, stacklevel=1)
        return selftune.solve_optimal_regulation(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(commands._solve, "solve_optimal_regulation", overflowing)
    output = tmp_path / "out.json"
    code, out, err = run(["solve", "--json", str(output)])
    line = assert_clean_failure(code, err, "paper preset", "not numerically meaningful")
    assert "overflow encountered in matmul" in line
    assert out == ""
    assert not output.exists()


@pytest.mark.parametrize(
    "argv",
    [
        [],
        ["nonsense"],
        ["solve", "--speed"],
        ["solve", "--speed", "fast"],
        ["solve", "--speed", "nan"],
        ["solve", "--torque", "inf"],
        ["solve", "--unknown"],
    ],
)
def test_usage_errors_exit_2(argv: list[str]) -> None:
    code, out, err = run(argv)
    assert code == 2
    assert out == ""
    assert "Traceback" not in err
    assert len(err.splitlines()) == 1 and err.startswith("selftune: error: "), err


def test_a_usage_error_names_the_command_and_its_help() -> None:
    code, _, err = run(["solve", "--speed"])
    assert code == 2
    assert err == (
        "selftune: error: solve: argument --speed: expected one argument"
        " (see 'selftune solve --help')\n"
    )


@pytest.mark.parametrize("speed", ["-1e3", "-1.5E2", "-.5", "-0"])
def test_negative_numbers_in_any_notation_are_values(speed: str) -> None:
    code, out, err = run(["solve", "--speed", speed, "--torque", "-2e0"])
    assert (code, err) == (0, ""), err
    assert f"speed = {float(speed):g} rad/s" in out and "torque = -2 N m" in out


def test_an_option_value_out_of_range_names_the_option() -> None:
    code, _, err = run(["solve", "--speed", "-1e9"])
    line = assert_clean_failure(code, err, "--speed", "between -100000 and 100000 rad/s")
    assert line.endswith("(paper preset)")
    code, _, err = run(["solve", "--speed", "9000"])
    assert_clean_failure(code, err, "--speed", "too fast for this motor")


def test_json_to_standard_output_replaces_the_report(tmp_path: Path) -> None:
    code, out, err = run(["solve", "--json", "-"])
    assert (code, err) == (0, "")
    data = json.loads(out)
    np.testing.assert_allclose(data["K"], 31.1868 * np.eye(2), atol=5e-5)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("kind", ["symlink", "device", "read-only", "directory"])
def test_json_is_never_written_over_what_is_not_a_writable_regular_file(
    tmp_path: Path, kind: str
) -> None:
    target = tmp_path / "out.json"
    if kind == "symlink":
        (tmp_path / "real.json").write_text("kept")
        target.symlink_to(tmp_path / "real.json")
    elif kind == "device":
        target = Path("/dev/null")
    elif kind == "read-only":
        target.write_text("kept")
        target.chmod(0o444)
    else:
        target.mkdir()
    code, out, err = run(["solve", "--json", str(target)])
    assert_clean_failure(code, err, str(target), "cannot write the file")
    assert out == ""
    if kind in ("symlink", "read-only"):
        assert target.is_symlink() == (kind == "symlink")
        assert target.read_text() == "kept"


# -- fuzzing the motor file ---------------------------------------------------------------

_LINES = MOTOR_TOML.splitlines()

_numbers = st.one_of(
    st.floats().map(repr),  # includes nan, inf, -inf, 5e-324 and 1.7976931348623157e+308
    st.floats(min_value=-1e3, max_value=1e3).map(repr),
    st.integers(min_value=-(10**20), max_value=10**20).map(str),
    st.sampled_from(["0", "-0.0", "1e-300", "1e300", "2", "0.5"]),
)
_matrices = st.lists(st.lists(_numbers, min_size=2, max_size=2), min_size=2, max_size=2).map(
    lambda rows: "[" + ", ".join("[" + ", ".join(row) + "]" for row in rows) + "]"
)
_other = st.recursive(
    st.one_of(_numbers, st.sampled_from(["true", '"2"', "2024-01-01", "{}", "[]"])),
    lambda inner: st.lists(inner, max_size=3).map(lambda items: "[" + ", ".join(items) + "]"),
    max_leaves=6,
)
_values = st.one_of(_numbers, _matrices, _other)
_edits = st.lists(
    st.tuples(
        st.integers(min_value=0, max_value=len(_LINES) - 1),
        st.one_of(
            st.just(None),  # delete the line
            _values,  # replace the value
            st.sampled_from(["Ls", "q", "speed", "J", "K0"]),  # rename the key
        ),
    ),
    min_size=1,
    max_size=4,
)


def _mutate(edits: list[tuple[int, str | None]]) -> str:
    lines = list(_LINES)
    for index, edit in edits:
        line = lines[index]
        if edit is None:
            lines[index] = ""
        elif "=" not in line:  # a table header: rename it
            lines[index] = "[" + edit.strip('[]"') + "]" if edit.isidentifier() else line
        elif edit.isidentifier() and edit not in ("true", "nan", "inf"):
            lines[index] = edit + " =" + line.split("=", 1)[1]
        else:
            lines[index] = line.split("=", 1)[0] + "= " + edit
    return "\n".join(lines) + "\n"


@examples(300, quick=30)  # a tenth, as the default profile draws of ci's 100
@given(edits=_edits)
def test_fuzzed_motor_files_exit_cleanly(edits: list[tuple[int, str | None]]) -> None:
    text = _mutate(edits)
    with tempfile.TemporaryDirectory() as directory:
        path = write_motor(Path(directory), text)
        output = Path(directory) / "out.json"
        code, _, err = run(["solve", "--motor", str(path), "--json", str(output)])
        if code == 0:
            assert err == ""
            assert set(json.loads(output.read_text())) >= {"K", "P", "X", "U", "theta"}
        else:
            assert_clean_failure(code, err, str(path))
            assert not output.exists()
        assert sorted(p.name for p in Path(directory).iterdir()) in (
            ["motor.toml"],
            ["motor.toml", "out.json"],
        )


# -- the real console script --------------------------------------------------------------


def _console_script() -> list[str]:
    script = Path(sys.executable).parent / "selftune"
    if not script.exists():
        pytest.skip("the selftune console script is not installed beside this Python")
    return [str(script)]


def test_console_script_prints_the_published_values() -> None:
    result = subprocess.run(
        [*_console_script(), "solve"], capture_output=True, text=True, timeout=120, check=False
    )
    assert result.returncode == 0, result.stderr
    assert result.stderr == ""
    assert f"x_e = X* w = {PUBLISHED['x_e']} A" in result.stdout
    assert f"u_e = U* w = {PUBLISHED['u_e']} V" in result.stdout
    assert PUBLISHED["theta"] in result.stdout


def test_module_entry_point_fails_cleanly(tmp_path: Path) -> None:
    path = write_motor(tmp_path, MOTOR_TOML.replace("[[1.0, 0.0], [0.0, 1.0]]", "[[0.0]]"))
    result = subprocess.run(
        [sys.executable, "-m", "selftune", "solve", "--motor", str(path)],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
        env={**os.environ, "PYTHONWARNINGS": "default"},
    )
    assert result.returncode == 2
    assert result.stdout == ""
    assert result.stderr == f"selftune: error: {path}: [cost] R: must be a 2x2 matrix, got 1x1\n"


def test_output_files_get_the_usual_permissions(tmp_path: Path) -> None:
    import os
    import stat

    out = tmp_path / "solve.json"
    assert main(["solve", "--json", str(out)]) == 0
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(out.stat().st_mode) == 0o666 & ~umask
    out.chmod(0o640)
    assert main(["solve", "--json", str(out)]) == 0
    assert stat.S_IMODE(out.stat().st_mode) == 0o640
