"""The three phases and the two axes: the amplitude-invariant Clarke and Park transforms.

A phase quantity ``(v_a, v_b, v_c)`` (currents, A; voltages, V) is the stationary vector
``v_alpha + j v_beta = (2/3) sum_x v_x exp(j 2 pi x / 3)`` (x = 0, 1, 2 for a, b, c; the
common mode ``v_a + v_b + v_c`` is dropped), and in the rotor frame at the electrical
angle ``theta`` the dq vector ``v_d + j v_q = exp(-j theta) (v_alpha + j v_beta)``. The
inverse gives balanced phases (no common mode). The functions take a sample's values
(floats) or many samples' (arrays of one shape), with ``cos theta`` and ``sin theta``;
:func:`to_phases` and :func:`from_phases` are the same transforms of complex stationary
vectors (the simulator's form).
"""

from __future__ import annotations

from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

from ._validation import Array

__all__ = [
    "CLARKE",
    "PHASE_DIRECTIONS",
    "ComplexArray",
    "Number",
    "dq_of_phases",
    "from_phases",
    "phase_currents",
    "phases_of_dq",
    "phases_to_dq",
    "space_vector_duties",
    "to_phases",
]

#: ``sqrt(3) / 2``: the phases b and c lie at -+120 degrees from a.
_HALF_ROOT3 = 0.5 * float(np.sqrt(3.0))

#: Complex arrays: a two-axis vector ``alpha + j beta`` or ``d + j q`` per entry.
ComplexArray = NDArray[np.complex128]

#: The directions of phases a, b, c in the stationary frame: ``exp(j 2 pi x / 3)``.
PHASE_DIRECTIONS: ComplexArray = np.exp(2j * np.pi * np.arange(3) / 3)
#: The amplitude-invariant Clarke transform as a row: ``i_ab = i_abc @ CLARKE``.
CLARKE: ComplexArray = (2.0 / 3.0) * PHASE_DIRECTIONS

#: A sample's value (float) or many samples' (ndarray).
Number = TypeVar("Number", float, Array)


def phases_of_dq(
    i_d: Number, i_q: Number, cos: Number, sin: Number
) -> tuple[Number, Number, Number]:
    """The phase values a, b, c of the dq values at the angle (amplitude-invariant)."""
    alpha, beta = i_d * cos - i_q * sin, i_d * sin + i_q * cos
    return alpha, -0.5 * alpha + _HALF_ROOT3 * beta, -0.5 * alpha - _HALF_ROOT3 * beta


def dq_of_phases(
    a: Number, b: Number, c: Number, cos: Number, sin: Number
) -> tuple[Number, Number]:
    """The dq components of ``(2/3) sum_x v_x exp(j 2 pi x / 3)`` at the angle."""
    v_alpha, v_beta = (2.0 / 3.0) * (a - 0.5 * (b + c)), (2.0 / 3.0) * _HALF_ROOT3 * (b - c)
    return v_alpha * cos + v_beta * sin, v_beta * cos - v_alpha * sin


def phase_currents(x: Array, angle: Array) -> Array:
    """The phase currents ``[i_a, i_b, i_c]`` (T, 3), A, of the dq currents ``x`` (T, 2) at
    the electrical angles (T,), rad (amplitude-invariant)."""
    return np.column_stack(phases_of_dq(x[:, 0], x[:, 1], np.cos(angle), np.sin(angle)))


def phases_to_dq(phases: Array, angle: Array) -> Array:
    """The dq values (T, 2) of phase values (T, 3) at the electrical angles (T,), rad: the
    inverse of :func:`phase_currents` (a common mode is dropped)."""
    return np.column_stack(
        dq_of_phases(phases[:, 0], phases[:, 1], phases[:, 2], np.cos(angle), np.sin(angle))
    )


def to_phases(vector: ComplexArray) -> Array:
    """Phase values ``[a, b, c]`` (..., 3) of stationary vectors (amplitude-invariant)."""
    return np.real(vector[..., np.newaxis] * np.conj(PHASE_DIRECTIONS))


def from_phases(phases: Array) -> ComplexArray:
    """``alpha + j beta`` of phase values (..., 3) (Clarke; the common mode is dropped)."""
    return phases @ CLARKE


def space_vector_duties(voltage: ComplexArray, dc_voltage: float) -> Array:
    """A two-level inverter's leg duties ``[d_a, d_b, d_c]`` (..., 3), in ``[0, 1]``, for
    stationary voltage references ``voltage`` (...), V: space-vector modulation,
    ``d_x = 1/2 + (v_x + v_0) / V_dc`` with the min-max zero sequence ``v_0 = -(max v_x +
    min v_x) / 2``, clipped (inside ``[0, 1]`` while ``|v| <= V_dc / sqrt(3)``)."""
    phases = to_phases(np.asarray(voltage))
    zero_sequence = -0.5 * (phases.max(axis=-1) + phases.min(axis=-1))
    return np.clip(0.5 + (phases + zero_sequence[..., np.newaxis]) / dc_voltage, 0.0, 1.0)
