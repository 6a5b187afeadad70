"""Self-tuning sessions on a drive: the paper's Algorithms 1-3 and the off-policy variant.

The learner knows only what a drive engineer knows without a motor model -- the pole
pairs ``p``, the held mechanical speed, the torque reference, the cost weights and (for
Algorithms 1 and 2) the magnet flux -- and sees only the trajectories a :class:`Drive`
returns. The model-based comparison (:func:`selftune.report.evaluate`) lives elsewhere.

- :func:`algorithm1`, :func:`algorithm2`, :func:`algorithm3`: on-policy, a new episode
  each iteration (:mod:`._onpolicy`);
- :func:`offpolicy`: one batch of data reused for every step (:mod:`._offpolicy`);
- :func:`run_algorithm`: a session on a simulated motor, by name;
- :func:`commission_interior`: an interior motor identified at one speed;
  :func:`commission_ramp`: a motor identified from a log over several held speeds, and
  the speeds it covers (:mod:`._ramp`);
- :func:`commission_over_current`: a saturating motor's incremental model learned at
  several current levels and its law scheduled over the current (:mod:`._saturation`).
"""

from __future__ import annotations

from ._drive import Drive
from ._episodes import DIVERGED_CURRENT, NOISE_FLOOR_FACTOR
from ._interior import InteriorCommissioning, check_current_range, commission_interior
from ._knowledge import PAPER_PERTURBATION, known_flux_form, reference_perturbation
from ._offpolicy import offpolicy
from ._online import (
    CHUNK_SECONDS,
    LOG_COLUMNS,
    PROBING_SHARE,
    SEGMENT_CHUNKS,
    TORQUE_LEVELS,
    OnlineRun,
    OnlineSwitch,
    follow,
    online_settings,
    replay,
    run_online,
)
from ._onpolicy import algorithm1, algorithm2, algorithm3
from ._ramp import RampCommissioning, commission_ramp
from ._results import TuningIteration, TuningResult
from ._saturation import CurrentCommissioning, CurrentLevel, commission_over_current
from ._session import ALGORITHMS, AlgorithmName, run_algorithm
from ._settings import (
    TUNING_KEYS,
    Perturbation,
    TuningSettings,
    default_exploration,
    tuning_settings,
)

__all__ = [
    "ALGORITHMS",
    "CHUNK_SECONDS",
    "DIVERGED_CURRENT",
    "LOG_COLUMNS",
    "NOISE_FLOOR_FACTOR",
    "PAPER_PERTURBATION",
    "PROBING_SHARE",
    "SEGMENT_CHUNKS",
    "TORQUE_LEVELS",
    "TUNING_KEYS",
    "AlgorithmName",
    "CurrentCommissioning",
    "CurrentLevel",
    "Drive",
    "InteriorCommissioning",
    "OnlineRun",
    "OnlineSwitch",
    "Perturbation",
    "RampCommissioning",
    "TuningIteration",
    "TuningResult",
    "TuningSettings",
    "algorithm1",
    "algorithm2",
    "algorithm3",
    "check_current_range",
    "commission_interior",
    "commission_over_current",
    "commission_ramp",
    "default_exploration",
    "follow",
    "known_flux_form",
    "offpolicy",
    "online_settings",
    "reference_perturbation",
    "replay",
    "run_algorithm",
    "run_online",
    "tuning_settings",
]
