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
from ._stepper import Feedback, one_step_map

__all__ = ["LinearLoop", "dq_sample_map"]


def _real(value: complex) -> Array:
    """The real 2 x 2 matrix acting on ``[re, im]`` as multiplying by ``value``."""
    return np.array([[value.real, -value.imag], [value.imag, value.real]])


def _pairs(values: Array) -> Array:
    return np.stack([values.real, values.imag], axis=-1)


def dq_sample_map(inputs: LoopInputs) -> tuple[complex, complex, complex, complex]:
    """One sample of the inverter and the motors in the rotor frame, where it is linear
    (average PWM, no dead time), read off the inverter's step (motor 0 of ``inputs``).

    Returns ``(a, b, c, v)``, complex: ``i_(k+1) = a i_k + b u_k + c`` (``u_k`` the dq
    command applied over sample k, ``c`` the back-EMF's part, A) and the mean dq voltage
    over the sample ``v u_k``, V; the same at every rotor angle (here at ``theta = 0``).
    """
    mod = inputs.modulator
    if mod.carrier or mod.dead_time_amplitude > 0.0:
        raise InputError("dq_sample_map: the inverter is not linear (carrier PWM or dead time)")
    motor = inputs.motor
    fields = {name: np.repeat(getattr(motor, name)[:1], 3) for name in motor.__dataclass_fields__}
    probe = MotorBatch(**fields)
    speed, h = probe.electrical_speed[:1], mod.period
    rotor = np.exp(1j * speed[:, np.newaxis] * np.array([0.0, h]))
    turn = inputs.modulation[:1, :1] / inputs.rotor[:1, :1]  # exp(j eps)
    one = LoopInputs(
        motor=probe, modulator=mod, feedback=inputs.feedback, sensor=inputs.sensor,
        rotor=np.repeat(rotor, 3, axis=0), modulation=np.repeat(turn, 3, axis=0),
        w=inputs.w, rho=inputs.rho,
    )  # fmt: skip
    current = np.array([1.0, 0.0, 0.0], dtype=complex)
    command = one.modulation[:, 0] * np.array([0.0, 1.0, 0.0])
    after, mean = _step(one, 0, current, command, np.zeros(3, dtype=complex))
    dq = after * np.conj(one.rotor[:, 1])
    return complex(dq[0] - dq[2]), complex(dq[1] - dq[2]), complex(dq[2]), complex(mean[1])


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
        self, inputs: LoopInputs, key: tuple[float, ...]
    ) -> tuple[Array, Array, Array, complex]:
        """The step (acting on rows of ``[xi; w; rho]``), the rows of a measurement error,
        the back-EMF's forcing and the mean voltage's factor ``v`` for the motor of
        ``inputs``; cached under ``key`` (the motor's values)."""
        if key not in self._maps:
            a, b, c, v = dq_sample_map(inputs)
            Ad, Bd = _real(a), _real(b)
            step = self.base.copy()
            step[:, :2] = self.base[:, :2] @ Bd.T
            error = step[:2].copy()  # a measurement error acts through the law only
            step[:2, :2] += Ad.T
            forcing = np.zeros(step.shape[1])
            forcing[:2] = c.real, c.imag
            if len(self._maps) > 64:
                self._maps.clear()
            self._maps[key] = (step, error, forcing, v)
        return self._maps[key]

    def run(
        self, inputs: LoopInputs, start: LoopState, key: tuple[float, ...]
    ) -> LoopOutputs | None:
        """:func:`~selftune.sim._inverter.run_loop` of one motor from ``start``, all samples
        at once; None if a command exceeds the voltage limit (the stepper limits it).

        Parameters
        ----------
        inputs : LoopInputs
            One motor, this loop's law.
        start : LoopState
            Where the loop stands at the first sample.
        key : tuple of float
            The motor's values (what its matrices are cached under).
        """
        step, error, forcing, v = self.maps(inputs, key)
        command, feedback, delay = self.command, self.feedback, self.delay
        count, memory = inputs.rho.shape[1], start.commands.shape[1]
        pad, size = max(feedback.history, delay), step.shape[1]
        rotor = inputs.rotor[0]
        noise = np.zeros((count + 1, 2))
        if inputs.sensor.noise is not None:
            noise = _pairs(from_phases(inputs.sensor.noise[0]) * np.conj(rotor))
        given = np.hstack([inputs.w[0, :count], inputs.rho[0]])
        first = start.current[0] * np.conj(rotor[0])
        xi0 = np.concatenate([
            [first.real, first.imag],
            start.commands[0, memory - pad :].ravel(),
            start.integrator[0, : feedback.integrators],
        ])  # fmt: skip
        f = given @ step[size:] + noise[:count] @ error + forcing
        xi = propagate_uniform(step[:size, :, np.newaxis], f[:, :, np.newaxis], xi0[:, np.newaxis])
        xi = xi[:, :, 0]
        u = xi[:-1] @ command[:size] + given @ command[size:] + noise[:count] @ command[:2]
        if np.any(np.hypot(u[:, 0], u[:, 1]) > inputs.modulator.limit):
            return None
        x = xi[:, 0] + 1j * xi[:, 1]
        commands = np.concatenate([start.commands[:, memory - pad :], u[np.newaxis]], axis=1)
        applied = commands[0, pad - delay : pad - delay + count]
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
