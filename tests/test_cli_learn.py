"""``selftune learn``: files in, the learned controller out; bad input is one line, exit 2."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from learners import regulator
from selftune import SPMSM, lqr, solve_optimal_regulation
from selftune.cli import main
from selftune.learn import (
    LearningOptions,
    LearningProblem,
    Trajectory,
    learn_controller,
    learn_lqr,
    save_trajectory,
)
from selftune.sim import held, prbs, simulate, uniform
from selftune.tuning._interior import CURRENT_REFERENCE_F
from selftune.tuning._saturation import incremental_theta, level_log
from test_saturation_learning import MOTOR as SATURATING
from test_saturation_learning import SATURATION
from test_saturation_learning import _settings as saturating_settings

MOTOR = SPMSM.paper()
PROBLEM = MOTOR.regulation_problem(10.0)
K0 = 20.0 * np.pi * np.eye(2)
Q, R = 1e3 * np.eye(2), np.eye(2)


def toml_matrix(M: np.ndarray) -> str:
    return "[" + ", ".join("[" + ", ".join(repr(float(v)) for v in row) + "]" for row in M) + "]"


def motor_data() -> Trajectory:
    w_base = MOTOR.exogenous(10.0, 10.0)
    return simulate(
        PROBLEM.A,
        PROBLEM.B,
        D=PROBLEM.D,
        exogenous=held(
            lambda t: w_base + np.column_stack([np.sin(1000 * t), 0.1 * np.cos(3000 * t)])
        ),
        K=K0,
        X=-PROBLEM.F,
        exploration=uniform(1.0),
        h=1e-5,
        num_samples=500,
        seed=4,
    )


def regulation_config(path: Path, interval: int = 10) -> Path:
    path.write_text(
        f"""[cost]
Q = {toml_matrix(Q)}
R = {toml_matrix(R)}
[policy]
K0 = {toml_matrix(K0)}
[regulation]
C = {toml_matrix(PROBLEM.C)}
E = {toml_matrix(PROBLEM.E)}
F = {toml_matrix(PROBLEM.F)}
[learning]
interval = {interval}
"""
    )
    return path


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_learn_from_a_file_equals_learning_in_memory(tmp_path: Path, suffix: str) -> None:
    data = motor_data()
    data_file = tmp_path / f"motor{suffix}"
    save_trajectory(data, data_file)
    config = regulation_config(tmp_path / "learn.toml")
    out = tmp_path / "out.json"
    assert main(["learn", str(data_file), "--config", str(config), "--json", str(out)]) == 0
    result = json.loads(out.read_text())
    problem = LearningProblem(Q, R, C=PROBLEM.C, E=PROBLEM.E, F=PROBLEM.F)
    expected = learn_controller(data, problem, K0, LearningOptions(interval=10))
    for key in ("P", "K", "B", "X", "U"):
        np.testing.assert_array_equal(np.array(result[key]), getattr(expected, key), err_msg=key)
    assert result["iterations"] == len(expected.history)
    assert (result["target"], result["method"], result["input_delay"]) == ("continuous", "adp", 0)
    assert result["state"] == ["x1", "x2"] and result["h"] == pytest.approx(1e-5)
    assert result["control_law"]["equations"].startswith("u_k = U w_k - K [xbar_k]")
    assert result["alignment"]["shift"] == 0 and result["quality"]["K_relative_se"] < 1e-4
    optimum = solve_optimal_regulation(PROBLEM, Q, R)
    assert np.linalg.norm(np.array(result["K"]) - optimum.K) < 1e-5 * np.linalg.norm(optimum.K)
    # the old paper learner agrees: the pipeline adds a verdict, not another answer
    paper = regulator(data, PROBLEM.C, PROBLEM.E, PROBLEM.F, Q, R, K0)
    assert np.linalg.norm(np.array(result["K"]) - paper.K) < 1e-8 * np.linalg.norm(paper.K)


def test_the_learn_json_states_the_whole_cost_and_the_pi_equivalent(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The README's log with an integral weight in CONFIG.toml: the JSON carries the cost
    the law optimized (Q, R, Q_i as in the file), h and the delay, and the PI equivalent
    the printout shows; the Q_i reached the learner (its K_i is the optimum's for it)."""
    examples = Path(__file__).resolve().parents[1] / "examples" / "data"
    weight = [[1e7, 0.0], [0.0, 2e7]]
    text = (examples / "learn.toml").read_text()
    config = tmp_path / "learn.toml"
    config.write_text(text.replace("[policy]", f"Q_i = {weight}\n[policy]", 1))
    out = tmp_path / "law.json"
    args = ["learn", str(examples / "drive_log.csv"), "--config", str(config)]
    assert main([*args, "--json", str(out)]) == 0
    result = json.loads(out.read_text())
    assert result["cost"] == {"Q": Q.tolist(), "R": R.tolist(), "Q_i": weight}
    assert (result["h"], result["input_delay"]) == (pytest.approx(1e-4), 1)
    pi = result["pi_equivalent"]
    assert pi["stable"] is True and 0.0 < pi["excess_cost"] < 0.1
    printed = capsys.readouterr().out
    assert f"excess cost over the learned law {pi['excess_cost']:+.2%}" in printed
    default = tmp_path / "default.json"
    args = ["learn", str(examples / "drive_log.csv"), "--config", str(examples / "learn.toml")]
    assert main([*args, "--json", str(default)]) == 0
    unweighted = json.loads(default.read_text())
    assert unweighted["cost"]["Q_i"] != weight
    assert not np.allclose(unweighted["K_i"], result["K_i"], rtol=0.01)


