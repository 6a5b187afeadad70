"""Learning while the drive runs: the sampled model from moments with forgetting, a
surface PMSM's parameters read off it, a change in them detected, and a controller
certified before it is switched in."""

from ._certify import Certificate, certify
from ._model import OnlineModel
from ._moments import ForgettingMoments
from ._physical import ChangeTest, ChangeWatch, PhysicalEstimate, physical_estimate
from ._settings import OnlineSettings
from ._tuner import OnlineTuner, TunerEvent

__all__ = [
    "Certificate",
    "ChangeTest",
    "ChangeWatch",
    "ForgettingMoments",
    "OnlineModel",
    "OnlineSettings",
    "OnlineTuner",
    "PhysicalEstimate",
    "TunerEvent",
    "certify",
    "physical_estimate",
]
