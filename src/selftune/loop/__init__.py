"""The sampled loop: one home for the facts of a drive's current loop and their algebra.

:class:`SampledLoop` holds the sampling period (0 for the continuous loop), the input delay
in samples, the voltage hold and the optional integrator ``(C, F, Q_i)``, and owns the
augmentation of the plant, the cost weights, the map between a gain and a
:class:`~selftune.core.ControlLaw`, the closed loop, its spectral radius, a law's value and
the optimum. It sits between :mod:`selftune.core` and the model and learners, which both
ask it (an import contract keeps the order).
"""

from __future__ import annotations

from ._sampled_loop import Cost, Hold, SampledLoop
from ._weights import LoopWeights

__all__ = ["Cost", "Hold", "LoopWeights", "SampledLoop"]
