"""The inverter's loop where it is linear, all samples at once: :class:`LinearLoop`.

With average PWM, no dead time and no ADC, one sample of the inverter and the motor is
affine in the rotor frame, the same at every rotor angle (:func:`dq_sample_map`, read
off the inverter's own step), and so is the closed loop: its matrices are those of
:func:`~selftune.sim._stepper.one_step_map` (read off one step of the stepper) and its
samples are propagated all at once (:func:`~selftune.core._propagate.propagate_uniform`);
the phase-current noise enters as the law's measurement error. To rounding, the samples
:func:`~selftune.sim._inverter.run_loop` gives one by one, while no command reaches the
voltage limit (where one does, :meth:`LinearLoop.run` returns None).
"""

from __future__ import annotations

import numpy as np

from ..core import Array
from ..core._propagate import propagate_uniform
from ..errors import InputError
from ._drive_settings import DriveSettings
from ._inverter import LoopInputs, LoopOutputs, LoopState, MotorBatch, _step, from_phases
from ._realistic import _as_pairs
from ._stepper import Feedback, one_step_map

__all__ = ["LinearLoop", "dq_sample_map", "stack_motors"]


def _real(value: complex) -> Array:
    """The real 2 x 2 matrix acting on ``[re, im]`` as multiplying by ``value``."""
    return np.array([[value.real, -value.imag], [value.imag, value.real]])


def stack_motors(motors: list[MotorBatch]) -> MotorBatch:
    """The motors of several batches as one batch (in order)."""
    fields = MotorBatch.__dataclass_fields__
    return MotorBatch(
        **{name: np.concatenate([getattr(m, name) for m in motors]) for name in fields}
    )


def dq_sample_map(inputs: LoopInputs, motor: MotorBatch) -> tuple[Array, Array, Array, Array]:
    """One sample of the inverter and each motor (P,) in the rotor frame, where it is linear
    (average PWM, no dead time), read off the inverter's step; the modulator, the law
    and the modulation's angle offset are those of ``inputs``.

    Returns ``(a, b, c, v)``, complex (P,): ``i_(k+1) = a i_k + b u_k + c`` (``u_k`` the dq
    command applied over sample k, ``c`` the back-EMF's part, A) and the mean dq voltage
    over the sample ``v u_k``, V; the same at every rotor angle (here at ``theta = 0``).
    """
    mod = inputs.modulator
    if mod.carrier or mod.dead_time_amplitude > 0.0:
        raise InputError("dq_sample_map: the inverter is not linear (carrier PWM or dead time)")
    count = motor.R_s.shape[0]
    probe = MotorBatch(
        **{name: np.tile(getattr(motor, name), 3) for name in motor.__dataclass_fields__}
    )
    rotor = np.exp(1j * probe.electrical_speed[:, np.newaxis] * np.array([0.0, mod.period]))
    turn = inputs.modulation[:1, :1] / inputs.rotor[:1, :1]  # exp(j eps)
    one = LoopInputs(
        motor=probe, modulator=mod, feedback=inputs.feedback, sensor=inputs.sensor,
        rotor=rotor, modulation=np.repeat(turn, 3 * count, axis=0), w=inputs.w, rho=inputs.rho,
    )  # fmt: skip
    units = np.zeros((3, count), dtype=complex)
    current, command = units.copy(), units.copy()
    current[0], command[1] = 1.0, 1.0
    after, mean = _step(
        one, 0, current.ravel(), one.modulation[:, 0] * command.ravel(), 0 * units.ravel()
    )
    dq = (after * np.conj(one.rotor[:, 1])).reshape(3, count)
    return dq[0] - dq[2], dq[1] - dq[2], dq[2], mean.reshape(3, count)[1]


