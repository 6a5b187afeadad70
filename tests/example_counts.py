"""How many hypothesis examples a test that asks for a number draws: all of them under
.ci/run's "ci" profile, a representative part in a plain ``pytest`` (the "default" profile
in tests/conftest.py, which draws a tenth of what "ci" draws where a test asks for no
number)."""

from __future__ import annotations

from hypothesis import settings


def examples(full: int, quick: int) -> settings:
    """``full`` examples under a profile that draws at least as many as "ci" does
    (``SELFTUNE_HYPOTHESIS_PROFILE=ci`` or ``thorough``), ``quick`` in a plain ``pytest``."""
    thorough = settings.default.max_examples >= settings.get_profile("ci").max_examples
    return settings(max_examples=full if thorough else quick)


def at_least(count: int) -> settings:
    """At least ``count`` examples under "ci", more when the profile draws more
    (``SELFTUNE_HYPOTHESIS_PROFILE=thorough``); in a plain ``pytest`` the same share of
    ``count`` as the default profile draws of "ci" (a tenth), never fewer than that
    profile."""
    drawn, ci = settings.default.max_examples, settings.get_profile("ci").max_examples
    return settings(max_examples=max(drawn, count * min(drawn, ci) // ci))
