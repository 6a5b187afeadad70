"""The architecture holds: the import contract, light start-up, sizes, documented parameters.

The import contract lives in pyproject.toml ([tool.importlinter]); ``.ci/run`` runs it
with ``lint-imports`` as well. Here it is run on the package, and on a copy of the
package with one forbidden import added, to show that it fails when it should.
"""

from __future__ import annotations

import inspect
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import selftune

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "selftune"
PACKAGES = (
    "core", "loop", "model", "learn", "sim", "config", "tuning", "report", "fleet", "bench",
)  # fmt: skip


def _lint(pythonpath: Path, cwd: Path) -> subprocess.CompletedProcess[str]:
    code = (
        "import sys; from importlinter.cli import lint_imports; "
        "sys.exit(lint_imports(no_cache=True))"
    )
    return subprocess.run(
        [sys.executable, "-c", code],
        cwd=cwd,
        env={"PYTHONPATH": str(pythonpath), "PATH": "/usr/bin:/bin"},
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_the_import_contract_is_kept() -> None:
    result = _lint(ROOT / "src", ROOT)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "1 kept, 0 broken" in result.stdout


@pytest.mark.parametrize(
    ("module", "line"),
    [
        ("learn/_probe.py", "from ..model import SPMSM\n"),  # the learner sees the model
        ("learn/_probe.py", "from .. import tuning\n"),  # the learner imports upward
        ("model/_probe.py", "from ..learn import Trajectory\n"),  # the truth uses the method
        ("core/_probe.py", "from ..sim import simulate\n"),  # the neutral layer imports up
        ("core/_probe.py", "from ..loop import SampledLoop\n"),  # the loop sits above core
        ("loop/_probe.py", "from ..model import SPMSM\n"),  # the loop sees the model
        ("loop/_probe.py", "from ..learn import Trajectory\n"),  # the loop sees the method
    ],
)
def test_the_import_contract_fails_on_a_forbidden_import(
    tmp_path: Path, module: str, line: str
) -> None:
    copy = tmp_path / "src" / "selftune"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    (copy / module).write_text(line)
    shutil.copy(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    result = _lint(tmp_path / "src", tmp_path)
    assert result.returncode != 0
    assert "BROKEN" in result.stdout


def test_solve_loads_no_learner_tuning_bench_or_integrator() -> None:
    code = (
        "import sys, contextlib, io\n"
        "from selftune.cli import main\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    assert main(['solve']) == 0\n"
        "print('\\n'.join(sorted(sys.modules)))\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    loaded = set(result.stdout.split())
    for name in ("selftune.bench", "selftune.tuning", "selftune.report", "scipy.integrate"):
        assert name not in loaded, name
    assert "matplotlib" not in loaded


def test_no_module_is_over_600_lines() -> None:
    sizes = {
        path.relative_to(PACKAGE): len(path.read_text(encoding="utf-8").splitlines())
        for path in PACKAGE.rglob("*.py")
    }
    too_long = {str(path): lines for path, lines in sizes.items() if lines > 600}
    assert not too_long


def _public_callables() -> list[tuple[str, object]]:
    """Every public function, class and method exported by a package's ``__all__``."""
    import importlib

    found: dict[int, tuple[str, object]] = {}
    modules = [selftune] + [importlib.import_module(f"selftune.{name}") for name in PACKAGES]
    for module in modules:
        for name in module.__all__:
            value = getattr(module, name)
            if inspect.isfunction(value) or inspect.isclass(value):
                found.setdefault(id(value), (f"{module.__name__}.{name}", value))
            if inspect.isclass(value):
                for attribute, member in vars(value).items():
                    function = member.__func__ if isinstance(member, classmethod) else member
                    if attribute.startswith("_") or not inspect.isfunction(function):
                        continue
                    key = f"{module.__name__}.{name}.{attribute}"
                    found.setdefault(id(function), (key, function))
    return sorted(found.values(), key=lambda item: item[0])


_SECTION = re.compile(
    r"^(Parameters|Attributes|Other Parameters)\n-+\n(.*?)(?=^[A-Z][A-Za-z ]+\n-+\n|\Z)",
    flags=re.DOTALL | re.MULTILINE,
)


def _documented(docstring: str) -> set[str]:
    """Names listed in the numpydoc Parameters and Attributes sections (dedented text:
    a name line starts at column 0, its description is indented)."""
    names: set[str] = set()
    for match in _SECTION.finditer(docstring):
        for line in match.group(2).splitlines():
            head = re.match(r"^([A-Za-z_*][\w, *]*?)\s*(?::|$)", line)
            if head:
                names.update(part.strip(" *") for part in head.group(1).split(","))
    return names


def _docstrings(value: object) -> str:
    """The docstring of a function; of a class, its own and its bases' (inherited fields)."""
    if not inspect.isclass(value):
        return inspect.getdoc(value) or ""
    return "\n".join(
        inspect.cleandoc(klass.__doc__ or "") for klass in value.__mro__ if klass is not object
    )


def test_every_public_parameter_is_documented() -> None:
    missing = []
    for name, value in _public_callables():
        if inspect.isclass(value) and (
            issubclass(value, BaseException) or getattr(value, "_is_protocol", False)
        ):
            continue  # exceptions take a message; protocols are not instantiated
        target = value.__init__ if inspect.isclass(value) else value  # type: ignore[misc]
        if target is object.__init__:
            continue
        parameters = inspect.signature(target).parameters
        documented = _documented(_docstrings(value))
        for parameter in parameters:
            if parameter in ("self", "cls") or parameter.startswith("_"):
                continue
            if parameter not in documented:
                missing.append(f"{name}({parameter})")
    assert not missing, "undocumented public parameters: " + ", ".join(missing)
