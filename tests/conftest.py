"""Shared test settings: one BLAS thread, hypothesis profiles (.ci/run loads "ci"), the
long computations several test files read, made once per session (the quick bench, the
reproduction), and the reproduction's figures written as small files.

The tests solve many tiny matrices; BLAS threads only contend for the cores (the suite
ran 1.5-3 times slower with them). The variables are set before numpy is first imported,
so a plain ``pytest`` runs like ``.ci/run``; a value already set in the environment wins.
"""

from __future__ import annotations

import os

for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

from pathlib import Path  # noqa: E402
from typing import TYPE_CHECKING, Any  # noqa: E402

import pytest  # noqa: E402
from hypothesis import HealthCheck, settings  # noqa: E402

if TYPE_CHECKING:
    from selftune.bench import BenchReport
    from selftune.report import Reproduction

# A plain pytest: 10 examples where a test does not ask for a number, and fewer than it
# asks for where it does (tests/example_counts.py); .ci/run loads "ci", which keeps
# hypothesis's 100 and every number asked for.
settings.register_profile(
    "default",
    deadline=None,
    derandomize=True,
    max_examples=10,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.register_profile("ci", settings.get_profile("default"), max_examples=100)
settings.register_profile(
    "thorough", deadline=None, max_examples=1000, suppress_health_check=[HealthCheck.too_slow]
)
settings.load_profile(os.environ.get("SELFTUNE_HYPOTHESIS_PROFILE", "default"))


@pytest.hookimpl(tryfirst=True)  # before -m deselects
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """A test that reads the quick bench is slow: the bench takes over a minute and a half
    of CPU (its cheap sections are also measured alone, for a plain ``pytest``)."""
    for item in items:
        if "quick_bench" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.slow)


@pytest.fixture(scope="session")
def quick_bench() -> BenchReport:
    """``selftune bench --quick``'s report (about a minute on 2 cores), made once per session:
    tests/test_bench.py reads all of it, tests/test_bench_realistic.py its realistic drive."""
    from selftune.bench import run_bench  # here: only the sessions that need it load it

    return run_bench(quick=True, progress=False)


@pytest.fixture(scope="session")
def reproduction() -> Reproduction:
    """``selftune reproduce``'s results with seed 0, made once per session: its figures are
    checked in tests/test_figures.py, its output set in tests/test_hostile.py."""
    from selftune.report import reproduce  # here: only the sessions that need it load it

    return reproduce(0)


@pytest.fixture
def quick_figures(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """Figures written as small files (the output set is what is tested, not matplotlib:
    tests/test_figures.py draws and saves the real ones); returns the stems saved, in
    order."""
    from selftune.core import write_text
    from selftune.report import _figures

    saved: list[str] = []

    def save_figure(figure: Any, stem: Any) -> list[Path]:
        saved.append(str(stem))
        paths = [Path(f"{stem}{suffix}") for suffix in (".png", ".svg")]
        for path in paths:
            write_text(path, f"{path.name} of run {len(saved)}")
        return paths

    monkeypatch.setattr(_figures, "_figures", lambda r: ((f"fig{i}", None) for i in range(1, 6)))
    monkeypatch.setattr(_figures, "save_figure", save_figure)
    return saved
