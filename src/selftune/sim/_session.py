"""A realistic drive that keeps running: :class:`DriveSession`, advanced chunk by chunk.

:meth:`RealisticDrive.start <selftune.sim.RealisticDrive.start>` starts the drive at rest
(currents, past commands and integrators zero, ``theta = 0``) under a law; each
:meth:`DriveSession.advance` runs N more samples with a held reference, an optional
probing signal and optionally a new law switched in at the chunk's first computed
command, and returns the chunk (:class:`DriveChunk`: the log and the truth). Everything
carries over from one chunk to the next: the true currents, the rotor angle, the commands
in the delay line and the dead-time compensation computed with them, the law's
integrators and past inputs, and the random generator (the measurement noise continues).
Run in chunks of any sizes with one law, the session gives the samples of one run over
all of them (the same seed), to rounding.

**Heating and faults** (:class:`~selftune.sim._profile.ParameterProfile`): the motor's
R_s, L_s and phi_pm are the drive's true motor's (:attr:`RealisticDrive.true_motor`)
times the profile's factors (an interior motor's L_d and L_q both take the L_s factor).
The drive holds them constant over intervals of at most ``max_hold`` on a grid fixed in
time (sample ``j M``, ``M = round(max_hold / h)``), cut at the profile's times moved to
the nearest sample instant (a step acts from the sample nearest its time: the current at
that sample is the old motor's, the next the new one's); over each interval the values
are the profile's at its midpoint, so a linear ramp's error is at most half its change
over ``max_hold`` (+40% over 120 s held 10 ms, the default: 1.7e-5 of R_s).
The motor is re-discretized only where the values change. The approximation: within a
sample the parameters never move (they move between samples only).

**Speed**: where the loop is linear (average PWM, no dead time, no ADC; noise allowed; the
voltage limit not reached) a chunk runs as matrices read off one step of the inverter
and of the stepper, propagated all at once (:class:`~selftune.sim._linear.LinearLoop`);
otherwise (or where a command reaches the limit) sample by sample through the stepper.
At 10 kHz on this 2-core machine (one BLAS thread, CPU time, the servo law of the tests;
``python tests/test_drive_session.py``, best of two, the ranges over runs beside other
work): as matrices 14-28x real time in chunks of 100 samples, 80-125x in chunks of
1,000; a motor warming along a ramp, held 10 ms: 5-7x and 13-22x (held 0.1 s: 11x and
47x; 1 ms: 1x and 2x, each interval a new discretization); through the stepper
(``hardware_like``: carrier PWM, dead time, ADC; each carrier period in Python floats,
:mod:`._pwm`) 2-3.5x in chunks of 100 and 2-4x in chunks of 1,000, warming or not (it
was 0.2-0.3x with the period in numpy).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core import Array, ControlLaw, positive_finite, positive_integer
from ..errors import InputError
from ..learn import Trajectory
from ._checks import as_float_array, as_generator
from ._inverter import (
    ComplexArray,
    LoopInputs,
    LoopOutputs,
    LoopState,
    MotorBatch,
    run_loop,
    scaled_motor,
)
from ._linear import LinearLoop
from ._profile import ParameterFactors, ParameterProfile, interpolate
from ._realistic import (
    RealisticDrive,
    _as_pairs,
    _check_finite,
    _laws,
    _loop_inputs,
    _read_only,
    encoder_angle,
)
from ._stepper import Feedback, feedback_of

__all__ = ["MEMORY", "DriveChunk", "DriveSession"]

#: Commands a session remembers (the most past inputs a law switched in may feed back).
MEMORY = 16


@dataclass(frozen=True, eq=False)
class DriveChunk:
    """One chunk of a running drive: what it logs, the truth, the motor in effect (SI).

    Samples ``first_sample .. first_sample + N``: the last is the next chunk's first (the
    same measurement). Arrays are read-only.

    Attributes
    ----------
    first_sample : int
        The index of the chunk's first sample since the start.
    h : float
        Sampling period, s.
    measured : ndarray, shape (N + 1, 2)
        The measured ``[i_d, i_q]`` (noise, ADC), A: the log's x.
    logged_input : ndarray, shape (N, 2)
        The dq command as the settings log it (``"applied"``: the one applied over each
        sample, from the delay line at first; ``"commanded"``: the one computed), V.
    reference : ndarray, shape (q,)
        The law's ``w``, held over the chunk.
    angle : ndarray, shape (N + 1,)
        Electrical rotor angle at each sample as the drive logs it, rad, in ``(-pi,
        pi]``: an encoder's counts with :attr:`DriveSettings.encoder_counts`, on the
        grid of the turns since the start (the run's own, chunk after chunk).
    true_currents : ndarray, shape (N + 1, 2)
        Noise-free ``[i_d, i_q]``, A.
    applied_voltages : ndarray, shape (N, 2)
        The true mean dq voltage over each sample (PWM and dead time included), V.
    commanded_voltages : ndarray, shape (N, 2)
        The command computed at each sample (probing included, limited), V.
    torque : ndarray, shape (N + 1,)
        True torque ``1.5 p (phi_pm + (L_d - L_q) i_d) i_q`` with the values in effect, N m.
    R_s, L_s, phi_pm : ndarray, shape (N + 1,)
        The true motor's values over ``[t_k, t_(k+1))``, ohm, H, Wb (``L_s``: the
        nameplate's ``L_d`` times the inductance factor, a surface motor's L_s).
    L_d, L_q : ndarray, shape (N + 1,)
        The d- and q-axis inductances over the same intervals, H (equal for a surface
        motor).
    """

    first_sample: int
    h: float
    measured: Array
    logged_input: Array
    reference: Array
    angle: Array
    true_currents: Array
    applied_voltages: Array
    commanded_voltages: Array
    torque: Array
    R_s: Array
    L_s: Array
    phi_pm: Array
    L_d: Array
    L_q: Array

    @property
    def num_samples(self) -> int:
        """N, samples in the chunk."""
        return int(self.logged_input.shape[0])

    @property
    def start_time(self) -> float:
        """The time of the chunk's first sample since the start, s."""
        return self.first_sample * self.h

    @property
    def time(self) -> Array:
        """The sample times since the start, shape (N + 1,), s."""
        stop = self.first_sample + self.num_samples + 1
        return self.h * np.arange(self.first_sample, stop, dtype=float)

    @cached_property
    def trajectory(self) -> Trajectory:
        """What the drive logs as a :class:`~selftune.learn.Trajectory` (times from 0:
        add :attr:`start_time`; ``w`` the reference at every sample)."""
        count = self.num_samples
        w = np.broadcast_to(self.reference, (count + 1, self.reference.shape[0]))
        t = self.h * np.arange(count + 1, dtype=float)
        return Trajectory(t=t, x=self.measured, u=self.logged_input, w=w, angle=self.angle)


