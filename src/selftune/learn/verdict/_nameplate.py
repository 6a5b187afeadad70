"""An identified motor's R_s against the nameplate's: where the fit took something else
for resistance (most likely the inverter's dead time near zero current), its inductances
moved with it, and every test of the verdict may pass.

One rule for every place that knows a nameplate: the commissionings of ``selftune tune``
(:mod:`selftune.tuning._resistance`: the interior and ramp commissioning, a saturating
motor's levels) and ``selftune learn`` with ``[learning] nameplate_resistance``
(:func:`check_fit_against_nameplate`).
"""

from __future__ import annotations

import numpy as np

from ...core import Array
from ...errors import ModelMissesEffect
from ..evidence._evidence import Evidence
from ._verdict import dead_time_voltage, motor_estimate

__all__ = [
    "NAMEPLATE_RESISTANCE",
    "NAMEPLATE_SHIFT",
    "check_against_nameplate",
    "check_fit_against_nameplate",
    "far_from_nameplate",
]

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
    key: str = "the motor file's [motor] R_s",
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
    key : str
        Where the nameplate's R_s was given, for the message.

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
        "it; dead-time compensation, a shorter dead time or larger currents help (or "
        f"{key} is wrong: check it)",
        statistic=float(max(R_s / nameplate, nameplate / R_s)), threshold=NAMEPLATE_RESISTANCE,
        causes=("the inverter's dead time near zero current", "a wrong nameplate R_s"),
    )  # fmt: skip


def check_fit_against_nameplate(evidence: Evidence, nameplate: float) -> None:
    """Refuse a structured fit whose R_s is far from the nameplate's
    (:func:`check_against_nameplate`; nothing to check without a structure).

    Parameters
    ----------
    evidence : Evidence
        The logs' evidence.
    nameplate : float
        The nameplate's R_s, ohm (``[learning] nameplate_resistance``).

    Raises
    ------
    ModelMissesEffect
        As :func:`check_against_nameplate`, naming ``nameplate_resistance``.
    """
    motor = motor_estimate(evidence)
    if motor is None or evidence.fit is None or evidence.fit.structure is None:
        return
    inductances = [value for value in (motor.L_s, motor.L_d, motor.L_q) if value is not None]
    currents = np.concatenate([episode.x for episode in evidence.episodes])
    rms = float(np.sqrt(np.mean(np.sum(currents**2, axis=1))))
    dead = dead_time_voltage(evidence) or 0.0
    check_against_nameplate(
        motor.R_s, min(inductances), max(inductances), nameplate, evidence.fit.structure.h,
        (dead, nameplate * rms),
        key="[learning] nameplate_resistance",
    )  # fmt: skip
