"""Which voltage acted during which sample: the alignment of a log, stated and checked.

A drive computes the voltage at sample k from the currents measured at ``t_k`` and applies
it ``d`` samples later (its computation delay), over ``[t_(k+d), t_(k+d+1))``. A log may
hold, in row k, the voltage APPLIED during sample k (``logged_input = "applied"``, the
default) or the voltage COMMANDED at sample k (``"commanded"``, the most common logging
with a computation delay). Both are one sequence shifted: the voltage applied during
sample k is in row ``k - s`` of the log, with the shift ``s = 0`` for an applied log and
``s = d`` for a commanded one.

The data show the shift: only the right one makes ``x_(k+1) = Ad x_k + Bd a_k + Ed w_k``
hold (:mod:`._discrete_model`); a wrong one leaves a residual that no noise explains,
whatever method then learns from the data. :func:`check_alignment` fits every shift from
-1 to +3, compares the stated one with the best, and either confirms it, uses the best
(``logged_input = "auto"``), or raises :class:`~selftune.errors.MisalignedLog` naming
the shift the data show and the likely logging mistake.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from ...core import Array, positive_integer
from ...errors import InputError, MisalignedLog, SamplingJitter, TooShort
from ..data._trajectory import Trajectory, as_trajectories
from ._discrete_model import DiscreteModel, Transitions, fit_discrete_model

__all__ = [
    "CANDIDATE_SHIFTS",
    "Alignment",
    "LoggedInput",
    "aligned_transitions",
    "applied_inputs",
    "check_alignment",
    "sampling_period",
    "stated_shift",
]

LoggedInput = Literal["applied", "commanded", "auto"]

#: The shifts the check compares: a log one sample late (-1) to three samples early.
CANDIDATE_SHIFTS = (-1, 0, 1, 2, 3)

#: Relative spread of the sampling steps accepted as a uniform sampling period.
SAMPLING_JITTER = 1e-6


def sampling_period(episodes: Sequence[Trajectory]) -> float:
    """The common sampling period of the episodes, s.

    Digital learning needs a uniform period: every step within :data:`SAMPLING_JITTER`
    (relative) of it, in every episode.

    Parameters
    ----------
    episodes : sequence of Trajectory
        The logs.

    Returns
    -------
    float

    Raises
    ------
    InputError
        If the steps are not uniform or differ between episodes.
    """
    periods = []
    for index, episode in enumerate(episodes):
        steps = np.diff(episode.t)
        h = float(steps.mean())
        spread = float(np.max(np.abs(steps - h))) / h
        if spread > SAMPLING_JITTER:
            raise SamplingJitter(
                f"episode {index}: the sampling steps vary by {spread:.2g} of the period "
                f"{h:.6g} s; digital learning needs a uniform sampling period",
                episode=index,
                spread=spread,
                max_spread=SAMPLING_JITTER,
            )
        periods.append(h)
    if max(periods) - min(periods) > SAMPLING_JITTER * max(periods):
        raise InputError(f"the episodes have different sampling periods: {periods}")
    return float(np.mean(periods))


def stated_shift(logged_input: LoggedInput, input_delay: int) -> int | None:
    """The shift a configuration states: 0 for an applied log, ``d`` for a commanded one,
    None for ``"auto"`` (read it off the data).

    Parameters
    ----------
    logged_input : {"applied", "commanded", "auto"}
        What row k of the log holds.
    input_delay : int
        d, the drive's computation delay in samples.
    """
    positive_integer(input_delay, "input_delay", minimum=0)
    if logged_input == "applied":
        return 0
    if logged_input == "commanded":
        return int(input_delay)
    if logged_input == "auto":
        return None
    raise InputError(
        f"logged_input: must be 'applied', 'commanded' or 'auto', got {logged_input!r}"
    )


def applied_inputs(episode: Trajectory, shift: int) -> tuple[Array, int]:
    """The applied inputs ``a_k`` read off a log with the given shift, and the first k.

    ``a_k = u[k - shift]`` for every k at which that row exists; returns the array of
    those ``a_k`` (consecutive k) and the first k.

    Parameters
    ----------
    episode : Trajectory
        The log.
    shift : int
        The voltage applied during sample k is in row ``k - shift``.
    """
    N = episode.num_samples
    first, last = max(0, shift), min(N - 1, N - 1 + shift)
    if last < first:
        raise TooShort(f"the log has {N} samples, too few for a shift of {shift}", samples=N)
    return episode.u[first - shift : last - shift + 1], first


def _w_held(episode: Trajectory) -> Array:
    return np.zeros((episode.num_samples, 0)) if episode.w is None else episode.w


def aligned_transitions(
    data: Trajectory | Sequence[Trajectory], shift: int, span: tuple[int, int] = (0, 0)
) -> Transitions:
    """The transitions ``(x_k, a_k, w_k) -> x_(k+1)`` of the logs with the given shift.

    Parameters
    ----------
    data : Trajectory or sequence of Trajectory
        The logs; ``w`` (if any) is held over each sample.
    shift : int
        The voltage applied during sample k is in row ``k - shift`` of the log.
    span : (int, int)
        ``(low, high)``: use only the k at which every shift from ``low`` to ``high`` has
        a row, so that fits of different shifts see the same transitions.

    Returns
    -------
    Transitions
    """
    episodes = as_trajectories(data)
    h = sampling_period(episodes)
    parts: list[tuple[Array, ...]] = []
    for episode in episodes:
        N = episode.num_samples
        first = max(0, shift, span[1])
        last = min(N - 1, N - 1 + shift, N - 1 + span[0])
        if last < first:
            continue
        k = np.arange(first, last + 1)
        w = _w_held(episode)
        parts.append((episode.x[k], episode.x[k + 1], episode.u[k - shift], w[k]))
    if not parts:
        raise TooShort(f"the logs are too short for a shift of {shift} samples")
    x, x_next, a, w = (np.concatenate([part[i] for part in parts]) for i in range(4))
    return Transitions(x=x, x_next=x_next, a=a, w=w, h=h)


@dataclass(frozen=True)
class Alignment:
    """The alignment of logged inputs used to learn, and what the data said about it.

    Attributes
    ----------
    logged_input : {"applied", "commanded", "auto"}
        What the configuration states the log holds.
    input_delay : int
        d, the drive's computation delay stated, samples.
    shift : int
        The shift used: the voltage applied during sample k is in row ``k - shift``.
    detected_shift : int
        The shift that explains the data best.
    residuals : dict of int to float
        Relative one-step residual of the exact discrete model for each candidate shift.
    ratio : float
        Residual of the shift used over the best other shift's (above 1: the data prefer
        the shift used; near 1: the data hardly tell them apart).
    model : DiscreteModel
        The discrete model fitted with the shift used.
    """

    logged_input: str
    input_delay: int
    shift: int
    detected_shift: int
    residuals: dict[int, float] = field(repr=False)
    ratio: float
    model: DiscreteModel = field(repr=False)

    @property
    def distinct(self) -> bool:
        """Whether the data tell the shift used from every other clearly (ratio > 2)."""
        return self.ratio > 2.0


def _residuals(
    episodes: list[Trajectory], candidates: Sequence[int]
) -> tuple[dict[int, float], dict[int, DiscreteModel]]:
    span = (min(candidates), max(candidates))
    residuals: dict[int, float] = {}
    models: dict[int, DiscreteModel] = {}
    for shift in candidates:
        model = fit_discrete_model(aligned_transitions(episodes, shift, span))
        residuals[shift] = float(np.linalg.norm(model.residual_rms))
        models[shift] = model
    return residuals, models


def _threshold(transitions: int) -> float:
    """The factor by which the stated shift's residual may exceed the best one's before
    the data are said to contradict it: sampling noise of a residual variance estimate
    from T transitions is about sqrt(2 / T); the margin is far above that."""
    return 1.0 + max(0.1, 8.0 / np.sqrt(max(transitions, 1)))


def check_alignment(
    data: Trajectory | Sequence[Trajectory],
    logged_input: LoggedInput = "applied",
    input_delay: int = 0,
    candidates: Sequence[int] = CANDIDATE_SHIFTS,
) -> Alignment:
    """Check the stated alignment of the logged inputs against the data (or detect it).

    Parameters
    ----------
    data : Trajectory or sequence of Trajectory
        The logs (uniform sampling; ``w`` held over each sample if present).
    logged_input : {"applied", "commanded", "auto"}
        What row k of the log holds: the voltage applied during sample k, the one
        commanded at sample k (applied ``input_delay`` samples later), or ``"auto"``: use
        the shift that fits the data best.
    input_delay : int
        d, the drive's computation delay, samples.
    candidates : sequence of int
        The shifts compared (the stated one is added if missing).

    Returns
    -------
    Alignment

    Raises
    ------
    MisalignedLog
        If the data contradict the stated alignment (a ConsistencyError): the message names
        the shift the data show and the likely logging mistake.
    ExcitationError
        If the data do not excite the model enough to fit it.
    """
    episodes = as_trajectories(data)
    stated = stated_shift(logged_input, input_delay)
    shifts = sorted(set(candidates) | ({stated} if stated is not None else set()))
    residuals, models = _residuals(episodes, shifts)
    best = min(residuals, key=lambda shift: residuals[shift])
    shift = best if stated is None else stated
    others = [value for key, value in residuals.items() if key != shift]
    floor = max(residuals[shift], 1e-300)
    ratio = min(others) / floor if others else float("inf")
    if stated is not None and best != stated:
        worse = residuals[stated] / max(residuals[best], 1e-300)
        if worse > _threshold(models[best].transitions):
            raise MisalignedLog(
                _misalignment_message(stated, best, input_delay, worse, residuals),
                key="input_delay" if stated > 0 and best > 0 else "logged_input",
                stated_shift=stated,
                found_shift=best,
            )
    return Alignment(
        logged_input=logged_input,
        input_delay=int(input_delay),
        shift=shift,
        detected_shift=best,
        residuals=residuals,
        ratio=float(ratio),
        model=models[shift],
    )


def _misalignment_message(
    stated: int, best: int, input_delay: int, worse: float, residuals: dict[int, float]
) -> str:
    """Say which shift the data show, and the likely logging cause and remedy."""
    lag = best - stated
    when = "later" if lag > 0 else "earlier"
    samples = f"{abs(lag)} sample{'s' if abs(lag) != 1 else ''}"
    if stated == 0 and best > 0:
        cause = (
            "the log holds the voltages commanded at each sample, which the drive applies "
            f"{best} sample(s) later (its computation delay); set logged_input = "
            f'"commanded" and input_delay = {best}, or logged_input = "auto"'
        )
    elif best == 0:
        cause = (
            "the log holds the voltages applied during each sample; set logged_input = "
            '"applied" (or "auto")'
        )
    elif best < 0:
        cause = (
            "each row holds the voltage applied during the previous sample (the log is "
            f"{-best} sample(s) late): move the voltage columns up by {-best} row(s), or "
            'set logged_input = "auto"'
        )
    else:
        cause = (
            f"the drive's computation delay is {best} sample(s), not {input_delay}: set "
            f'input_delay = {best}, or logged_input = "auto"'
        )
    return (
        f"the logged voltages act {samples} {when} than the configuration says: the exact "
        f"discrete model fits the data with a shift of {best} sample(s) (one-step residual "
        f"{residuals[best]:.3g}) and leaves {worse:.3g} times that residual with the stated "
        f"shift of {stated} ({residuals[stated]:.3g}); {cause}"
    )
