"""Shared test settings: one BLAS thread, and hypothesis profiles (CI runs the default one).

The tests solve many tiny matrices; BLAS threads only contend for the cores (the suite
ran 1.5-3 times slower with them). The variables are set before numpy is first imported,
so a plain ``pytest`` runs like ``.ci/run``; a value already set in the environment wins.
"""

from __future__ import annotations

import os

for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

from hypothesis import HealthCheck, settings  # noqa: E402

settings.register_profile(
    "default",
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.register_profile(
    "thorough", deadline=None, max_examples=1000, suppress_health_check=[HealthCheck.too_slow]
)
settings.load_profile(os.environ.get("SELFTUNE_HYPOTHESIS_PROFILE", "default"))
