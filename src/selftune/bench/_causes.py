"""What a refusal says: the error's class and a short cause key read off its message.

The learners refuse data that do not support a controller with an exception whose message
names the cause (:mod:`selftune.learn`). The studies of the bench count refusals by cause;
:func:`refusal_cause` reads the key off the message. A message no pattern recognizes is
``"unnamed"``: the bench reports those as refusals that do not name their cause.
"""

from __future__ import annotations

from ..errors import (
    ConsistencyError,
    ConvergenceError,
    ExcitationError,
    InputError,
    SelftuneError,
    UnsolvableError,
)
from ..learn import TOO_LITTLE_DATA

__all__ = ["CAUSE_TITLES", "UNNAMED", "refusal_cause"]

#: The key of a refusal whose message names no recognizable cause.
UNNAMED = "unnamed"

#: (error class, phrase in the message, cause key), the first match wins.
_PATTERNS: tuple[tuple[type[SelftuneError], str, str], ...] = (
    (ConsistencyError, "than the configuration says", "alignment"),
    (ConsistencyError, "cannot explain the data", "consistency"),
    (SelftuneError, "misses an effect", "consistency"),
    (ConsistencyError, "likely cause", "consistency"),
    (ExcitationError, TOO_LITTLE_DATA, "too little data"),
    (ExcitationError, "rank", "excitation"),
    (ExcitationError, "too short", "too short"),
    (ExcitationError, "too few", "too short"),
    (ExcitationError, "only", "too short"),
    (ConvergenceError, "does not stabilize every plant", "instability"),
    (ConvergenceError, "did not behave as theory says", "policy iteration"),
    (ConvergenceError, "not positive", "policy iteration"),
    (InputError, "too coarse for sampling steps", "time resolution"),
    (InputError, "sampling steps vary", "sampling jitter"),
    (UnsolvableError, "", "unsolvable"),
)

#: What each cause key means, for the tables.
CAUSE_TITLES = {
    "alignment": "the logged voltages act at another sample than stated (names the shift)",
    "consistency": "no linear model explains the data: residuals correlated with the inputs "
    "or in time (names dead time, timing, nonlinearity, resolution)",
    "too little data": f"{TOO_LITTLE_DATA} (names the length needed)",
    "excitation": "a channel is not excited (names the block)",
    "too short": "fewer samples than unknowns",
    "instability": "the controller would not stabilize every plant the data allow",
    "policy iteration": "policy iteration did not behave as theory says",
    "time resolution": "the time column cannot resolve the sampling period",
    "sampling jitter": "the sampling steps are not uniform",
    "unsolvable": "the regulation problem has no solution",
    UNNAMED: "the message names no recognizable cause",
}


def refusal_cause(error: SelftuneError) -> str:
    """The cause key of a learner's refusal (:data:`CAUSE_TITLES`), or :data:`UNNAMED`.

    Parameters
    ----------
    error : SelftuneError
        What the learner raised.
    """
    message = str(error)
    for kind, phrase, key in _PATTERNS:
        if isinstance(error, kind) and phrase in message:
            return key
    return UNNAMED
