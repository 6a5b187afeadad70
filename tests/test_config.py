"""Reading TOML configuration: the generic helpers and MOTOR.toml."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from selftune import SPMSM, DataFileError, InputError
from selftune.config import (
    ConfigFile,
    ConfigTable,
    MotorConfig,
    load_motor_config,
    read_toml,
)
from selftune.errors import SelftuneDeprecationWarning
from selftune.tuning import tuning_settings

MOTOR_TOML = """\
[motor]            # R_s, L_s, phi_pm, p, and optional J
R_s = 0.439
L_s = 0.0601
phi_pm = 0.46
p = 2
[operating_point]  # mechanical speed in rad/s, torque reference in N m
speed = 10.0
torque = 10.0
[cost]             # weights of the cost (5); both symmetric positive definite
Q = [[1000.0, 0.0], [0.0, 1000.0]]
R = [[1.0, 0.0], [0.0, 1.0]]
"""


def write(tmp_path: Path, text: str, name: str = "motor.toml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def load_error(tmp_path: Path, text: str) -> str:
    path = write(tmp_path, text)
    with pytest.raises(DataFileError) as info:
        load_motor_config(path)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(f"{path}: ")
    return message[len(f"{path}: ") :]


# -- the motor file ---------------------------------------------------------------------


def test_the_documented_file_is_the_paper_setting(tmp_path: Path) -> None:
    config = load_motor_config(write(tmp_path, MOTOR_TOML))
    default = MotorConfig.default()
    assert config.motor.R_s == 0.439
    assert config.motor.L_s == 0.0601
    assert config.motor.phi_pm == 0.46
    assert config.motor.p == 2
    assert isinstance(config.motor.p, int)
    assert config.motor.J is None
    assert (config.speed, config.torque) == (default.speed, default.torque) == (10.0, 10.0)
    np.testing.assert_array_equal(config.Q, default.Q)
    np.testing.assert_array_equal(config.R, default.R)
    assert dict(config.learning) == {}
    assert config.source == str(tmp_path / "motor.toml")


def test_default_is_the_paper_preset() -> None:
    config = MotorConfig.default()
    assert config.motor == SPMSM.paper()
    np.testing.assert_array_equal(config.Q, 1e3 * np.eye(2))
    np.testing.assert_array_equal(config.R, np.eye(2))
    assert config.source == "paper preset"
    np.testing.assert_allclose(config.exogenous(), [2 * 10.0 * 0.46, 10.0])
    np.testing.assert_array_equal(
        config.regulation_problem().A, SPMSM.paper().regulation_problem(10.0).A
    )


def test_optional_tables_and_keys_take_the_paper_defaults(tmp_path: Path) -> None:
    text = (
        "[motor]\nR_s = 1\nL_s = 0.01\nphi_pm = 0.1\np = 4\nJ = 0.002\n"
        "[cost]\nR = [[2, 0], [0, 3]]\n"
    )
    config = load_motor_config(write(tmp_path, text))
    assert config.motor == SPMSM(R_s=1.0, L_s=0.01, phi_pm=0.1, p=4, J=0.002)
    assert (config.speed, config.torque) == (10.0, 10.0)
    np.testing.assert_array_equal(config.Q, 1e3 * np.eye(2))
    np.testing.assert_array_equal(config.R, np.diag([2.0, 3.0]))


def test_operating_point_may_be_zero_or_negative(tmp_path: Path) -> None:
    text = MOTOR_TOML.replace("speed = 10.0", "speed = -50").replace("torque = 10.0", "torque = 0")
    config = load_motor_config(write(tmp_path, text))
    assert (config.speed, config.torque) == (-50.0, 0.0)


def test_whole_float_pole_pairs_are_accepted(tmp_path: Path) -> None:
    config = load_motor_config(write(tmp_path, MOTOR_TOML.replace("p = 2", "p = 3.0")))
    assert config.motor.p == 3
    assert isinstance(config.motor.p, int)


def test_a_learning_table_is_kept_raw(tmp_path: Path) -> None:
    text = MOTOR_TOML + "[learning]\nh = 1e-5\nK0 = [[62.8, 0], [0, 62.8]]\n"
    config = load_motor_config(write(tmp_path, text))
    assert config.learning == {"h": 1e-5, "K0": [[62.8, 0], [0, 62.8]]}
    with pytest.raises(TypeError):
        config.learning["h"] = 1.0  # type: ignore[index]


def test_the_old_name_of_the_sampling_period_is_read_with_a_deprecation_warning(
    tmp_path: Path,
) -> None:
    text = MOTOR_TOML + "[learning]\nsampling = 2e-5\n"
    with pytest.warns(
        SelftuneDeprecationWarning, match=r"\[learning\] sampling is deprecated: call it h"
    ):
        config = load_motor_config(write(tmp_path, text))
    assert config.learning == {"sampling": 2e-5}  # kept as written
    with pytest.warns(SelftuneDeprecationWarning):
        assert tuning_settings(config).h == 2e-5
    with pytest.raises(
        DataFileError, match=r"\[learning\] sampling: the old name of h, which is set"
    ):
        load_motor_config(write(tmp_path, text + "h = 2e-5\n"))


def test_the_command_line_says_a_deprecated_key_in_one_line_after_success(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from selftune.cli import main

    motor = write(tmp_path, MOTOR_TOML + "[learning]\nsampling = 1e-5\n")
    assert main(["solve", "--motor", str(motor)]) == 0
    lines = capsys.readouterr().err.splitlines()
    assert lines == [
        f"selftune: warning: {motor}: [learning] sampling is deprecated: call it h (same value)"
    ]
    bad = write(tmp_path, MOTOR_TOML.replace("p = 2", "p = -2") + "[learning]\nsampling = 1e-5\n")
    assert main(["solve", "--motor", str(bad)]) == 2
    assert len(capsys.readouterr().err.splitlines()) == 1


@pytest.mark.parametrize(
    ("line", "expected"),
    [
        ("anything = 'x'", "[learning] anything: unknown key (known: h,"),
        ("sampeling = 1e-5", "[learning] sampeling: unknown key (known: h,"),
        ("sampling = -1e-5", "[learning] sampling: must be positive"),
        ("sampling = 1e-12", "[learning] sampling: must be between 1e-08 and 0.1 s"),
        ("exploration = 'a'", "[learning] exploration: must be a number, got a string"),
        ("K0 = [[1.0]]", "[learning] K0: must be a 2x2 matrix"),
        ("input_hold = 1e6", "[learning] input_hold: must be at most 200000"),
        ("max_iterations = 2.5", "[learning] max_iterations: must be a whole number"),
    ],
)
def test_the_learning_table_is_checked_on_load(tmp_path: Path, line: str, expected: str) -> None:
    """Every command that reads MOTOR.toml (solve too) refuses a bad [learning] table."""
    message = load_error(tmp_path, MOTOR_TOML + "[learning]\n" + line + "\n")
    assert message.startswith(expected), message


def test_the_integral_weight_is_read_with_integral_action(tmp_path: Path) -> None:
    """[cost] Q_i reaches the learner's problem; without it the learner's default stands."""
    from selftune.learn import LearningProblem
    from selftune.tuning import known_flux_form
    from selftune.tuning._learning import learning_problem

    weight = [[3e6, 1e5], [1e5, 2e6]]
    text = MOTOR_TOML + f"Q_i = {weight}\n[learning]\nintegral_action = true\n"
    config = load_motor_config(write(tmp_path, text))
    np.testing.assert_array_equal(config.Q_i, weight)
    settings = tuning_settings(config)
    np.testing.assert_array_equal(settings.Q_i, weight)

    class Drive:
        pole_pairs = config.motor.p

    problem = learning_problem(Drive(), settings, config.motor.phi_pm)  # type: ignore[arg-type]
    np.testing.assert_array_equal(problem.integral_weight, weight)
    unweighted = tuning_settings(
        load_motor_config(write(tmp_path, MOTOR_TOML + "[learning]\nintegral_action = true\n"))
    )
    assert unweighted.Q_i is None
    C, _, F, _ = known_flux_form(2, 10.0, 10.0, 0.46)
    default = LearningProblem(settings.Q, settings.R, C=C, F=F, integral_action=True)
    np.testing.assert_array_equal(
        learning_problem(Drive(), unweighted, 0.46).integral_weight,  # type: ignore[arg-type]
        default.integral_weight,
    )


@pytest.mark.parametrize(
    ("motor", "extra", "share"),
    [
        ("L_s = 0.002\n", "", 0.02),  # a surface motor
        ("L_d = 0.002\nL_q = 0.002\n", "", 0.02),  # equal inductances: a surface motor
        ("L_d = 0.002\nL_q = 0.005\n", "", 0.03),  # an interior motor
        ("L_d = 0.002\nL_q = 0.005\n", "[saturation]\ni_sat = 6.0\ndrop = 0.15\n", 0.02),
    ],
)
def test_a_drive_explores_at_a_share_of_its_bus_an_interior_motor_more(
    tmp_path: Path, motor: str, extra: str, share: float
) -> None:
    """A [drive] with a DC bus sets the exploration's default: 2% of the bus, 3% for an
    interior motor without [saturation]; a [learning] exploration always wins."""
    text = (
        f"[motor]\nR_s = 0.2\n{motor}phi_pm = 0.1\np = 4\n"
        "[operating_point]\nspeed = 100.0\ntorque = 5.0\n"
        "[drive]\ndc_voltage = 540.0\nswitching_frequency = 10000.0\n" + extra
    )
    config = load_motor_config(write(tmp_path, text))
    assert tuning_settings(config).exploration == pytest.approx(share * 540.0, rel=1e-12)
    chosen = load_motor_config(write(tmp_path, text + "[learning]\nexploration = 4.5\n"))
    assert tuning_settings(chosen).exploration == 4.5


@pytest.mark.parametrize(
    ("lines", "expected"),
    [
        (
            "Q_i = [[1.0, 0.0], [0.0, 1.0]]\n",
            "[cost] Q_i: weighs the integrated current error, but integral action is off: "
            "set [learning] integral_action = true, or remove Q_i",
        ),
        (
            "Q_i = [[1.0, 0.0], [0.0, 1.0]]\n[learning]\nintegral_action = false\n",
            "[cost] Q_i: weighs the integrated current error, but integral action is off",
        ),
        (
            "Q_i = [[1.0, 2.0], [2.0, 1.0]]\n[learning]\nintegral_action = true\n",
            "[cost] Q_i: must be symmetric positive definite (smallest eigenvalue -1)",
        ),
        (
            "Q_i = [[1.0, 0.0, 0.0]]\n[learning]\nintegral_action = true\n",
            "[cost] Q_i: must be a 2x2 matrix, got 1x3",
        ),
        (
            "Q_i = [[1e20, 0.0], [0.0, 1.0]]\n[learning]\nintegral_action = true\n",
            "[cost] Q_i: entries must be 0 or between 1e-12 and 1e+12 in magnitude",
        ),
    ],
)
def test_a_bad_integral_weight_names_the_key(tmp_path: Path, lines: str, expected: str) -> None:
    message = load_error(tmp_path, MOTOR_TOML + lines)
    assert message.startswith(expected), message


def test_motor_config_is_frozen_and_checks_its_fields() -> None:
    config = MotorConfig.default()
    with pytest.raises(AttributeError):
        config.speed = 3.0  # type: ignore[misc]
    with pytest.raises(ValueError):
        config.Q[0, 0] = 1.0
    with pytest.raises(InputError, match="R: must be symmetric positive definite"):
        MotorConfig(motor=SPMSM.paper(), R=np.zeros((2, 2)))
    with pytest.raises(InputError, match="speed"):
        MotorConfig(motor=SPMSM.paper(), speed=float("nan"))


@pytest.mark.parametrize(
    ("old", "new", "expected"),
    [
        ("L_s = 0.0601\n", "", "[motor] L_s: missing"),
        ("p = 2\n", "", "[motor] p: missing"),
        (
            "L_s =",
            "Ls =",
            "[motor] Ls: unknown key (known: R_s, L_s, L_d, L_q, phi_pm, p, J; did you mean L_s?)",
        ),
        ("speed =", "sped =", "[operating_point] sped: unknown key"),
        ("R_s = 0.439", "R_s = 0", "[motor] R_s: must be positive, got 0"),
        ("phi_pm = 0.46", "phi_pm = -0.46", "[motor] phi_pm: must be positive"),
        ("R_s = 0.439", "R_s = nan", "[motor] R_s: must be finite, got nan"),
        ("L_s = 0.0601", "L_s = inf", "[motor] L_s: must be finite"),
        ("L_s = 0.0601", "L_s = '0.0601'", "[motor] L_s: must be a number, got a string"),
        ("p = 2", "p = 2.5", "[motor] p: must be a whole number, got 2.5"),
        ("p = 2", "p = true", "[motor] p: must be a number, got a boolean"),
        ("p = 2", "p = 0", "[motor] p: must be positive"),
        ("speed = 10.0", "speed = nan", "[operating_point] speed: must be finite"),
        ("torque = 10.0", "torque = [1.0]", "[operating_point] torque: must be a number"),
        (
            "Q = [[1000.0, 0.0], [0.0, 1000.0]]",
            "Q = [[1000.0, 1.0], [0.0, 1000.0]]",
            "[cost] Q: must be symmetric positive definite (it is not symmetric)",
        ),
        (
            "Q = [[1000.0, 0.0], [0.0, 1000.0]]",
            "Q = [[1000.0, 0.0], [0.0, 0.0]]",
            "[cost] Q: must be symmetric positive definite (smallest eigenvalue 0)",
        ),
        (
            "R = [[1.0, 0.0], [0.0, 1.0]]",
            "R = [[1.0, 2.0], [2.0, 1.0]]",
            "[cost] R: must be symmetric positive definite (smallest eigenvalue -1)",
        ),
        (
            "Q = [[1000.0, 0.0], [0.0, 1000.0]]",
            "Q = [[1000.0, 0.0, 0.0], [0.0, 1000.0, 0.0]]",
            "[cost] Q: must be a 2x2 matrix, got 2x3",
        ),
        (
            "R = [[1.0, 0.0], [0.0, 1.0]]",
            "R = [[1e11, 0.0], [0.0, 1.0]]",
            "[cost] R: must be symmetric positive definite; it is nearly singular"
            " (eigenvalues from 1 to 1e+11)",
        ),
        (
            "R = [[1.0, 0.0], [0.0, 1.0]]",
            "R = [[1e20, 0.0], [0.0, 1.0]]",
            "[cost] R: entries must be 0 or between 1e-12 and 1e+12 in magnitude, got 1e+20",
        ),
        ("R_s = 0.439", "R_s = 1e-300", "[motor] R_s: must be between 1e-06 and 1000 ohm"),
        ("L_s = 0.0601", "L_s = 1e300", "[motor] L_s: must be between 1e-07 and 10 H"),
        ("phi_pm = 0.46", "phi_pm = 1e300", "[motor] phi_pm: must be between 1e-05 and 10 Wb"),
        ("p = 2", "p = 1e15", "[motor] p: must be at most 100"),
        ("p = 2", "p = 1" + "0" * 400, "[motor] p: must be finite"),
        ("torque = 10.0", "torque = 1e308", "[operating_point] torque: must be between -1e+06"),
        ("speed = 10.0", "speed = -1e9", "[operating_point] speed: must be between -100000"),
        ("speed = 10.0", "speed = 9000", "[operating_point] speed: 9000 rad/s is too fast"),
        ("R = [[1.0, 0.0], [0.0, 1.0]]", "R = [1.0, 1.0]", "[cost] R: must be a 2x2 matrix"),
        ("R = [[1.0, 0.0], [0.0, 1.0]]", "R = 1.0", "[cost] R: must be a 2x2 matrix"),
        ("R = [[1.0, 0.0], [0.0, 1.0]]", "R = [[1.0, 0.0], [0.0]]", "[cost] R: rows have"),
        ("R = [[1.0, 0.0], [0.0, 1.0]]", "R = [[1.0, 0.0], [0.0, nan]]", "[cost] R: contains NaN"),
        ("R = [[1.0, 0.0], [0.0, 1.0]]", "R = [[1.0, 0.0], [0.0, '1']]", "[cost] R: entries must"),
        ("[cost]", "[costs]", "costs: unknown table (known: [motor], [operating_point], [cost]"),
        ("[motor]", "[Motor]", "Motor: unknown table"),
        ("[motor]            # R_s, L_s, phi_pm, p, and optional J\n", "", "R_s: a key outside"),
    ],
)
def test_bad_values_name_the_table_and_key(
    tmp_path: Path, old: str, new: str, expected: str
) -> None:
    assert old in MOTOR_TOML
    message = load_error(tmp_path, MOTOR_TOML.replace(old, new, 1))
    assert message.startswith(expected), message


def test_a_known_table_given_as_a_value_is_named(tmp_path: Path) -> None:
    text = "cost = 1\n" + MOTOR_TOML[: MOTOR_TOML.index("[cost]")]
    assert load_error(tmp_path, text) == "cost: must be a table [cost], got a number"


def test_a_missing_motor_table_is_named(tmp_path: Path) -> None:
    assert load_error(tmp_path, "[cost]\n") == "[motor]: missing table"


def test_an_empty_file_lacks_the_motor_table(tmp_path: Path) -> None:
    assert load_error(tmp_path, "") == "[motor]: missing table"


# -- reading TOML -----------------------------------------------------------------------


def test_read_toml_names_an_unreadable_file(tmp_path: Path) -> None:
    missing = tmp_path / "absent.toml"
    with pytest.raises(DataFileError, match=r"absent\.toml: cannot read the file"):
        read_toml(missing)
    with pytest.raises(DataFileError, match="cannot read the file"):
        read_toml(tmp_path)


def test_read_toml_names_a_file_that_is_not_toml(tmp_path: Path) -> None:
    with pytest.raises(DataFileError, match=r"bad\.toml: not a valid TOML file \(.*line 1"):
        read_toml(write(tmp_path, "this is = = not toml\n", "bad.toml"))
    binary = tmp_path / "binary.toml"
    binary.write_bytes(b"\xff\xfe\x00")
    with pytest.raises(DataFileError, match=r"binary\.toml: not a TOML file \(not UTF-8"):
        read_toml(binary)


def test_read_toml_returns_the_document(tmp_path: Path) -> None:
    assert read_toml(write(tmp_path, "[a]\nb = 1\n")) == {"a": {"b": 1}}


def test_read_toml_accepts_a_byte_order_mark(tmp_path: Path) -> None:
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf[a]\nb = 1\n")
    assert read_toml(path) == {"a": {"b": 1}}


def test_read_toml_refuses_what_is_not_a_small_regular_file(tmp_path: Path) -> None:
    fifo = tmp_path / "fifo.toml"
    os.mkfifo(fifo)
    with pytest.raises(DataFileError, match=r"fifo\.toml: cannot read the file \(it is a FIFO"):
        read_toml(fifo)  # refused without waiting for a writer
    with pytest.raises(DataFileError, match=r"cannot read the file \(it is a character device"):
        read_toml("/dev/null")
    big = write(tmp_path, "# " + "x" * (1 << 20) + "\n", "big.toml")
    with pytest.raises(DataFileError, match=r"more than the 1048576 bytes \(1 MiB\)"):
        read_toml(big)
    deep = write(tmp_path, "a = " + "[" * 5000 + "]" * 5000 + "\n", "deep.toml")
    with pytest.raises(DataFileError, match=r"deep\.toml: not a valid TOML file \(nested too"):
        read_toml(deep)


# -- the generic table helpers ----------------------------------------------------------


def test_table_getters() -> None:
    table = ConfigTable(
        "f.toml",
        "learning",
        {"n": 3, "x": -2.5, "M": [[1, 2, 3]], "S": [[2.0, 1.0], [1.0, 2.0]]},
    )
    assert table.number("x") == -2.5
    assert table.number("absent", 4.0) == 4.0
    assert table.positive("n") == 3.0
    assert table.positive_integer("n") == 3
    assert table.positive_integer("absent", 7) == 7
    np.testing.assert_array_equal(table.matrix("M", (1, None)), [[1.0, 2.0, 3.0]])
    np.testing.assert_array_equal(table.matrix("absent", (2, 2), np.eye(2)), np.eye(2))
    np.testing.assert_array_equal(table.positive_definite("S", 2), [[2.0, 1.0], [1.0, 2.0]])
    assert "n" in table
    assert "absent" not in table


@pytest.mark.parametrize(
    ("call", "expected"),
    [
        (lambda t: t.number("absent"), "f.toml: [learning] absent: missing"),
        (lambda t: t.positive("x"), "f.toml: [learning] x: must be positive, got -2.5"),
        (lambda t: t.positive_integer("x"), "f.toml: [learning] x: must be positive"),
        (lambda t: t.matrix("M", (2, None)), "f.toml: [learning] M: must be a 2xn matrix, got 1x3"),
        (lambda t: t.matrix("x", (2, 2)), "f.toml: [learning] x: must be a 2x2 matrix"),
        (lambda t: t.positive_definite("M", 3), "f.toml: [learning] M: must be a 3x3 matrix"),
    ],
)
def test_table_getter_errors(call: object, expected: str) -> None:
    table = ConfigTable("f.toml", "learning", {"x": -2.5, "M": [[1, 2, 3]]})
    with pytest.raises(DataFileError) as info:
        call(table)  # type: ignore[operator]
    assert str(info.value).startswith(expected), str(info.value)


def test_table_known_keys_catch_typos() -> None:
    with pytest.raises(DataFileError, match=r"\[learning\] sampeling: unknown key .*sampling\?"):
        ConfigTable("f.toml", "learning", {"sampeling": 1e-5}, known_keys=["sampling", "K0"])
    with pytest.raises(DataFileError, match="did you mean K0"):
        ConfigTable("f.toml", "learning", {"k0": 1}, known_keys=["sampling", "K0"])


def test_config_file_tables(tmp_path: Path) -> None:
    path = write(tmp_path, "[a]\nx = 1\n[b]\nanything = 2\n")
    config = ConfigFile(path, {"a": ("x",), "b": (), "c": ("y",)})
    assert config.table("a").number("x") == 1.0
    assert config.table("b").number("anything") == 2.0
    assert "c" not in config
    assert "y" not in config.table("c")
    with pytest.raises(DataFileError, match=r"\[c\]: missing table"):
        config.table("c", required=True)
    with pytest.raises(DataFileError, match=r"\[a\] x: unknown key"):
        ConfigFile(path, {"a": ("y",), "b": ()}).table("a")
