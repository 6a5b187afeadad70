"""How many hypothesis examples an expensive test draws: all of them under .ci/run's "ci"
profile, a representative few in a plain ``pytest`` (the "default" profile in
tests/conftest.py, which draws a quarter of hypothesis's 100 where a test asks for no
number)."""

from __future__ import annotations

from hypothesis import settings


def examples(full: int, quick: int) -> settings:
    """``full`` examples under a profile that draws at least as many as "ci" does
    (``SELFTUNE_HYPOTHESIS_PROFILE=ci`` or ``thorough``), ``quick`` in a plain ``pytest``."""
    thorough = settings.default.max_examples >= settings.get_profile("ci").max_examples
    return settings(max_examples=full if thorough else quick)
