"""The levels' inductance standard errors from the inductances' curvature over each
level's log (:func:`curvature_errors`): a saturating motor's levels, commissioned
(:func:`~._saturation.commission_over_current`) or learned from logs (``selftune learn``
of several logs), each found by a fit that averages the inductances over its log's
currents.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any, ClassVar, Protocol, TypeVar

import numpy as np

from ..core import Array
from ..errors import ExcitationError

__all__ = [
    "IMPRECISE_INDUCTANCE",
    "LevelFields",
    "curvature_errors",
    "precise_levels",
    "with_curvature",
]

#: A level whose identified ``L_dd`` or ``L_qq`` has a standard error (its curvature's
#: included) above this share of itself is left out of the schedule
#: (:func:`precise_levels`). A law designed on an inductance 10 % off costs about 0.4-1.2 %
#: more than the optimum (the excess is quadratic in the error, :data:`INDUCTANCE_MOVE
#: <selftune.tuning._saturation.INDUCTANCE_MOVE>`), so the schedule's 2 % holds within
#: about one such standard error. On a drawn 46.8 mH motor rated 0.21 A on 540 V (24 mA
#: ADC steps, 2 V of dead time) the levels from 55 % to 85 % of rated torque had standard
#: errors of 9-55 % of their inductances, one was 10 % off, and the schedule designed on
#: them cost 2.9 % over the true optimum at 10 % of rated current.
IMPRECISE_INDUCTANCE = 0.1


class LevelFields(Protocol):
    """What :func:`with_curvature` and the levels' table read of a level (CurrentLevel
    or LearnedLevel): a dataclass with these fields."""

    __dataclass_fields__: ClassVar[dict[str, Any]]

    @property
    def reference(self) -> Array: ...
    @property
    def curvature_errors(self) -> Array: ...
    @property
    def mean_current(self) -> Array: ...
    @property
    def current_spread(self) -> Array: ...
    @property
    def theta(self) -> Array: ...
    @property
    def standard_errors(self) -> Array: ...


LevelT = TypeVar("LevelT", bound=LevelFields)


def curvature_errors(currents: Array, inductances: Array, noise: Array, spreads: Array) -> Array:
    """The standard error each level's incremental inductances take from their curvature
    over the level's log.

    A level's fit explains its whole log with one linear model, so it finds the
    inductances averaged over the log's currents, not their value at the mean current:
    to second order ``L(i0) + L'' s^2 / 2`` for a log spread by ``s`` about ``i0``. Where
    the exploration and the steps move the current over a good part of the saturation's
    scale (a small-current motor: 1.1 A about 0.29 A on a 55 uH motor rated 2.9 A) that
    bias was up to 11 times the noise's standard error (docs/saturation.md). The levels'
    own inductances give ``L''`` along ``i_q``: each three neighbouring levels' parabola,
    whose leading coefficient ``c = L'' / 2`` has a noise of its own (its standard error
    ``s_c`` from the three levels' ``noise``); ``max(c^2 - s_c^2, 0)`` estimates the true ``c^2``
    (without that, on the study's closely spaced levels, where the curvature is small,
    the levels' noise alone raised 65 % of errors within one standard error to 88 %). A
    level takes the largest among the parabolas through it or through its neighbours (an
    end level lies on one parabola, whose curvature is the middle level's: on the 55 uH
    motor it missed the bend at rated current by 5 standard errors), and the bias
    ``|c| s_q^2`` is its standard error. The curvature along ``i_d``, which levels along
    ``i_q`` do not show, is not in it. With fewer than three levels, zeros.

    Parameters
    ----------
    currents : ndarray, shape (g,)
        The levels' mean ``i_q``, A, rising.
    inductances, noise : ndarray, shape (g, 3)
        Their identified ``[L_dd, L_qq, L_dq]`` and the fits' standard errors of them, H.
    spreads : ndarray, shape (g,)
        Their logs' standard deviation of ``i_q``, A.

    Returns
    -------
    ndarray, shape (g, 3)
        H.
    """
    currents, inductances = np.asarray(currents, float), np.asarray(inductances, float)
    noise, spreads = np.asarray(noise, float), np.asarray(spreads, float)
    count = currents.size
    errors = np.zeros((count, 3))
    if count < 3:
        return errors
    curvatures = []  # each window's c, net of its noise
    for start in range(count - 2):
        window = currents[start : start + 3]
        # c = sum_j L_j / prod_(k != j) (i_j - i_k): the parabola's leading coefficient
        weights = np.array(
            [1.0 / np.prod([window[j] - window[k] for k in range(3) if k != j]) for j in range(3)]
        )
        c = weights @ inductances[start : start + 3]
        variance = weights**2 @ noise[start : start + 3] ** 2
        curvatures.append(np.sqrt(np.maximum(c * c - variance, 0.0)))
    for k in range(count):
        near = [curvatures[start] for start in range(max(0, k - 3), min(k + 1, count - 3) + 1)]
        errors[k] = np.max(near, axis=0) * spreads[k] ** 2
    return errors


def with_curvature(levels: Sequence[LevelT]) -> tuple[LevelT, ...]:
    """The levels with :func:`curvature_errors` added to their inductances' standard
    errors (in quadrature) and kept in ``curvature_errors``.

    Parameters
    ----------
    levels : sequence of CurrentLevel or LearnedLevel
        By rising ``i_q*``, each with ``mean_current``, ``current_spread``, ``theta`` and
        ``standard_errors``.
    """
    extra = curvature_errors(
        np.array([level.mean_current[1] for level in levels]),
        np.array([level.theta[1:4] for level in levels]),
        np.array([level.standard_errors[1:4] for level in levels]),
        np.array([level.current_spread[1] for level in levels]),
    )
    found = []
    for level, added in zip(levels, extra, strict=True):
        errors = np.array(level.standard_errors, dtype=float)
        errors[1:4] = np.hypot(errors[1:4], added)
        found.append(replace(level, standard_errors=errors, curvature_errors=added))
    return tuple(found)


def precise_levels(
    levels: Sequence[LevelT], names: Sequence[str]
) -> tuple[tuple[LevelT, ...], tuple[LevelT, ...], str]:
    """The levels whose ``L_dd`` and ``L_qq`` are known within
    :data:`IMPRECISE_INDUCTANCE` of themselves (one standard error, their curvature's
    included: :func:`with_curvature`'s), those left out, and why ("" when none were).

    Parameters
    ----------
    levels : sequence of CurrentLevel or LearnedLevel
        By rising ``i_q*``.
    names : sequence of str
        Each level's name (its share of rated torque, or its log).

    Raises
    ------
    ExcitationError
        Fewer than two levels are known so well, or the highest is not.
    """
    relative = [
        np.abs(np.asarray(level.standard_errors[1:3]) / np.asarray(level.theta[1:3]))
        for level in levels
    ]
    left = [k for k, values in enumerate(relative) if np.max(values) > IMPRECISE_INDUCTANCE]
    if not left:
        return tuple(levels), (), ""
    found = ", ".join(
        f"{names[k]}: L_dd +-{relative[k][0]:.1%}, L_qq +-{relative[k][1]:.1%}" for k in left
    )
    text = (
        f"left out of the schedule, their inductances' standard errors over "
        f"{IMPRECISE_INDUCTANCE:.0%} ({found}): a law designed on them may cost more than "
        "the schedule's check says (larger currents against the ADC's steps, an ADC range "
        "suited to the motor or longer logs help)"
    )
    if len(levels) - 1 in left or len(levels) - len(left) < 2:
        raise ExcitationError(
            f"too few levels know their inductances within {IMPRECISE_INDUCTANCE:.0%} for "
            f"a schedule (at least two, the highest among them): {text}"
        )
    kept = tuple(level for k, level in enumerate(levels) if k not in left)
    return kept, tuple(levels[k] for k in left), text
