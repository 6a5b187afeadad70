"""The physics and the time loop under :class:`~selftune.sim._realistic.RealisticDrive`.

Everything acts on P motors at once. A complex number ``a + j b`` is a two-axis vector:
``[alpha, beta]`` (stationary frame) or ``[d, q]`` (rotor frame), ``i_dq = exp(-j theta)
i_ab`` (Park). SI units.

**Motor**: ``L_s di/dt = v - R_s i - e``, back-EMF ``e = j w_e phi_pm exp(j theta)``
(``w_e phi_pm [-sin theta, cos theta]``, V), ``theta = w_e t``, ``w_e = p speed``; in dq
exactly PAPER_NOTES eq. (8) with ``w_1 = p speed phi_pm``. For a voltage ``c + r exp(j
w_e s)`` over ``[0, tau]`` (a constant part and one turning with the rotor), exactly::

    i(tau) = a i(0) + (1 - a) c / R_s
             + (r - j w_e phi_pm exp(j theta_0)) (exp(j w_e tau) - a) / (L_s (gamma + j w_e))

``a = exp(-gamma tau)``, ``gamma = R_s / L_s``: the EMF and a turning voltage are the same
integral ``int_0^tau exp(-gamma (tau - s)) exp(j w_e s) ds``. No ODE solver. An interior
motor (``L_d != L_q``, :class:`~selftune.model.IPMSM`) is not a complex scalar in the
stationary frame: it is propagated in the rotor frame, as exactly (:mod:`._salient`), and
its torque has the reluctance term. A batch with an interior motor takes that path for
all its motors (a surface motor's numbers then agree with its own path to rounding). A
batch with magnetic saturation (:mod:`._saturation`) is propagated in the rotor frame by
Runge-Kutta steps of its current-dependent flux linkages, not exactly, and its torque is
``1.5 p (psi_d i_q - psi_q i_d)``.

**Inverter**: two-level legs on ``V_dc``; space-vector duties ``d_x = 1/2 + (v_x + v_0) /
V_dc``, ``v_0 = -(max v_x + min v_x) / 2``, in ``[0, 1]`` while ``|v| <= V_dc / sqrt(3)``.
Center-aligned carrier: leg x high on ``[(1 - d_x) T/2, (1 + d_x) T/2]``, all legs low at
the period boundary (the carrier peak, where the currents are sampled); up to 7 constant
segments per period, propagated as the three legs' pulses superposed (the voltage is
``V_dc sum_x CLARKE_x [leg x high]``: :func:`~selftune.sim._pwm.carrier_sample`). Dead
time ``t_d``: a leg whose current flows out (``i_x > 0``) rises ``t_d`` late, one whose
current flows in falls ``t_d`` late, so the mean phase voltage moves by ``-t_d f_sw V_dc
sign(i_x)``; the sign is the one at the period start (the sample instant) for all the
period's edges (exact unless a phase current crosses zero within the period). A leg at
duty 0 or 1 does not switch; a pulse cannot be shorter than 0 or longer than the period
(the average model does not clip its error).

**Sensor**: phase currents (amplitude-invariant inverse Clarke) plus Gaussian noise, then
an ADC rounding to the LSB ``adc_range / 2**(adc_bits - 1)`` and clipping to the codes
``-2**(adc_bits - 1) .. 2**(adc_bits - 1) - 1``; then Clarke (dropping the common mode).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from functools import cached_property
from typing import TYPE_CHECKING, TypeVar, cast

import numpy as np

from ..core import Array
from ..core._voltage_limit import limit_magnitude
from ..errors import InputError
from ..model import IPMSM, SPMSM, Motor
from ._checks import as_float_array, as_generator
from ._exploration import Exploration
from ._pwm import (
    CLARKE,
    ComplexArray,
    PwmSegments,
    _CarrierInverter,
    _Results,
    carrier_segments,
    dead_time_amplitude,
    dead_time_voltage,
    from_phases,
    leg_duties,
    to_phases,
)
from ._salient import RotorFrames
from ._saturation import SaturatedMotors, Saturation
from ._stepper import Feedback, run_closed_loop

__all__ = [
    "CLARKE",
    "COPPER_COEFFICIENT",
    "MAGNET_COEFFICIENT",
    "ComplexArray",
    "CurrentSensor",
    "LoopInputs",
    "LoopOutputs",
    "LoopState",
    "Modulator",
    "MotorBatch",
    "MotorT",
    "PwmSegments",
    "carrier_segments",
    "dead_time_voltage",
    "from_phases",
    "heated_motor",
    "leg_duties",
    "phasor_mean",
    "random_inputs",
    "run_loop",
    "scaled_motor",
    "to_phases",
]

#: Resistance rise of copper per kelvin, 1/K.
COPPER_COEFFICIENT = 0.0039
#: Flux loss of NdFeB magnets per kelvin, 1/K.
MAGNET_COEFFICIENT = 0.001


if TYPE_CHECKING:  # a default (PEP 696) for the type checker: a drive's motor is a surface one
    from typing_extensions import TypeVar as DefaultTypeVar

    #: A surface or an interior motor, kept through what is made of it.
    MotorT = DefaultTypeVar("MotorT", bound=SPMSM | IPMSM, default=SPMSM)
else:
    MotorT = TypeVar("MotorT", bound=SPMSM | IPMSM)


def scaled_motor(motor: MotorT, R_s: float, L: float, phi_pm: float) -> MotorT:
    """The motor with its R_s, inductances (L_s; an interior motor's L_d and L_q both)
    and phi_pm multiplied by the factors ``R_s``, ``L`` and ``phi_pm`` (of its type)."""
    given: Motor = motor
    R, phi = given.R_s * R_s, given.phi_pm * phi_pm
    if isinstance(given, IPMSM):
        scaled: Motor = replace(given, R_s=R, L_d=given.L_d * L, L_q=given.L_q * L, phi_pm=phi)
    else:
        scaled = replace(given, R_s=R, L_s=given.L_s * L, phi_pm=phi)
    return cast(MotorT, scaled)


def heated_motor(motor: MotorT, temperature_rise: float) -> MotorT:
    """The motor at ``temperature_rise`` (K) above its nameplate's: ``R_s (1 + 0.0039 dT)``,
    ``phi_pm (1 - 0.001 dT)``, the inductances unchanged."""
    copper = 1.0 + COPPER_COEFFICIENT * temperature_rise
    return scaled_motor(motor, copper, 1.0, 1.0 - MAGNET_COEFFICIENT * temperature_rise)


def phasor_mean(x: Array) -> ComplexArray:
    """``(1 - exp(-j x)) / (j x) = exp(-j x / 2) sin(x / 2) / (x / 2)``: the mean of
    ``exp(-j s)`` over ``[0, x]`` (x in rad), without cancellation at small x."""
    x = np.asarray(x, dtype=float)
    return np.exp(-0.5j * x) * np.sinc(x / (2.0 * np.pi))


@dataclass(frozen=True, eq=False)
class MotorBatch:
    """P motors at their operating temperature and held speed, as arrays (P,).

    Attributes
    ----------
    R_s : ndarray
        Stator resistance, ohm, heated: ``R_s (1 + 0.0039 dT)``.
    L_d, L_q : ndarray
        d- and q-axis inductances, H (a surface motor's L_s both).
    phi_pm : ndarray
        Magnet flux linkage, Wb, heated: ``phi_pm (1 - 0.001 dT)``.
    p : ndarray
        Pole pairs.
    electrical_speed : ndarray
        ``w_e = p speed``, rad/s.
    interior : ndarray of bool
        Whether the motor is an :class:`~selftune.model.IPMSM` (propagated in the rotor
        frame, :mod:`._salient`, even with ``L_d == L_q``).
    saturation : SaturationModel or FluxMap or None
        The motors' flux linkages (:mod:`._saturation`; then ``L_d``, ``L_q`` and
        ``phi_pm`` are unused); None: the constant inductances.
    """

    R_s: Array
    L_d: Array
    L_q: Array
    phi_pm: Array
    p: Array
    electrical_speed: Array
    interior: Array
    saturation: Saturation | None = None

    @classmethod
    def build(cls, motors: Sequence[Motor], speed: Array, temperature_rise: float) -> MotorBatch:
        """The motors (nameplate values) heated by ``temperature_rise`` (K), at ``speed``
        (rad/s, mechanical, one per motor)."""
        motors = [heated_motor(motor, temperature_rise) for motor in motors]
        p = np.array([motor.p for motor in motors], dtype=float)
        return cls(
            R_s=np.array([m.R_s for m in motors]),
            L_d=np.array([m.L_d for m in motors]),
            L_q=np.array([m.L_q for m in motors]),
            phi_pm=np.array([m.phi_pm for m in motors]),
            p=p,
            electrical_speed=p * speed,
            interior=np.array([isinstance(m, IPMSM) for m in motors], dtype=bool),
        )

    @property
    def L_s(self) -> Array:
        """A surface motor's inductance ``L_d = L_q``, H (the complex path's)."""
        return self.L_d

    def frames(self, period: float) -> RotorFrames | SaturatedMotors | None:
        """The motors in the rotor frame over ``period`` (s): saturating
        (:mod:`._saturation`), or if one is an interior motor (:mod:`._salient`); else
        None (the complex path)."""
        if self.saturation is not None:
            return SaturatedMotors(self.saturation, self.R_s, self.electrical_speed, period)
        if not np.any(self.interior):
            return None
        return RotorFrames.build(
            self.R_s, self.L_d, self.L_q, self.phi_pm, self.electrical_speed, period
        )

    @property
    def gamma(self) -> Array:
        """``R_s / L_s``, 1/s."""
        return self.R_s / self.L_s

    def rotating_gain(self, tau: float) -> ComplexArray:
        """``(exp(j w_e tau) - exp(-gamma tau)) / (L_s (gamma + j w_e))``, A/V: the current
        that a voltage ``exp(j w_e s)`` makes from rest over ``tau`` (s); computed as
        ``exp(-gamma tau) expm1((gamma + j w_e) tau) / ...`` (no cancellation)."""
        rate = np.asarray(self.gamma + 1j * self.electrical_speed, dtype=np.complex128)
        return np.exp(-self.gamma * tau) * np.expm1(rate * tau) / (self.L_s * rate)

    def emf_phasor(self, rotor: ComplexArray) -> ComplexArray:
        """The back-EMF ``j w_e phi_pm exp(j theta)``, V, at ``rotor = exp(j theta)`` (P, ...)."""
        shape = (-1,) + (1,) * (rotor.ndim - 1)
        return 1j * (self.electrical_speed * self.phi_pm).reshape(shape) * rotor

    def torque(self, i_q: Array, i_d: Array) -> Array:
        """``1.5 p (phi_pm + (L_d - L_q) i_d) i_q``, N m, with the true (heated) flux;
        ``i_q``, ``i_d`` (P, ...) in A (a surface motor's ``1.5 p phi_pm i_q``, bit for bit);
        saturating, ``1.5 p (psi_d i_q - psi_q i_d)`` with the flux linkages there."""
        shape = (-1,) + (1,) * (i_q.ndim - 1)
        if self.saturation is not None:
            psi_d, psi_q = self.saturation.flux(i_d, i_q)
            return 1.5 * self.p.reshape(shape) * (psi_d * i_q - psi_q * i_d)
        flux = self.phi_pm.reshape(shape) + (self.L_d - self.L_q).reshape(shape) * i_d
        return 1.5 * (self.p.reshape(shape) * flux) * i_q


@dataclass(frozen=True, eq=False)
class CurrentSensor:
    """Phase-current measurement: noise, then an ADC (see the module docstring).

    Attributes
    ----------
    noise : ndarray, shape (P or 1, N + 1, 3), or None
        The noise added to each phase at each sample, A (drawn in advance).
    lsb : float or None
        The ADC's least significant bit, A; None: no ADC.
    codes : int
        ``2**(adc_bits - 1)``: the ADC codes are ``-codes .. codes - 1``.
    """

    noise: Array | None
    lsb: float | None
    codes: int

    @property
    def exact(self) -> bool:
        """Whether the measurement returns the true currents (no noise, no ADC)."""
        return self.noise is None and self.lsb is None

    def phases(self, current: ComplexArray, k: int) -> Array:
        """The measured phase currents (P, 3), A, at sample ``k`` of the true ``i_ab`` (P,)."""
        phases = to_phases(current)
        if self.noise is not None:
            phases = phases + self.noise[:, k]
        if self.lsb is not None:
            codes = np.clip(np.round(phases / self.lsb), -self.codes, self.codes - 1)
            phases = codes * self.lsb
        return phases

    def phase_values(
        self, phases: tuple[float, float, float], noise: Sequence[float] | None
    ) -> tuple[float, float, float]:
        """:meth:`phases` of one motor in Python floats: its true phase currents, A, and
        the noise added to each at the sample (None: no noise)."""
        if noise is not None:
            phases = (phases[0] + noise[0], phases[1] + noise[1], phases[2] + noise[2])
        if self.lsb is None:
            return phases
        lsb, low, high = self.lsb, -self.codes, self.codes - 1
        return (
            _adc_code(phases[0] / lsb, low, high) * lsb,
            _adc_code(phases[1] / lsb, low, high) * lsb,
            _adc_code(phases[2] / lsb, low, high) * lsb,
        )


def _adc_code(value: float, low: int, high: int) -> float:
    """``clip(round(value), low, high)`` of one float as numpy's (half to even, as
    round(); NaN stays NaN, infinities clip)."""
    if low <= value <= high:
        return float(round(value))
    return float(high) if value > high else float(low) if value < low else value


@dataclass(frozen=True, eq=False)
class Modulator:
    """What the drive does between the controller's command and the motor's terminals.

    Attributes
    ----------
    period : float
        Sampling and PWM period h, s.
    delay : int
        Computation delay d, samples.
    carrier, stationary, compensation : bool
        Carrier PWM (else average); hold the ``alpha-beta`` vector (else the dq vector);
        dead-time compensation from the measured currents.
    dc_voltage : float or None
        DC bus, V (None: no limit).
    dead_time : float
        ``t_d``, s.
    anti_windup : bool
        The laws' integrators hold at the samples where :attr:`limit` scales their command
        (:mod:`selftune.core._voltage_limit`); False: they integrate regardless.
    """

    period: float
    delay: int
    carrier: bool
    stationary: bool
    dc_voltage: float | None
    dead_time: float
    compensation: bool
    anti_windup: bool = False

    @property
    def dead_time_amplitude(self) -> float:
        """``t_d f_sw V_dc``, V (:func:`dead_time_amplitude`)."""
        return dead_time_amplitude(self.dead_time, self.dc_voltage, self.period)

    @property
    def limit(self) -> float:
        """The largest voltage magnitude, ``V_dc / sqrt(3)``, V (inf without a DC bus)."""
        return np.inf if self.dc_voltage is None else self.dc_voltage / np.sqrt(3.0)


@dataclass(frozen=True, eq=False)
class LoopInputs:
    """Everything the time loop needs, over P motors and N samples.

    Attributes
    ----------
    motor, modulator, feedback, sensor : MotorBatch, Modulator, Feedback, CurrentSensor
        The motors, the inverter, the controllers, the measurement.
    rotor : ndarray of complex, shape (P, N + 1)
        ``exp(j theta_k)``.
    modulation : ndarray of complex, shape (P, N)
        ``exp(j (theta_k + eps))``: the modulator's angle over sample k.
    w, rho : ndarray, shape (P or 1, N + 1, q) and (P or 1, N, 2)
        The controllers' reference and the exploration, V.
    """

    motor: MotorBatch
    modulator: Modulator
    feedback: Feedback
    sensor: CurrentSensor
    rotor: ComplexArray
    modulation: ComplexArray
    w: Array
    rho: Array

    @cached_property
    def frames(self) -> RotorFrames | SaturatedMotors | None:
        """:meth:`MotorBatch.frames` over a sample: None for surface motors only."""
        return self.motor.frames(self.modulator.period)

    @cached_property
    def decay(self) -> Array:
        """``exp(-gamma h)`` (P,)."""
        return np.exp(-self.motor.gamma * self.modulator.period)

    @cached_property
    def charge(self) -> Array:
        """``(1 - exp(-gamma h)) / R_s`` (P,), A/V: a constant voltage's effect over h."""
        return -np.expm1(-self.motor.gamma * self.modulator.period) / self.motor.R_s

    @cached_property
    def gain(self) -> ComplexArray:
        """:meth:`MotorBatch.rotating_gain` over a sample (P,), A/V."""
        return self.motor.rotating_gain(self.modulator.period)

    @cached_property
    def emf(self) -> ComplexArray:
        """The back-EMF's part of ``i_(k+1)`` (P, N), A."""
        return -self.motor.emf_phasor(self.rotor[:, :-1]) * self.gain[:, np.newaxis]

    @cached_property
    def turn(self) -> ComplexArray:
        """The mean of ``exp(-j w_e s)`` over a sample (P,)."""
        return phasor_mean(self.motor.electrical_speed * self.modulator.period)


