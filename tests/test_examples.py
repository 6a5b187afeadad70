"""The files in examples/ and the commands docs/paper.md quotes give what the docs say."""

from __future__ import annotations

import json
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


def test_every_example_script_runs_and_learns() -> None:
    scripts = sorted(EXAMPLES.glob("*.py"))
    assert scripts
    for script in scripts:
        printed = run_script(script)
        errors = [float(word.rstrip(",")) for word in printed.split() if "e-" in word]
        assert errors, f"{script.name} printed no error figure"
        assert max(errors) < 1e-6, f"{script.name}: {printed}"
