"""An encoder's angle: whole counts of its resolution, read to better than a count.

A drive logs its encoder's angle as whole counts ``q = 2 pi p / N`` (N counts a mechanical
turn, p pole pairs). The count read is the true angle rounded, off by up to ``q / 2``:
the phase signs of the dead-time model (:mod:`._dead_time`) then switch up to half a count
early or late, and a part's speed read off its two ends is off by up to ``q / T``. Both
left the fit off by several of its standard errors (a 4,096-count encoder on 5 pole
pairs: R_s 2.4% off at 4.3 standard errors). Averaged over a window in which they run
through :data:`AVERAGED_COUNTS` counts (:func:`read_angle`), the rounding errors (a
sawtooth of the true angle, one period a count) mostly cancel, while the angle still
follows the speed's changes slower than that window.
"""

from __future__ import annotations

import math

import numpy as np

from ...core import Array

__all__ = [
    "AVERAGED_COUNTS",
    "angle_count",
    "fitted_line",
    "read_angle",
    "rounding_cycles",
    "unwrapped",
]

#: The counts the angle moves over the window it is averaged on (:func:`read_angle`):
#: what is left of the rounding is about ``q / (8 n)`` for ``n`` counts.
AVERAGED_COUNTS = 16

#: The share of the angle's steps (those not wrapping) that must be whole counts for it
#: to be read as an encoder's.
WHOLE_SHARE = 0.99

#: How near a whole number of counts a step must be, in counts: a log's angle written
#: with 7 significant digits is within 5e-7 rad of its count, so a step within 1e-6 rad,
#: 0.0104 counts of a 65,536-count encoder on one pole pair (at 0.01, 8-15% of such
#: angles were not read as an encoder's). Steps that are not counts do not come near:
#: closer than :data:`DIGITS` they are one (a continuous speed's steps are all one).
COUNT_TOLERANCE = 0.05

#: Steps closer than this (rad) are the same count written with a log's digits (7
#: significant digits of an angle up to pi: 5e-7 rad; an encoder's count is 1e-4 rad at
#: 65,536 counts a turn, 6e-6 at 2**20, where the gap between counts is taken instead).
DIGITS = 1e-5

#: The smallest count read, rad: an encoder of 2**32 counts a turn on one pole pair
#: counts 1.5e-9 rad. An exact angle's steps differ in their last bits (4e-16 rad near
#: pi), which would read as whole counts of one bit.
SMALLEST_COUNT = 1e-9

#: The longest repeating pattern of rows (``Q`` of :func:`rounding_cycles`) whose drift
#: is taken as the rounding's own.
LONGEST_PATTERN = 16


def unwrapped(angle: Array) -> Array:
    """``angle`` (rad) unwrapped from its first value: each step taken within ``(-pi, pi]``.

    Parameters
    ----------
    angle : ndarray, shape (T,)
        An electrical angle, rad.
    """
    steps = np.angle(np.exp(1j * np.diff(angle)))
    return float(angle[0]) + np.concatenate([[0.0], np.cumsum(steps)])


def angle_count(angle: Array) -> float | None:
    """The count ``q`` (rad) the angle steps by whole numbers of, or None where it does
    not (an exact angle, or one that steps by one amount only).

    ``q`` is the smallest gap between the means of the angle's distinct steps (an encoder
    at 8.3 counts a sample steps by 8 and 9 counts; steps closer than :data:`DIGITS`, or
    than a quarter of the largest gap, are one count written with a log's digits, and
    never apart by less than :data:`SMALLEST_COUNT`),
    refined by least squares over the whole steps; at least :data:`WHOLE_SHARE` of the
    steps that do not wrap must be whole numbers of it.

    Parameters
    ----------
    angle : ndarray, shape (T,)
        An electrical angle, rad.
    """
    raw = np.diff(np.asarray(angle, dtype=float))
    steps = raw[np.abs(raw) <= np.pi]  # a wrap's step is not a whole count of q
    if steps.size < 2:
        return None
    ordered = np.sort(steps)
    gaps = np.diff(ordered)
    if float(np.max(gaps)) == 0.0:
        return None
    # gaps between different counts: not a float's last bits (an exact angle's steps)
    apart = max(min(DIGITS, 0.25 * float(np.max(gaps))), SMALLEST_COUNT)
    cluster = np.concatenate([[0], np.cumsum(gaps > apart)])
    centres = np.bincount(cluster, weights=ordered) / np.bincount(cluster)  # one a count
    if centres.size < 2:
        return None
    counts = steps / float(np.min(np.diff(centres)))
    whole = np.abs(counts - np.round(counts)) <= COUNT_TOLERANCE
    if float(np.mean(whole)) < WHOLE_SHARE:
        return None
    # the count that fits the whole steps best (the gap itself is off by a log's digits)
    return float(np.sum(np.abs(steps[whole])) / np.sum(np.abs(np.round(counts[whole]))))