@dataclass(frozen=True, eq=False)
class LoopOutputs:
    """The time loop's results for P motors (complex: ``d + j q`` or ``alpha + j beta``).

    Attributes
    ----------
    measured, current : ndarray of complex, shape (P, N + 1)
        Measured ``i_dq`` and true ``i_ab``, A.
    commands : ndarray, shape (P, N + pad, 2)
        The limited commands, V; row ``pad + k`` computed at sample k (the start's before).
    applied : ndarray of complex, shape (P, N)
        Mean dq voltage over each sample, V.
    pad : int
        Rows before the first command (zeros, or the start's commands).
    state : LoopState
        Where the loop stands after the last sample (a next run's start).
    """

    measured: ComplexArray
    current: ComplexArray
    commands: Array
    applied: ComplexArray
    pad: int
    state: LoopState


@dataclass(frozen=True, eq=False)
class LoopState:
    """Where the time loop stands at a sample: what a run continues from.

    Attributes
    ----------
    current : ndarray of complex, shape (P,)
        True ``i_ab`` at the sample, A.
    commands : ndarray, shape (P, M, m)
        The last M limited commands computed before the sample, oldest first, V (M at
        least the loop's ``max(H, d)``; zeros before the first).
    extras : ndarray of complex, shape (P, d)
        The stationary dead-time compensation computed with the last d of them, V.
    integrator : ndarray, shape (P, R)
        The laws' integrators at the sample.
    """

    current: ComplexArray
    commands: Array
    extras: ComplexArray
    integrator: Array

    @classmethod
    def rest(cls, plants: int, memory: int, delay: int, integrators: int) -> LoopState:
        """Currents, past commands, compensation and integrators zero (``theta`` aside)."""
        return cls(
            current=np.zeros(plants, dtype=complex),
            commands=np.zeros((plants, memory, 2)),
            extras=np.zeros((plants, delay), dtype=complex),
            integrator=np.zeros((plants, integrators)),
        )


