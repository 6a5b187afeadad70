"""The inverter's loop where it is linear, all samples at once: :class:`LinearLoop`.

With average PWM, no dead time and no ADC, one sample of the inverter and the motor is
affine in the rotor frame, the same at every rotor angle (:func:`dq_sample_map`, read
off the inverter's own step), and so is the closed loop: its matrices are those of
:func:`~selftune.sim._stepper.one_step_map` (read off one step of the stepper) and its
samples are propagated in blocks (:class:`Lifted`); the phase-current noise enters as the
law's measurement error. To rounding, the samples
:func:`~selftune.sim._inverter.run_loop` gives one by one, while no command reaches the
voltage limit (where one does, :meth:`LinearLoop.run` returns None).

:class:`Lifted` is :func:`~selftune.core._propagate.propagate_uniform`'s two-level scheme
with its block matrices kept: a session propagates many short chunks with one map, and
rebuilding the powers of T for each (as ``propagate_uniform`` does, for one long run)
cost more than the chunk (100 samples: 0.33 ms against 0.07 ms; 1,000: 1.0 against
0.27; building the blocks: 0.23 ms once).
"""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from ..core import Array
from ..errors import InputError
from ._drive_settings import DriveSettings
from ._inverter import LoopInputs, LoopOutputs, LoopState, MotorBatch, _step, from_phases
from ._realistic import _as_pairs
from ._stepper import Feedback, one_step_map

__all__ = ["LinearLoop", "dq_sample_map", "stack_motors"]


def _real(value: complex) -> Array:
    """The real 2 x 2 matrix acting on ``[re, im]`` as multiplying by ``value``."""
    return np.array([[value.real, -value.imag], [value.imag, value.real]])


def _linear_batch(array: Callable[[str], Array]) -> MotorBatch:
    """The batch whose field ``name`` is ``array(name)``, without saturation."""
    return MotorBatch(
        R_s=array("R_s"), L_d=array("L_d"), L_q=array("L_q"), phi_pm=array("phi_pm"),
        p=array("p"), electrical_speed=array("electrical_speed"), interior=array("interior"),
    )  # fmt: skip


def stack_motors(motors: list[MotorBatch]) -> MotorBatch:
    """The motors of several batches as one batch (in order; none saturating)."""
    if any(m.saturation is not None for m in motors):
        raise InputError("stack_motors: a saturating motor is not linear")
    return _linear_batch(lambda name: np.concatenate([getattr(m, name) for m in motors]))


