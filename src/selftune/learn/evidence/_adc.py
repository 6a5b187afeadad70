"""The ADC's steps, read from the logged currents, and simulated.

A drive measures its phase currents with an ADC: each measured phase current is a whole
number of steps (least significant bits), and the dq currents of the log are those
phases turned by the angle. Where the noise before the ADC is small against a step, the
rounding is no white noise: it is a fixed function of the current, and a simulation of
the data that adds Gaussian noise instead (:mod:`._sign_bias`) measures the bias of
another drive (the corpus's 48 V motor, 48.8 mA steps and 2 mA of noise, at 0.5-2 s:
K's error 1.1-4.5 of its stated standard errors with Gaussian noise simulated, 1.0-2.9
with the steps simulated; ``selftune bench``, section 10).

The steps are found without being told: the differences between two phases currents
(``i_a - i_b`` and its turns, computed from ``i_d``, ``i_q`` and the angle) are whole
steps whether the drive measures two phases (the third their negative sum) or three (the
common mode the Clarke transform drops cancels in a difference). Where the log's
currents are not on such a lattice (no ADC, noise before it, a filter after it), none
is found and the simulation stays Gaussian; where the steps are not coarse against the
noise (:data:`COARSE_ADC_STEPS`), it stays Gaussian too, of the rounding's and the
noise's variance.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from ...core import Array
from ...core._phases import phase_currents, phases_to_dq
from ._dead_time import line_to_line

__all__ = ["LATTICE_TOLERANCE", "CurrentLattice", "current_lattice"]

#: The largest rms departure from the lattice, in steps, at which currents are on it
#: (rounding the log to 7 significant digits leaves 1e-4 steps of a 12-bit ADC; values
#: off any lattice leave 0.29, a uniform fraction's).
LATTICE_TOLERANCE = 1e-2

#: Values closer than this, relative to the largest, are one ADC code (a log written to
#: 7 significant digits moves a code by 5e-7 of the largest; a 16-bit ADC's step over
#: a range 10 times the currents' is 3e-4 of them).
MERGED = 1e-5

#: The ADC's step, in standard deviations of the noise before it, beyond which its
#: rounding is simulated as rounding: a uniform rounding's rms (step / sqrt(12)) is then
#: over the noise, and the rounding follows the current instead of averaging out. Below
#: it, noise of the rounding's variance describes it (the README's drive: 24.4 mA steps
#: under 10 mA of noise).
COARSE_ADC_STEPS = 4.0

#: The variance of a uniform rounding error, in steps squared.
_UNIFORM = 1.0 / 12.0

#: The measured phases: ``"two"`` (each phase on the lattice: two measured, the third
#: their negative sum) or ``"three"`` (each measured, the common mode dropped after).
Measured = Literal["two", "three"]


@dataclass(frozen=True)
class CurrentLattice:
    """The ADC seen in a log's currents.

    Attributes
    ----------
    step : float
        One step of the ADC, A.
    measured : {"two", "three"}
        How many phases the ADC measures (see :data:`Measured`).
    offsets : ndarray, shape (3,)
        Each phase's place on the lattice, in steps (0: the lattice holds zero; zeros for
        three measured phases, whose common mode the log lost).
    """

    step: float
    measured: Measured
    offsets: Array

    def noise_sd(self, R: Array) -> float:
        """The noise before the ADC on each phase, A (standard deviation), from the
        covariance ``R`` (2, 2) of the dq currents' measurement errors: the rounding's
        share taken out of their mean variance (0 where the rounding explains it all).

        Parameters
        ----------
        R : ndarray, shape (2, 2)
            Covariance of the measurement errors of ``[i_d, i_q]``, A^2.
        """
        # per-phase variance v becomes 2/3 v per dq axis when three phases are measured
        # (the Clarke transform's average), 4/3 v when the third is the others' sum
        gain = 2.0 / 3.0 if self.measured == "three" else 4.0 / 3.0
        per_phase = 0.5 * float(np.trace(R)) / gain
        return float(np.sqrt(max(per_phase - _UNIFORM * self.step**2, 0.0)))

    def coarse(self, noise: float) -> bool:
        """Whether the steps are coarse against ``noise`` (:data:`COARSE_ADC_STEPS`).

        Parameters
        ----------
        noise : float
            The noise before the ADC on each phase, A (standard deviation).
        """
        return self.step > COARSE_ADC_STEPS * noise

    def measure(self, x: Array, angle: Array, noise: Array) -> Array:
        """The dq currents an ADC of this lattice reports for the true ones.

        Parameters
        ----------
        x : ndarray, shape (T, 2)
            True ``[i_d, i_q]``, A.
        angle : ndarray, shape (T,)
            Electrical angle, rad.
        noise : ndarray, shape (T, 3)
            Noise added to each phase before the ADC, A.
        """
        phases = phase_currents(x, angle) + noise
        steps = phases / self.step - self.offsets
        rounded = (np.round(steps) + self.offsets) * self.step
        if self.measured == "two":
            rounded[:, 2] = -rounded[:, 0] - rounded[:, 1]
        return phases_to_dq(rounded, angle)


def _on_lattice(values: Array, step: float) -> tuple[bool, float]:
    """Whether ``values`` are whole steps plus one offset (within
    :data:`LATTICE_TOLERANCE`), and the offset in steps (in [-0.5, 0.5))."""
    fraction = values / step
    turns = np.exp(2j * np.pi * fraction)
    offset = float(np.angle(np.mean(turns)) / (2.0 * np.pi))
    departure = fraction - offset - np.round(fraction - offset)
    return bool(np.sqrt(np.mean(departure**2)) <= LATTICE_TOLERANCE), offset


def _smallest_step(values: Array) -> float | None:
    """The smallest gap between the values' distinct codes (values within
    :data:`MERGED` of the largest merged); None without two codes."""
    scale = float(np.max(np.abs(values))) if values.size else 0.0
    if scale == 0.0:
        return None
    ordered = np.sort(values)
    gaps = np.diff(ordered)
    gaps = gaps[gaps > MERGED * scale]
    return float(np.min(gaps)) if gaps.size else None


def _refined(values: Array, step: float) -> float:
    """The step that fits the values' codes best (least squares of ``value = step k + b``
    with ``k`` the codes counted from the smallest value at ``step``): the smallest gap,
    from values rounded in the log, is short of the step by their rounding."""
    codes = np.round((values - np.min(values)) / step)
    slope, _ = np.polyfit(codes, values, 1)
    return float(slope)


def current_lattice(x: Array, angle: Array) -> CurrentLattice | None:
    """The ADC lattice of the logged currents, or None when they are on none.

    Parameters
    ----------
    x : ndarray, shape (T, 2)
        Measured ``[i_d, i_q]``, A.
    angle : ndarray, shape (T,)
        Electrical angle of each row, rad.
    """
    differences = line_to_line(x, angle)
    candidates = [_smallest_step(column) for column in differences.T]
    if any(step is None for step in candidates):
        return None
    smallest = min(step for step in candidates if step is not None)
    step = float(np.mean([_refined(column, smallest) for column in differences.T]))
    if not all(_on_lattice(column, step)[0] for column in differences.T):
        return None
    phases = phase_currents(x, angle)
    placed = [_on_lattice(column, step) for column in phases.T]
    if all(on for on, _ in placed):
        return CurrentLattice(step, "two", np.array([offset for _, offset in placed]))
    return CurrentLattice(step, "three", np.zeros(3))