def test_learn_without_regulation_learns_state_feedback(tmp_path: Path) -> None:
    A = np.array([[0.0, 1.0], [-2.0, 0.3]])
    B = np.array([[0.0], [1.0]])
    K_init = lqr(A, B, np.eye(2), np.eye(1))[0]
    data = simulate(
        A, B, K=K_init, exploration=prbs(1.0, 5), x0=[1.0, 0.0], h=1e-3, num_samples=4000, seed=2
    )
    save_trajectory(data, tmp_path / "plant.csv")
    (tmp_path / "lqr.toml").write_text(
        f"[cost]\nQ = {toml_matrix(np.eye(2))}\nR = [[1.0]]\n[policy]\nK0 = {toml_matrix(K_init)}\n"
    )
    out = tmp_path / "out.json"
    args = ["learn", str(tmp_path / "plant.csv"), "--config", str(tmp_path / "lqr.toml")]
    assert main([*args, "--json", str(out)]) == 0
    result = json.loads(out.read_text())
    assert result["X"] == [[], []] and result["U"] == [[]] and result["K_i"] is None
    expected = learn_lqr(data, LearningProblem(np.eye(2), np.eye(1)), K_init)
    np.testing.assert_allclose(np.array(result["K"]), expected.K, rtol=1e-8)


