"""Test helper: exact sampled loops with a computation delay, for any linear plant.

An independent implementation (a plain loop over samples on the exact zero-order-hold
discretization) of what a digital controller with a delay of d samples does: the voltage
computed at sample k from x_k acts over [t_(k+d), t_(k+d+1)). It returns the log either
as applied (row k = the voltage acting during sample k) or as commanded (row k = the
voltage computed at sample k).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from selftune.core import discretize
from selftune.learn import Trajectory

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Loop:
    """A plant ``x' = A x + B u + D w`` sampled at h under ``u = -K0 (x - X w) + rho``."""

    A: Array
    B: Array
    D: Array
    h: float
    K0: Array
    X: Array

    def run(
        self,
        delay: int,
        reference: Callable[[Array], Array],
        exploration: Array,
    ) -> tuple[Trajectory, Trajectory]:
        """The applied-voltage log and the commanded-voltage log of one run from rest."""
        exact = discretize(self.A, self.B, self.h, D=self.D)
        count, m = exploration.shape
        n = self.A.shape[0]
        w = reference(np.arange(count + 1) * self.h)
        x = np.zeros((count + 1, n))
        commanded = np.zeros((count, m))
        applied = np.zeros((count, m))
        for k in range(count):
            commanded[k] = -self.K0 @ (x[k] - self.X @ w[k]) + exploration[k]
            applied[k] = commanded[k - delay] if k >= delay else 0.0
            x[k + 1] = exact.Ad @ x[k] + exact.Bd @ applied[k] + exact.Ed @ w[k]
        t = np.arange(count + 1) * self.h
        q = w.shape[1]
        w_log = w if q else None
        return Trajectory(t, x, applied, w_log), Trajectory(t, x, commanded, w_log)


def steps_and_sines(base: Array, amplitude: float) -> Callable[[Array], Array]:
    """A held reference: ``base`` plus a sine and a square wave on every channel but the
    first (the first stays constant, like a motor's back-EMF channel)."""

    def reference(t: Array) -> Array:
        values = np.tile(base, (t.shape[0], 1)).astype(float)
        for channel in range(1, base.shape[0]):
            values[:, channel] += amplitude * (
                np.sin(2 * np.pi * (40.0 + 17 * channel) * t)
                + 0.5 * np.sign(np.sin(2 * np.pi * (9.0 + 5 * channel) * t + 0.3))
            )
        if base.shape[0] == 1:
            values[:, 0] += amplitude * np.sin(2 * np.pi * 31.0 * t)
        return values

    return reference
