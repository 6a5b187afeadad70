"""An inverter's dead time as the data see it: a voltage error the log does not show.

Each leg of a two-level inverter switches ``t_d`` late on one edge, which moves its mean
phase voltage by ``-v sign(i_x)``, ``v = t_d f_sw V_dc`` (V, per phase; x = a, b, c). In
the stationary frame the error is ``-v (2/3) sum_x sign(i_x) exp(j 2 pi x / 3)``: a vector
of length ``4 v / 3`` at the centre of the 60-degree sector the current points into. In
the rotor (dq) frame it turns with the rotor and jumps by 60 degrees six times per
electrical revolution; its average along the current is ``4 v / pi``. It enters the
exact discrete model as one more held input, ``x_(k+1) = ... - v Bd s_k``, with ``s_k`` the
dq vector of the phase signs: two extra exogenous channels whose gain ``-v Bd`` the
model fits (:mod:`._evidence`), so that the dead time is neither refused as an
unexplained error nor mistaken for back-EMF or feedforward.

``s_k`` needs the rotor angle at each sample (``theta_e``, electrical):

- the log's own angle column (:attr:`Trajectory.angle`) when it has one: ``s_k`` exact;
- else, at a known constant electrical speed ``w_e``, ``theta_k = w_e (t_k - t_0) +
  theta_0`` with the offset ``theta_0`` of each log estimated by least squares (the
  one-step residual of the exact discrete model over a grid of offsets; ``s`` repeats
  every 60 degrees of offset, so the grid covers 60 degrees);
- else the current's direction, ``(4 / pi) x / |x|``: the error's average along the
  current, without the six-step ripple. That ripple then stays in the residual: on the
  library's realistic drive (2 V dead time, 10 kHz) it left the flux 0.3-0.9% off where
  the phase signs gave 0.01-0.2%.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any, Literal, cast

import numpy as np

from ...core import Array
from ...core._phases import (
    Number,
    dq_of_phases,
    from_phases,
    phase_currents,
    phases_of_dq,
    to_phases,
)
from ...errors import ConfigurationMismatch, InputError
from ..data._trajectory import Trajectory
from ._alignment import aligned_transitions
from ._encoder import read_angle

__all__ = [
    "OFFSET_GRID",
    "SWITCHING_SIGNS",
    "DeadTimeChannels",
    "DeadTimeModel",
    "Switching",
    "angle_offset",
    "check_angle",
    "direction_signs",
    "line_to_line",
    "path_signs",
    "path_vector",
    "phase_sign_values",
    "phase_signs",
    "sign_vector",
    "with_dead_time",
    "with_signs_of",
]

#: Offsets tried per log when the angle comes from the speed: 1 degree apart over 60,
#: then refined 0.05 degree apart around the best.
OFFSET_GRID = np.deg2rad(np.arange(0.0, 60.0, 1.0))

#: How the phase signs were computed: from the log's angle, from the electrical speed
#: with a fitted offset, or the current's direction (see the module docstring).
DeadTimeModel = Literal["phase signs", "speed", "current direction"]


#: The largest electrical angle read, rad (an unwrapped angle of 1e6 rad is 160,000
#: electrical turns): a larger one is not an angle in rad.
ANGLE_LIMIT = 1e6

#: The most the angle's sample-to-sample steps may scatter about their median (median
#: absolute deviation, rad) for an angle sampled at each row: at constant speed they are
#: equal; a speed changing by 1,000 rad/s within 10 ms at 10 kHz scatters them by 0.005.
ANGLE_SCATTER = np.pi / 8

#: How far the angle's own speed may be from ``electrical_speed`` (relative).
SPEED_AGREEMENT = 0.1

#: How many standard deviations ``sqrt(2 / T)`` of a residual sum over T samples the
#: angle's dead-time model may explain the data worse than the current's direction.
ANGLE_EVIDENCE = 3.0


def check_angle(
    angle: Array, t: Array, electrical_speed: float | None, key: str = "electrical_speed"
) -> None:
    """Raise unless ``angle`` is an electrical rotor angle in rad, sampled at each row.

    Checked where the dead-time model uses it: finite and within :data:`ANGLE_LIMIT`;
    wrapping (if it does) by 2 pi, not 360; advancing smoothly from row to row; and, with
    ``electrical_speed`` given, at that speed (its sign too).

    Parameters
    ----------
    angle : ndarray, shape (N + 1,)
        The log's angle column ``theta``, rad.
    t : ndarray, shape (N + 1,)
        The sample times, s.
    electrical_speed : float or None
        ``p speed`` the configuration states, rad/s.
    key : str
        Where the configuration states it, for the message.

    Raises
    ------
    InputError
        Naming the column, for an angle that is not one in rad at each row.
    ConfigurationMismatch
        Naming ``electrical_speed``, when the angle turns at another speed.
    """
    column = "theta (the electrical rotor angle, rad)"
    largest = float(np.max(np.abs(angle)))
    if largest > ANGLE_LIMIT:
        raise InputError(f"{column}: reaches {largest:.3g}: not an angle in rad")
    steps = np.diff(angle)
    jumps = np.abs(steps[np.abs(steps) > np.pi])
    if jumps.size and float(np.median(jumps)) > 3.0 * np.pi:
        row = int(np.flatnonzero(np.abs(steps) > np.pi)[0])
        raise InputError(
            f"{column}: jumps by {steps[row]:.4g} from row {row} to {row + 1}, as an angle in "
            "degrees wraps; give it in rad"
        )
    wrapped = (steps + np.pi) % (2.0 * np.pi) - np.pi
    middle = float(np.median(wrapped))
    scatter = float(np.median(np.abs(wrapped - middle)))
    if scatter > ANGLE_SCATTER:
        raise InputError(
            f"{column}: does not advance smoothly from row to row (its steps scatter by "
            f"{scatter:.3g} rad about their median {middle:.3g} rad): it should be the "
            "electrical angle at each row's sample time"
        )
    if electrical_speed is None:
        return
    # the mean step, not the median: an encoder's angle steps by whole counts, and the
    # median of steps of 0 and 1 count is one of them, not the speed
    rate = float(np.mean(wrapped)) / float(np.mean(np.diff(t)))
    if abs(rate - electrical_speed) > SPEED_AGREEMENT * abs(electrical_speed) + 1e-9:
        raise ConfigurationMismatch(
            f"{key}: says {electrical_speed:.6g} rad/s, but the angle column theta turns at "
            f"{rate:.6g} rad/s; check the speed's sign and the pole pairs (p speed), or the "
            "angle's sign",
            key=key,
        )


def against_back_emf(w: Array | None, electrical_speed: float) -> float | None:
    """The mean of the back-EMF reference ``w_1 = p speed phi_assumed`` (a motor
    structure's first exogenous channel) where its sign is not that of
    ``electrical_speed`` (rad/s): the log counts the rotation in the other sense, and the
    structure's cross-coupling would be reversed; else None (no reference, standstill).

    Parameters
    ----------
    w : ndarray, shape (N, q), or None
        The log's exogenous channels.
    electrical_speed : float
        ``p speed``, rad/s.
    """
    if w is None or w.shape[1] == 0:
        return None
    mean = float(np.mean(w[:, 0]))
    return mean if mean * electrical_speed < 0.0 else None


def _check_angle_explains(episodes: Sequence[Trajectory], signs: list[Array], shift: int) -> None:
    """Raise unless the phase signs of the log's angle explain the data at least about as
    well as the current's direction alone, which needs no angle: a wrong angle (its sign,
    the mechanical for the electrical, a constant) puts the dead-time voltage at the wrong
    place, and the one-step residual rises above the direction's by more than the
    :data:`ANGLE_EVIDENCE` standard deviations its sampling allows."""
    scale = _current_scale([e.x for e in episodes])
    floor = DIRECTION_FLOOR * scale
    with_angle = sum(_residual(e, s, shift) for e, s in zip(episodes, signs, strict=True))
    without = sum(_residual(e, direction_signs(e.x, floor), shift) for e in episodes)
    count = sum(e.num_samples for e in episodes)
    # a residual at the rounding of the currents (an exact drive: no noise, no dead time)
    # tells no angle from another, however the two roundings compare
    rounding = (ROUNDING * scale) ** 2 * episodes[0].n
    excess = (with_angle - without) / max(without, rounding)
    if excess > ANGLE_EVIDENCE * np.sqrt(2.0 / count):
        raise InputError(
            f"theta (the electrical rotor angle, rad): explains the data worse than no angle "
            f"at all (the one-step residual is {excess:.1%} above that of the current's "
            "direction alone): check its sign, its unit (rad), that it is the electrical "
            "angle (p times the mechanical) and that row k holds the angle at row k's time"
        )


def phase_signs(x: Array, angle: Array) -> Array:
    """The dq vector ``(2/3) sum_x sign(i_x) exp(j 2 pi x / 3)`` of the phase currents' signs.

    :func:`sign_vector` of arrays, on complex views of ``x`` and of a ``[cos, sin]``
    buffer rather than complex arrays built from their halves (for a running drive's
    chunk of a few hundred rows, numpy's calls cost more than their arithmetic).

    Parameters
    ----------
    x : ndarray, shape (..., T, 2)
        ``[i_d, i_q]``, A (leading axes: other currents at the same angles).
    angle : ndarray, shape (T,)
        Electrical rotor angle ``theta_e`` at each sample, rad.

    Returns
    -------
    ndarray, shape (..., T, 2)
        Length 4/3 (or 0 where every phase current is 0), dimensionless.
    """
    turn = np.empty((*np.shape(angle), 2))  # [cos, sin]: the rotor's direction as complex
    np.cos(angle, out=turn[..., 0])
    np.sin(angle, out=turn[..., 1])
    current = np.ascontiguousarray(x, dtype=np.float64).view(np.complex128)[..., 0]
    vector = _signs(current, turn.view(np.complex128)[..., 0])
    return vector.view(np.float64).reshape(*vector.shape, 2)


def phase_sign_values(x: Array, angle: Array) -> Array:
    """``sign(i_x)`` of each phase current (T, 3), 0 within rounding of none (as
    :func:`phase_signs`, whose dq vector they make).

    Parameters
    ----------
    x : ndarray, shape (T, 2)
        ``[i_d, i_q]``, A.
    angle : ndarray, shape (T,)
        Electrical rotor angle at each row, rad.
    """
    current = (x[:, 0] + 1j * x[:, 1]) * np.exp(1j * np.asarray(angle, dtype=float))
    phases = to_phases(current)
    kept = _kept(phases, np.abs(current)[:, np.newaxis])
    return np.sign(phases, out=np.zeros(phases.shape), where=kept)


def path_signs(x: Array, angle: Array) -> Array:
    """The phase signs averaged over each sample along the current's path: row k's signs
    over ``[t_k, t_(k+1)]`` with each phase current moving linearly from its value at
    row k to its value at row k + 1 (the last row: its own signs).

    Parameters
    ----------
    x : ndarray, shape (T, 2)
        ``[i_d, i_q]``, A.
    angle : ndarray, shape (T,)
        Electrical rotor angle ``theta_e`` at each sample, rad.

    Returns
    -------
    ndarray, shape (T, 2)
        At most 4/3 long, dimensionless; in the dq frame of row k.
    """
    cos, sin = np.cos(angle), np.sin(angle)
    start = (x[:-1, 0], x[:-1, 1], cos[:-1], sin[:-1])
    end = (x[1:, 0], x[1:, 1], cos[1:], sin[1:])
    last = sign_vector(x[-1:, 0], x[-1:, 1], cos[-1:], sin[-1:])
    return np.vstack([np.column_stack(path_vector(start, end)), np.column_stack(last)])


def line_to_line(x: Array, angle: Array) -> Array:
    """The differences ``[i_a - i_b, i_b - i_c, i_c - i_a]`` (T, 3), A, of the phase
    currents of the dq currents ``x`` (T, 2) at the electrical angles (T,)."""
    phases = phase_currents(x, angle)
    return phases - np.roll(phases, -1, axis=1)


def sign_vector(i_d: Number, i_q: Number, cos: Number, sin: Number) -> tuple[Number, Number]:
    """:func:`phase_signs` of one sample (floats) or of many (arrays of one shape).

    Parameters
    ----------
    i_d, i_q : float or ndarray
        The dq currents, A.
    cos, sin : float or ndarray
        ``cos theta_e`` and ``sin theta_e`` of the electrical rotor angle.

    Returns
    -------
    (d, q)
        The dq components of the signs' vector.
    """
    vector = _signs(i_d + 1j * i_q, np.asarray(cos + 1j * sin))
    return cast("tuple[Number, Number]", (vector.real, vector.imag))


def _signs(current: Any, turn: Any) -> Any:
    """The signs' vector ``d + j q`` of the dq currents ``current`` (complex) at the
    rotor frame's direction in the stationary one, ``turn = cos + j sin`` (complex,
    broadcasting against ``current``)."""
    stationary = current * turn
    phases = to_phases(stationary)
    kept = _kept(phases, np.abs(stationary)[..., np.newaxis])
    signs = np.sign(phases, out=np.zeros(np.shape(phases)), where=kept)
    return from_phases(signs) * np.conj(turn)


#: A phase current rebuilt from dq within this share of the current's size is taken as
#: 0: the rotations leave about 1e-16 of it where the drive measured exactly 0 (a 12-bit
#: ADC reads 0 A in about 2% of the samples of a small current), and its sign was the
#: rounding's (multiplying the README's log by 1 + 1e-15 noise moved K by 2.3 standard
#: errors).
ROUNDING = 1e-12


def _phases(i_d: Number, i_q: Number, cos: Number, sin: Number) -> tuple[Number, Number, Number]:
    """The phase currents of the dq currents, those within :data:`ROUNDING` of zero 0."""
    size = np.hypot(i_d, i_q)
    a, b, c = (_settled(phase, size) for phase in phases_of_dq(i_d, i_q, cos, sin))
    return cast("tuple[Number, Number, Number]", (a, b, c))


def _settled(phases: Any, size: Any) -> Any:
    """``phases`` with those within :data:`ROUNDING` of ``size`` (the current's) set to 0."""
    return np.where(_kept(phases, size), phases, 0.0)


def _kept(phases: Any, size: Any) -> Any:
    """Where ``phases`` are beyond :data:`ROUNDING` of ``size`` (the current's): not 0."""
    return np.abs(phases) > ROUNDING * size


def path_vector(
    start: tuple[Number, Number, Number, Number], end: tuple[Number, Number, Number, Number]
) -> tuple[Number, Number]:
    """:func:`path_signs` of one sample (floats) or of many (arrays of one shape).

    A phase current moving linearly from ``p0`` to ``p1`` is positive over the fraction
    ``p0 / (p0 - p1)`` of the sample where it changes sign, so its mean sign is
    ``(p0 + p1) / (|p0| + |p1|)`` (its sign where it does not change; 0 where both are 0).

    Parameters
    ----------
    start, end : (i_d, i_q, cos, sin)
        The dq currents, A, and the angle's cosine and sine at the sample's start and end.

    Returns
    -------
    (d, q)
        The mean signs' vector in the dq frame of the start.
    """
    means = []
    for p0, p1 in zip(_phases(*start), _phases(*end), strict=True):
        total = np.abs(p0) + np.abs(p1)
        means.append(np.divide(p0 + p1, total, out=np.zeros_like(total), where=total > 0.0))
    return dq_of_phases(means[0], means[1], means[2], start[2], start[3])


def direction_signs(x: Array, floor: float) -> Array:
    """``(4 / pi) x / max(|x|, floor)``: the phase signs' average along the current.

    Parameters
    ----------
    x : ndarray, shape (T, 2)
        ``[i_d, i_q]``, A.
    floor : float
        Below this current, A, the vector fades to zero (noise decides the signs there).
    """
    size = np.linalg.norm(x, axis=1, keepdims=True)
    return np.asarray((4.0 / np.pi) * x / np.maximum(size, floor))


def _appended(episode: Trajectory, signs: Array) -> Trajectory:
    w = signs if episode.w is None else np.hstack([episode.w, signs[: episode.w.shape[0]]])
    return Trajectory(t=episode.t, x=episode.x, u=episode.u, w=w, angle=episode.angle)


#: Below this share of the currents' rms the direction's vector fades
#: (:func:`direction_signs`).
DIRECTION_FLOOR = 0.02


def _current_scale(currents: Sequence[Array]) -> float:
    """The currents' rms (A), at least the smallest positive float."""
    return max(float(np.sqrt(np.mean(np.concatenate(list(currents)) ** 2))), 1e-300)


def _direction_floor(currents: Sequence[Array]) -> float:
    """Below :data:`DIRECTION_FLOOR` of the currents' rms the direction's vector fades."""
    return DIRECTION_FLOOR * _current_scale(currents)


def _residual(episode: Trajectory, signs: Array, shift: int) -> float:
    """The least-squares one-step residual of the log with these signs: the mean square
    per state, summed. Defined whatever the rank (a feedback episode under a constant
    reference has constant w columns), so the offset is chosen on any log."""
    transitions = aligned_transitions(_appended(episode, signs), shift)
    Z, Y = transitions.regressors, transitions.x_next
    scale = np.linalg.norm(Z, axis=0)
    scale[scale == 0.0] = 1.0
    coefficients = np.linalg.lstsq(Z / scale, Y, rcond=None)[0]
    return float(np.sum(np.mean((Y - (Z / scale) @ coefficients) ** 2, axis=0)))


def angle_offset(episode: Trajectory, electrical_speed: float, shift: int) -> float:
    """The offset ``theta_0`` of ``theta_k = w_e (t_k - t_0) + theta_0`` that explains the
    log best (least one-step residual with the phase signs as inputs), rad in [0, pi/3).

    Parameters
    ----------
    episode : Trajectory
        The log (n = 2: ``[i_d, i_q]``).
    electrical_speed : float
        ``w_e``, rad/s (constant over the log).
    shift : int
        The alignment of the logged inputs.
    """
    elapsed = electrical_speed * (episode.t - episode.t[0])

    def cost(offset: float) -> float:
        return _residual(episode, phase_signs(episode.x, elapsed + offset), shift)

    coarse = [cost(float(offset)) for offset in OFFSET_GRID]
    best = float(OFFSET_GRID[int(np.argmin(coarse))])
    fine = best + np.deg2rad(np.arange(-1.0, 1.0 + 1e-9, 0.05))
    return float(fine[int(np.argmin([cost(float(offset)) for offset in fine]))] % (np.pi / 3))


#: When the inverter's error switches: with the current's sign at each sample, held over
#: the sample (a drive that samples once per period), or along the current's path within
#: the sample (each leg switching with its current's own sign, as a real inverter does).
Switching = Literal["sample", "path"]

#: The signs' channels of each way of switching.
SWITCHING_SIGNS: dict[Switching, Callable[[Array, Array], Array]] = {
    "sample": phase_signs,
    "path": path_signs,
}


@dataclass(frozen=True)
class DeadTimeChannels:
    """The logs with the dead time's channels, and how they were computed.

    Attributes
    ----------
    episodes : list of Trajectory
        The logs with the two channels appended to ``w``.
    model : str
        ``"phase signs"``, ``"speed"`` or ``"current direction"`` (the module docstring).
    angles : list of ndarray or None
        The electrical angle of each log's rows, rad (None for the current's direction).
    switching : {"sample", "path"} or None
        The way of switching the data preferred (:data:`Switching`; None for the current's
        direction).
    """

    episodes: list[Trajectory]
    model: DeadTimeModel
    angles: list[Array] | None = None
    switching: Switching | None = None


def with_dead_time(
    episodes: Sequence[Trajectory], electrical_speed: float | None, shift: int
) -> DeadTimeChannels:
    """The logs with the dq vector of the phase signs appended to ``w`` (two channels).

    With an angle, both ways of switching (:data:`Switching`) are tried and the one with
    the smaller one-step residual is kept.

    Parameters
    ----------
    episodes : sequence of Trajectory
        The logs (n = 2).
    electrical_speed : float or None
        ``w_e``, rad/s, to compute the angle of a log without an angle column.
    shift : int
        The alignment of the logged inputs (for the offset's fit).

    Returns
    -------
    DeadTimeChannels
    """
    angles = [episode.angle for episode in episodes if episode.angle is not None]
    if len(angles) == len(episodes):
        for episode, angle in zip(episodes, angles, strict=True):
            check_angle(angle, episode.t, electrical_speed)
        angles = [read_angle(angle) for angle in angles]  # an encoder's, within its count
        model: DeadTimeModel = "phase signs"
    elif electrical_speed is not None:
        angles = [
            electrical_speed * (e.t - e.t[0]) + angle_offset(e, electrical_speed, shift)
            for e in episodes
        ]
        model = "speed"
    else:
        floor = _direction_floor([e.x for e in episodes])
        appended = [_appended(e, direction_signs(e.x, floor)) for e in episodes]
        return DeadTimeChannels(appended, "current direction")
    candidates = {
        switching: [signs(e.x, a) for e, a in zip(episodes, angles, strict=True)]
        for switching, signs in SWITCHING_SIGNS.items()
    }
    residuals = {
        switching: sum(_residual(e, s, shift) for e, s in zip(episodes, signs, strict=True))
        for switching, signs in candidates.items()
    }
    switching = min(residuals, key=residuals.__getitem__)
    if model == "phase signs":
        _check_angle_explains(episodes, candidates[switching], shift)
    appended = [_appended(e, s) for e, s in zip(episodes, candidates[switching], strict=True)]
    return DeadTimeChannels(appended, model, angles, switching)


def with_signs_of(channels: DeadTimeChannels, currents: Sequence[Array]) -> DeadTimeChannels:
    """The channels with the signs of other currents at the logs' rows: the fitted model's
    noise-free simulation of them (same angles, same way of switching).

    The measured currents' signs are wrong where a phase current is within the noise of
    zero: the dead-time voltage the channels then carry is off by ``2 v`` on that phase
    for that sample, and the model's simulation carries the current it drives for a time
    constant of the plant. Its output errors are then correlated in time (16-65 times
    the variance white noise gives, on 0.2 s logs of the hardware-like drive, against
    0.8-1.3 with the true signs), which the consistency and structure tests read as an
    effect the model misses. A noise-free simulation's signs are wrong only where the
    true current is within the model's own error of zero.

    Parameters
    ----------
    channels : DeadTimeChannels
        The logs with their channels (an angle: ``"phase signs"`` or ``"speed"``).
    currents : sequence of ndarray, shape (T, 2)
        ``[i_d, i_q]`` at each log's rows, A.

    Returns
    -------
    DeadTimeChannels
    """
    assert channels.angles is not None and channels.switching is not None
    signs = SWITCHING_SIGNS[channels.switching]
    episodes = []
    for episode, x, angle in zip(channels.episodes, currents, channels.angles, strict=True):
        assert episode.w is not None
        q = episode.w.shape[1] - 2
        channel = signs(x, angle)[: episode.w.shape[0]]
        w = np.hstack([episode.w[:, :q], channel])
        episodes.append(Trajectory(t=episode.t, x=episode.x, u=episode.u, w=w, angle=episode.angle))
    return replace(channels, episodes=episodes)