def _step(
    inputs: LoopInputs, k: int, current: ComplexArray, command: ComplexArray, extra: ComplexArray
) -> tuple[ComplexArray, ComplexArray]:
    """Sample k with average PWM: ``i_ab`` at ``t_(k+1)`` and the mean dq voltage over the
    sample.

    ``command`` is ``exp(j (theta_k + eps)) u`` of the command applied now and ``extra``
    the stationary dead-time compensation computed with it, V.
    """
    mod, rotor = inputs.modulator, inputs.rotor[:, k]
    amplitude = mod.dead_time_amplitude
    signs = np.sign(to_phases(current)) if amplitude > 0.0 else np.zeros((current.shape[0], 3))
    steady, turning = (command + extra, None) if mod.stationary else (extra, command)
    assert not mod.carrier, "carrier PWM steps through _CarrierInverter"
    steady = steady + dead_time_voltage(signs, amplitude)
    mean = steady * np.conj(rotor) * inputs.turn
    if turning is not None:
        mean = mean + turning * np.conj(rotor)
    frames = inputs.frames
    if frames is not None:  # interior or saturating: the rotor frame (._salient, ._saturation)
        return frames.advance(current, steady, turning, rotor, inputs.rotor[:, k + 1]), mean
    after = inputs.decay * current + inputs.charge * steady + inputs.emf[:, k]
    if turning is not None:
        after = after + turning * inputs.gain
    return after, mean


