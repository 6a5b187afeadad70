"""Sampled data of a plant: the only thing the learners see.

A :class:`Trajectory` holds N samples (N + 1 sample times) of a plant
``x' = A x + B u + D w``:

- ``t`` (N + 1,): strictly increasing sample times, s, relative to the first sample
  (``t[0] = 0``: the learners use only differences, and a clock's offset is dropped);
- ``x`` (N + 1, n): the state at each sample time;
- ``u`` (N, m): the input, ``u[k]`` held over ``[t[k], t[k+1])`` (zero-order hold);
- ``w`` (N + 1, q) or (N, q), optional: the exogenous signal;
- ``angle`` (N + 1,), optional: the electrical rotor angle at each sample time, rad
  (a drive knows it; the learners use it to model an inverter's dead time from the phase
  currents' signs, :mod:`selftune.learn.evidence._dead_time`).

What ``w`` means depends on the exosystem matrix E that the learner is given:

- ``E = 0``: ``w[k]`` is held over ``[t[k], t[k+1])`` like ``u`` (a digital reference
  that may step at sample instants); a last row, if present, is unused.
- ``E != 0``: ``w[k]`` is the exosystem state ``w' = E w`` sampled at ``t[k]``; all
  N + 1 rows are needed.

File formats (CSV and NPZ) live in :mod:`selftune.learn.data._io`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ...core import Array, first_non_increasing, positive_integer
from ...core._validation import check_time_resolution
from ...errors import InputError

__all__ = ["Trajectory", "as_trajectories"]


def _as_2d(value: ArrayLike, name: str) -> Array:
    try:
        array = np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"Trajectory.{name}: not numeric ({exc})") from None
    if array.ndim == 1:
        array = array.reshape(-1, 1)
    if array.ndim != 2:
        raise InputError(
            f"Trajectory.{name}: expected a 2-D array (samples x channels), got shape {array.shape}"
        )
    return array


def _check_finite(array: Array, name: str) -> None:
    bad = ~np.isfinite(array)
    if np.any(bad):
        row = int(np.argwhere(bad)[0][0])
        raise InputError(f"Trajectory.{name}: NaN or infinite value at sample {row}")


@dataclass(frozen=True, init=False)
class Trajectory:
    """Samples of a plant's state, input and exogenous signal (SI units).

    Parameters
    ----------
    t : array_like, shape (N + 1,)
        Sample times, s, strictly increasing; stored relative to the first
        (``t - t[0]``). The numbers they are given in must resolve the sampling steps
        (:func:`~selftune.core._validation.check_time_resolution`): a clock's offset of
        1e9 s leaves float64 times only 1.2e-7 s apart.
    x : array_like, shape (N + 1, n)
        State at each sample time.
    u : array_like, shape (N, m) or (N + 1, m)
        Input held over each sample; a last row (N + 1 rows) is dropped.
    w : array_like, shape (N + 1, q) or (N, q), optional
        Exogenous signal at each sample time (see the module docstring).
    angle : array_like, shape (N + 1,), optional
        Electrical rotor angle at each sample time, rad (for a dq log: what turns dq
        currents into phase currents).

    Raises
    ------
    InputError
        If times are not strictly increasing or too coarse for their steps, shapes do not
        match, there is no sample, or a value is not finite; the message names the field
        and the sample.
    """

    t: Array
    x: Array
    u: Array
    w: Array | None
    angle: Array | None

    def __init__(
        self,
        t: ArrayLike,
        x: ArrayLike,
        u: ArrayLike,
        w: ArrayLike | None = None,
        *,
        angle: ArrayLike | None = None,
    ) -> None:
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "u", u)
        object.__setattr__(self, "w", w)
        object.__setattr__(self, "angle", angle)
        self._validate()

    def _validate(self) -> None:
        try:
            t = np.array(self.t, dtype=float)
        except (TypeError, ValueError) as exc:
            raise InputError(f"Trajectory.t: not numeric ({exc})") from None
        if t.ndim != 1:
            raise InputError(f"Trajectory.t: expected a 1-D array, got shape {t.shape}")
        if t.shape[0] < 2:
            raise InputError(
                f"Trajectory.t: need at least 2 sample times (1 sample), got {t.shape[0]}"
            )
        _check_finite(t, "t")
        k = first_non_increasing(t)
        if k is not None:
            raise InputError(
                f"Trajectory.t: times must be strictly increasing, but t[{k + 1}] = "
                f"{t[k + 1]!r} <= t[{k}] = {t[k]!r}"
            )
        given = self.t if isinstance(self.t, np.ndarray) else t  # in its own precision
        check_time_resolution(given, "Trajectory.t")
        t = t - t[0]
        count = t.shape[0]
        x = _as_2d(self.x, "x")
        if x.shape[0] != count:
            raise InputError(
                f"Trajectory.x: expected {count} rows (one per sample time), got {x.shape[0]}"
            )
        u = _as_2d(self.u, "u")
        if u.shape[0] == count:
            u = u[:-1]
        if u.shape[0] != count - 1:
            raise InputError(
                f"Trajectory.u: expected {count - 1} rows (held inputs) or {count}, "
                f"got {u.shape[0]}"
            )
        w = None
        if self.w is not None:
            w = _as_2d(self.w, "w")
            if w.shape[0] not in (count - 1, count):
                raise InputError(
                    f"Trajectory.w: expected {count} rows (one per sample time) or "
                    f"{count - 1} (held values), got {w.shape[0]}"
                )
            if w.shape[1] == 0:
                w = None
        for name, array in (("x", x), ("u", u), ("w", w)):
            if array is not None:
                _check_finite(array, name)
                if array.shape[1] == 0:
                    raise InputError(f"Trajectory.{name}: has no channels")
                array.setflags(write=False)
        t.setflags(write=False)
        object.__setattr__(self, "angle", self._angle(count))
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "u", u)
        object.__setattr__(self, "w", w)

    def _angle(self, count: int) -> Array | None:
        if self.angle is None:
            return None
        try:
            angle = np.array(self.angle, dtype=float)
        except (TypeError, ValueError) as exc:
            raise InputError(f"Trajectory.angle: not numeric ({exc})") from None
        if angle.shape != (count,):
            raise InputError(
                f"Trajectory.angle: expected {count} values (one per sample time), got "
                f"shape {angle.shape}"
            )
        _check_finite(angle.reshape(-1, 1), "angle")
        angle.setflags(write=False)
        return angle

    @property
    def num_samples(self) -> int:
        """N, the number of held-input samples."""
        return int(self.u.shape[0])

    @property
    def n(self) -> int:
        """State dimension."""
        return int(self.x.shape[1])

    @property
    def m(self) -> int:
        """Input dimension."""
        return int(self.u.shape[1])

    @property
    def q(self) -> int:
        """Exogenous-signal dimension (0 without w)."""
        return 0 if self.w is None else int(self.w.shape[1])

    @property
    def duration(self) -> float:
        """``t[-1] - t[0]``, s: how much plant data this is."""
        return float(self.t[-1] - self.t[0])

    def head(self, num_samples: int) -> Trajectory:
        """The first ``num_samples`` samples (``num_samples + 1`` sample times).

        Parameters
        ----------
        num_samples : int
            Number of samples kept, between 1 and :attr:`num_samples`.
        """
        num_samples = positive_integer(num_samples, "head: num_samples")
        if num_samples > self.num_samples:
            raise InputError(
                f"head: num_samples must be between 1 and {self.num_samples}, got {num_samples}"
            )
        stop = num_samples + 1
        w = None if self.w is None else self.w[: min(stop, self.w.shape[0])]
        angle = None if self.angle is None else self.angle[:stop]
        return Trajectory(
            t=self.t[:stop], x=self.x[:stop], u=self.u[:num_samples], w=w, angle=angle
        )


def as_trajectories(data: Trajectory | Sequence[Trajectory]) -> list[Trajectory]:
    """One trajectory or several (episodes) as a non-empty list of consistent trajectories.

    Parameters
    ----------
    data : Trajectory or sequence of Trajectory
        One trajectory, or the episodes.

    Raises
    ------
    InputError
        If the list is empty or the episodes differ in n, m or q.
    """
    given: list[object] = [data] if isinstance(data, Trajectory) else list(data)
    if not given:
        raise InputError("no trajectory given")
    episodes: list[Trajectory] = []
    for index, episode in enumerate(given):
        if not isinstance(episode, Trajectory):
            kind = type(episode).__name__
            raise InputError(f"episode {index}: expected a Trajectory, got {kind}")
        first = episodes[0] if episodes else episode
        if (episode.n, episode.m, episode.q) != (first.n, first.m, first.q):
            raise InputError(
                f"episode {index}: dimensions (n, m, q) = {(episode.n, episode.m, episode.q)} "
                f"differ from episode 0's {(first.n, first.m, first.q)}"
            )
        episodes.append(episode)
    return episodes
