"""The README stays true: its commands, examples and file formats are run here."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import numpy as np

from selftune.cli import build_parser, main
from selftune.config import LEARN_TABLES, load_learn_config, load_log_format

README = Path(__file__).resolve().parents[1] / "README.md"


def fenced(language: str) -> list[str]:
    text = README.read_text(encoding="utf-8")
    return re.findall(rf"^```{language}\n(.*?)^```", text, flags=re.DOTALL | re.MULTILINE)


def test_readme_opens_with_the_two_commands() -> None:
    text = README.read_text(encoding="utf-8")
    opening = text[: text.index("\n## ")]
    assert "pip install -e '.[test]' && pytest" in opening
    assert "pip install . && selftune reproduce" in opening


def test_every_python_example_runs_and_learns_the_optimum() -> None:
    """Each example prints how far its result is from the truth: exact examples to the
    learning target on noise-free data, examples on a drive's log within 3 of the
    standard errors they state."""
    blocks = fenced("python")
    assert len(blocks) >= 2
    for block in blocks:
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            exec(compile(block, "README.md", "exec"), {"__name__": "__readme__"})
        printed = out.getvalue()
        stated = re.search(
            r"relative error of [^:]+: (\S+) \(stated standard error (\S+)\)", printed
        )
        if stated:
            assert float(stated[1]) <= 3 * float(stated[2]), printed
            assert "u_k = U w_k - K" in printed and "quality" in printed
        else:
            assert "31.1868" in printed
            error = float(printed.rsplit("relative error of Theta:", 1)[1].split()[0])
            assert error < 1e-6  # the learning target on noise-free data


def test_every_toml_example_is_a_valid_file(tmp_path: Path) -> None:
    blocks = fenced("toml")
    assert len(blocks) >= 2
    for index, block in enumerate(blocks):
        path = tmp_path / f"example{index}.toml"
        path.write_text(block)
        if "[motor]" in block:
            assert main(["solve", "--motor", str(path)]) == 0
        else:
            config = load_learn_config(path, n=2, m=2, q=2)
            assert config.regulation and np.allclose(config.K0, 62.83 * np.eye(2))
            log = load_log_format(path, LEARN_TABLES)
            assert log is None or log.dimensions == (2, 2, 2)


def test_every_command_and_option_is_documented() -> None:
    text = README.read_text(encoding="utf-8")
    parser = build_parser()
    subparsers = next(
        action for action in parser._actions if action.__class__.__name__ == "_SubParsersAction"
    )
    for name, subparser in subparsers.choices.items():  # type: ignore[attr-defined]
        assert f"selftune {name}" in text, name
        for action in subparser._actions:
            for option in action.option_strings:
                if option not in ("-h", "--help"):
                    assert option in text, f"{name} {option}"
