"""Learning while the drive runs: the sampled model from moments with forgetting, a
surface PMSM's parameters read off it, and a change in them detected."""

from ._model import OnlineModel
from ._moments import ForgettingMoments
from ._physical import ChangeTest, PhysicalEstimate, change_test, physical_estimate

__all__ = [
    "ChangeTest",
    "ForgettingMoments",
    "OnlineModel",
    "PhysicalEstimate",
    "change_test",
    "physical_estimate",
]