def _measure(
    inputs: LoopInputs, k: int, current: ComplexArray
) -> tuple[ComplexArray, ComplexArray]:
    """The measured ``i_dq`` at sample k and the dead-time compensation it asks for, V."""
    mod, sensor = inputs.modulator, inputs.sensor
    compensate = mod.compensation and mod.dead_time_amplitude > 0.0
    measured, extra = current, np.zeros_like(current)
    if not sensor.exact:
        phases = sensor.phases(current, k)
        measured = from_phases(phases)
    elif compensate:
        phases = to_phases(current)
    if compensate:
        extra = -dead_time_voltage(np.sign(phases), mod.dead_time_amplitude)
    return measured * np.conj(inputs.rotor[:, k]), extra


class _Inverter:
    """The inverter, the motors and the sensor as the stepper's plant (a ``LoopPlant``)."""

    def __init__(self, inputs: LoopInputs, start: LoopState | None = None) -> None:
        count, plants = inputs.rho.shape[1], inputs.rotor.shape[0]
        self.inputs = inputs
        self.measured = np.empty((plants, count + 1), dtype=complex)
        self.currents = np.empty((plants, count + 1), dtype=complex)
        self.applied = np.empty((plants, count), dtype=complex)
        self.extras = np.zeros((plants, count + 1), dtype=complex)
        delay = inputs.modulator.delay
        self.current = np.zeros(plants, dtype=complex) if start is None else start.current
        self.earlier = np.zeros((plants, delay), dtype=complex) if start is None else start.extras

    def measure(self, k: int) -> Array:
        """The measured ``i_dq`` (P, 2) at sample k; keeps the compensation it asks for."""
        self.currents[:, k] = self.current
        self.measured[:, k], self.extras[:, k] = _measure(self.inputs, k, self.current)
        return np.stack([self.measured[:, k].real, self.measured[:, k].imag], axis=-1)

    def advance(self, k: int, applied: Array, computed_at: int) -> None:
        """Modulate the command computed at ``computed_at`` over sample k."""
        command = self.inputs.modulation[:, k] * (applied[:, 0] + 1j * applied[:, 1])
        extra = self.extras[:, computed_at] if computed_at >= 0 else self.earlier[:, computed_at]
        self.current, self.applied[:, k] = _step(self.inputs, k, self.current, command, extra)

    def results(self) -> _Results:
        """The measured ``i_dq`` and the true ``i_ab`` (P, N + 1), the mean dq voltages
        (P, N), the compensation computed at each sample with those before the run
        (P, d + N + 1), and the current after the last sample (P,)."""
        extras = np.concatenate([self.earlier, self.extras], axis=1)
        return self.measured, self.currents, self.applied, extras, self.current