@dataclass(frozen=True, eq=False)
class _Piece:
    """One interval of constant motor parameters within a chunk: samples ``[a, b)``."""

    a: int
    b: int
    factors: ParameterFactors


class DriveSession:
    """A :class:`RealisticDrive` running under a law, advanced chunk by chunk (see the
    module docstring); made by :meth:`RealisticDrive.start`.

    Parameters
    ----------
    drive : RealisticDrive
        The drive (motor, speed, h, settings).
    law : ControlLaw
        The law at the start (n = m = 2; q is the reference's).
    seed : int
        Seed of the generator of the measurement noise (drawn sample by sample as the
        session runs).
    profile : ParameterProfile, optional
        Factors on the true motor's R_s, L_s, phi_pm over time (default: constant).
    max_hold : float
        The longest interval the parameters are held constant over, s (default 10 ms;
        at least one sample).
    integrator : array_like, shape (r,), optional
        The law's integrators at the start (default zeros).

    Raises
    ------
    InputError
        Naming the argument, if a value is invalid.
    """

    def __init__(
        self,
        drive: RealisticDrive[Any],
        law: ControlLaw,
        *,
        seed: int,
        profile: ParameterProfile | None = None,
        max_hold: float = 1e-2,
        integrator: ArrayLike | None = None,
    ) -> None:
        if not isinstance(drive, RealisticDrive):
            raise InputError(f"drive: expected a RealisticDrive, got {type(drive).__name__}")
        profile = ParameterProfile.constant() if profile is None else profile
        if not isinstance(profile, ParameterProfile):
            raise InputError(f"profile: expected a ParameterProfile, got {type(profile).__name__}")
        self.drive = drive
        self.profile = profile
        h = drive.h
        self.hold = max(1, round(positive_finite(max_hold, "max_hold") / h))
        # the profile on the sample grid: its times moved to the nearest sample instant
        self._break_samples = np.round(profile.time / h).astype(np.int64)
        columns = (profile.R_s, profile.L_s, profile.phi_pm)
        self._points = ParameterFactors(*columns)
        same = all(np.all(column == column[0]) for column in columns)
        self._constant = ParameterFactors(*(float(c[0]) for c in columns)) if same else None
        self._true = drive.true_motor
        self._speed = np.array([drive.speed])
        self._nameplate = MotorBatch.build([self._true], self._speed, 0.0)
        self._rng = as_generator(seed)
        self._sample = 0
        self._noise_row = self._draw_noise(1)
        self._law, self._feedback = self._checked_law(law)
        delay = drive.settings.input_delay
        self._state = LoopState.rest(1, MEMORY, delay, law.r)
        self._state = self._with_integrator(self._state, law, integrator)
        self._motors: dict[tuple[float, float, float], MotorBatch] = {}
        linear = LinearLoop.applies(drive.settings)
        self._loop = LinearLoop(self._feedback, delay) if linear else None

    # -- what the caller sees between chunks ---------------------------------------------

    @property
    def sample(self) -> int:
        """The index of the next chunk's first sample (samples run so far)."""
        return self._sample

    @property
    def time(self) -> float:
        """The drive time of the next chunk's first sample, s."""
        return self._sample * self.drive.h

    @property
    def law(self) -> ControlLaw:
        """The law in effect."""
        return self._law

    @property
    def integrator(self) -> Array:
        """The law's integrators at the next sample, shape (r,)."""
        return _read_only(self._state.integrator[0, : self._law.r].copy())

    @property
    def past_commands(self) -> Array:
        """The last :data:`MEMORY` commands computed (limited, probing included), oldest
        first, shape (MEMORY, 2), V (zeros before the start): the law's past inputs and
        the delay line."""
        return _read_only(self._state.commands[0].copy())

    def factors(self, sample: int) -> ParameterFactors:
        """The profile's factors the drive holds over one sample: the profile at the
        midpoint of the hold interval holding it.

        Parameters
        ----------
        sample : int
            The sample's index since the start.
        """
        index = positive_integer(sample, "sample", minimum=0)
        values = self._held(np.array([index]))
        return ParameterFactors(*(float(np.asarray(value)[0]) for value in values))

    def _held(self, samples: Array) -> ParameterFactors:
        """:meth:`factors` of each of ``samples`` (integers, >= 0), arrays."""
        breaks, h = self._break_samples, self.drive.h
        grid = samples - samples % self.hold
        index = np.searchsorted(breaks, samples, side="right")  # breaks[: index] <= sample
        below = breaks[np.maximum(index - 1, 0)]
        above = np.append(breaks, np.iinfo(np.int64).max)[index]
        start = np.maximum(grid, below)
        stop = np.minimum(grid + self.hold, above)
        return interpolate(breaks * h, self._points, 0.5 * (start + stop) * h)

    # -- running --------------------------------------------------------------------------

    def advance(
        self,
        num_samples: int,
        reference: ArrayLike,
        *,
        probing: ArrayLike | None = None,
        law: ControlLaw | None = None,
        integrator: ArrayLike | None = None,
    ) -> DriveChunk:
        """Run N more samples and return them.

        Parameters
        ----------
        num_samples : int
            N, samples.
        reference : array_like, shape (q,)
            The law's ``w``, held over the chunk (e.g. ``[p speed phi, T*]``).
        probing : array_like, shape (N, 2), optional
            Added to each computed command before the voltage limit, V (default none).
        law : ControlLaw, optional
            A law to switch to: it computes the chunk's first command (from the
            measurement at :attr:`sample`, the past commands and ``integrator``).
        integrator : array_like, shape (r,), optional
            The new law's integrators at the switch (with ``law``; default: the current
            ones if the new law has as many, else required), e.g. chosen so the first
            command equals the old law's (a bumpless switch).

        Returns
        -------
        DriveChunk

        Raises
        ------
        InputError
            Naming the argument, if a value is invalid or the currents overflow.
        """
        count = positive_integer(num_samples, "num_samples")
        switch = None
        if law is not None:
            new_law, feedback = self._checked_law(law)
            switch = (new_law, feedback, self._with_integrator(self._state, new_law, integrator))
        elif integrator is not None:
            raise InputError("integrator: given without a law to switch to")
        w = self._reference(reference, count)
        rho = self._probing(probing, count)
        if switch is not None:  # every argument checked: the switch happens
            self._law, self._feedback, self._state = switch
            if self._loop is not None:
                self._loop = LinearLoop(self._feedback, self.drive.settings.input_delay)
        noise = None
        if self._noise_row is not None:
            noise = np.concatenate([self._noise_row, self._draw_noise(count)])[np.newaxis]
            self._noise_row = noise[0, -1:]
        before, first = self._state, self._sample
        pieces, following = self._pieces(first, count)
        with np.errstate(over="ignore", invalid="ignore"):
            run = self._run_linear(pieces, w, rho, noise) if self._loop is not None else None
            if run is None:
                runs = [self._run_piece(piece, w, rho, noise) for piece in pieces]
                rotor = np.concatenate([r[0][0, :-1] for r in runs] + [runs[-1][0][0, -1:]])
                outputs = [r[1] for r in runs]
            else:
                rotor, outputs = run[0][0], [run[1]]
        self._sample = first + count
        return self._chunk(first, count, before, pieces, rotor, outputs, w, following)

    # -- inside ---------------------------------------------------------------------------

    def _draw_noise(self, rows: int) -> Array | None:
        noise = self.drive.settings.current_noise
        return self._rng.normal(0.0, noise, size=(rows, 3)) if noise > 0.0 else None

    def _checked_law(self, law: ControlLaw) -> tuple[ControlLaw, Feedback]:
        if not isinstance(law, ControlLaw):
            raise InputError(f"law: expected a ControlLaw, got {type(law).__name__}")
        if hasattr(self, "_law") and law.q != self._law.q:
            raise InputError(
                f"law: has q = {law.q}; the session's reference has {self._law.q} channels"
            )
        checked = _laws(law, 1, law.q)[0]
        if max(checked.history, self.drive.settings.input_delay) > MEMORY:
            raise InputError(
                f"law: feeds back {checked.history} past inputs; a session keeps {MEMORY}"
            )
        return checked, feedback_of([checked])

    def _with_integrator(
        self, state: LoopState, law: ControlLaw, integrator: ArrayLike | None
    ) -> LoopState:
        current = state.integrator
        if integrator is None:
            if current.shape[1] != law.r:
                raise InputError(
                    f"integrator: the law has {law.r} integrator(s), the law in effect "
                    f"{current.shape[1]}: give the new law's (shape ({law.r},))"
                )
            values = current
        else:
            values = as_float_array(integrator, "integrator").reshape(1, -1)
            if values.shape != (1, law.r) or not np.all(np.isfinite(values)):
                raise InputError(
                    f"integrator: expected {law.r} finite value(s) (the law's r), got "
                    f"{np.shape(integrator)}"
                )
        return LoopState(state.current, state.commands, state.extras, values.copy())

    def _reference(self, reference: ArrayLike, count: int) -> Array:
        w = as_float_array(reference, "reference")
        if w.shape != (self._law.q,) or not np.all(np.isfinite(w)):
            raise InputError(
                f"reference: expected {self._law.q} finite value(s) (the law's q), got "
                f"shape {w.shape}"
            )
        return np.broadcast_to(w, (1, count + 1, w.shape[0]))

    def _probing(self, probing: ArrayLike | None, count: int) -> Array:
        if probing is None:
            return np.zeros((1, count, 2))
        rho = as_float_array(probing, "probing")
        if rho.shape != (count, 2) or not np.all(np.isfinite(rho)):
            raise InputError(
                f"probing: expected {(count, 2)} finite values (V, one row per sample), got "
                f"shape {rho.shape}"
            )
        return rho[np.newaxis]

    def _pieces(self, first: int, count: int) -> tuple[list[_Piece], ParameterFactors]:
        """The chunk cut where the held parameters change (values merged where equal), and
        the values held over the sample after it."""
        stop = first + count
        if self._constant is not None:
            return [_Piece(0, count, self._constant)], self._constant
        grid = np.arange(first - first % self.hold + self.hold, stop, self.hold)
        steps = self._break_samples[(self._break_samples > first) & (self._break_samples < stop)]
        cuts = np.unique(np.concatenate([[first, stop], grid, steps]))
        values = np.stack(self._held(cuts), axis=-1)
        changes = (np.flatnonzero(np.any(values[1:-1] != values[:-2], axis=-1)) + 1).tolist()
        starts, ends = [0, *changes], [*changes, len(cuts) - 1]
        pieces = [
            _Piece(
                int(cuts[i]) - first, int(cuts[j]) - first,
                ParameterFactors(*(float(value) for value in values[i])),
            )
            for i, j in zip(starts, ends, strict=True)
        ]  # fmt: skip
        return pieces, ParameterFactors(*(float(value) for value in values[-1]))

    def _motor(self, factors: ParameterFactors) -> MotorBatch:
        key = (float(factors.R_s), float(factors.L_s), float(factors.phi_pm))
        if key not in self._motors:
            motor = scaled_motor(self._true, *key)
            if len(self._motors) > 64:
                self._motors.clear()
            self._motors[key] = MotorBatch.build([motor], self._speed, 0.0)
        return self._motors[key]

    def _inputs(
        self, a: int, b: int, motor: MotorBatch, w: Array, rho: Array, noise: Array | None
    ) -> LoopInputs:
        """The loop's inputs over the chunk's samples ``[a, b)``."""
        h, first = self.drive.h, self._sample
        t = h * np.arange(first + a, first + b + 1, dtype=float)
        return _loop_inputs(
            motor, self.drive.settings, self._feedback, t, h, w[:, a : b + 1], rho[:, a:b],
            None if noise is None else noise[:, a : b + 1],
        )  # fmt: skip

    def _logged_angle(self, first: int, count: int, rotor: ComplexArray) -> Array:
        """The angle column of samples ``first .. first + count``: the rotor's, or an
        encoder's reading of the angle turned since the start (``w_e t``, as the rotor)."""
        counts = self.drive.settings.encoder_counts
        if counts is None:
            return np.angle(rotor)
        speed = float(self._nameplate.electrical_speed[0])
        turned = speed * self.drive.h * np.arange(first, first + count + 1, dtype=float)
        return encoder_angle(turned[np.newaxis], [self._true.p], counts)[0]

    def _advanced(self, outputs: LoopOutputs) -> None:
        """The session's state moved to where ``outputs`` stop."""
        state = outputs.state
        new = outputs.commands[:, outputs.pad :]
        self._state = LoopState(
            current=state.current,
            commands=np.concatenate([self._state.commands, new], axis=1)[:, -MEMORY:],
            extras=state.extras,
            integrator=state.integrator,
        )

    def _run_linear(
        self, pieces: list[_Piece], w: Array, rho: Array, noise: Array | None
    ) -> tuple[ComplexArray, LoopOutputs] | None:
        """The chunk as matrices (:class:`LinearLoop`); None where the limit acts."""
        assert self._loop is not None
        motors = [self._motor(piece.factors) for piece in pieces]
        inputs = self._inputs(0, pieces[-1].b, motors[0], w, rho, noise)
        given = [
            (piece.a, piece.b, motor, tuple(float(value) for value in piece.factors))
            for piece, motor in zip(pieces, motors, strict=True)
        ]
        outputs = self._loop.run(inputs, self._state, given)
        if outputs is None:
            return None
        self._advanced(outputs)
        return inputs.rotor, outputs

    def _run_piece(
        self, piece: _Piece, w: Array, rho: Array, noise: Array | None
    ) -> tuple[ComplexArray, LoopOutputs]:
        """One piece through the stepper (:func:`run_loop`)."""
        inputs = self._inputs(piece.a, piece.b, self._motor(piece.factors), w, rho, noise)
        outputs = run_loop(inputs, self._state)
        self._advanced(outputs)
        return inputs.rotor, outputs

    def _chunk(
        self,
        first: int,
        count: int,
        before: LoopState,
        held: list[_Piece],
        rotor: ComplexArray,
        pieces: list[LoopOutputs],
        w: Array,
        following: ParameterFactors,
    ) -> DriveChunk:
        h, settings = self.drive.h, self.drive.settings

        def joined(arrays: list[ComplexArray]) -> ComplexArray:
            """Per-sample arrays of the pieces (N + 1 each), the shared samples once."""
            if len(arrays) == 1:  # (what leaves is copied)
                return arrays[0]
            return np.concatenate([array[:, :-1] for array in arrays[:-1]] + [arrays[-1]], axis=1)

        def stacked(arrays: list[NDArray[Any]]) -> NDArray[Any]:
            return arrays[0] if len(arrays) == 1 else np.concatenate(arrays)

        current = joined([piece.current for piece in pieces])[0]
        measured = joined([piece.measured for piece in pieces])[0]
        computed = stacked([piece.commands[0, piece.pad :] for piece in pieces])
        applied = stacked([piece.applied[0] for piece in pieces])
        true_dq = current * np.conj(rotor)
        _check_finite(true_dq[np.newaxis], h * np.arange(first, first + count + 1, dtype=float))
        logged = computed
        if settings.logged_input == "applied":
            delay = settings.input_delay
            earlier = before.commands[0, MEMORY - delay :]
            logged = np.concatenate([earlier, computed])[:count]
        lengths = [piece.b - piece.a for piece in held] + [1]
        factors = np.array([piece.factors for piece in held] + [following], dtype=float)
        R_s, L_s, phi_pm = np.repeat(factors, lengths, axis=0).T
        true = self._true
        # 1.5 p (phi f_phi + (L_d - L_q) f_L i_d) i_q as the nameplate's torque with i_d
        # scaled by f_L / f_phi, times f_phi (a surface motor's as before, bit for bit)
        scaled_d = (true_dq.real * (L_s / phi_pm))[np.newaxis]
        torque = self._nameplate.torque(true_dq.imag[np.newaxis], scaled_d)[0] * phi_pm
        return DriveChunk(
            first_sample=first,
            h=h,
            measured=_read_only(_as_pairs(measured)),
            logged_input=_read_only(logged.copy()),
            reference=_read_only(w[0, 0].copy()),
            angle=_read_only(self._logged_angle(first, count, rotor)),
            true_currents=_read_only(_as_pairs(true_dq)),
            applied_voltages=_read_only(_as_pairs(applied)),
            commanded_voltages=_read_only(computed.copy()),
            torque=_read_only(torque),
            R_s=_read_only(true.R_s * R_s),
            L_s=_read_only(true.L_d * L_s),
            phi_pm=_read_only(true.phi_pm * phi_pm),
            L_d=_read_only(true.L_d * L_s),
            L_q=_read_only(true.L_q * L_s),
        )
