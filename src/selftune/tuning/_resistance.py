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

#: A level whose R_s is beyond this factor of the nameplate's (either way) is left out in a
#: commissioning (:func:`far_from_nameplate`), where the gap moves the sampled plant by
#: more than :data:`NAMEPLATE_SHIFT`: a winding's resistance moves by about 40 % from 20 to
#: 120 degrees C. On a 4.2/8.4 mH motor rated 0.21 A on 540 V (2 V of dead time, 50 times
#: the resistive drop at rated current) every level found 7-21 times the truth, within 5
#: standard errors of each other, and the schedule was 3.6 % off.
NAMEPLATE_RESISTANCE = 2.0

#: The least gap ``|R_s - nameplate| h / L`` (the sampled plant's pole moved by about that
#: share) that :func:`far_from_nameplate` counts: below it the law barely depends on R_s.
#: On a 40/80 uH motor on 48 V the highest level found R_s 2 times off the nameplate's
#: (3.3 mOhm), a gap of 0.4 % of the pole, and the schedule was within 0.021 %; the 0.21 A
#: motor's levels were 2.7-9 % off.
NAMEPLATE_SHIFT = 0.01


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


def far_from_nameplate(thetas: Array, nameplate: float | None, h: float) -> list[int]:
    """The levels whose R_s is beyond :data:`NAMEPLATE_RESISTANCE` times the nameplate's
    or below its inverse, by enough to move the sampled plant: ``|R_s - nameplate| h /
    L`` beyond :data:`NAMEPLATE_SHIFT` (L the smaller incremental inductance; none
    without a nameplate).

    Parameters
    ----------
    thetas : ndarray, shape (g, 6)
        The levels' parameters (``theta[:, 0]``: R_s, ohm; ``theta[:, 1:3]``: the
        inductances, H).
    nameplate : float or None
        The nameplate's R_s, ohm (None: not known, as from a drive's logs alone).
    h : float
        Sampling period, s.

    Returns
    -------
    list of int
        Their rows.
    """
    if nameplate is None:
        return []
    ratio = thetas[:, 0] / nameplate
    shift = np.abs(thetas[:, 0] - nameplate) * h / np.min(thetas[:, 1:3], axis=1)
    far = ((ratio > NAMEPLATE_RESISTANCE) | (ratio < 1.0 / NAMEPLATE_RESISTANCE)) & (
        shift > NAMEPLATE_SHIFT
    )
    return [int(k) for k in np.flatnonzero(far)]


def check_against_nameplate(
    R_s: float, L_d: float, L_q: float, nameplate: float, h: float, drop: tuple[float, float],
) -> None:  # fmt: skip
    """Refuse an identified motor whose R_s is far from the nameplate's
    (:func:`far_from_nameplate`): the fit took something else for resistance, and what
    it took moved the inductances too.

    On the hardware-like drive's 2 V of dead time on a 48 V bus (4.2 us), a 91/136 uH
    interior motor of 3.2 mOhm rated 58 A (the dead time's voltage 11 times the resistive
    drop) was learned with R_s 10 times the nameplate's and L_d, L_q 16% and 18% high at
    3.8-4.0 standard errors (excess cost 2.9%); on 30 + 30 random interior motors with
    0.5 us on 48 V and 2 V on 540 V the identified R_s was within a factor 3.1 of the
    nameplate's, and none of them beyond 2 moved the sampled plant by more than 0.2% of
    its pole.

    Parameters
    ----------
    R_s, L_d, L_q : float
        The identified motor's resistance (ohm) and inductances (H).
    nameplate : float
        The nameplate's R_s, ohm.
    h : float
        Sampling period, s.
    drop : (float, float)
        The dead time's voltage (V; 0 without dead time) and the nameplate's resistive
        drop at the experiment's current, V, for the message.

    Raises
    ------
    ModelMissesEffect
        Naming the R_s, the nameplate's, the two voltages and the remedies.
    """
    if not far_from_nameplate(np.array([[R_s, L_d, L_q]]), nameplate, h):
        return
    dead, resistive = drop
    voltages = (
        f" (the dead time's {dead:.3g} V against the resistive drop's {resistive:.3g} V at "
        "the experiment's current)"
        if dead > 0.0
        else ""
    )
    raise ModelMissesEffect(
        f"the identified R_s, {R_s:.4g} ohm, is {R_s / nameplate:.3g} times the nameplate's "
        f"{nameplate:.4g} ohm (beyond {NAMEPLATE_RESISTANCE:g} times either way, by enough to "
        "move the sampled plant): the fit took something else for resistance, most likely "
        f"the inverter's dead time near zero current{voltages}, and its inductances with "
        "it; dead-time compensation, a shorter dead time or larger currents help (or the "
        "motor file's [motor] R_s is wrong: check it)",
        statistic=float(max(R_s / nameplate, nameplate / R_s)), threshold=NAMEPLATE_RESISTANCE,
        causes=("the inverter's dead time near zero current", "a wrong nameplate R_s"),
    )  # fmt: skip


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


def too_few_levels(
    names: Sequence[str], thetas: Array, errors: Array, left: Sequence[int],
    nameplate: float | None = None,
) -> ModelMissesEffect:  # fmt: skip
    """The refusal when fewer than two levels, the highest among them, are kept
    (arguments as :func:`left_out_text`'s)."""
    return ModelMissesEffect(
        "too few levels agree on R_s for a schedule (at least two, the highest among "
        f"them): {left_out_text(names, thetas, errors, left, nameplate)}",
        statistic=float(len(names) - len(left)), threshold=2.0,
        causes=("the inverter's dead time near zero current", "a coarse ADC"),
    )  # fmt: skip


def kept_levels(
    names: Sequence[str], thetas: Array, errors: Array, nameplate: float | None = None,
    h: float = 0.0,
) -> tuple[list[int], str]:  # fmt: skip
    """The levels a schedule is designed on and why the others were left out
    (:func:`misled_levels`; "" when none were).

    Parameters
    ----------
    names, thetas, errors, nameplate
        As :func:`left_out_text` takes them.
    h : float
        Sampling period, s (with ``nameplate``).

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
        raise too_few_levels(names, thetas, errors, left, nameplate)
    return kept, left_out_text(names, thetas, errors, left, nameplate) if left else ""
