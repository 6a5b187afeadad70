"""What a refusal says: the cause key of its class.

The learners refuse data that do not support a controller with a
:class:`~selftune.errors.Refusal`, one class per cause. The studies of the bench count
refusals by cause; :func:`refusal_cause` gives the key of the error's class. An error of
no class here is ``"unnamed"``: the bench reports those as refusals that do not name
their cause.
"""

from __future__ import annotations

from ..errors import (
    CoarseTimeResolution,
    ConfigurationMismatch,
    CurrentOverrange,
    MisalignedLog,
    ModelMissesEffect,
    NotExciting,
    NotStabilizing,
    PolicyIterationFailure,
    SamplingJitter,
    SelftuneError,
    TooLittleData,
    TooShort,
    UnsolvableError,
)
from ..learn import TOO_LITTLE_DATA

__all__ = ["CAUSE_TITLES", "UNNAMED", "refusal_cause"]

#: The key of a refusal whose class names no cause.
UNNAMED = "unnamed"

#: The cause key of each class; an error takes that of the first of its classes (in method
#: resolution order) found here, so a subclass may have its own.
_KEYS: dict[type[SelftuneError], str] = {
    MisalignedLog: "alignment",
    ConfigurationMismatch: "consistency",
    ModelMissesEffect: "consistency",
    TooLittleData: "too little data",
    NotExciting: "excitation",
    TooShort: "too short",
    CurrentOverrange: "current over range",
    NotStabilizing: "instability",
    PolicyIterationFailure: "policy iteration",
    CoarseTimeResolution: "time resolution",
    SamplingJitter: "sampling jitter",
    UnsolvableError: "unsolvable",
}

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
    "current over range": "the experiment drove the current beyond the ADC's full scale "
    "(names the peak and the scale)",
    UNNAMED: "the message names no recognizable cause",
}


def refusal_cause(error: SelftuneError) -> str:
    """The cause key of a learner's refusal (:data:`CAUSE_TITLES`) by its class, or
    :data:`UNNAMED`.

    Parameters
    ----------
    error : SelftuneError
        What the learner raised.
    """
    for kind in type(error).__mro__:
        if kind in _KEYS:
            return _KEYS[kind]
    return UNNAMED