def test_learn_file_identifies_a_saturating_motor_about_its_operating_current(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A saturating motor's log at 70 % of rated torque (0.2 s on the realistic drive, as
    the incremental structure's own test) learned by ``selftune learn`` with ``structure =
    "incremental"`` (docs/saturation.md's file): the law the learner gives in memory with
    the log's options, the JSON's R_s, incremental L_d, L_q, L_dq and flux offset phi_pm,
    phi_q within 3.5 of their standard errors of the truth at the log's mean current
    (``d psi / d i`` and ``psi - L i`` there), and the printout showing L_dq and phi_q."""
    settings, drive = saturating_settings()
    log, options = level_log(SATURATING, SATURATION, settings, drive, 0.7, seconds=0.2, seed=0)
    save_trajectory(log, tmp_path / "level.npz")
    # docs/saturation.md's learn file: it must state the options the drive's log needs
    docs = (Path(__file__).resolve().parents[1] / "docs" / "saturation.md").read_text()
    section = docs.split("## In a learn file", 1)[1].split("\n## ", 1)[0]
    config = tmp_path / "incremental.toml"
    config.write_text(re.findall(r"^```toml\n(.*?)^```", section, re.DOTALL | re.MULTILINE)[0])
    out = tmp_path / "out.json"
    args = ["learn", str(tmp_path / "level.npz"), "--config", str(config), "--json", str(out)]
    assert main(args) == 0
    result = json.loads(out.read_text())
    problem = LearningProblem(
        settings.Q, settings.R, C=np.eye(2), F=CURRENT_REFERENCE_F,
        integral_action=settings.integral_action, integral_weight=settings.Q_i,
    )  # fmt: skip
    expected = learn_controller(log, problem, settings.K0, options)
    for key in ("K", "K_i", "U"):
        np.testing.assert_array_equal(np.array(result[key]), getattr(expected.law, key), key)
    motor = result["quality"]["motor"]
    # the truth's flux offset over 1 Wb: c = psi(i0) - L i0 itself, Wb (phi_pm, phi_q)
    truth = incremental_theta(SATURATION, SATURATING.R_s, np.mean(log.x, axis=0), 1.0)
    names = ("R_s", "L_d", "L_q", "L_dq", "phi_pm", "phi_q")
    for name, true in zip(names, truth, strict=True):
        se = motor[f"{name}_se"]
        assert se > 0.0 and abs(motor[name] - true) < 3.5 * se, (name, motor[name], se, true)
    printed = capsys.readouterr().out
    for name, unit in (("L_dq", "H"), ("phi_q", "Wb")):
        assert f"{name} = {motor[name]:.6g} +- {motor[f'{name}_se']:.2g} {unit}" in printed


def one_error_line(capsys: pytest.CaptureFixture[str]) -> str:
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert "Traceback" not in captured.err
    return lines[0]


@pytest.mark.parametrize(
    ("edit", "expected"),
    [
        (lambda text: text.replace("[policy]\n", "[policy]\nK1 = 1\n"), "[policy] K1: unknown key"),
        (
            lambda text: re.sub(r"K0 = .*", "K0 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]", text),
            "[policy] K0: must be a 2x2 matrix, got 2x3",
        ),
        (
            lambda text: text.replace(
                "[cost]\n", "[cost]\nQ = [[1.0, 2.0], [2.0, 1.0]]\n", 1
            ).replace("Q = [[1000.0", "#", 1),
            "Q: must be symmetric positive definite",
        ),
        (lambda text: text.replace("interval = 10", "interval = 0"), "interval: must be positive"),
        (lambda text: text.replace("F = [[", "F = [[1.0, "), "[regulation] F"),
        (lambda text: text.split("[policy]")[0], "[policy]: missing table"),
        (  # data with w columns and no [regulation]: said against the file (was a traceback)
            lambda text: text.split("[regulation]")[0] + "[learning]" + text.split("[learning]")[1],
            "[regulation]: missing table, but the data have 2 exogenous column(s)",
        ),
        (  # a configuration the learner objects to is said against the file (was the data's)
            lambda text: (
                re.sub(r"E = .*", "E = [[0.0, 1.0], [-1.0, 0.0]]", text)
                + 'target = "digital"\ninput_delay = 0\n'
            ),
            "learn.toml: [regulation] E: the digital target and identify-then-design need w held",
        ),
        (  # the digital optimum depends on the delay: never assumed silently
            lambda text: text + 'target = "digital"\n',
            '[learning] input_delay: missing: target = "digital"',
        ),
        (  # an integral weight with nothing to weigh: the key and the fix
            lambda text: text.replace("[policy]", "Q_i = [[1.0, 0.0], [0.0, 1.0]]\n[policy]"),
            "[cost] Q_i: weighs the integrated error, but integral action is off: set "
            "[learning] integral_action = true",
        ),
        (
            lambda text: (
                text.replace("[policy]", "Q_i = [[1.0, 0.0], [0.0, -1.0]]\n[policy]")
                + "integral_action = true\n"
            ),
            "[cost] Q_i: must be symmetric positive definite (smallest eigenvalue -1)",
        ),
        (
            lambda text: (
                text.replace("[policy]", "Q_i = [[1.0]]\n[policy]") + "integral_action = true\n"
            ),
            "[cost] Q_i: must be a 2x2 matrix, got 1x1",
        ),
        (  # the saturating motor's structure: the choices listed, the key named
            lambda text: text + 'method = "identify"\nstructure = "saturating"\n',
            '[learning] structure: must be one of "none", "spmsm", "ipmsm", "incremental", '
            "got 'saturating'",
        ),
        (
            lambda text: text + 'structure = "incremental"\nelectrical_speed = 400.0\n',
            "[learning] structure: a model structure is for method = 'identify'",
        ),
        (
            lambda text: text + 'method = "identify"\nstructure = "incremental"\n',
            '[learning] electrical_speed: structure = "incremental" needs p speed (rad/s)',
        ),
        (
            lambda text: (
                text + 'method = "identify"\nstructure = "incremental"\nelectrical_speed = -inf\n'
            ),
            "[learning] electrical_speed: must be finite, got -inf",
        ),
        (  # one operating current's motor: no speed schedule on it, said with the way out
            lambda text: (
                text + 'method = "identify"\nstructure = "incremental"\n'
                "[schedule]\npole_pairs = 4\nspeeds = [5.0, 100.0]\n"
            ),
            "[schedule]: a speed schedule is designed on a surface or interior motor, not on "
            '[learning] structure = "incremental" (its L_dq and phi_q hold at one operating '
            'current): remove [schedule], or set structure = "ipmsm"',
        ),
    ],
)
def test_bad_config_is_one_line_naming_the_key(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    edit,
    expected: str,  # type: ignore[no-untyped-def]
) -> None:
    save_trajectory(motor_data(), tmp_path / "motor.csv")
    config = regulation_config(tmp_path / "learn.toml")
    config.write_text(edit(config.read_text()))
    out = tmp_path / "out.json"
    code = main(["learn", str(tmp_path / "motor.csv"), "--config", str(config), "--json", str(out)])
    assert code == 2
    line = one_error_line(capsys)
    assert "learn.toml" in line
    assert expected in line
    assert not out.exists()


def test_bad_data_and_weak_excitation_are_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = regulation_config(tmp_path / "learn.toml")
    data_file = tmp_path / "motor.csv"
    save_trajectory(motor_data(), data_file)
    text = data_file.read_text().splitlines()
    text[5] = text[5].replace(text[5].split(",")[1], "nan", 1)
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(text) + "\n")
    assert main(["learn", str(bad), "--config", str(config)]) == 2
    assert "bad.csv" in one_error_line(capsys)

    short = motor_data().head(8)  # 8 one-sample intervals for 11 unknowns
    save_trajectory(short, tmp_path / "short.npz")
    assert main(["learn", str(tmp_path / "short.npz"), "--config", str(config)]) == 2
    line = one_error_line(capsys)
    assert "short.npz" in line and ("intervals" in line or "samples" in line)

    no_w = Trajectory(t=short.t, x=short.x, u=short.u)
    save_trajectory(no_w, tmp_path / "no_w.csv")
    assert main(["learn", str(tmp_path / "no_w.csv"), "--config", str(config)]) == 2
    assert "exogenous" in one_error_line(capsys)


@pytest.mark.parametrize(("bus", "refused"), [(10.0, True), (48.0, True), (540.0, False)])
def test_a_dc_bus_that_cannot_have_applied_the_logged_voltages_is_refused_naming_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], bus: float, refused: bool
) -> None:
    """The example log's voltages are about 53 V (its drive's bus 540 V); on 10 V or 48 V
    (2 V_dc / pi: 6.4 V, 31 V) no inverter applies them. Before, 10 V was learned with
    the flux's standard error 6,000 times the one on 540 V (the carrier's pulses computed
    on duties far outside [0, 1])."""
    examples = Path(__file__).resolve().parents[1] / "examples" / "data"
    config = tmp_path / "learn.toml"
    config.write_text(
        (examples / "learn.toml").read_text()
        + 'method = "identify"\nstructure = "spmsm"\nelectrical_speed = 150.0\n'
        + f"dc_voltage = {bus}\n"
    )
    out = tmp_path / "out.json"
    args = ["learn", str(examples / "drive_log.csv"), "--config", str(config), "--json", str(out)]
    assert main(args) == (2 if refused else 0)
    if refused:
        line = one_error_line(capsys)
        assert "drive_log.csv: dc_voltage: says" in line and "2 V_dc / pi" in line
        assert not out.exists()
    else:
        motor = json.loads(out.read_text())["quality"]["motor"]
        assert motor["phi_pm"] == pytest.approx(0.35, abs=3 * motor["phi_pm_se"] + 1e-4)


@pytest.mark.parametrize(("nameplate", "refused"), [(0.6, False), (6.0, True), (0.06, False)])
def test_a_nameplate_resistance_refuses_a_fit_far_from_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], nameplate: float, refused: bool
) -> None:
    """``[learning] nameplate_resistance``: the example log's motor (0.6 ohm, 8 mH, fitted
    0.65 ohm) is learned against its own nameplate; against 6 ohm (10 times, moving the
    sampled plant's pole by 7%) refused naming the key; against 0.06 ohm, 10 times the
    other way but a gap of 0.8% of the pole, where the law barely depends on R_s, learned
    (the rule of tune's commissionings)."""
    examples = Path(__file__).resolve().parents[1] / "examples" / "data"
    config = tmp_path / "learn.toml"
    config.write_text(
        (examples / "learn.toml").read_text()
        + 'method = "identify"\nstructure = "spmsm"\nelectrical_speed = 150.0\n'
        + f"nameplate_resistance = {nameplate}\n"
    )
    args = ["learn", str(examples / "drive_log.csv"), "--config", str(config)]
    assert main(args) == (2 if refused else 0)
    if refused:
        line = one_error_line(capsys)
        assert "is 0.108 times the nameplate's 6 ohm" in line
        assert "[learning] nameplate_resistance is wrong: check it" in line
