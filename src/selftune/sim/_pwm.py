"""The inverter's phases and pulses (see :mod:`._inverter` for the physics; the Clarke
transform is :mod:`selftune.core._phases`): the legs' duties and carrier edges, one
carrier period exactly, and the carrier PWM's plant, one motor's sample at a time in
Python floats: numpy's cost per call on arrays of 2, 3 or 7 values made a sample about
0.35 ms, in Python floats the plant's part is about 0.02 ms. The measured currents' Park
transform stays numpy's (its complex product rounds as a fused multiply-add does), so the
logged currents and commands are those of the former numpy plant to the bit wherever an
ADC rounds the phase currents (but for a current within rounding of a step's edge); the
true currents and voltages differ by rounding (1e-13 A, 2e-13 V over 5,000 samples)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from math import cos, exp, expm1, sin
from typing import TYPE_CHECKING

import numpy as np

from ..core import Array
from ..core._phases import (
    CLARKE,
    PHASE_DIRECTIONS,
    ComplexArray,
    from_phases,
    space_vector_duties,
    to_phases,
)
from ._salient import RotorFrames
from ._saturation import SaturatedMotors

if TYPE_CHECKING:
    from ._inverter import LoopInputs, LoopState
    from ._salient import RotorFrame

__all__ = [
    "CLARKE",
    "PHASE_DIRECTIONS",
    "ComplexArray",
    "PwmSegments",
    "carrier_edges",
    "carrier_sample",
    "carrier_segments",
    "dead_time_amplitude",
    "dead_time_voltage",
    "from_phases",
    "leg_duties",
    "to_phases",
]

#: A plant's results: measured i_dq and true i_ab (P, N + 1), mean dq voltages (P, N), the
#: compensations (P, d + N + 1) and the current after the last sample (P,).
_Results = tuple[ComplexArray, ComplexArray, ComplexArray, ComplexArray, ComplexArray]

#: ``conj(PHASE_DIRECTIONS)`` and CLARKE as Python complex numbers (one motor's sample).
_DIRECTIONS = tuple(complex(d) for d in np.conj(PHASE_DIRECTIONS))
_CLARKE = tuple(complex(c) for c in CLARKE)


def dead_time_amplitude(dead_time: float, dc_voltage: float | None, period: float) -> float:
    """The dead time's voltage error per phase, ``t_d f_sw V_dc``, V (0 without a DC bus).

    Parameters
    ----------
    dead_time : float
        ``t_d``, s.
    dc_voltage : float or None
        ``V_dc``, V.
    period : float
        The PWM period ``1 / f_sw``, s.
    """
    return dead_time * (dc_voltage or 0.0) / period


def dead_time_voltage(signs: Array, amplitude: float) -> ComplexArray:
    """The stationary vector (P,) of the phase errors ``-amplitude sign(i_x)``, V.

    ``signs`` (P, 3) are ``sign(i_x)`` (0: no error); ``amplitude`` is ``t_d f_sw V_dc``, V.
    """
    return -amplitude * from_phases(signs)


def leg_duties(voltage: ComplexArray, dc_voltage: float) -> Array:
    """Space-vector duties (P, 3) of legs a, b, c for the references ``voltage`` (P,), V
    (:func:`~selftune.core._phases.space_vector_duties`); ``dc_voltage`` in V."""
    return space_vector_duties(np.asarray(voltage).reshape(-1), dc_voltage)


def _duties(voltage: complex, dc_voltage: float) -> tuple[float, float, float]:
    """:func:`leg_duties` of one reference, in Python floats (a sample's modulation)."""
    a, b, c = _phase_values(voltage)
    zero_sequence = -0.5 * (max(a, b, c) + min(a, b, c))
    return (
        min(max(0.5 + (a + zero_sequence) / dc_voltage, 0.0), 1.0),
        min(max(0.5 + (b + zero_sequence) / dc_voltage, 0.0), 1.0),
        min(max(0.5 + (c + zero_sequence) / dc_voltage, 0.0), 1.0),
    )


@dataclass(frozen=True, eq=False)
class PwmSegments:
    """The voltage over one carrier period, piecewise constant.

    Attributes
    ----------
    boundaries : ndarray, shape (P, 8)
        Segment boundaries from the period start, s: ``0 <= b_1 <= ... <= b_6 <= T``.
    voltages : ndarray of complex, shape (P, 7)
        The stationary-frame voltage of each segment, V.
    """

    boundaries: Array
    voltages: ComplexArray

    @property
    def durations(self) -> Array:
        """Segment lengths, s, shape (P, 7)."""
        return np.diff(self.boundaries, axis=-1)


def _phase_values(vector: complex) -> tuple[float, float, float]:
    """:func:`to_phases` of one vector (Python floats)."""
    return (
        (vector * _DIRECTIONS[0]).real,
        (vector * _DIRECTIONS[1]).real,
        (vector * _DIRECTIONS[2]).real,
    )


def _signs(phases: tuple[float, float, float]) -> tuple[float, float, float]:
    """``numpy.sign`` of each of three floats (NaN stays NaN)."""
    a, b, c = phases
    return (
        1.0 if a > 0.0 else -1.0 if a < 0.0 else a,
        1.0 if b > 0.0 else -1.0 if b < 0.0 else b,
        1.0 if c > 0.0 else -1.0 if c < 0.0 else c,
    )


@lru_cache(maxsize=16)
def _compensations(amplitude: float) -> dict[tuple[float, float, float], complex]:
    """``-dead_time_voltage(signs, amplitude)`` of every sign pattern, V."""
    signs = np.array(np.meshgrid(*[[-1.0, 0.0, 1.0]] * 3, indexing="ij")).reshape(3, -1).T
    values = -dead_time_voltage(signs, amplitude)
    return {(a, b, c): complex(v) for (a, b, c), v in zip(signs.tolist(), values, strict=True)}


def carrier_edges(
    voltage: complex, dc_voltage: float, period: float, dead_time: float, signs: Sequence[float]
) -> tuple[tuple[float, float], tuple[float, float], tuple[float, float]]:
    """Each leg's high interval ``[rise, fall)`` over one center-aligned carrier period
    (s from its start), with dead time, for one reference ``voltage`` (``alpha + j
    beta``, V) and the signs of the phase currents at the period start; in Python floats
    (numpy's cost per call on 3 values was most of a sample's)."""
    half = 0.5 * period
    a, b, c = _duties(voltage, dc_voltage)
    return (
        _leg(a, signs[0], half, dead_time),
        _leg(b, signs[1], half, dead_time),
        _leg(c, signs[2], half, dead_time),
    )


def _leg(duty: float, sign: float, half: float, dead_time: float) -> tuple[float, float]:
    """One leg's :func:`carrier_edges` (``half`` = T / 2)."""
    switching = 0.0 < duty < 1.0  # a leg held at 0 or 1 does not switch
    rise = (1.0 - duty) * half + (dead_time if sign > 0.0 and switching else 0.0)
    fall = min((1.0 + duty) * half + (dead_time if sign < 0.0 and switching else 0.0), 2 * half)
    return min(rise, fall), fall


def carrier_segments(
    voltage: ComplexArray, dc_voltage: float, period: float, dead_time: float, signs: Array
) -> PwmSegments:
    """The segments of one center-aligned carrier period, with dead time (the legs'
    :func:`carrier_edges`, sorted).

    Parameters
    ----------
    voltage : ndarray of complex, shape (P,)
        Reference ``alpha + j beta`` over the period, V.
    dc_voltage : float
        DC-bus voltage, V.
    period : float
        Carrier period ``T = 1 / f_sw``, s.
    dead_time : float
        ``t_d``, s.
    signs : ndarray, shape (P, 3)
        ``sign(i_x)`` of the phase currents at the period start.

    Returns
    -------
    PwmSegments
        Without dead time the volt-seconds equal ``voltage * period`` exactly.
    """
    legs = np.array(
        [
            carrier_edges(complex(v), dc_voltage, period, dead_time, s)
            for v, s in zip(np.asarray(voltage).tolist(), np.asarray(signs).tolist(), strict=True)
        ],
        dtype=float,
    ).reshape(-1, 3, 2)
    rise, fall = legs[:, :, 0], legs[:, :, 1]
    count = rise.shape[0]
    edges = np.sort(legs.reshape(count, 6), axis=-1)
    boundaries = np.concatenate([np.zeros((count, 1)), edges, np.full((count, 1), period)], -1)
    middle = 0.5 * (boundaries[:, 1:] + boundaries[:, :-1])[:, :, np.newaxis]
    high = (rise[:, np.newaxis, :] <= middle) & (middle < fall[:, np.newaxis, :])
    voltages = dc_voltage * (high.astype(float) @ CLARKE)  # the -V_dc/2 common mode cancels
    return PwmSegments(boundaries=boundaries, voltages=voltages)


def carrier_sample(
    motor: tuple[float, float, float, float],
    current: complex,
    edges: Sequence[tuple[float, float]],
    dc_voltage: float,
    period: float,
    emf: complex,
    rotor: complex,
    frame: RotorFrame | None = None,
    following: complex = 1.0,
) -> tuple[complex, complex]:
    """One motor over one carrier period (``period`` = T, s), exactly: ``i_ab`` at its end
    and the mean rotor-frame voltage over it, V.

    ``motor`` is ``(gamma, R_s, w_e, exp(-gamma T))``; ``current`` the start's ``i_ab``;
    ``edges`` the legs' :func:`carrier_edges`; ``emf`` (A) the back-EMF's part over the
    whole period; ``rotor`` ``exp(j theta)`` at its start. The voltage is the legs'
    pulses superposed, ``V_dc sum_x CLARKE_x [r_x <= t < f_x]`` (the ``-V_dc / 2`` common
    mode cancels), so with ``w_x = f_x - r_x``::

        i(T) = a_T i(0) + V_dc sum_x CLARKE_x (exp(-gamma (T - f_x)) - exp(-gamma (T - r_x)))
               / R_s + emf
        mean = exp(-j theta) V_dc sum_x CLARKE_x w_x exp(-j w_e m_x) sinc_x / T

    ``m_x = (r_x + f_x) / 2``, ``sinc_x = sin(y) / y``, ``y = w_e w_x / 2``: the mean of
    ``exp(-j w_e s)`` over the pulse. A leg that never rises adds nothing. An interior
    motor gives its ``frame`` (:class:`~selftune.sim._salient.RotorFrame`; then
    ``gamma``, ``R_s`` and ``emf`` are unused) and ``following``, ``exp(j theta)`` at the
    period's end: each pulse is :meth:`RotorFrame.pulse` in the rotor frame.
    """
    gamma, R_s, w, decay = motor
    turn = rotor.conjugate()
    forced = 0j
    for (rise, fall), direction in zip(edges, _CLARKE, strict=True):
        width = fall - rise
        if width == 0.0:
            continue
        if frame is None:
            forced += direction * (-exp(-gamma * (period - fall)) * expm1(-gamma * width))
        else:
            forced += frame.pulse(rise, fall, turn * direction)
    if frame is None:
        after = decay * current + dc_voltage * forced / R_s + emf
    else:
        after = following * (frame.free(turn * current) + dc_voltage * forced)
    return after, pulses_mean(edges, dc_voltage, period, w, rotor)


def pulses_mean(
    edges: Sequence[tuple[float, float]], dc_voltage: float, period: float, w: float, rotor: complex
) -> complex:
    """The mean rotor-frame voltage (V) over a carrier period of the legs' pulses
    ``edges`` (:func:`carrier_sample`'s ``mean``; ``w`` = ``w_e``, rad/s; ``rotor`` =
    ``exp(j theta)`` at the period's start)."""
    total = 0j
    for (rise, fall), direction in zip(edges, _CLARKE, strict=True):
        width = fall - rise
        if width == 0.0:
            continue
        half = 0.5 * w * width
        middle = w * (rise + 0.5 * width)
        mean = sin(half) / half if half != 0.0 else 1.0
        total += direction * (width * mean) * complex(cos(middle), -sin(middle))
    return rotor.conjugate() * (dc_voltage * total) / period


# -- the time loop ----------------------------------------------------------------------


class _CarrierInverter:
    """The inverter with carrier PWM, the motors and the sensor as the stepper's plant (a
    ``LoopPlant``), each motor's sample in Python floats (:func:`carrier_edges`,
    :func:`carrier_sample`; see the module docstring). It records the true phase signs
    when it measures sample k, and uses them to advance over sample k (the stepper's
    order)."""

    def __init__(self, inputs: LoopInputs, start: LoopState | None = None) -> None:
        mod, motor, sensor = inputs.modulator, inputs.motor, inputs.sensor
        assert mod.carrier and mod.stationary and mod.dc_voltage is not None
        count, plants = inputs.rho.shape[1], inputs.rotor.shape[0]
        self.plants, self.sensor, self.dc_voltage = plants, sensor, mod.dc_voltage
        self.period, self.dead_time = mod.period, mod.dead_time
        self.signed = mod.dead_time_amplitude > 0.0
        self.compensations = (
            _compensations(mod.dead_time_amplitude)
            if mod.compensation and mod.dead_time_amplitude > 0.0
            else None
        )
        self.motors = list(
            zip(
                motor.gamma.tolist(), motor.R_s.tolist(), motor.electrical_speed.tolist(),
                inputs.decay.tolist(), strict=True,
            )
        )  # fmt: skip
        self.rotor, self.modulation = inputs.rotor.tolist(), inputs.modulation.tolist()
        frames = inputs.frames  # interior motors: the rotor frame (._salient)
        self.frames = frames.frames if isinstance(frames, RotorFrames) else None
        self.saturated = (  # saturating motors: segment by segment (._saturation)
            [frames.motor(i) for i in range(plants)]
            if isinstance(frames, SaturatedMotors)
            else None
        )
        self.emf = inputs.emf.tolist() if frames is None else []
        noise = sensor.noise
        if noise is not None and noise.shape[0] != plants:  # one noise for all motors
            noise = np.broadcast_to(noise, (plants, *noise.shape[1:]))
        self.noise = None if noise is None else noise.tolist()
        # sample by sample (rows): the Park transform's exp(-j theta) and i_dq
        self.turn = np.conj(inputs.rotor).T.copy()
        self.measured = np.empty((count + 1, plants), dtype=complex)
        self.pairs = self.measured.view(float).reshape(count + 1, plants, 2)  # [d, q] rows
        self.currents = [[0j] * (count + 1) for _ in range(plants)]
        self.applied = [[0j] * count for _ in range(plants)]
        self.extras = [[0j] * (count + 1) for _ in range(plants)]
        #: the signs of the true phase currents at the last measurement (the sample's start)
        self.signs = [(0.0, 0.0, 0.0)] * plants
        delay = mod.delay
        self.current: list[complex] = [0j] * plants if start is None else start.current.tolist()
        self.earlier: list[list[complex]] = (
            [[0j] * delay for _ in range(plants)] if start is None else start.extras.tolist()
        )

    def measure(self, k: int) -> Array:
        """The measured ``i_dq`` (P, 2) at sample k; keeps the compensation it asks for.

        The Park transform is numpy's (its complex product rounds as a fused multiply-add
        does, Python's does not): a log's currents are, to the bit, the other plant's."""
        sensor, compensations = self.sensor, self.compensations
        read = []
        for i in range(self.plants):
            current = self.current[i]
            self.currents[i][k] = current
            phases = _phase_values(current)
            if self.signed:  # the dead time acts with the true signs at the period start
                self.signs[i] = _signs(phases)
            if sensor.exact:
                read.append(current)
            else:
                noise = None if self.noise is None else self.noise[i][k]
                phases = sensor.phase_values(phases, noise)
                read.append(
                    phases[0] * _CLARKE[0] + phases[1] * _CLARKE[1] + phases[2] * _CLARKE[2]
                )
            if compensations is not None:
                extra = compensations.get(_signs(phases))
                self.extras[i][k] = complex(np.nan, np.nan) if extra is None else extra  # NaN
        np.multiply(np.array(read), self.turn[k], out=self.measured[k])
        return self.pairs[k]

    def advance(self, k: int, applied: Array, computed_at: int) -> None:
        """Modulate the command computed at ``computed_at`` over sample k (measured
        before, as the stepper does)."""
        for i, (u_d, u_q) in enumerate(applied.tolist()):
            command = self.modulation[i][k] * complex(u_d, u_q)
            extras = self.extras[i] if computed_at >= 0 else self.earlier[i]
            extra, current = extras[computed_at], self.current[i]
            dc, period = self.dc_voltage, self.period
            edges = carrier_edges(command + extra, dc, period, self.dead_time, self.signs[i])
            if self.saturated is not None:
                segments = carrier_segments(
                    np.array([command + extra]),
                    dc,
                    period,
                    self.dead_time,
                    np.array([self.signs[i]]),
                )
                rotor = self.rotor[i][k]
                self.current[i] = self.saturated[i].carrier(
                    current, segments, rotor, self.rotor[i][k + 1]
                )
                self.applied[i][k] = pulses_mean(edges, dc, period, self.motors[i][2], rotor)
            elif self.frames is None:
                self.current[i], self.applied[i][k] = carrier_sample(
                    self.motors[i], current, edges, dc, period, self.emf[i][k], self.rotor[i][k]
                )
            else:
                self.current[i], self.applied[i][k] = carrier_sample(
                    self.motors[i], current, edges, dc, period, 0j, self.rotor[i][k],
                    self.frames[i], self.rotor[i][k + 1],
                )  # fmt: skip

    def results(self) -> _Results:
        """As :meth:`._inverter._Inverter.results`."""
        extras = [before + after for before, after in zip(self.earlier, self.extras, strict=True)]
        return (
            np.ascontiguousarray(self.measured.T),
            np.array(self.currents, dtype=complex),
            np.array(self.applied, dtype=complex).reshape(self.plants, -1),
            np.array(extras, dtype=complex).reshape(self.plants, -1),
            np.array(self.current, dtype=complex),
        )
