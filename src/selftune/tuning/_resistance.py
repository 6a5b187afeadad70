"""The identified R_s checked: the current levels' against each other and against the
nameplate (a saturating motor's commissioning over its load,
:func:`~._saturation.commission_over_current`, and ``selftune learn`` of several logs), and
one identified motor's against the nameplate (:func:`check_against_nameplate`: the
interior and the ramp commissioning).

R_s does not depend on the current, and the levels are logged seconds apart (one
temperature). At small currents the inverter's dead time near zero current acts as a
resistance, and a level's fit may take it for R_s with every check of the verdict passed:
a level whose R_s disagrees with the highest level's (:func:`disagreeing_levels`), or is far
from the nameplate's where one is known (:func:`far_from_nameplate`), is left out of the
schedule; with fewer than two levels kept, or the highest not among them, the schedule is
refused (:func:`kept_levels`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..core import Array
from ..errors import ModelMissesEffect
from ..learn.verdict._nameplate import (
    NAMEPLATE_RESISTANCE,
    NAMEPLATE_SHIFT,
    check_against_nameplate,
    far_from_nameplate,
)

__all__ = [
    "NAMEPLATE_RESISTANCE",
    "NAMEPLATE_SHIFT",
    "RESISTANCE_SHARE",
    "RESISTANCE_SPREAD",
    "check_against_nameplate",
    "disagreeing_levels",
    "far_from_nameplate",
    "kept_levels",
    "left_out_text",
    "misled_levels",
    "small_levels",
    "too_few_levels",
]

#: A level whose identified R_s is off the highest level's by more than this share of it
#: and by more than :data:`RESISTANCE_SPREAD` combined standard errors is left out of the
#: schedule (:func:`disagreeing_levels`). R_s does not depend on the current, and the
#: levels are logged within seconds of each other (one temperature); a fit that finds it
#: 25 % and 5 standard errors away has taken something else for resistance: on a motor
#: rated 0.29 A (25/75 mH, 540 V, 2 V of dead time, 24 mA ADC steps) the level at 10 % of
#: rated current, 0.03 A, found 31 ohm against 0.80 (18 standard errors), the inverter's
#: dead time near zero current acting as a resistance, and the schedule on it cost 78 %
#: more than the optimum there.
RESISTANCE_SHARE = 0.25

#: See :data:`RESISTANCE_SHARE`.
RESISTANCE_SPREAD = 5.0


def disagreeing_levels(thetas: Array, errors: Array) -> list[int]:
    """The levels whose identified R_s disagrees with the highest level's (the last):
    off by more than :data:`RESISTANCE_SHARE` of it and :data:`RESISTANCE_SPREAD`
    combined standard errors.

    Parameters
    ----------
    thetas, errors : ndarray, shape (g, 6)
        The levels' parameters (:func:`incremental_parameters`) and standard errors, by
        rising ``i_q*``.

    Returns
    -------
    list of int
        Their rows.
    """
    R_s, se = thetas[:, 0], errors[:, 0]
    gap = np.abs(R_s - R_s[-1])
    bound = np.maximum(RESISTANCE_SPREAD * np.hypot(se, se[-1]), RESISTANCE_SHARE * abs(R_s[-1]))
    return [int(k) for k in np.flatnonzero(gap[:-1] > bound[:-1])]


def misled_levels(
    thetas: Array, errors: Array, nameplate: float | None = None, h: float = 0.0
) -> list[int]:
    """The levels left out of a schedule: those whose R_s disagrees with the highest
    level's (:func:`disagreeing_levels`) or is far from the nameplate's
    (:func:`far_from_nameplate`).

    Parameters
    ----------
    thetas, errors : ndarray, shape (g, 6)
        The levels' parameters and standard errors, by rising ``i_q*``.
    nameplate : float, optional
        The nameplate's R_s, ohm.
    h : float
        Sampling period, s (with ``nameplate``).

    Returns
    -------
    list of int
        Their rows, rising.
    """
    far = far_from_nameplate(thetas, nameplate, h)
    return sorted({*disagreeing_levels(thetas, errors), *far})


def left_out_text(
    names: Sequence[str], thetas: Array, errors: Array, left: Sequence[int],
    nameplate: float | None = None,
) -> str:  # fmt: skip
    """What :func:`misled_levels` found, in one sentence.

    Parameters
    ----------
    names : sequence of str
        Each level's name (its share of rated torque, or its log).
    thetas, errors : ndarray, shape (g, 6)
        The levels' parameters and standard errors.
    left : sequence of int
        The rows left out.
    nameplate : float, optional
        The nameplate's R_s, ohm.
    """
    last = len(names) - 1
    top, top_se = thetas[last, 0], errors[last, 0]
    found = ", ".join(
        f"{names[k]}: {thetas[k, 0]:.4g} ohm"
        + ("" if k == last else
           f" ({abs(thetas[k, 0] - top) / np.hypot(errors[k, 0], top_se):.1f} standard errors)")
        for k in left
    )  # fmt: skip
    far = (
        ""
        if nameplate is None
        else f" or beyond {NAMEPLATE_RESISTANCE:g} times the nameplate's {nameplate:.4g} ohm "
        "either way (by enough to move the sampled plant)"
    )
    return (
        f"left out of the schedule, their R_s far from the {top:.4g} ohm of the highest level"
        f"{far} ({found}); R_s does not depend on the current: the fit took something else "
        "for resistance there, most likely the inverter's dead time near zero current "
        "(larger currents, an ADC range suited to the motor or dead-time compensation help)"
    )


def small_levels(current: float, torque: float) -> str:
    """What :func:`too_few_levels` says of commissioned levels whose highest is far from
    the nameplate's R_s: its current (A) may be small against the dead time, and the
    levels are shares of the stated rated ``torque`` (N m), the user's to raise.

    Parameters
    ----------
    current : float
        The highest level's current reference's magnitude, A.
    torque : float
        ``[operating_point] torque``, N m.
    """
    return (
        f"its {current:.3g} A may be too small against the dead time; the levels are "
        f"shares of [operating_point] torque = {torque:g} N m, which should be the "
        "motor's rated torque"
    )


def too_few_levels(
    names: Sequence[str], thetas: Array, errors: Array, left: Sequence[int],
    nameplate: float | None = None, small: str = "",
) -> ModelMissesEffect:  # fmt: skip
    """The refusal when fewer than two levels, the highest among them, are kept
    (arguments as :func:`left_out_text`'s; ``small``: where the highest level is left
    out too, what says that its current is the user's to raise, appended)."""
    top_too = bool(small) and len(names) - 1 in left
    top_text = f"; the highest level's R_s is far from the nameplate's too: {small}"
    return ModelMissesEffect(
        "too few levels agree on R_s for a schedule (at least two, the highest among "
        f"them): {left_out_text(names, thetas, errors, left, nameplate)}"
        + (top_text if top_too else ""),
        statistic=float(len(names) - len(left)), threshold=2.0,
        causes=("the inverter's dead time near zero current", "a coarse ADC"),
    )  # fmt: skip


def kept_levels(
    names: Sequence[str], thetas: Array, errors: Array, nameplate: float | None = None,
    h: float = 0.0, small: str = "",
) -> tuple[list[int], str]:  # fmt: skip
    """The levels a schedule is designed on and why the others were left out
    (:func:`misled_levels`; "" when none were).

    Parameters
    ----------
    names, thetas, errors, nameplate
        As :func:`left_out_text` takes them.
    h : float
        Sampling period, s (with ``nameplate``).
    small : str
        What the refusal says where the highest level is far from the nameplate too
        (:func:`too_few_levels`).

    Returns
    -------
    kept : list of int
        The rows kept, rising.
    text : str
        :func:`left_out_text` of the others.

    Raises
    ------
    ModelMissesEffect
        Fewer than two levels kept, or the highest left out (:func:`too_few_levels`).
    """
    left = misled_levels(thetas, errors, nameplate, h)
    kept = [k for k in range(len(names)) if k not in left]
    if len(kept) < 2 or len(names) - 1 in left:
        raise too_few_levels(names, thetas, errors, left, nameplate, small)
    return kept, left_out_text(names, thetas, errors, left, nameplate) if left else ""
