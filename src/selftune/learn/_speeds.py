"""A log over several held speeds: cut where its speed changes, each part learned at its
own speed with the motor's structure, the motor's parameters combined.

At a held speed the current loop's plant is ``A(omega) = A_0 + omega A_1``; R_s, the
inductances and the flux do not depend on the speed, so the parts of one log are one
motor seen at several speeds. The speed is the log's angle column's change over blocks
of 10 ms (the electrical speed, rad/s); a new part starts where it leaves a band about
the part's (:func:`speed_segments`), so that a drive's encoder counts and speed ripple
read as the speed held, and the changes between held speeds are left out; each part's
speed is the slope of the least-squares line through its angle, with its error
(:func:`speed_errors`; an encoder's counts, :mod:`.evidence._encoder`). Each part is
learned by :func:`~selftune.learn.learn_controller` with the options' structure at that
part's speed (its verdict on each); the parts' parameters are combined by their inverse
variances (:func:`combined_estimate`). The data cover the parts' lowest to highest
speed. The top speed's part passes the whole verdict;
a part below it refused only because its own law is too imprecise (``TooLittleData``) is
learned again with that gate open, every other check kept, and counts by its variance
(:func:`_imprecise_part`). A part at standstill is not learned (its back-EMF channel
``w_1`` is zero: the structure's flux is not in it, and the data's rank says so) but
counts as covered: R_s and the inductances do not depend on the speed, and the plant at
standstill is the one learned at the others with ``omega = 0``.

Not done: one fit over a log whose speed changes every sample (a linear ramp). The
output-error fit simulates one time-invariant sampled plant over a log; a speed per
sample needs a plant per sample, in its simulation, its sensitivities, its bootstrap and
the structure's and the verdict's checks. Such a log is refused, saying so.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from dataclasses import dataclass, fields, replace

import numpy as np

from ..core import Array
from ..errors import (
    ConfigurationMismatch,
    InputError,
    ModelMissesEffect,
    SelftuneError,
    TooLittleData,
)
from ._pipeline import learn_controller
from ._problem import LearningOptions, LearningProblem
from ._result import LearnedController
from .data._trajectory import Trajectory
from .evidence._dead_time import against_back_emf, check_angle
from .evidence._encoder import angle_count, fitted_line, rounding_cycles, unwrapped
from .verdict._quality import MotorEstimate
from .verdict._verdict import motor_estimate

__all__ = [
    "HELD_BAND",
    "MIN_SEGMENT",
    "SpeedsLearned",
    "combined_estimate",
    "learn_over_speeds",
    "speed_errors",
    "speed_segments",
    "top_part",
]

#: How far a held speed may wander, a share of the log's largest speed: a block's mean
#: speed further than this from its part's mean starts a new part. It is absolute (the
#: plant's error is the coupling ``(w - w_part) L i``, the same at every speed), and
#: admits what a drive's held speed does: an encoder's quantized angle (a 16,384-count
#: encoder on 4 pole pairs steps the angle by 1.5 mrad, so its speed over one 10 ms block
#: is known to 0.15 rad/s) and the speed loop's ripple.
HELD_BAND = 0.02

#: A part slower than this share of the log's largest speed is standstill (its speed
#: within an encoder count or two of zero): not learned, covered (see the module).
STANDSTILL = 1e-3

#: The shortest part at a held speed that is learned, s (four of the commissioning's
#: 10 ms current steps).
MIN_SEGMENT = 0.04

#: The blocks the speed is judged over, a share of :data:`MIN_SEGMENT` (10 ms of it).
BLOCK_SHARE = 0.25

#: The most of a log that may lie between its held speeds (the speed changing), a share
#: of its samples; more is a ramp, refused.
MOST_BETWEEN = 0.25


#: The band's least width in standard deviations of the blocks' speeds about the speed
#: they hold (an encoder's counts over a block: 4,096 counts a turn on 20 pole pairs read
#: a 10 ms block's speed to 3 rad/s, more than 2% of a 40 rad/s top speed).
NOISE_BANDS = 4.0


#: The band's least width in an encoder's counts over a block (:func:`angle_count`): a
#: held speed's blocks move by neighbouring whole counts, within one of their mean. The
#: blocks' scatter (:func:`_block_noise`) does not say so where one block in many has the
#: other count (at 0.34 counts a row, 34 counts a block and one in twenty-five 35): the
#: median of their second differences is zero, and a 4,096-count encoder's held 47 rad/s
#: on 9 pole pairs was cut into five parts.
COUNT_BANDS = 1.5


def _block_noise(angle: Array, edges: Array, blocks: Array, t: Array) -> float:
    """The standard deviation of the blocks' speeds about the speed they hold, rad/s.

    Of their second differences (robustly, by their median), which a speed held or
    changing linearly leaves at zero (a ramp does not widen the band), and white noise of
    deviation s makes ``sqrt(6) s``; at most what the angle's resolution explains (its
    smallest step between samples, ``q``, read to ``q / sqrt(12)`` at each end of a
    block), so that held speeds changing every other block (a quick staircase) are not
    taken for noise."""
    if blocks.size < 3:
        return 0.0
    scatter = float(1.4826 * np.median(np.abs(np.diff(blocks, 2))) / np.sqrt(6.0))
    steps = np.abs(np.diff(angle))
    moving = steps[steps > 0.0]
    if moving.size == 0:
        return 0.0
    block = float(t[edges[1]] - t[edges[0]])
    resolution = float(np.min(moving)) * np.sqrt(2.0 / 12.0) / block
    return min(scatter, resolution)


#: The most a held part's speed may trend over its length (its blocks' least-squares
#: line's change), a share of the band: a linear ramp's parts trend by about twice the
#: band (a part ends where a block leaves the band about the part's mean), so none is
#: held; a speed held, with an encoder's counts or a ripple about it, trends by the
#: noise alone.
MOST_TREND = 0.5


def _trend(times: Array, speeds: Array) -> float:
    """The change of the least-squares line through ``speeds`` (rad/s) at ``times`` (s)
    over their span, rad/s (zero for one point)."""
    if times.size < 2:
        return 0.0
    return abs(fitted_line(times, speeds)[2]) * float(times[-1] - times[0])


def _blocks(log: Trajectory) -> tuple[Array, Array, Array]:
    """The log's unwrapped angle from 0 (rad), its blocks' edges (sample indices; the
    last block takes a short tail) and their speeds (rad/s): the angle's change over each
    block by its length (see :func:`speed_segments`)."""
    assert log.angle is not None
    periods = np.diff(log.t)
    angle = unwrapped(log.angle) - float(log.angle[0])
    count = periods.size
    size = max(1, round(BLOCK_SHARE * MIN_SEGMENT / float(np.median(periods))))
    edges = np.append(np.arange(0, count, size), count)
    if edges.size > 2 and edges[-1] - edges[-2] < size // 2:  # a short tail joins the last
        edges = np.delete(edges, -2)
    return angle, edges, np.diff(angle[edges]) / np.diff(log.t[edges])


def speed_errors(log: Trajectory, segments: Sequence[tuple[int, int, float]]) -> list[float]:
    """The standard error of each part's speed, rad/s (:func:`_held_line`).

    Parameters
    ----------
    log : Trajectory
        The log, with its angle column.
    segments : sequence of (first, last, electrical speed)
        Its parts (:func:`speed_segments`).
    """
    assert log.angle is not None
    angle, _, _ = _blocks(log)
    count = angle_count(log.angle)
    return [_held_line(angle, log.t, first, last, count)[1] for first, last, _ in segments]


def _held_line(
    angle: Array, t: Array, first: int, last: int, count: float | None
) -> tuple[float, float]:
    """A part's speed and its standard error, rad/s: the slope of the least-squares line
    through its unwrapped ``angle`` (rad) at rows ``first .. last`` (row ``last`` ends
    the part's last sample); ``count``: the log's encoder's (rad, of its angle as logged:
    unwrapped, a wrap's step is no whole count), or None.

    The error is the slope's as the residuals about the line scatter (independent from
    row to row), and an encoder's: its counts' rounding errors are a sawtooth of the true
    angle, one period a count, which leaves the slope off by about ``q / (2 n T)`` where
    the rounding runs through ``n`` counts ``q`` over the part's length ``T``
    (:func:`~.evidence._encoder.rounding_cycles`; measured on rounded lines of random
    offsets and slow speeds: 0.44, 0.21, 0.065 and 0.031 times ``q / T`` at 1, 2, 5 and
    10 counts, where the residuals' own estimate said 0.014). Read from the two ends
    instead (the angle's change over the part), the part's speed was off by ``q / T``:
    on a 4,096-count encoder with 9 pole pairs at 56 rad/s over 0.5 s, 1.7e-4 of it,
    which left the flux at 6 of its standard errors.
    """
    rows = slice(first, last + 1)
    middle, mean, slope = fitted_line(t[rows], angle[rows])
    times = t[rows] - middle
    spread = float(times @ times)
    residual = angle[rows] - mean - slope * times
    white = float(np.sqrt(residual @ residual / max(times.size - 2, 1) / spread))
    if count is None:  # not an encoder's: no rounding
        return slope, white
    span = float(times[-1] - times[0])
    cycles = rounding_cycles(angle[rows], count)
    return slope, float(np.hypot(white, count / (2.0 * span * max(cycles, 0.5))))


def speed_segments(log: Trajectory) -> list[tuple[int, int, float]]:
    """The log's parts at held speeds, cut where the speed of its angle column changes.

    The speed is judged over consecutive blocks of :data:`BLOCK_SHARE` of
    :data:`MIN_SEGMENT`: the angle's change over a block by its length, so that an
    encoder's quantized angle and a speed loop's ripple read as the speed they hold. A
    block further than :data:`HELD_BAND` of the log's largest speed (or
    :data:`NOISE_BANDS` times the blocks' own scatter, :func:`_block_noise`, or
    :data:`COUNT_BANDS` of an encoder's counts over a block, where that is wider) from
    its part's mean starts a new part. A part shorter than :data:`MIN_SEGMENT`, or whose
    speed trends by more than :data:`MOST_TREND` of the band over it, is the speed
    changing from one held speed to the next, and is left out, up to
    :data:`MOST_BETWEEN` of the log. The angle is checked first (in rad, advancing
    smoothly: :func:`~selftune.learn.evidence._dead_time.check_angle`). A log of exactly
    held speeds whose changes fall on block edges is cut exactly there.

    Parameters
    ----------
    log : Trajectory
        A log with an angle column (the electrical rotor angle, rad).

    Returns
    -------
    list of (first, last, electrical speed)
        Samples ``first .. last - 1`` at one speed (over ``[t_first, t_last)``) and that
        speed, rad/s (the slope of the least-squares line through the part's angle,
        :func:`_held_line`).

    Raises
    ------
    InputError
        Without an angle column, or when no speed holds for :data:`MIN_SEGMENT` or more
        than :data:`MOST_BETWEEN` of the log is between held speeds (a speed that changes
        every sample: a linear ramp, which the fit cannot take).
    """
    if log.angle is None:
        raise InputError("angle: a log over several speeds needs its angle column theta")
    check_angle(log.angle, log.t, None)  # in rad, advancing smoothly: else said so here
    angle, edges, blocks = _blocks(log)
    count = edges[-1]
    encoder = angle_count(log.angle)
    block = float(log.t[edges[1]] - log.t[edges[0]])
    band = max(
        HELD_BAND * float(np.max(np.abs(blocks))),
        NOISE_BANDS * _block_noise(angle, edges, blocks, log.t),
        0.0 if encoder is None else COUNT_BANDS * encoder / block,
        1e-300,
    )
    groups: list[list[int]] = [[0]]
    for index in range(1, blocks.size):
        if abs(blocks[index] - float(np.mean(blocks[groups[-1]]))) > band:
            groups.append([])
        groups[-1].append(index)
    parts = [(int(edges[group[0]]), int(edges[group[-1] + 1])) for group in groups]
    middles = 0.5 * (log.t[edges[:-1]] + log.t[edges[1:]])
    held = [
        (a, b)
        for (a, b), group in zip(parts, groups, strict=True)
        if log.t[b] - log.t[a] >= MIN_SEGMENT * (1.0 - 1e-9)
        and _trend(middles[group], blocks[group]) <= MOST_TREND * band
    ]
    between = count - sum(b - a for a, b in held)
    if not held or between > MOST_BETWEEN * count:
        raise InputError(
            f"angle: the speed holds (within {band:.3g} rad/s, without trending) for at least "
            f"{MIN_SEGMENT:g} s at a time over {1 - between / count:.0%} of the log, and "
            f"{1 - MOST_BETWEEN:.0%} is needed: the identification fits one plant at a held "
            "speed per part and cannot fit a speed that changes every sample (a ramp); log a "
            "staircase of held speeds"
        )
    return [(a, b, _held_line(angle, log.t, a, b, encoder)[0]) for a, b in held]


def _part(log: Trajectory, first: int, last: int) -> Trajectory:
    """Samples ``first .. last - 1`` of the log: row ``last`` starts the next speed's
    sample, and its reference is that speed's (``w_1 = p speed phi_assumed``; kept, it
    moved the flux read off the part's mean ``w_1`` by 0.4% at 5% and 100% of a speed)."""
    rows = slice(first, last)
    return Trajectory(
        t=log.t[rows], x=log.x[rows], u=log.u[first : last - 1],
        w=None if log.w is None else log.w[rows],
        angle=None if log.angle is None else log.angle[rows],
    )  # fmt: skip


def combined_estimate(estimates: list[MotorEstimate]) -> MotorEstimate:
    """One motor's estimates combined by their inverse variances, parameter by parameter
    (each standard error ``1 / sqrt(sum 1 / se^2)``).

    Parameters
    ----------
    estimates : list of MotorEstimate
        Of one kind (all surface or all interior; with or without the dead-time voltage).
    """
    values: dict[str, float | None] = {}
    for item in fields(MotorEstimate):
        name = item.name
        if name.endswith("_se") or getattr(estimates[0], name) is None:
            continue
        estimate = np.array([getattr(e, name) for e in estimates], dtype=float)
        errors = np.array([getattr(e, f"{name}_se") for e in estimates], dtype=float)
        weights = 1.0 / np.maximum(errors, 1e-300) ** 2
        values[name] = float(np.sum(weights * estimate) / np.sum(weights))
        values[f"{name}_se"] = float(1.0 / np.sqrt(np.sum(weights)))
    return replace(estimates[0], **values)  # type: ignore[arg-type]


#: The precision limit of a part below the top speed learned again after its law was
#: refused as too imprecise (:func:`_imprecise_part`): not gated.
UNGATED = sys.float_info.max


def _imprecise_part(
    part: Trajectory,
    problem: LearningProblem,
    K0: Array,
    options: LearningOptions,
    imprecise: TooLittleData,
) -> LearnedController:
    """A part below the top speed whose own law is too imprecise, learned again with its
    precision not gated (every other check of the verdict kept), with a note: its
    parameters count by their variance in :func:`combined_estimate`, and its law is not
    what the schedule uses (the schedule is designed on the combined motor).

    At 5% of the rated speed the back-EMF and the cross-coupling are small, and the
    feedforward U of a part's own law is small with them: on 5 of 60 motors drawn at
    random across the issue's range (hardware-like drive, docs/schedule.md) that part's
    U had a relative standard error of 30-39% against the 25% limit, while the top
    speed's part passed and the motor's parameters were known to 0.1%; 4 of them are
    learned so, within one standard error.
    """
    learned = learn_controller(part, problem, K0, replace(options, max_relative_error=UNGATED))
    assert learned.quality is not None
    note = (
        f"this part's own law is too imprecise ({imprecise}); its parameters count by their "
        "variance in the combined motor, and the schedule is designed on that motor"
    )
    quality = replace(learned.quality, notes=(*learned.quality.notes, note))
    return replace(learned, quality=quality)


@dataclass(frozen=True)
class SpeedsLearned:
    """A log over several held speeds, learned part by part.

    Attributes
    ----------
    parts : tuple of (float, LearnedController)
        Each held speed (electrical, rad/s) and the law learned there, with its verdict
        and its identified motor (``quality.motor``).
    motor : MotorEstimate or None
        The parts' motors combined (:func:`combined_estimate`); None from ADP, which
        learns no motor.
    covered : (float, float)
        The lowest and highest electrical speed of the data, rad/s.
    standstill : bool
        Whether the log has a part at standstill, not learned (its back-EMF channel is
        zero, so the flux is not in it) but covered: the motor learned at the other
        speeds is the plant there too.
    """

    parts: tuple[tuple[float, LearnedController], ...]
    motor: MotorEstimate | None
    covered: tuple[float, float]
    standstill: bool = False

    @property
    def top(self) -> tuple[float, LearnedController]:
        """The part at the highest speed in magnitude (:func:`top_part`)."""
        return top_part(self.parts)


def top_part(
    parts: Sequence[tuple[float, LearnedController]],
) -> tuple[float, LearnedController]:
    """The part at the highest speed in magnitude: its electrical speed (rad/s) and its
    law (the single-speed law a schedule is judged beside, and a report's law).

    Parameters
    ----------
    parts : sequence of (float, LearnedController)
        Held speeds (electrical, rad/s) and the laws learned there.
    """
    return max(parts, key=lambda part: abs(part[0]))


def _others(learned: list[float], refused: list[tuple[float, SelftuneError]]) -> str:
    """What the held speeds learned beside the refused ones would cover (a refusal's
    end): the speeds above every refused one, if those are the lowest."""
    if not learned:
        return ""
    named = ", ".join(f"{speed:g}" for speed in learned)
    others = "" if len(refused) == 1 else f" (and at {len(refused) - 1} more)"
    low = min(abs(speed) for speed in learned)
    if max(abs(speed) for speed, _ in refused) < low:
        return (
            f"{others}; the held speeds above it were learned ({named} rad/s): a schedule "
            f"from {low:g} rad/s (electrical) up is covered without it"
        )
    return f"{others}; learned at {named} rad/s (electrical)"


def learn_over_speeds(
    log: Trajectory, problem: LearningProblem, K0: Array, options: LearningOptions
) -> SpeedsLearned:
    """Learn each held speed's part of ``log`` at its own speed, and combine the motors
    (see the module docstring).

    Parameters
    ----------
    log : Trajectory
        The log, with its angle column.
    problem : LearningProblem
        What the learner knows.
    K0 : ndarray
        The feedback the log ran under.
    options : LearningOptions
        How to learn: identify-then-design with a motor's structure (its
        ``electrical_speed`` is each part's), or the paper's ADP (``method = "adp"``),
        each part's law learned from that part alone (no motor combined; a part too
        imprecise for its own law is refused, since that law is the one scheduled).

    Raises
    ------
    InputError
        If identify-then-design has no motor structure, :func:`speed_segments` refuses
        the log, or a part's angle turns against its back-EMF reference ``w_1``
        (:func:`_check_sense`).
    SelftuneError
        The learner's refusal of a part, naming its speed (of a part below the top speed,
        not for its own law's precision alone), and the speeds the other parts were
        learned at: every part is tried first.
    """
    adp = options.method == "adp"
    if options.structure == "none" and not adp:
        raise InputError(
            'structure: a log over several speeds is learned by method = "identify" with a '
            'motor\'s structure ("spmsm" or "ipmsm"), whose parameters do not depend on '
            'the speed, or by method = "adp", the law at each held speed'
        )
    parts: list[tuple[float, LearnedController]] = []
    relative: list[float] = []  # each learned part's speed's relative standard error
    refused: list[tuple[float, SelftuneError]] = []
    segments = speed_segments(log)
    errors = dict(zip(segments, speed_errors(log, segments), strict=True))
    top = max(abs(speed) for _, _, speed in segments)
    if top == 0.0:
        raise InputError(
            "angle: the log holds the rotor at standstill only; the flux is learned from "
            "the back-EMF of a turning rotor: log held speeds above zero"
        )
    if not adp:  # the motor's form: w_1 = p speed phi_assumed
        _check_sense(log, segments, top)
    standstill = False
    for first, last, speed in segments:
        if abs(speed) <= STANDSTILL * top:  # no back-EMF: nothing of the flux to learn
            standstill = True
            continue
        part = _part(log, first, last)  # learned with the structure or not at all
        own = replace(options, electrical_speed=speed, compare_without_structure=False)
        try:
            try:
                learned = learn_controller(part, problem, K0, own)
            except TooLittleData as imprecise:
                if abs(speed) == top or adp:  # ADP schedules each part's own law
                    raise
                learned = _imprecise_part(part, problem, K0, own, imprecise)
        except SelftuneError as error:  # every part is tried, so the refusal can say
            refused.append((speed, error))  # which speeds the others would cover
            continue
        parts.append((speed, learned))
        relative.append(errors[(first, last, speed)] / abs(speed))
    if refused:
        speed, refusal = refused[0]
        others = _others([learned_speed for learned_speed, _ in parts], refused)
        told = f"at {speed:g} rad/s (electrical): {refusal}{others}{_angle_hint(refusal)}"
        raise refusal.retold(told) from None
    speeds = [speed for speed, _ in parts] + ([0.0] if standstill else [])
    return SpeedsLearned(
        tuple(parts),
        None if adp else _combined([learned for _, learned in parts], relative),
        (min(speeds), max(speeds)),
        standstill,
    )


def _angle_hint(refusal: SelftuneError) -> str:
    """What a refusal by the model's or the structure's test adds (the parts' speeds are
    the angle column's, and a log whose angle is not the electrical one, p times the
    mechanical, was refused so at every part: its cross-coupling is wrong by that factor),
    or nothing."""
    structure = isinstance(refusal, ConfigurationMismatch) and refusal.key == "structure"
    if not (structure or isinstance(refusal, ModelMissesEffect)):
        return ""
    return (
        "; each part's speed is read off the angle column theta, which must be the "
        "electrical angle (p times the mechanical one)"
    )


def _check_sense(log: Trajectory, segments: Sequence[tuple[int, int, float]], top: float) -> None:
    """Refuse a part whose angle turns against its back-EMF reference: in the motor's form
    ``w_1 = p speed phi_assumed`` has the speed's sign (rad/s, electrical; ``top`` the
    log's largest speed, standstill parts not judged). A drive that counts its angle in the
    other sense would be learned at the opposite speed, its cross-coupling reversed."""
    for first, last, speed in segments:
        if abs(speed) <= STANDSTILL * top:
            continue
        reference = against_back_emf(None if log.w is None else log.w[first:last], speed)
        if reference is not None:
            raise InputError(
                f"angle: turns at {speed:.4g} rad/s (electrical) over rows {first} to "
                f"{last - 1}, where the back-EMF reference w1 (p speed phi) averages "
                f"{reference:.4g}: they count the rotation in opposite senses; negate the "
                "angle column (or w1, whichever has the other sense)"
            )


def _with_speed_error(estimate: MotorEstimate, relative: float) -> MotorEstimate:
    """The estimate with its flux's standard error widened by its part's speed's
    (``phi_pm = kappa w_1 / w_e`` is off by the share ``w_e`` is)."""
    spread = abs(estimate.phi_pm) * relative
    return replace(estimate, phi_pm_se=float(np.hypot(estimate.phi_pm_se, spread)))


def _combined(parts: list[LearnedController], relative: Sequence[float]) -> MotorEstimate:
    """The parts' motors combined (:func:`combined_estimate`) by the fits' own variances;
    where a part's reported standard errors hold more (the dead time's pulses' shift,
    :mod:`.evidence._pulses`), that excess is a bias of one sign at every speed, not
    noise that averages out: the parts' excesses are combined with the same weights as
    the values and added to the combined standard error. Each part's flux counts with
    its speed's error (``relative``, :func:`speed_errors` over the speed), independent
    from part to part: on a 4,096-count encoder, 20 pole pairs at 40 rad/s, the flux was
    0.08-0.1% off at 5 of its standard errors without it."""
    fitted, reported = [], []
    for learned, speed_error in zip(parts, relative, strict=True):
        assert learned.quality is not None and learned.quality.motor is not None
        assert learned.evidence is not None
        own = motor_estimate(learned.evidence)
        assert own is not None  # the reported motor is this one's
        fitted.append(_with_speed_error(own, speed_error))
        reported.append(_with_speed_error(learned.quality.motor, speed_error))
    combined = combined_estimate(fitted)
    widened: dict[str, float] = {}
    for item in fields(MotorEstimate):
        name = item.name
        if not name.endswith("_se") or getattr(combined, name) is None:
            continue
        errors = np.array([getattr(e, name) for e in fitted], dtype=float)
        total = np.array([getattr(e, name) for e in reported], dtype=float)
        weights = 1.0 / np.maximum(errors, 1e-300) ** 2
        excess = np.sqrt(np.maximum(total**2 - errors**2, 0.0))
        shift = float(np.sum(weights * excess) / np.sum(weights))
        widened[name] = float(np.hypot(getattr(combined, name), shift))
    return replace(combined, **widened)
