"""The levels' inductance error bars and the inductances' curvature over each log.

A level's fit finds the inductances averaged over its log's currents; where the log
spreads the current over a good part of the saturation's scale, that average is off the
value at the mean current by more than the noise's standard error
(:func:`selftune.tuning._curvature.curvature_errors`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import pytest

from selftune.core import Array
from selftune.errors import ExcitationError
from selftune.model import IPMSM
from selftune.report._saturation_report import level_table
from selftune.sim import DriveSettings
from selftune.tuning._curvature import (
    IMPRECISE_INDUCTANCE,
    curvature_errors,
    precise_levels,
    with_curvature,
)
from selftune.tuning._saturation import CurrentLevel, incremental_theta, learn_level
from test_saturation_tune import saturating_case


def test_levels_on_a_parabola_take_its_curvature_times_their_spread_squared() -> None:
    """Inductances on one parabola in ``i_q`` (unevenly spaced levels): every level's
    error is ``|c| s^2`` of its own spread ``s``, ``c`` the parabola's leading
    coefficient (``L'' / 2``); on a line, none; with two levels, none."""
    currents = np.array([0.3, 1.2, 1.6, 2.9, 3.1])
    coefficients = np.array([-4e-7, 2e-7, 0.0])  # H / A^2: L_dd, L_qq, L_dq
    inductances = 5e-5 + 1e-6 * currents[:, None] + coefficients * currents[:, None] ** 2
    spreads = np.array([1.1, 0.9, 0.5, 0.2, 1.0])
    exact = np.zeros((5, 3))
    errors = curvature_errors(currents, inductances, exact, spreads)
    expected = np.abs(coefficients) * spreads[:, None] ** 2
    np.testing.assert_allclose(errors, expected, rtol=1e-6, atol=1e-18)
    line = 5e-5 - 1e-6 * currents[:, None] * np.ones(3)
    np.testing.assert_allclose(curvature_errors(currents, line, exact, spreads), 0.0, atol=1e-18)
    assert not np.any(curvature_errors(currents[:2], inductances[:2], exact[:2], spreads[:2]))


def test_a_curvature_the_levels_noise_explains_counts_for_nothing() -> None:
    """Levels at 0, 1, 2 A whose middle inductance is 1e-8 H above the line through the
    others, with standard errors s: the parabola's leading coefficient is -1e-8 H/A^2 and
    its own standard error sqrt(1/4 + 1 + 1/4) s; the curvature counted is the root of
    the difference of their squares, none where the noise is the larger."""
    currents = np.array([0.0, 1.0, 2.0])
    inductances = np.array([1e-4, 1e-4 + 1e-8, 1e-4])[:, None] * np.ones(3)
    for s, expected in ((4e-9, np.sqrt(1e-16 - 1.5 * 16e-18)), (1e-8, 0.0)):
        noise = np.full((3, 3), s)
        errors = curvature_errors(currents, inductances, noise, np.ones(3))
        np.testing.assert_allclose(errors, expected, rtol=1e-6, atol=1e-24)


def test_a_level_takes_the_largest_curvature_of_the_parabolas_through_it_or_beside() -> None:
    """Six levels on a cubic: each window's parabola bends more than the one before
    (leading coefficients 3, 6, 9, 12); a level takes the largest among the parabolas
    through it or through its neighbours."""
    currents = np.arange(6.0)
    values = currents**3  # the window from level j: (3 j + 3) i^2 + ...
    inductances = np.column_stack([values, -values, np.zeros(6)])
    errors = curvature_errors(currents, inductances, np.zeros((6, 3)), np.ones(6))
    np.testing.assert_allclose(errors[:, 0], [6.0, 9.0, 12.0, 12.0, 12.0, 12.0], rtol=1e-9)
    np.testing.assert_allclose(errors[:, 1], errors[:, 0], rtol=1e-9)


@dataclass(frozen=True)
class _Level:
    reference: Array
    mean_current: Array
    current_spread: Array
    theta: Array
    standard_errors: Array
    curvature_errors: Array = field(default_factory=lambda: np.zeros(3))


def _levels(currents: Array, spread: float, noise: float) -> list[_Level]:
    """Levels at ``currents`` (A) whose inductances lie on ``1e-4 - 2e-6 (i_q - 1.5)^2``
    (H), their logs' i_q spread ``spread`` (A), their standard errors ``noise``."""
    theta = np.zeros((currents.size, 6))
    theta[:, 1:4] = 1e-4 - 2e-6 * (currents[:, None] - 1.5) ** 2
    return [
        _Level(
            np.array([0.0, q]),
            np.array([0.0, q]),
            np.array([0.4, spread]),
            theta[k],
            np.full(6, noise),
        )
        for k, q in enumerate(currents)
    ]


