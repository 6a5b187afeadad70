"""The voltage limit of a drive's law and its anti-windup: one rule for Python and firmware.

A two-level inverter with space-vector modulation makes any dq voltage of magnitude up to
``U_max = V_dc / sqrt(3)`` (the linear modulation range). A law's command beyond it is
scaled back onto the circle, its angle kept (:func:`limit_magnitude`); the limited command
is what the drive applies, logs and feeds back as a past input.

**Anti-windup by conditional integration (clamping)**: at a sample where the limit scaled
the command, the law's integrators hold (``z_(k+1) = z_k``); elsewhere they integrate as
the law states (``z_(k+1) = z_k + h e_k``). So an error the voltage cannot remove (a torque
step the bus cannot follow at once) does not charge the integrator, which would otherwise
discharge it as a current overshoot once the voltage is free again
(:func:`held_integrators`). Where the limit never acts, the law is exactly the law.

The simulated drives run this rule (:func:`selftune.sim._stepper.run_closed_loop`); the C
code of ``selftune export`` (:mod:`selftune.report._firmware`) implements the same two
steps in float32.
"""

from __future__ import annotations

from math import sqrt

import numpy as np

from ._validation import Array

__all__ = ["held_integrators", "limit_magnitude"]


def limit_magnitude(u: Array, limit: float) -> Array:
    """Each row of ``u`` (P, 2) scaled to a magnitude of at most ``limit``, V.

    A row of magnitude ``|u| <= limit`` is kept; a longer one is multiplied by
    ``limit / |u|``. Returns ``u`` itself where no row exceeds the limit (computed in
    Python floats: numpy's cost per call on 2 values was half of the drive's stepper's).

    Parameters
    ----------
    u : ndarray, shape (P, 2)
        The commands, V.
    limit : float
        The largest magnitude, V (``inf``: no limit).

    Returns
    -------
    ndarray, shape (P, 2)
    """
    scales = []
    for a, b in u.tolist():
        magnitude = sqrt(a * a + b * b)
        scales.append(1.0 if magnitude <= limit else limit / magnitude)  # NaN: NaN
    if all(scale == 1.0 for scale in scales):
        return u
    return u * np.array(scales)[:, np.newaxis]


def held_integrators(computed: Array, limited: Array) -> Array:
    """The anti-windup rule: which laws hold their integrators at this sample.

    Parameters
    ----------
    computed : ndarray, shape (P, m)
        The commands the laws computed.
    limited : ndarray, shape (P, m)
        The same after the voltage limit (:func:`limit_magnitude`).

    Returns
    -------
    ndarray of bool, shape (P,)
        True where the limit changed the command: that law's integrators hold.
    """
    return np.any(limited != computed, axis=-1)
