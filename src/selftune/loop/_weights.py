"""The weights of a sampled loop's cost (:meth:`~selftune.loop.SampledLoop.weights`)."""

from __future__ import annotations

from dataclasses import dataclass

from ..core import Array

__all__ = ["LoopWeights"]


@dataclass(frozen=True)
class LoopWeights:
    """The weights of a loop's cost over ``(zeta_k, ubar_k)``.

    Attributes
    ----------
    Qz : ndarray, shape (nz, nz)
        Weight of the augmented state.
    Rz : ndarray, shape (m, m)
        Weight of the computed input's deviation.
    Nz : ndarray, shape (nz, m)
        Cross weight.
    first_stages : ndarray, shape (nz, nz)
        The value of the stages no decision changes (the first d of the sampled cost), a
        quadratic form in ``zeta_0``; zero otherwise.
    """

    Qz: Array
    Rz: Array
    Nz: Array
    first_stages: Array