def run_loop(inputs: LoopInputs, start: LoopState | None = None) -> LoopOutputs:
    """The time loop: measure, compute, limit, modulate, propagate, all motors at once
    (:func:`~selftune.sim._stepper.run_closed_loop` on the inverter).

    Parameters
    ----------
    inputs : LoopInputs
        The motors, the drive and the controllers (``rotor`` from the start's angle).
    start : LoopState, optional
        Where a previous run stopped (default: rest). A run continued from the state
        another stopped in gives, to the bit, the samples of one run over both.
    """
    plant = (_CarrierInverter if inputs.modulator.carrier else _Inverter)(inputs, start)
    limit, delay = inputs.modulator.limit, inputs.modulator.delay
    pad = max(inputs.feedback.history, delay)
    given = None
    if start is not None:
        memory = start.commands.shape[1]
        given = (start.commands[:, memory - pad :], start.integrator)
    loop = run_closed_loop(
        plant, inputs.feedback, inputs.w, inputs.rho, delay,
        limit=lambda u: limit_magnitude(u, limit), start=given,
        anti_windup=inputs.modulator.anti_windup,
    )  # fmt: skip
    measured, currents, applied, extras, current = plant.results()
    count = inputs.rho.shape[1]
    state = LoopState(
        current=current,
        commands=loop.commands,
        extras=extras[:, count : count + delay],
        integrator=loop.integrator,
    )
    return LoopOutputs(measured, currents, loop.commands, applied, loop.pad, state)