def dq_sample_map(inputs: LoopInputs, motor: MotorBatch) -> tuple[Array, Array, Array, Array]:
    """One sample of the inverter and each motor (P,) in the rotor frame, where it is linear
    (average PWM, no dead time), read off the inverter's step; the modulator, the law
    and the modulation's angle offset are those of ``inputs``.

    Returns ``(Ad, Bd, c, v)``: ``i_(k+1) = Ad i_k + Bd u_k + c`` (real, (P, 2, 2) and
    (P, 2), on ``[d, q]``; ``u_k`` the dq command applied over sample k, ``c`` the
    back-EMF's part, A) and the mean dq voltage over the sample ``v u_k``, V (complex
    (P,)); the same at every rotor angle (here at ``theta = 0``). A surface motor's maps
    are complex scalars (read off the units 1); an interior motor's are read off 1 and j.
    """
    mod = inputs.modulator
    if mod.carrier or mod.dead_time_amplitude > 0.0:
        raise InputError("dq_sample_map: the inverter is not linear (carrier PWM or dead time)")
    count = motor.R_s.shape[0]
    interior = bool(np.any(motor.interior))
    units = (
        np.array([[1, 0], [0, 1], [0, 0]], dtype=complex)
        if not interior
        else np.array([[1, 0], [1j, 0], [0, 1], [0, 1j], [0, 0]], dtype=complex)
    )
    probes = units.shape[0]
    if motor.saturation is not None:
        raise InputError("dq_sample_map: a saturating motor is not linear")
    probe = _linear_batch(lambda name: np.tile(getattr(motor, name), probes))
    rotor = np.exp(1j * probe.electrical_speed[:, np.newaxis] * np.array([0.0, mod.period]))
    turn = inputs.modulation[:1, :1] / inputs.rotor[:1, :1]  # exp(j eps)
    one = LoopInputs(
        motor=probe, modulator=mod, feedback=inputs.feedback, sensor=inputs.sensor,
        rotor=rotor, modulation=np.repeat(turn, probes * count, axis=0), w=inputs.w,
        rho=inputs.rho,
    )  # fmt: skip
    current = np.repeat(units[:, :1], count, axis=1).ravel()
    command = np.repeat(units[:, 1:], count, axis=1).ravel()
    after, mean = _step(one, 0, current, one.modulation[:, 0] * command, 0 * current)
    dq = (after * np.conj(one.rotor[:, 1])).reshape(probes, count)
    free = dq[-1]
    if not interior:
        a, b = dq[0] - free, dq[1] - free
        Ad = np.array([_real(complex(value)) for value in a]).reshape(count, 2, 2)
        Bd = np.array([_real(complex(value)) for value in b]).reshape(count, 2, 2)
        return Ad, Bd, _as_pairs(free), mean.reshape(probes, count)[1]
    columns = _as_pairs(dq[:4] - free)  # (4, P, 2): the responses to 1, j; 1, j
    Ad = np.stack([columns[0], columns[1]], axis=-1)
    Bd = np.stack([columns[2], columns[3]], axis=-1)
    return Ad, Bd, _as_pairs(free), mean.reshape(probes, count)[2]


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
        self._maps: dict[tuple[float, ...], tuple[Array, Array, Array, complex, Lifted]] = {}

    @staticmethod
    def applies(settings: DriveSettings) -> bool:
        """Whether the drive's loop is linear: average PWM, no dead time, no ADC."""
        average = settings.pwm == "average" and settings.dead_time == 0.0
        return average and settings.adc_bits is None

    def maps(
        self, inputs: LoopInputs, motors: list[MotorBatch], keys: list[tuple[float, ...]]
    ) -> list[tuple[Array, Array, Array, complex, Lifted]]:
        """For each motor: the step (acting on rows of ``[xi; w; rho]``), the rows of a
        measurement error, the back-EMF's forcing and the mean voltage's factor ``v``;
        cached under its key (the motor's values)."""
        missing = [index for index, key in enumerate(keys) if key not in self._maps]
        if missing:
            if len(self._maps) + len(missing) > 256:
                self._maps.clear()
                missing = list(range(len(keys)))
            As, Bs, c, v = dq_sample_map(inputs, stack_motors([motors[i] for i in missing]))
            for row, index in enumerate(missing):
                Ad, Bd = As[row], Bs[row]
                step = self.base.copy()
                step[:, :2] = self.base[:, :2] @ Bd.T
                error = step[:2].copy()  # a measurement error acts through the law only
                step[:2, :2] += Ad.T
                forcing = np.zeros(step.shape[1])
                forcing[:2] = c[row]
                lifted = Lifted(step[: self.base.shape[1]])
                self._maps[keys[index]] = (step, error, forcing, complex(v[row]), lifted)
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
        xi = np.empty((count + 1, size))
        xi[0] = xi0
        for (a, b, _, _), (step, error, forcing, _, lifted) in zip(pieces, maps, strict=True):
            f = given[a:b] @ step[size:] + noise[a:b] @ error + forcing
            xi[a : b + 1] = lifted.run(f, xi[a])
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


#: Samples per block of :class:`Lifted` (its block map is (32 S) x (32 S)).
BLOCK = 32


@lru_cache(maxsize=4)
def _pairs_within(length: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """The pairs ``j <= k`` of a block's samples (:func:`numpy.triu_indices`, kept)."""
    return np.triu_indices(length)


class Lifted:
    """``x[k+1] = x[k] @ T + f[k]`` (rows) for one T, lifted to blocks of L samples.

    Within a block, the states from a zero start are one linear map of the block's
    forcing (``f_j T^(k-j)``, j <= k: a block lower-triangular matrix of T's powers), and
    the free motion is the start times ``[T, T^2, ... T^L]``: the blocks of a run take two
    matrix products at once, and only their starts follow one another (``T^L``). The
    matrices are built once per T and kept, so a map used for many chunks pays once.

    Parameters
    ----------
    T : ndarray, shape (S, S)
        The one-step map, acting on rows.
    length : int
        L, samples per block.
    """

    def __init__(self, T: Array, length: int = BLOCK) -> None:
        size = T.shape[0]
        powers = np.empty((length + 1, size, size))
        powers[0] = np.eye(size)
        for power in range(length):
            powers[power + 1] = powers[power] @ T
        j, k = _pairs_within(length)  # forcing j reaches position k + 1 (k >= j)
        blocks = np.zeros((length, size, length, size))
        blocks[j, :, k, :] = powers[k - j]
        self.length = length
        self.forced = blocks.reshape(length * size, length * size)
        self.free = powers[1:].transpose(1, 0, 2).reshape(size, length * size)
        self.block = powers[length]

    def run(self, f: Array, x0: Array) -> Array:
        """The states (N + 1, S) from ``x0`` (S,) under the forcing ``f`` (N, S)."""
        count, size = f.shape
        length = self.length
        blocks = -(-count // length)
        forcing = np.zeros((blocks * length, size))
        forcing[:count] = f
        forced = (forcing.reshape(blocks, length * size) @ self.forced).reshape(
            blocks, length, size
        )
        starts = np.empty((blocks, size))
        starts[0] = x0
        for b in range(1, blocks):
            starts[b] = starts[b - 1] @ self.block + forced[b - 1, -1]
        x = np.empty((blocks * length + 1, size))
        x[0] = x0
        x[1:] = (forced + (starts @ self.free).reshape(blocks, length, size)).reshape(-1, size)
        return x[: count + 1]