class LinearLoop:
    """One law's loop on the linear inverter (see the module docstring).

    Parameters
    ----------
    feedback : Feedback
        One law (P = 1).
    delay : int
        d, samples between computing a command and applying it.
    """

    def __init__(self, feedback: Feedback, delay: int) -> None:
        self.feedback, self.delay = feedback, delay
        # the input each unit of [xi; w; rho] applies: the loop with Ad = 0, Bd = I
        plant = (np.zeros((2, 2)), np.eye(2), np.zeros((2, feedback.q)))
        self.base, self.command = (m[0] for m in one_step_map(plant, feedback, delay))
        self._maps: dict[tuple[float, ...], tuple[Array, Array, Array, complex]] = {}

    @staticmethod
    def applies(settings: DriveSettings) -> bool:
        """Whether the drive's loop is linear: average PWM, no dead time, no ADC."""
        average = settings.pwm == "average" and settings.dead_time == 0.0
        return average and settings.adc_bits is None

    def maps(
        self, inputs: LoopInputs, motors: list[MotorBatch], keys: list[tuple[float, ...]]
    ) -> list[tuple[Array, Array, Array, complex]]:
        """For each motor: the step (acting on rows of ``[xi; w; rho]``), the rows of a
        measurement error, the back-EMF's forcing and the mean voltage's factor ``v``;
        cached under its key (the motor's values)."""
        missing = [index for index, key in enumerate(keys) if key not in self._maps]
        if missing:
            if len(self._maps) + len(missing) > 256:
                self._maps.clear()
                missing = list(range(len(keys)))
            a, b, c, v = dq_sample_map(inputs, stack_motors([motors[i] for i in missing]))
            for row, index in enumerate(missing):
                Ad, Bd = _real(a[row]), _real(b[row])
                step = self.base.copy()
                step[:, :2] = self.base[:, :2] @ Bd.T
                error = step[:2].copy()  # a measurement error acts through the law only
                step[:2, :2] += Ad.T
                forcing = np.zeros(step.shape[1])
                forcing[:2] = c[row].real, c[row].imag
                self._maps[keys[index]] = (step, error, forcing, complex(v[row]))
        return [self._maps[key] for key in keys]

    def run(
        self,
        inputs: LoopInputs,
        start: LoopState,
        pieces: list[tuple[int, int, MotorBatch, tuple[float, ...]]],
    ) -> LoopOutputs | None:
        """:func:`~selftune.sim._inverter.run_loop` of one motor from ``start``, all samples
        at once, the motor changing between pieces; None if a command exceeds the voltage
        limit (the stepper limits it).

        Parameters
        ----------
        inputs : LoopInputs
            The chunk's rotor, reference, probing, noise and this loop's law (its motor
            unused).
        start : LoopState
            Where the loop stands at the first sample.
        pieces : list of (a, b, MotorBatch, key)
            Samples ``[a, b)`` (covering the chunk in order) of one motor, its values as
            the key its matrices are cached under.
        """
        maps = self.maps(inputs, [p[2] for p in pieces], [p[3] for p in pieces])
        command, feedback, delay = self.command, self.feedback, self.delay
        count, memory = inputs.rho.shape[1], start.commands.shape[1]
        pad, size = max(feedback.history, delay), self.base.shape[1]
        rotor = inputs.rotor[0]
        noise = np.zeros((count + 1, 2))
        if inputs.sensor.noise is not None:
            noise = _as_pairs(from_phases(inputs.sensor.noise[0]) * np.conj(rotor))
        given = np.hstack([inputs.w[0, :count], inputs.rho[0]])
        first = start.current[0] * np.conj(rotor[0])
        xi0 = np.concatenate([
            [first.real, first.imag],
            start.commands[0, memory - pad :].ravel(),
            start.integrator[0, : feedback.integrators],
        ])  # fmt: skip
        forcings = [
            given[a:b] @ step[size:] + noise[a:b] @ error + forcing
            for (a, b, _, _), (step, error, forcing, _) in zip(pieces, maps, strict=True)
        ]
        xi = _propagate([m[0][:size] for m in maps], forcings, xi0)
        u = xi[:-1] @ command[:size] + given @ command[size:] + noise[:count] @ command[:2]
        if np.any(np.hypot(u[:, 0], u[:, 1]) > inputs.modulator.limit):
            return None
        x = xi[:, 0] + 1j * xi[:, 1]
        commands = np.concatenate([start.commands[:, memory - pad :], u[np.newaxis]], axis=1)
        applied = commands[0, pad - delay : pad - delay + count]
        v = np.repeat([m[3] for m in maps], [b - a for a, b, _, _ in pieces])
        after = LoopState(
            current=x[-1:] * rotor[-1:],
            commands=commands,
            extras=np.zeros((1, delay), dtype=complex),
            integrator=xi[-1:, size - feedback.integrators :],
        )
        return LoopOutputs(
            measured=(x + noise[:, 0] + 1j * noise[:, 1])[np.newaxis],
            current=(x * rotor)[np.newaxis],
            commands=commands,
            applied=(v * (applied[:, 0] + 1j * applied[:, 1]))[np.newaxis],
            pad=pad,
            state=after,
        )


def _propagate(steps: list[Array], forcings: list[Array], x0: Array) -> Array:
    """``x[k+1] = x[k] @ T_j + f[k]`` over consecutive pieces j (``f`` (L_j, S) each),
    all pieces at once: their responses to their forcing from zero as one batch of plants
    (:func:`propagate_uniform`), their starts chained by the powers ``T_j^(L_j)``, then
    the free responses from those starts as one batch. Returns x, shape (sum L_j + 1, S)."""
    if len(steps) == 1:
        return propagate_uniform(
            steps[0][:, :, np.newaxis], forcings[0][:, :, np.newaxis], x0[:, np.newaxis]
        )[:, :, 0]
    lengths = [forcing.shape[0] for forcing in forcings]
    longest, size, plants = max(lengths), x0.shape[0], len(steps)
    T = np.stack(steps, axis=-1)  # (S, S, P), acting on rows
    F = np.zeros((longest, size, plants))
    for j, forcing in enumerate(forcings):
        F[: lengths[j], :, j] = forcing
    forced = propagate_uniform(T, F, np.zeros((size, plants)))
    starts = np.empty((size, plants + 1))
    starts[:, 0] = x0
    powers = {}
    for length in set(lengths):
        chosen = [j for j in range(plants) if lengths[j] == length]
        for j, power in zip(
            chosen, np.linalg.matrix_power(T[:, :, chosen].transpose(2, 0, 1), length), strict=True
        ):
            powers[j] = power
    for j in range(plants):
        starts[:, j + 1] = starts[:, j] @ powers[j] + forced[lengths[j], :, j]
    free = propagate_uniform(T, np.zeros((longest, size, plants)), starts[:, :plants])
    x = np.empty((sum(lengths) + 1, size))
    offset = 0
    for j, length in enumerate(lengths):
        x[offset : offset + length] = forced[:length, :, j] + free[:length, :, j]
        offset += length
    x[offset] = starts[:, plants]
    return x