def _draws(
    exploration: Exploration | None, t: Array, seed: int, noise: float
) -> tuple[Array, Array | None]:
    """``rho`` (N, 2) then the phase noise (N + 1, 3) from one generator made from ``seed``."""
    if exploration is not None and not isinstance(exploration, Exploration):
        raise InputError(
            f"exploration: expected an Exploration (uniform, prbs, sum_of_sines) or None, "
            f"got {type(exploration).__name__}"
        )
    rng = as_generator(seed)
    count = t.shape[0] - 1
    rho = np.zeros((count, 2))
    if exploration is not None:
        rho = as_float_array(exploration.sample(t.copy(), 2, rng), "exploration.sample")
        if rho.shape != (count, 2):
            raise InputError(f"exploration.sample: expected shape {(count, 2)}, got {rho.shape}")
    drawn = rng.normal(0.0, noise, size=(count + 1, 3)) if noise > 0.0 else None
    return rho, drawn


def random_inputs(
    exploration: Exploration | None, t: Array, seed: int | Sequence[int], plants: int, noise: float
) -> tuple[Array, Array | None]:
    """``rho`` (P or 1, N, 2) and noise (P or 1, N + 1, 3): one seed shared, or one per motor."""
    if isinstance(seed, Sequence):
        if len(seed) != plants:
            raise InputError(
                f"seed: expected one integer or {plants} (one per motor), got {len(seed)}"
            )
        draws = [_draws(exploration, t, item, noise) for item in seed]
        rho = np.stack([item[0] for item in draws])
        noises = [item[1] for item in draws]
        return rho, None if noises[0] is None else np.stack(noises)  # type: ignore[arg-type]
    rho_one, noise_one = _draws(exploration, t, seed, noise)
    return rho_one[np.newaxis], None if noise_one is None else noise_one[np.newaxis]
