"""A realistic simulated drive: what a real digital current loop does to the data.

:class:`RealisticDrive` runs a PMSM (surface, :class:`~selftune.model.SPMSM`, or interior,
:class:`~selftune.model.IPMSM`) held at a speed by a load machine under a
:class:`~selftune.core.ControlLaw` and logs what a drive logs; the motor is propagated
exactly, a surface motor in the stationary frame (:mod:`._inverter`), an interior one in
the rotor frame (:mod:`._salient`); :func:`run_drive_batch` runs P motors in one time loop.
The formulas below are the surface motor's (``L_s``); an interior motor's effects are the
same in kind. The effects, and what each does to the ideal drive's sampled data
``x_(k+1) = Ad x_k + Bd u_k + Ed w_k`` (SI units; ``w_e = p speed``, rad/s; h, s):

- **Delay** d (``input_delay``): the command computed at ``t_k`` acts over
  ``[t_(k+d), t_(k+d+1))``; the controller's state is ``[x_k; u_(k-d); ...; u_(k-1)]``.
  Logged ``"applied"``, the equation keeps its form; ``"commanded"``, u is d rows early.
- **Stationary hold** (``voltage_hold``): the inverter holds ``exp(j (theta_k + eps)) u``
  in ``alpha-beta`` over a sample, so the dq voltage turns by ``-w_e h`` within it.
  Exactly ``Bd = (1 - a) / R_s Rot(eps - w_e h)``, ``a = exp(-R_s h / L_s)``, instead of
  the dq hold's ``(1 - exp(-(gamma + j w_e) h)) / (L_s (gamma + j w_e))``; Ad, Ed are
  unchanged. With ``angle_compensation`` (the command turned by ``w_e (d + 1/2) h``)
  ``eps = w_e h / 2`` and the two differ by ``(w_e h)^2 / 24 - j gamma w_e h^2 / 12``
  relative; without, ``eps = -d w_e h``: Bd is rotated by ``-(d + 1/2) w_e h``.
  ``"rotor"`` holds the dq vector (the ideal drive's and the paper's hold).
- **DC-bus limit**: ``|u| <= V_dc / sqrt(3)`` (linear space-vector range) by scaling the
  command, which is what is logged and fed back; with ``anti_windup`` the law's
  integrators hold while it acts (:mod:`selftune.core._voltage_limit`).
- **Dead time** ``t_d``: each phase voltage is off by ``-t_d f_sw V_dc sign(i_phase)`` V
  on average (``f_sw = 1/h``): in dq an unlogged input along ``-i``, of mean magnitude
  ``(4/pi) t_d f_sw V_dc`` for a held current vector, rippling at ``6 w_e``.
  Compensation adds the opposite with the sign of the measured current at the computation
  instant: it fails near zero current and for d samples after each sign change.
- **Carrier PWM**: sampled at the carrier peak, the current differs from the average
  model's by the ripple's curvature only: without dead time the pulses' volt-seconds and
  their first moment about the period's center are the average model's, so in open loop
  the difference stays below ``e^(gamma h) (2/3 + 1/sqrt(3)) gamma h^2 V_dc / (24 L_s)``.
- **Measurement**: phase noise and quantization enter ``x_k`` as the controller sees it
  and as logged (errors in variables); ``i_d`` and ``i_q`` get ``sqrt(2/3) current_noise``.
- **Temperature** dT: ``R_s (1 + 0.0039 dT)``, ``phi_pm (1 - 0.001 dT)``; the back-EMF is
  always the motor's own, whatever flux the controller's ``w`` assumes.
- **Torque**: ``1.5 p (phi_pm + (L_d - L_q) i_d) i_q`` with the true flux (the reluctance
  term is an interior motor's; a surface motor's is ``1.5 p phi_pm i_q``).
- **Saturation** (``saturation``, :mod:`._saturation`): current-dependent flux linkages,
  analytic or a flux-map table; the motor is then propagated in the rotor frame by RK4
  steps (not exactly: to 2e-7 of the current's scale, measured; carrier PWM segment by
  segment) and its torque is ``1.5 p (psi_d i_q - psi_q i_d)``. At the nameplate
  temperature only, not in a session.

The log holds the dq command, never the voltage the inverter made; :class:`DriveRecord`
adds what a real drive cannot log. Timings (``python tests/test_drive_session.py``: this
2-core machine, one BLAS thread, CPU time, best of two, the ranges over runs beside other
work; 20 motors x 20,000 samples at 10 kHz under a law with one past input and integral
action; one motor in brackets): average PWM 1.7-2.4 s (1.2-1.6 s); with dead time, noise
and a 12-bit ADC 1.8-2.6 s (1.5-1.6 s); carrier PWM, hardware_like, 8.5 s (0.6-0.8 s):
each motor's carrier period is stepped in Python floats (:mod:`._pwm`), so a batch costs
its motors' sum (with the period in numpy it was 8.2 s (7.1 s) beside the same work).
An interior motor (``L_q = 3 L_d``, the rotor-frame path; one run each beside other work):
average PWM 2.2 s (1.5 s), with dead time, noise and ADC 3.3 s (2.4 s), carrier PWM 14.8 s
(1.3 s): each carrier pulse takes two closed-form 2 x 2 exponentials.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Generic

import numpy as np
from numpy.typing import ArrayLike

from ..core import Array, ControlLaw, finite_float, positive_finite, positive_integer
from ..errors import InputError
from ..learn import LoggedInput, Trajectory
from ..loop import SampledLoop
from ..model import IPMSM, SPMSM, Motor
from ._checks import as_float_array
from ._drive_settings import DriveSettings
from ._exploration import Exploration
from ._inverter import (
    ComplexArray,
    CurrentSensor,
    LoopInputs,
    LoopOutputs,
    Modulator,
    MotorBatch,
    MotorT,
    heated_motor,
    random_inputs,
    run_loop,
)
from ._profile import ParameterProfile
from ._saturation import FluxMap, Saturation, SaturationModel
from ._signals import ExogenousSignal, check_signal_values, constant
from ._stepper import Feedback, feedback_of

if TYPE_CHECKING:
    from ._session import DriveSession

__all__ = ["DriveRecord", "DriveSettings", "RealisticDrive", "run_drive_batch"]


def _read_only(array: Array) -> Array:
    array.setflags(write=False)
    return array


@dataclass(frozen=True, eq=False)
class DriveRecord:
    """One run: what the drive logs, and the truth a real drive cannot log (SI units).

    Attributes
    ----------
    trajectory : Trajectory
        What the drive logs (what :meth:`RealisticDrive.run` returns).
    true_currents : ndarray, shape (N + 1, 2)
        Noise-free ``[i_d, i_q]`` at the sample instants, A.
    applied_voltages : ndarray, shape (N, 2)
        The true mean dq voltage over each sample (PWM and dead time included), V (the
        mean, not the ``exp(A (h - s))``-weighted input of the exact discrete model).
    commanded_voltages : ndarray, shape (N, 2)
        The command computed at each sample (exploration included, limited), V.
    torque : ndarray, shape (N + 1,)
        True electromagnetic torque ``1.5 p (phi_pm + (L_d - L_q) i_d) i_q`` (true flux;
        saturating, ``1.5 p (psi_d i_q - psi_q i_d)``), N m.
    """

    trajectory: Trajectory
    true_currents: Array
    applied_voltages: Array
    commanded_voltages: Array
    torque: Array

    def steady_torque(self) -> float:
        """The mean true torque over the record's second half, N m, taken over the whole
        electrical turns it holds (ending at the last sample) where the rotor turns at
        least once in it: the dead time's six-step ripple and every other harmonic of the
        speed then average out, which over a part of a turn they do not."""
        half = self.torque[self.torque.shape[0] // 2 :]
        if self.trajectory.angle is None:
            return float(np.mean(half))
        angle = np.unwrap(self.trajectory.angle[self.torque.shape[0] - half.shape[0] :])
        turned = np.abs(angle[-1] - angle)
        turns = np.floor(turned[0] / (2.0 * np.pi))
        if turns < 1.0:
            return float(np.mean(half))
        start = int(np.flatnonzero(turned <= turns * 2.0 * np.pi)[0])
        return float(np.mean(half[start:-1]))


@dataclass(frozen=True)
class RealisticDrive(Generic[MotorT]):
    """A realistic simulated drive (see the module docstring); implements the Drive protocol.

    Episodes (:meth:`record`, :meth:`run`) start from rest (currents, past commands and
    integrators zero, ``theta = 0``); :meth:`start` keeps one running, chunk by chunk, its
    motor heating or failing along a profile (:class:`~selftune.sim.DriveSession`).

    Attributes
    ----------
    motor : SPMSM or IPMSM
        The true motor (nameplate values; ``settings.temperature_rise`` heats it).
    speed : float
        Held mechanical speed, rad/s.
    h : float
        Sampling period, s (also the PWM period).
    settings : DriveSettings
        The drive's effects (default: one-sample delay, average PWM, nothing else).
    saturation : SaturationModel or FluxMap or None
        The motor's current-dependent flux linkages (:mod:`._saturation`; the motor then
        gives R_s and p, its inductances and flux only through ``saturation``); None: the
        motor's constant inductances (exact propagation).
    """

    motor: MotorT
    speed: float
    h: float
    settings: DriveSettings = field(default_factory=DriveSettings)
    saturation: Saturation | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.motor, SPMSM | IPMSM):
            raise InputError(
                f"motor: expected an SPMSM or an IPMSM, got {type(self.motor).__name__}"
            )
        object.__setattr__(self, "speed", finite_float(self.speed, "speed"))
        object.__setattr__(self, "h", positive_finite(self.h, "h"))
        _check_settings(self.settings, self.h)
        _check_saturation(self.saturation, self.settings)

    @property
    def pole_pairs(self) -> int:
        """Number of pole pairs (nameplate)."""
        return self.motor.p

    @property
    def true_motor(self) -> MotorT:
        """The motor at its operating temperature (R_s and phi_pm corrected; of the
        motor's own type)."""
        return heated_motor(self.motor, self.settings.temperature_rise)

    @property
    def loop(self) -> SampledLoop:
        """The drive's loop: sampled at h, the settings' computation delay and hold."""
        return SampledLoop(self.h, self.settings.input_delay, self.settings.voltage_hold)

    @property
    def logged_input(self) -> LoggedInput:
        """What row k of the log's voltages holds (from the settings)."""
        return self.settings.logged_input

    def record(
        self,
        law: ControlLaw,
        reference: ExogenousSignal,
        *,
        num_samples: int,
        exploration: Exploration | None,
        seed: int,
    ) -> DriveRecord:
        """One episode from rest, with what a real drive cannot log.

        Parameters
        ----------
        law : ControlLaw
            The controller (n = m = 2; q of the reference).
        reference : ExogenousSignal
            The controller's ``w`` at the sample instants (held).
        num_samples : int
            N, samples.
        exploration : Exploration or None
            ``rho``, V, added to each command; None for none.
        seed : int
            Seed of the one generator of the exploration and the noise.
        """
        return run_drive_batch(
            [self.motor], self.speed, self.h, self.settings, law, reference,
            num_samples=num_samples, exploration=exploration, seed=seed,
            saturation=self.saturation,
        )[0]  # fmt: skip

    def run(
        self,
        law: ControlLaw,
        reference: ExogenousSignal,
        *,
        num_samples: int,
        exploration: Exploration | None,
        seed: int,
        assumed_flux: float | None = None,
    ) -> Trajectory:
        """One known-flux episode from rest: what the drive logs.

        Parameters
        ----------
        law : ControlLaw
            The controller (n = m = 2; q = 2 for a surface motor, 3 for an interior one).
        reference : ExogenousSignal
            ``w`` as the controller sees it (held): the motor's
            :meth:`~selftune.model.SPMSM.exogenous` form, ``[p speed phi, T*]`` (surface)
            or ``[p speed phi, i_d*, i_q*]`` (interior).
        num_samples : int
            N, samples.
        exploration : Exploration or None
            ``rho``, V, added to each command; None for none.
        seed : int
            Seed of the one generator of the exploration and the noise.
        assumed_flux : float, optional
            Accepted and ignored: the motor's back-EMF is always its own (true, heated)
            flux; the controller's assumption is already in ``reference``.
        """
        return self.record(
            law, reference, num_samples=num_samples, exploration=exploration, seed=seed
        ).trajectory

    def start(
        self,
        law: ControlLaw,
        *,
        seed: int,
        profile: ParameterProfile | None = None,
        max_hold: float = 1e-2,
        integrator: ArrayLike | None = None,
    ) -> DriveSession:
        """Start the drive at rest under ``law``, to run chunk by chunk
        (:class:`~selftune.sim._session.DriveSession`).

        Parameters
        ----------
        law : ControlLaw
            The law at the start (n = m = 2, q of the references to come).
        seed : int
            Seed of the generator of the measurement noise.
        profile : ParameterProfile, optional
            Factors on :attr:`true_motor`'s R_s, L_s, phi_pm over time (default: none; an
            interior motor's L_d and L_q both take the L_s factor).
        max_hold : float
            The longest interval the parameters are held constant over, s.
        integrator : array_like, shape (r,), optional
            The law's integrators at the start (default zeros).
        """
        from ._session import DriveSession  # the session builds on this module

        if self.saturation is not None:
            raise InputError("saturation: a drive session does not model saturation yet")
        return DriveSession(
            self, law, seed=seed, profile=profile, max_hold=max_hold, integrator=integrator
        )

    def run_no_load(
        self, law: ControlLaw, *, num_samples: int, exploration: Exploration | None, seed: int
    ) -> Trajectory:
        """One no-load episode (PAPER_NOTES eq. 15): ``T* = 0``, ``w = [p speed]``, q = 1.

        Parameters
        ----------
        law : ControlLaw
            The controller, with q = 1.
        num_samples : int
            N, samples.
        exploration : Exploration or None
            ``rho``, V, added to each command; None for none.
        seed : int
            Seed of the one generator of the exploration and the noise.
        """
        reference = constant(self.motor.no_load_exogenous(self.speed))
        return self.run(law, reference, num_samples=num_samples, exploration=exploration, seed=seed)


def _check_settings(settings: object, h: float) -> DriveSettings:
    if not isinstance(settings, DriveSettings):
        raise InputError(f"settings: expected DriveSettings, got {type(settings).__name__}")
    if settings.dead_time >= 0.5 * h:
        raise InputError(f"dead_time: {settings.dead_time!r} s is not under half of h = {h!r} s")
    return settings


def _check_saturation(saturation: object, settings: DriveSettings) -> Saturation | None:
    if saturation is None:
        return None
    if not isinstance(saturation, SaturationModel | FluxMap):
        raise InputError(
            f"saturation: expected a SaturationModel, a FluxMap or None, got "
            f"{type(saturation).__name__}"
        )
    if settings.temperature_rise != 0.0:
        raise InputError(
            "saturation: its flux linkages hold at one temperature; give them at the "
            "operating one and temperature_rise = 0"
        )
    return saturation


def _motors(motors: Sequence[Motor], speed: ArrayLike) -> tuple[list[Motor], Array]:
    given = list(motors) if isinstance(motors, Sequence) else [motors]
    if not given:
        raise InputError("motors: no motor given")
    for index, motor in enumerate(given):
        if not isinstance(motor, SPMSM | IPMSM):
            raise InputError(
                f"motors: item {index} is a {type(motor).__name__}, not an SPMSM or an IPMSM"
            )
    speeds = as_float_array(speed, "speed")
    if speeds.ndim > 1 or (speeds.ndim == 1 and speeds.shape[0] not in (1, len(given))):
        raise InputError(
            f"speed: expected a number or one per motor ({len(given)},), got shape {speeds.shape}"
        )
    return given, np.broadcast_to(speeds, (len(given),)).astype(float)


def _laws(laws: ControlLaw | Sequence[ControlLaw], plants: int, q: int) -> list[ControlLaw]:
    given = [laws] * plants if isinstance(laws, ControlLaw) else list(laws)
    if len(given) != plants:
        raise InputError(
            f"laws: expected one ControlLaw or {plants} (one per motor), got {len(given)}"
        )
    for index, law in enumerate(given):
        if not isinstance(law, ControlLaw):
            raise InputError(f"laws: item {index} is a {type(law).__name__}, not a ControlLaw")
        if (law.n, law.m, law.q) != (2, 2, q):
            raise InputError(
                f"laws: item {index} has (n, m, q) = {(law.n, law.m, law.q)}; the drive "
                f"needs (2, 2, {q}) (currents, voltages, the reference's channels)"
            )
    return given


def _reference(reference: ExogenousSignal, t: Array, plants: int) -> Array:
    if not isinstance(reference, ExogenousSignal):
        raise InputError(f"reference: expected an exogenous signal, got {type(reference).__name__}")
    values = check_signal_values(reference.values(t), t.shape[0], "reference")
    if values.ndim == 3 and values.shape[0] not in (1, plants):
        raise InputError(f"reference: a batch of {values.shape[0]} signals for {plants} motors")
    return values.reshape(-1, *values.shape[-2:])


def _modulation_offset(settings: DriveSettings, w_e: Array, h: float) -> Array:
    """``eps`` (rad): the modulator's angle over sample k is ``theta_k + eps``."""
    if not settings.angle_compensation:
        return -settings.input_delay * w_e * h
    return 0.5 * w_e * h if settings.voltage_hold == "stationary" else np.zeros_like(w_e)


def _sensor(settings: DriveSettings, noise: Array | None) -> CurrentSensor:
    if settings.adc_bits is None or settings.adc_step is None:
        return CurrentSensor(noise=noise, lsb=None, codes=0)
    return CurrentSensor(noise=noise, lsb=settings.adc_step, codes=2 ** (settings.adc_bits - 1))


def _loop_inputs(
    motor: MotorBatch,
    settings: DriveSettings,
    feedback: Feedback,
    t: Array,
    h: float,
    w: Array,
    rho: Array,
    noise: Array | None,
    angle: Array | None = None,
) -> LoopInputs:
    """The loop's inputs over the samples ``t`` (s); ``angle`` (P,): the rotor's angle at
    ``t[0]``, rad, from which it turns at the held speed (None: ``theta = w_e t``, the
    angle of a speed held since ``t = 0``)."""
    w_e = motor.electrical_speed[:, np.newaxis]
    if angle is None:
        rotor = np.exp(1j * w_e * t)
    else:
        rotor = np.exp(1j * (angle[:, np.newaxis] + w_e * (t - t[0])))
    offset = _modulation_offset(settings, motor.electrical_speed, h)[:, np.newaxis]
    modulator = Modulator(
        period=h,
        delay=settings.input_delay,
        carrier=settings.pwm == "carrier",
        stationary=settings.voltage_hold == "stationary",
        dc_voltage=settings.dc_voltage,
        dead_time=settings.dead_time,
        compensation=settings.dead_time_compensation,
        anti_windup=settings.anti_windup,
    )
    return LoopInputs(
        motor=motor,
        modulator=modulator,
        feedback=feedback,
        sensor=_sensor(settings, noise),
        rotor=rotor,
        modulation=rotor[:, :-1] * np.exp(1j * offset),
        w=w,
        rho=rho,
    )


def _as_pairs(values: ComplexArray) -> Array:
    return np.stack([values.real, values.imag], axis=-1)


def encoder_angle(turned: Array, pole_pairs: ArrayLike, counts: int) -> Array:
    """The electrical angle as an encoder of ``counts`` counts a mechanical turn logs it.

    Parameters
    ----------
    turned : ndarray, shape (P, N)
        Each rotor's electrical angle at each sample, rad, unwrapped (continuous over
        the turns: the count grid turns ``p`` times a mechanical turn, and where ``p``
        does not divide ``counts`` an electrical turn is not a whole number of counts).
    pole_pairs : array_like, shape (P,)
        Each rotor's pole pairs.
    counts : int
        Counts a mechanical turn.

    Returns
    -------
    ndarray, shape (P, N)
        ``p`` times the mechanical angle in whole counts of ``2 pi / counts``, wrapped
        to ``(-pi, pi]``, rad.
    """
    count = 2.0 * np.pi * np.asarray(pole_pairs, dtype=float)[:, np.newaxis] / counts
    return np.angle(np.exp(1j * np.round(turned / count) * count))


def _records(
    inputs: LoopInputs, outputs: LoopOutputs, settings: DriveSettings, t: Array
) -> list[DriveRecord]:
    count, pad = inputs.rho.shape[1], outputs.pad
    true_dq = outputs.current * np.conj(inputs.rotor)
    _check_finite(true_dq, t)
    computed = outputs.commands[:, pad : pad + count]
    logged = computed
    if settings.logged_input == "applied":
        start = pad - settings.input_delay
        logged = outputs.commands[:, start : start + count]
    measured, true_pairs = _as_pairs(outputs.measured), _as_pairs(true_dq)
    applied, torque = _as_pairs(outputs.applied), inputs.motor.torque(true_dq.imag, true_dq.real)
    w = np.broadcast_to(inputs.w, (true_dq.shape[0], *inputs.w.shape[1:]))
    angles = np.angle(inputs.rotor)  # the rotor angle at each sample, in (-pi, pi]
    if settings.encoder_counts is not None:  # the log's angle in whole counts of the turn
        angles = encoder_angle(
            np.unwrap(angles, axis=-1), np.asarray(inputs.motor.p), settings.encoder_counts
        )
    records = []
    for index in range(true_dq.shape[0]):
        trajectory = Trajectory(
            t=t, x=measured[index], u=logged[index], w=w[index], angle=angles[index]
        )
        records.append(
            DriveRecord(
                trajectory=trajectory,
                true_currents=_read_only(true_pairs[index].copy()),
                applied_voltages=_read_only(applied[index].copy()),
                commanded_voltages=_read_only(computed[index].copy()),
                torque=_read_only(torque[index].copy()),
            )
        )
    return records


def _check_finite(values: ComplexArray, t: Array) -> None:
    bad = ~np.isfinite(values)
    if np.any(bad):
        motor, k = (int(i) for i in np.argwhere(bad)[0])
        raise InputError(
            f"the currents of motor {motor} overflow at sample {k} (t = {t[k]:.6g} s): the "
            "closed loop is unstable over this horizon; stabilize it, limit the voltage "
            "(dc_voltage) or shorten the run"
        )


def run_drive_batch(
    motors: Sequence[Motor],
    speed: ArrayLike,
    h: float,
    settings: DriveSettings,
    laws: ControlLaw | Sequence[ControlLaw],
    reference: ExogenousSignal,
    *,
    num_samples: int,
    exploration: Exploration | None,
    seed: int | Sequence[int],
    saturation: Saturation | None = None,
) -> list[DriveRecord]:
    """Run P motors on realistic drives in one vectorized time loop.

    Motor i's record equals :meth:`RealisticDrive.record` of that motor with seed
    ``seed`` (an integer: every motor sees the same exploration and noise, common random
    numbers) or ``seed[i]`` (a sequence: independent draws).

    Parameters
    ----------
    motors : sequence of SPMSM or IPMSM
        The P motors (nameplate values; a batch with an interior motor propagates all in
        the rotor frame, :mod:`._salient`).
    speed : float or array_like, shape (P,)
        Held mechanical speed, rad/s (common or one per motor).
    h : float
        Sampling (and PWM) period h, s.
    settings : DriveSettings
        The drives' effects (common).
    laws : ControlLaw or sequence of ControlLaw
        One law for all, or one per motor (n = m = 2, q of the reference; histories and
        integrators may differ).
    reference : ExogenousSignal
        The controllers' ``w`` at the sample instants, (N + 1, q) or a batch (P, N + 1, q).
    num_samples : int
        N, samples.
    exploration : Exploration or None
        ``rho``, V, added to each command; None for none.
    seed : int or sequence of int
        The seed of the one generator that draws the exploration, then the noise.
    saturation : SaturationModel or FluxMap or None
        The motors' flux linkages (common; :mod:`._saturation`); None: constant
        inductances.

    Returns
    -------
    list of DriveRecord
        One per motor.

    Raises
    ------
    InputError
        Naming the argument, if a value is invalid or the currents overflow.
    """
    h = positive_finite(h, "h")
    checked = _check_settings(settings, h)
    count = positive_integer(num_samples, "num_samples")
    given, speeds = _motors(motors, speed)
    saturating = _check_saturation(saturation, checked)
    t = h * np.arange(count + 1, dtype=float)
    w = _reference(reference, t, len(given))
    checked_laws = _laws(laws, len(given), w.shape[-1])
    motor = replace(
        MotorBatch.build(given, speeds, checked.temperature_rise), saturation=saturating
    )
    rho, noise = random_inputs(exploration, t, seed, len(given), checked.current_noise)
    inputs = _loop_inputs(motor, checked, feedback_of(checked_laws), t, h, w, rho, noise)
    with np.errstate(over="ignore", invalid="ignore"):
        outputs = run_loop(inputs)
    return _records(inputs, outputs, checked, t)
