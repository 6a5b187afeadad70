"""The files in examples/ and the commands docs/paper.md quotes give what the docs say."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from selftune.cli import main

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def test_table_ii_does_not_reproduce_the_paper(tmp_path: Path) -> None:
    out = tmp_path / "table2.json"
    assert main(["solve", "--motor", str(EXAMPLES / "paper_table2.toml"), "--json", str(out)]) == 0
    result = json.loads(out.read_text())
    np.testing.assert_allclose(result["K"], 99.562 * np.eye(2), atol=5e-4)
    np.testing.assert_allclose(result["P"], 6.1231 * np.eye(2), atol=5e-5)


def run_script(path: Path) -> str:
    import contextlib
    import io
    import runpy

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        runpy.run_path(str(path), run_name="__main__")
    return out.getvalue()


#: A relative error an example prints: "K error 1.3e-09", "... / ||Theta*|| = 2.8e-10", in any
#: number format (2.1, 2.1e+00, 3e-7).
ERROR_FIGURE = re.compile(
    r"(?:error|\|\|Theta\*\|\|)\s*[=:]?\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)"
)


def error_figures(printed: str) -> list[float]:
    """Every relative error an example printed."""
    return [float(value) for value in ERROR_FIGURE.findall(printed)]


def test_error_figures_are_read_in_any_format() -> None:
    printed = "K error 2.1e+00, U error 3, Theta error 0.5\n||Theta - Theta*|| / ||Theta*|| = 1e-7"
    assert error_figures(printed) == [2.1, 3.0, 0.5, 1e-7]


#: Examples that need an optional extra, and the module it installs.
NEEDS = {"tune_gem.py": "gym_electric_motor"}  # pip install 'selftune[gem]'


def test_the_examples_are_there() -> None:
    assert {path.name for path in EXAMPLES.glob("*.py")} >= set(NEEDS) | {"tune_motors.py"}


@pytest.mark.parametrize("script", sorted(EXAMPLES.glob("*.py")), ids=lambda path: path.name)
def test_every_example_script_runs_and_learns(script: Path) -> None:
    if script.name in NEEDS:  # skipped, not failed, under the README's '.[test]' install
        pytest.importorskip(NEEDS[script.name])
    printed = run_script(script)
    errors = error_figures(printed)
    assert errors, f"{script.name} printed no error figure"
    assert max(errors) < 1e-6, f"{script.name}: {printed}"


DATA = EXAMPLES / "data"


def test_the_sample_drive_log_is_what_its_script_makes(tmp_path: Path) -> None:
    """The committed log is the script's output, to the rounding of the computation.

    The file holds every value to the last digit (round-trip floats), so it is read back
    exactly; another machine's BLAS rounds each step of the drive differently (another
    summation order, fused multiply-adds). Rounding of eps at a column's scale in each
    step accumulates in the script's stable loop (the plant held over a sample, one
    sample of computation delay, its K0) to at most eps times the sum of the norms of the
    loop's powers over the log: the tolerance of every column.
    """
    import runpy
    import sys

    from selftune.core import discretize

    out = tmp_path / "log.csv"
    argv = sys.argv
    sys.argv = ["make_drive_log.py", str(out)]
    try:
        with contextlib_quiet():
            script = runpy.run_path(str(DATA / "make_drive_log.py"), run_name="__main__")
    finally:
        sys.argv = argv
    committed, made = DATA / "drive_log.csv", out
    header = committed.read_text(encoding="utf-8").splitlines()[0]
    assert made.read_text(encoding="utf-8").splitlines()[0] == header
    old, new = (np.loadtxt(path, delimiter=",", skiprows=1) for path in (committed, made))
    assert new.shape == old.shape == (script["log"].t.size, len(header.split(",")))
    # the loop [x_k, u_(k-1)] -> [A_d x_k + B_d u_(k-1), -K0 x_k] and its powers' norms
    problem = script["motor"].regulation_problem(script["speed"])
    exact = discretize(problem.A, problem.B, script["h"])
    K0 = script["K0"]
    loop = np.block([[exact.Ad, exact.Bd], [-K0, np.zeros((K0.shape[0], K0.shape[0]))]])
    power, gain = np.eye(loop.shape[0]), 0.0
    for _ in range(old.shape[0]):
        gain += float(np.linalg.norm(power, 2))
        power = loop @ power
    rounding = np.finfo(float).eps * gain * np.max(np.abs(old), axis=0)
    worst = np.max(np.abs(new - old), axis=0)
    assert np.all(worst <= rounding), dict(zip(header.split(","), worst / rounding, strict=True))


def contextlib_quiet():  # type: ignore[no-untyped-def]
    import contextlib
    import io

    return contextlib.redirect_stdout(io.StringIO())


def test_the_sample_drive_log_learns_the_drive_controller_within_its_errors(
    tmp_path: Path,
) -> None:
    """The README's `selftune learn` example: the digital servo controller of the drive in
    make_drive_log.py, within the standard errors it states."""
    from selftune import SPMSM
    from selftune.learn import LearningProblem
    from selftune.model import solve_digital_regulation

    out = tmp_path / "learned.json"
    args = ["learn", str(DATA / "drive_log.csv"), "--config", str(DATA / "learn.toml")]
    with contextlib_quiet():
        assert main([*args, "--json", str(out)]) == 0
    result = json.loads(out.read_text())
    motor = SPMSM(R_s=0.6, L_s=8e-3, phi_pm=0.35, p=3)  # the script's, unknown to the learner
    problem = motor.regulation_problem(50.0)
    weight = LearningProblem(
        1e3 * np.eye(2), np.eye(2), C=problem.C, F=problem.F, integral_action=True
    ).integral_weight
    truth = solve_digital_regulation(
        problem, 1e3 * np.eye(2), np.eye(2), 1e-4, input_delay=1, integral_weight=weight,
        plant=motor.sampled_plant(50.0, 1e-4, "stationary"),
    )  # fmt: skip
    assert result["alignment"]["shift"] == 1 and result["target"] == "digital"
    quality = result["quality"]
    for name, stated in (("K", quality["K_relative_se"]), ("K_i", quality["K_i_relative_se"])):
        best = getattr(truth, name)
        error = np.linalg.norm(np.array(result[name]) - best) / np.linalg.norm(best)
        assert error <= 3 * stated, (name, error, stated)
    assert result["quality"]["voltage_error"] == pytest.approx(2.0, rel=0.15)