def rounding_cycles(angle: Array, count: float) -> float:
    """How many counts an encoder's rounding errors run through over the angle, as the
    rows sample them.

    At ``r`` counts a row, row k's rounding error is a sawtooth of ``k r`` modulo one
    count. Near a fraction ``P / Q`` its rows fall on ``Q`` points of the sawtooth that
    drift together by ``|Q r - P|`` counts every ``Q`` rows; their mean is a sawtooth of
    ``1 / Q`` of its height, so they count as ``Q`` times the counts they drift through
    (at least half a count: a pattern that does not drift is an offset, which the slope
    does not see). The fewest over ``Q`` up to :data:`LONGEST_PATTERN` is returned.
    Measured on rounded lines of 5,000 rows, the least-squares slope's error was
    ``0.43 q / (n T)`` (root mean square) at ``n`` such counts, near 0, 15, 8.5 and 3.33
    counts a row alike.

    Parameters
    ----------
    angle : ndarray, shape (T,)
        The angle, rad, unwrapped (:func:`unwrapped`), at a held speed.
    count : float
        Its count (:func:`angle_count`), rad.
    """
    rows = max(angle.size - 1, 1)
    per_row = abs(float(angle[-1] - angle[0])) / count / rows
    patterns = np.arange(1, LONGEST_PATTERN + 1)
    multiples = patterns * per_row
    drift = rows * np.abs(multiples - np.round(multiples))  # the pattern's counts
    return float(np.min(patterns * np.maximum(drift, 0.5)))


def read_angle(angle: Array, count: float | None = None) -> Array:
    """An encoder's angle read to better than its count: each row's the mean of the
    unwrapped angle over the rows about it (as many on each side) over which its rounding
    errors run through :data:`AVERAGED_COUNTS` counts; any other angle as it is.

    The rounding errors run through a count every ``1 / d`` rows, ``d`` what
    :func:`rounding_cycles` finds a row (at 4.04 counts a row, every 25 rows: a window of
    a few rows, 16 counts of the angle, left 0.24 of a count of the 0.29 the rounding
    has). The rows nearer an end than half the window read the least-squares line through
    the window at that end. A centred mean, and a line, leave an angle turning at a
    constant speed as it is.

    Parameters
    ----------
    angle : ndarray, shape (T,)
        An electrical angle, rad.
    count : float, optional
        Its encoder's count, rad, where already known (a drive's log read chunk by
        chunk); None: :func:`angle_count` of its steps.

    Returns
    -------
    ndarray, shape (T,)
        The angle read, rad (unwrapped, where it is an encoder's).
    """
    if count is None:
        count = angle_count(angle)
    if count is None:
        return angle
    line = unwrapped(angle)
    distance = rounding_cycles(line, count) / max(line.size - 1, 1)
    longest = (line.size - 1) // 2
    if longest == 0:  # a row or two: nothing to average
        return angle
    half = min(math.ceil(0.5 * AVERAGED_COUNTS / distance), longest)
    rows = np.arange(line.size)
    reach = np.minimum(half, np.minimum(rows, line.size - 1 - rows))
    sums = np.concatenate([[0.0], np.cumsum(line - line[0])])
    read = line[0] + (sums[rows + reach + 1] - sums[rows - reach]) / (2 * reach + 1)
    ends = slice(0, half), slice(line.size - half, line.size)
    fits = slice(0, 2 * half + 1), slice(line.size - 2 * half - 1, line.size)
    at = rows.astype(float)
    for fitted, end in zip(fits, ends, strict=True):
        read[end] = _line_at(at[fitted], line[fitted], at[end])
    return read


def fitted_line(x: Array, y: Array) -> tuple[float, float, float]:
    """The least-squares line through the points ``(x, y)``: the mean of ``x``, the mean
    of ``y`` (the line's value there) and its slope.

    Parameters
    ----------
    x, y : ndarray, shape (T,)
        At least two points, ``x`` not all equal.
    """
    middle, mean = float(np.mean(x)), float(np.mean(y))
    centred = x - middle
    return middle, mean, float(centred @ (y - mean)) / float(centred @ centred)


def _line_at(rows: Array, values: Array, at: Array) -> Array:
    """The least-squares line through ``values`` at ``rows``, at the rows ``at``: the
    rows nearer an end than the window's half read with the whole window, not a shorter
    one (the first row's would be the count as logged)."""
    middle, mean, slope = fitted_line(rows, values)
    return mean + slope * (at - middle)
