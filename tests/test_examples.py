"""The files in examples/ and the commands docs/paper.md quotes give what the docs say."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

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


def test_every_example_script_runs_and_learns() -> None:
    scripts = sorted(EXAMPLES.glob("*.py"))
    assert scripts
    for script in scripts:
        printed = run_script(script)
        errors = error_figures(printed)
        assert errors, f"{script.name} printed no error figure"
        assert max(errors) < 1e-6, f"{script.name}: {printed}"
