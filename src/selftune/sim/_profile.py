"""How a motor's parameters move while a drive runs: :class:`ParameterProfile`.

A profile is piecewise linear in time: points ``(t_i, R_s_i, L_s_i, phi_pm_i)`` of
factors on the motor's values, linear between consecutive points, the last held after
the last point. Two points at the same time make a step (a fault): the first is the value
just before, the second the value from that time on (right-continuous). A warm-up of
+40% on R_s and -8% on the flux over 120 s is the two points ``(0, 1, 1, 1)`` and
``(120, 1.4, 1, 0.92)``; a loose connection at 60 s adds ``(60, 1, 1, 1)`` and
``(60, 1.2, 1, 1)``.
The L_s factor scales an interior motor's L_d and L_q both.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from ..core import Array
from ..errors import InputError
from ._checks import as_float_array

__all__ = ["ParameterFactors", "ParameterProfile", "interpolate"]


class ParameterFactors(NamedTuple):
    """Factors on the motor's R_s, L_s and phi_pm (floats, or arrays of one shape)."""

    R_s: Array | float
    L_s: Array | float
    phi_pm: Array | float


def _column(values: ArrayLike, name: str, count: int) -> Array:
    column = as_float_array(values, name)
    if column.shape != (count,):
        raise InputError(f"{name}: expected {count} values (one per point), got {column.shape}")
    return column


@dataclass(frozen=True, init=False)
class ParameterProfile:
    """Factors on a motor's R_s, L_s and phi_pm, piecewise linear in time (see the module).

    Parameters
    ----------
    time : array_like, shape (K,)
        The points' times, s: starting at 0, non-decreasing, at most two at one time (a
        step).
    R_s, phi_pm : array_like, shape (K,)
        Factors on the stator resistance and the magnet flux, positive.
    L_s : array_like, shape (K,), optional
        Factors on the stator inductance, positive (default ones).

    Raises
    ------
    InputError
        ``"row i: key: reason"`` (rows counted from 1) for the first bad point.
    """

    time: Array
    R_s: Array
    L_s: Array
    phi_pm: Array

    def __init__(
        self, time: ArrayLike, R_s: ArrayLike, phi_pm: ArrayLike, L_s: ArrayLike | None = None
    ) -> None:
        times = as_float_array(time, "time")
        if times.ndim != 1 or times.shape[0] == 0:
            raise InputError(f"time: expected one time per point (K,), got shape {times.shape}")
        count = times.shape[0]
        columns = {
            "time": times,
            "R_s": _column(R_s, "R_s", count),
            "L_s": np.ones(count) if L_s is None else _column(L_s, "L_s", count),
            "phi_pm": _column(phi_pm, "phi_pm", count),
        }
        _check_points(columns)
        for name, column in columns.items():
            column = column.copy()
            column.setflags(write=False)
            object.__setattr__(self, name, column)

    @classmethod
    def constant(cls) -> ParameterProfile:
        """The motor's own values throughout (all factors 1)."""
        return cls([0.0], [1.0], [1.0])

    @property
    def breakpoints(self) -> Array:
        """The distinct times of the points, s (where the slope may change or a step lands)."""
        return np.unique(self.time)

    def factors(self, t: ArrayLike) -> ParameterFactors:
        """The factors at times ``t`` (s, >= 0; any shape): linear between points, the
        later point of a step from its time on, the last point's after it.

        Parameters
        ----------
        t : float or array_like
            Times, s.

        Returns
        -------
        ParameterFactors
            Arrays of the shape of ``t``.
        """
        return interpolate(self.time, ParameterFactors(self.R_s, self.L_s, self.phi_pm), t)


def interpolate(times: ArrayLike, points: ParameterFactors, t: ArrayLike) -> ParameterFactors:
    """:meth:`ParameterProfile.factors` of the points ``points`` at ``times`` (sorted; any
    number at one time, the last of them from that time on)."""
    at, times = np.asarray(t, dtype=float), np.asarray(times, dtype=float)
    last = times.shape[0] - 1
    index = np.clip(np.searchsorted(times, at, side="right") - 1, 0, last)
    after = np.minimum(index + 1, last)
    span = times[after] - times[index]
    share = (at - times[index]) / np.where(span > 0.0, span, 1.0)
    share = np.where(span > 0.0, np.clip(share, 0.0, 1.0), 0.0)

    def value(column: Array | float) -> Array:
        values = np.asarray(column, dtype=float)
        return values[index] + share * (values[after] - values[index])

    return ParameterFactors(*(value(column) for column in points))


def _check_points(columns: dict[str, Array]) -> None:
    """The rules of a profile, each error naming the row (from 1) and the key."""
    times = columns["time"]
    for index in range(times.shape[0]):
        row = index + 1
        for name, column in columns.items():  # finite already (as_float_array)
            if name != "time" and column[index] <= 0.0:
                raise InputError(f"row {row}: {name}: must be positive, got {column[index]!r}")
        now = float(times[index])
        if index == 0 and now != 0.0:
            raise InputError(f"row 1: time: must be 0 (the drive's start), got {now!r}")
        if index > 0 and now < times[index - 1]:
            raise InputError(
                f"row {row}: time: {now!r} s is before row {row - 1}'s "
                f"{float(times[index - 1])!r} s (times must not decrease)"
            )
        if index > 1 and now == times[index - 2]:
            raise InputError(
                f"row {row}: time: a third point at {now!r} s (two points at one time make a "
                "step; a third is ambiguous)"
            )
