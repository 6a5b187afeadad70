"""``selftune reproduce`` and ``selftune tune``: complete outputs, sane numbers, clean errors."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from selftune import SPMSM, solve_optimal_regulation
from selftune.cli import main
from selftune.report import Reproduction

PAPER_THETA = [1.8743, 1.8743, 0, 31.1868, 0, 0, 31.1868, 0, 27.1642, -31.1868, -9.9210]
FIGURES = ("fig1", "fig2", "fig3", "fig4", "fig5")


def run_reproduce(out: Path, monkeypatch: pytest.MonkeyPatch, reproduction: Reproduction) -> None:
    """``selftune reproduce --out OUT`` on the session's reproduction (``reproduce(0)``,
    what the command computes with the default seed); it succeeds and leaves no temporary
    file."""
    import selftune.report

    seeds: list[int] = []

    def session_reproduce(seed: int, step: Callable[[str], None]) -> Reproduction:
        seeds.append(seed)
        return reproduction

    monkeypatch.setattr(selftune.report, "reproduce", session_reproduce)
    assert main(["reproduce", "--out", str(out)]) == 0
    assert seeds == [0]
    assert not [p for p in out.iterdir() if p.name.startswith(".")]  # no temporary files


def test_reproduce_writes_the_numbers_and_a_file_per_figure(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    reproduction: Reproduction,
    quick_figures: list[str],
) -> None:
    """The command writes the session's reproduction: the numbers, and each figure as PNG
    and SVG (small files here; the next test saves the real ones)."""
    out = tmp_path / "results"
    run_reproduce(out, monkeypatch, reproduction)
    printed = capsys.readouterr().out
    for stem in FIGURES:
        for suffix in (".png", ".svg"):
            assert (out / f"{stem}{suffix}").is_file(), stem
    results = json.loads((out / "results.json").read_text())
    np.testing.assert_allclose(results["model_based"]["theta"], PAPER_THETA, atol=1e-4)
    algorithms = results["algorithms"]
    assert set(algorithms) == {"1", "2", "3", "offpolicy"}
    for name in ("2", "3", "offpolicy"):
        assert algorithms[name]["theta_relative_error"] < 1e-5
        assert algorithms[name]["U_relative_error"] < 1e-4
    assert algorithms["1"]["K_relative_error"] < 1e-5
    assert algorithms["1"]["rank"] == 9 and algorithms["1"]["unknowns"] == 11
    assert algorithms["1"]["U_relative_error"] > 0.1
    assert abs(algorithms["3"]["identified"]["phi_pm"] / 0.46 - 1) < 1e-4
    assert algorithms["offpolicy"]["data_seconds"] < algorithms["2"]["data_seconds"]
    # every printed Theta entry is the JSON's, to the printed digits
    for key, column in (("2", 3), ("offpolicy", 5)):
        printed_row = [line for line in printed.splitlines() if line.strip().startswith("K_11")]
        assert printed_row
        value = float(printed_row[0].split()[column])
        assert value == pytest.approx(algorithms[key]["theta"][3], abs=5e-5)
    assert "rank 9 of 11" in printed


# Drawing and saving all five figures twice takes 4-6 s of matplotlib: a plain pytest
# writes the set above and saves a real figure as PNG and SVG in tests/test_figures.py.
@pytest.mark.slow
def test_reproduce_draws_and_saves_every_figure(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, reproduction: Reproduction
) -> None:
    out = tmp_path / "results"
    run_reproduce(out, monkeypatch, reproduction)
    for stem in FIGURES:
        for suffix in (".png", ".svg"):
            path = out / f"{stem}{suffix}"
            assert path.stat().st_size > 1000, path
    assert (out / "fig1.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "<svg" in (out / "fig4.svg").read_text()[:500]


def motor_file(tmp_path: Path, learning: str = "") -> Path:
    path = tmp_path / "motor.toml"
    path.write_text(
        "[motor]\nR_s = 0.8\nL_s = 0.02\nphi_pm = 0.15\np = 3\n"
        "[operating_point]\nspeed = 80.0\ntorque = 4.0\n" + learning
    )
    return path


# Algorithms 2 and 3 through the command line are slow: tests/test_torque.py runs them on
# the paper's motor, and this route is the same for every algorithm.
@pytest.mark.parametrize(
    "algorithm",
    [
        pytest.param("2", marks=pytest.mark.slow),
        pytest.param("3", marks=pytest.mark.slow),
        "offpolicy",
    ],
)
def test_tune_learns_the_optimum_of_the_motor_in_the_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], algorithm: str
) -> None:
    out = tmp_path / "tune.json"
    args = ["tune", "--motor", str(motor_file(tmp_path)), "--algorithm", algorithm]
    assert main([*args, "--json", str(out)]) == 0
    result = json.loads(out.read_text())
    motor = SPMSM(R_s=0.8, L_s=0.02, phi_pm=0.15, p=3)
    optimum = solve_optimal_regulation(motor.regulation_problem(80.0), 1e3 * np.eye(2), np.eye(2))
    np.testing.assert_allclose(result["model_based"]["K"], optimum.K, rtol=1e-12)
    learned_K = np.array(result["control_law"]["K"])
    learned_U = np.array(result["control_law"]["U"])
    assert np.linalg.norm(learned_K - optimum.K) < 1e-5 * np.linalg.norm(optimum.K)
    assert np.linalg.norm(learned_U - optimum.U) < 1e-4 * np.linalg.norm(optimum.U)
    assert result["control_law"]["equations"].startswith("u_k = U w_k - K [xbar_k]")
    assert result["target"] == "continuous" and result["integral_action"] is False
    assert result["quality"]["K_relative_se"] < 1e-4
    assert result["history"], "history is empty"
    if algorithm == "3":
        assert result["identified"]["phi_pm"] == pytest.approx(0.15, rel=1e-4)
    printed = capsys.readouterr().out
    assert "the controller" in printed and "steady torque error" in printed


def test_the_tune_json_states_the_whole_problem(tmp_path: Path) -> None:
    """The digital servo optimum recomputed from the JSON alone (motor, operating point,
    Q, R, Q_i, h, delay) is the one the JSON compares with; the file's Q_i is used, and
    the PI equivalent is there, judged stable."""
    from selftune.model import solve_digital_regulation

    weight = [[2e7, 0.0], [0.0, 3e7]]
    learning = '[learning]\ntarget = "digital"\nintegral_action = true\n'
    path = motor_file(tmp_path, f"[cost]\nQ_i = {weight}\n" + learning)
    out = tmp_path / "tune.json"
    assert main(["tune", "--motor", str(path), "--json", str(out)]) == 0
    result = json.loads(out.read_text())
    assert result["cost"]["Q_i"] == weight
    motor = SPMSM(**{key: value for key, value in result["motor"].items() if value is not None})
    settings = result["settings"]
    optimum = solve_digital_regulation(
        motor.regulation_problem(settings["speed"]), result["cost"]["Q"], result["cost"]["R"],
        result["h"], input_delay=result["input_delay"], integral_weight=result["cost"]["Q_i"],
    )  # fmt: skip
    np.testing.assert_allclose(result["model_based"]["K"], optimum.law.K, rtol=1e-12)
    np.testing.assert_allclose(result["model_based"]["K_i"], optimum.law.K_i, rtol=1e-12)
    pi = result["pi_equivalent"]
    assert pi["stable"] is True and pi["k_i"] is not None and pi["excess_cost"] > -1e-6
    assert pi["control_law"]["history"] == result["input_delay"]


def test_tune_reads_the_learning_table(tmp_path: Path) -> None:
    learning = "[learning]\nsampling = 2e-5\nepisode_length = 4e-3\nexploration = 2.0\n"
    out = tmp_path / "tune.json"
    path = motor_file(tmp_path, learning)
    assert main(["tune", "--motor", str(path), "--json", str(out)]) == 0
    assert json.loads(out.read_text())["data_seconds"] == pytest.approx(4e-3)


@pytest.mark.parametrize(
    ("learning", "expected"),
    [
        ("[learning]\nsampling = -1.0\n", "[learning] sampling"),
        ("[learning]\nK0 = [[1.0, 0.0]]\n", "[learning] K0"),
        ("[learning]\nsamplng = 1e-5\n", "did you mean h (formerly sampling)?"),
        ("[learning]\nepisode_length = 1e-5\n", "episode_length"),
    ],
)
def test_tune_bad_learning_table_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], learning: str, expected: str
) -> None:
    out = tmp_path / "tune.json"
    path = motor_file(tmp_path, learning)
    assert main(["tune", "--motor", str(path), "--json", str(out)]) == 2
    error = capsys.readouterr().err.strip().splitlines()
    assert len(error) == 1 and "Traceback" not in error[0]
    assert "motor.toml" in error[0] and expected in error[0]
    assert not out.exists()


def test_tune_unstable_initial_policy_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "small.toml"
    path.write_text(
        "[motor]\nR_s = 0.05\nL_s = 0.0005\nphi_pm = 0.02\np = 5\n"
        "[operating_point]\nspeed = 300.0\ntorque = 1.0\n"
    )
    assert main(["tune", "--motor", str(path)]) == 2
    error = capsys.readouterr().err.strip().splitlines()
    assert len(error) == 1 and "smaller K0" in error[0]
