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