def test_with_curvature_adds_the_term_to_the_inductances_alone() -> None:
    """The inductances' standard errors take the curvature's in quadrature; R_s's and the
    flux offsets' stay; the term is kept apart."""
    currents = np.array([0.5, 1.5, 2.5])
    found = with_curvature(_levels(currents, 0.5, 1e-7))
    curvature = np.sqrt(4e-12 - 1.5e-14)  # H/A^2: c = -2e-6, its noise sqrt(1.5) 1e-7
    for level in found:
        np.testing.assert_allclose(level.curvature_errors, [curvature * 0.25] * 3, rtol=1e-6)
        added = np.hypot(1e-7, curvature * 0.25)
        np.testing.assert_allclose(level.standard_errors[1:4], added, rtol=1e-6)
        assert np.all(level.standard_errors[[0, 4, 5]] == 1e-7)


def test_levels_whose_inductances_are_imprecise_are_left_out_or_refuse_the_schedule() -> None:
    """A level whose L_dd or L_qq standard error is over IMPRECISE_INDUCTANCE of itself is
    left out, named with both relative errors; just under it, kept. Fewer than two kept,
    or the highest left out, refuse the schedule."""
    currents = np.array([0.5, 1.0, 1.5, 2.0])
    levels = _levels(currents, 0.5, 1e-7)
    names = ["10%", "40%", "70%", "100%"]
    wide = np.full(6, 1e-7)
    wide[2] = 1.01 * IMPRECISE_INDUCTANCE * levels[1].theta[2]  # L_qq just over
    levels[1] = replace(levels[1], standard_errors=wide)
    barely = np.full(6, 1e-7)
    barely[1] = 0.99 * IMPRECISE_INDUCTANCE * levels[0].theta[1]  # L_dd just under
    levels[0] = replace(levels[0], standard_errors=barely)
    kept, left, text = precise_levels(levels, names)
    assert kept == (levels[0], levels[2], levels[3]) and left == (levels[1],)
    assert "(40%: L_dd +-0.1%, L_qq +-10.1%)" in text
    assert precise_levels(levels[2:], names[2:]) == (tuple(levels[2:]), (), "")
    for chosen in (
        [levels[0], levels[3], levels[1]],
        [levels[1], levels[3]],
        [levels[2], levels[1]],
    ):
        with pytest.raises(ExcitationError, match="too few levels know their inductances"):
            precise_levels(chosen, names[: len(chosen)])


@pytest.mark.slow
def test_a_small_current_motors_inductance_bars_hold_the_truth() -> None:
    """A 55 uH surface motor rated 2.9 A on 48 V (one of the drawn saturating motors in
    docs/saturation.md): the exploration and the steps spread each level's current by
    about 1.1 A, over the saturation's scale (0.98 of rated). The noise's bars alone left
    L_qq up to 9 standard errors from the truth at the mean current; with the curvature's
    every inductance is within 3."""
    motor = IPMSM(R_s=0.05, L_d=55e-6, L_q=55e-6, phi_pm=0.0056, p=13)
    drive = replace(DriveSettings.hardware_like(dc_voltage=48.0), pwm="average", dead_time=5e-7)
    settings, saturation = saturating_case(motor, drive, 22.0, 0.32, 919, 0.98, 0.2)
    levels = [
        learn_level(motor, saturation, settings, drive, share, seed=919)
        for share in (0.1, 0.4, 0.7, 1.0)
    ]

    def largest_z(found: Sequence[CurrentLevel]) -> float:
        z = [
            (level.theta - incremental_theta(saturation, 0.05, level.mean_current, 0.0056))[1:4]
            / level.standard_errors[1:4]
            for level in found
        ]
        return float(np.max(np.abs(z)))

    assert largest_z(levels) > 4.0  # the noise's bars alone
    assert largest_z(with_curvature(levels)) <= 3.0


def test_the_levels_table_notes_bars_the_curvature_widens_beyond_the_noise() -> None:
    """Where the curvature's part of some level's inductance bars is more than the noise's,
    the table says so, naming the level and its log's spread of i_q, and what would
    narrow them; where it is less, no note."""
    currents = np.array([0.5, 1.5, 2.5])
    names = ["low.csv", "middle.csv", "high.csv"]
    for noise, spread, noted in ((1e-7, 0.5, True), (1e-6, 0.5, False)):
        levels = with_curvature(_levels(currents, spread, noise))
        lines = level_table("log", names, levels)
        assert len(lines) == 5 + noted
        if noted:  # 5e-7 H of curvature against 1e-7 of noise
            assert "up to 5 times the noise's (at low.csv" in lines[-1]
            assert "spreads by 0.5 A" in lines[-1] and "smaller exploration" in lines[-1]
