"""The realistic drive over a speed profile: the load machine changes the speed while the
current loop runs (a speed ramp or staircase).

The mechanical speed is held constant within each sample and changes between samples:
``speeds[k]`` over sample k (``[t_k, t_(k+1))``), and the rotor angle integrates it,
``theta_(k+1) = theta_k + p speeds[k] h`` (``theta_0 = 0``). The mechanical speed of a
drive changes slowly against a 100 us sample (a load's inertia), so the held speed is the
stated approximation: a linear ramp of ``a`` rad/s^2 (electrical) is off by at most ``a h
/ 2`` within a sample. Each run of equal speeds is one :func:`~selftune.sim._inverter.
run_loop` of the drive at that held speed, continued from where the previous one stopped
(currents, delay line, dead-time compensation, integrators; the exploration and the
measurement noise drawn once for the whole log, as :func:`run_drive_batch` draws them):
every effect of :class:`~selftune.sim.RealisticDrive` (average and carrier PWM, dead time,
noise, ADC, delay, voltage limit, surface and interior motors) holds unchanged, and a
profile of one speed is :meth:`RealisticDrive.record` to the bit. A per-sample ramp is a
run per sample (about 0.2 ms each, with an interior motor's exponentials); a staircase of
a few levels costs a constant-speed run.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from itertools import pairwise
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core import Array, ControlLaw, positive_finite, positive_integer
from ..errors import InputError
from ..model import Motor
from ._checks import as_float_array
from ._drive_settings import DriveSettings
from ._exploration import Exploration
from ._inverter import LoopInputs, LoopOutputs, LoopState, MotorBatch, random_inputs, run_loop
from ._realistic import (
    DriveRecord,
    _check_settings,
    _laws,
    _loop_inputs,
    _motors,
    _records,
    _reference,
)
from ._signals import ExogenousSignal
from ._stepper import Feedback, feedback_of

__all__ = ["ramp_speeds", "run_speed_profile"]


def ramp_speeds(low: float, high: float, num_samples: int, levels: int | None = None) -> Array:
    """Mechanical speeds (N,) from ``low`` to ``high`` over N samples: linear, one speed a
    sample (``levels`` None), or a staircase of ``levels`` equal-length steps whose speeds
    are spaced linearly from ``low`` to ``high`` (rad/s).

    Parameters
    ----------
    low, high : float
        The first and last speed, rad/s (mechanical).
    num_samples : int
        N, samples.
    levels : int, optional
        Steps of the staircase (at least 2, at most N); None: a speed per sample.
    """
    count = positive_integer(num_samples, "num_samples")
    first, last = as_float_array(low, "low"), as_float_array(high, "high")
    if levels is None:
        return np.linspace(float(first), float(last), count)
    steps = positive_integer(levels, "levels", minimum=2)
    if steps > count:
        raise InputError(f"levels: {steps} steps for {count} samples")
    level = np.minimum((np.arange(count) * steps) // count, steps - 1)
    return np.linspace(float(first), float(last), steps)[level]


def run_speed_profile(
    motor: Motor,
    speeds: ArrayLike,
    h: float,
    settings: DriveSettings,
    law: ControlLaw | Callable[[float], ControlLaw],
    reference: ExogenousSignal,
    *,
    exploration: Exploration | None,
    seed: int,
) -> DriveRecord:
    """One episode from rest of a realistic drive whose speed follows ``speeds`` (see the
    module docstring); the log's angle column is the integrated angle.

    Parameters
    ----------
    motor : SPMSM or IPMSM
        The true motor (nameplate values; ``settings.temperature_rise`` heats it).
    speeds : array_like, shape (N,)
        The mechanical speed held over each sample, rad/s (finite).
    h : float
        Sampling (and PWM) period, s.
    settings : DriveSettings
        The drive's effects.
    law : ControlLaw or callable
        The controller (n = m = 2; q of the reference), or a function of the held
        mechanical speed (rad/s) giving the controller over each run of equal speeds: a
        feedforward that follows the speed (the experiment's decoupling), a schedule's
        law. Every speed's law has the first one's dimensions, fed-back inputs and
        integrators: the loop's state carries over from one speed to the next.
    reference : ExogenousSignal
        The controller's ``w`` at the sample instants (e.g. ``w_1 = p speed phi`` following
        the speed).
    exploration : Exploration or None
        ``rho``, V, added to each command; None for none.
    seed : int
        Seed of the one generator of the exploration and the noise.

    Returns
    -------
    DriveRecord

    Raises
    ------
    InputError
        Naming the argument, if a value is invalid or the currents overflow.
    """
    h = positive_finite(h, "h")
    checked = _check_settings(settings, h)
    profile = as_float_array(speeds, "speeds")
    if profile.ndim != 1 or profile.size == 0 or not np.all(np.isfinite(profile)):
        raise InputError(f"speeds: expected finite speeds (N,), got shape {profile.shape}")
    count = profile.size
    given, _ = _motors([motor], 0.0)
    t = h * np.arange(count + 1, dtype=float)
    w = _reference(reference, t, 1)
    law_at = None
    if isinstance(law, ControlLaw) or not callable(law):
        [first] = _laws(law, 1, w.shape[-1])
    else:
        law_at = law
        [first] = _laws(law_at(float(profile[0])), 1, w.shape[-1])
    feedback = feedback_of([first])
    rho, noise = random_inputs(exploration, t, seed, 1, checked.current_noise)
    cuts = [0, *(np.flatnonzero(np.diff(profile) != 0.0) + 1).tolist(), count]
    state: LoopState | None = None
    angle = np.zeros(1)
    pieces: list[tuple[LoopInputs, LoopOutputs]] = []
    for a, b in pairwise(cuts):
        if law_at is not None and a > 0:
            feedback = _same_loop(first, law_at(float(profile[a])), float(profile[a]))
        batch = MotorBatch.build(given, np.array([profile[a]]), checked.temperature_rise)
        inputs = _loop_inputs(
            batch, checked, feedback, t[a : b + 1], h, w[:, a : b + 1], rho[:, a:b],
            None if noise is None else noise[:, a : b + 1], angle,
        )  # fmt: skip
        with np.errstate(over="ignore", invalid="ignore"):
            outputs = run_loop(inputs, state)
        pieces.append((inputs, outputs))
        state = outputs.state
        angle = angle + batch.electrical_speed * (t[b] - t[a])
    return _records(*_joined(pieces, t, w, rho), checked, t)[0]


def _same_loop(first: ControlLaw, law: ControlLaw, speed: float) -> Feedback:
    """``law`` (the one at ``speed``, rad/s) as the loop's map, if its state is the first
    law's: the same dimensions, fed-back inputs and integrators."""
    expected = (first.n, first.m, first.q, first.history, first.r)
    if not isinstance(law, ControlLaw):
        raise InputError(
            f"law: at {speed:g} rad/s it gave a {type(law).__name__}, not a ControlLaw"
        )
    shape = (law.n, law.m, law.q, law.history, law.r)
    if shape != expected:
        raise InputError(
            f"law: at {speed:g} rad/s its (n, m, q, history, integrators) are {shape}, the "
            f"first speed's {expected}: the loop's state carries over between speeds"
        )
    return feedback_of([law])


def _joined(
    pieces: list[tuple[LoopInputs, LoopOutputs]], t: Array, w: Array, rho: Array
) -> tuple[LoopInputs, LoopOutputs]:
    """The pieces' inputs and outputs as one run's (what :func:`_records` reads)."""
    first_inputs, first_outputs = pieces[0]

    def samples(arrays: list[NDArray[Any]]) -> NDArray[Any]:  # (P, n_i + 1), joints shared
        return np.concatenate([a[:, :-1] for a in arrays[:-1]] + [arrays[-1]], axis=1)

    rotor = samples([inputs.rotor for inputs, _ in pieces])
    inputs = replace(first_inputs, rotor=rotor, w=w, rho=rho)
    pad = first_outputs.pad
    commands = np.concatenate(
        [first_outputs.commands[:, :pad]] + [out.commands[:, out.pad :] for _, out in pieces],
        axis=1,
    )
    outputs = LoopOutputs(
        measured=samples([out.measured for _, out in pieces]),
        current=samples([out.current for _, out in pieces]),
        commands=commands,
        applied=np.concatenate([out.applied for _, out in pieces], axis=1),
        pad=pad,
        state=pieces[-1][1].state,
    )
    return inputs, outputs
