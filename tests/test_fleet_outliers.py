"""The fleet summary's outlier rule (selftune.fleet._summary): a group of ordinary drives,
normally or uniformly spread, of any size from 5 to 60, names one of them in at most the
stated share of groups; a hot winding (R_s +30%) among +-5% units with realistic standard
errors is named in a group of 50, and a gross fault in a group of 8.

Seeded simulations; each bound is a binomial quantile of the number of trials, so a rule
whose rate exceeds the stated one by a fraction (pooled over the sizes) or by a factor
(at any one size) fails."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy import stats

from selftune.fleet import (
    FALSE_ALARM_RATE,
    MIN_GROUP,
    PARAMETERS,
    SUMMARY_COLUMNS,
    outlier_threshold,
    robust_z,
    summarize,
)

#: Groups simulated per size and spread (each with the four parameters).
GROUPS = 4000

#: The chance that a correct rule fails one of these tests.
MISS = 1e-4

#: The group sizes judged.
SIZES = range(MIN_GROUP, 61)

#: R_s's standard error relative to R_s: the median over bench section 12's realistic
#: drive (0.2 s logs, 164 drives learned; 90% of them below 2.1%).
R_S_SE = 0.012


def _spread(kind: str, rng: np.random.Generator, shape: tuple[int, ...]) -> tuple[
    np.ndarray, np.ndarray | None
]:  # fmt: skip
    """Values of ordinary drives around 1, and their standard errors (or none)."""
    if kind == "normal":
        return 1.0 + 0.03 * rng.standard_normal(shape), None
    if kind == "uniform":
        return rng.uniform(0.95, 1.05, shape), None
    # +-5% manufacturing spread estimated with normal errors whose se vary 4x by drive
    se = R_S_SE * np.exp(rng.uniform(-0.7, 0.7, shape))
    return rng.uniform(0.95, 1.05, shape) + se * rng.standard_normal(shape), se


def _groups_naming_a_drive(values: np.ndarray, se: np.ndarray | None) -> int:
    """Groups (axis 0) naming a drive by any parameter (axis 1), drives along axis 2."""
    z, _ = robust_z(values, se)
    return int(np.count_nonzero((np.abs(z) > outlier_threshold(values.shape[-1])).any(axis=(1, 2))))


@pytest.mark.parametrize("kind", ["normal", "uniform", "uniform with estimation errors"])
def test_ordinary_groups_name_a_drive_at_most_at_the_stated_rate(kind: str) -> None:
    rng = np.random.default_rng(20)
    alarms = {
        n: _groups_naming_a_drive(*_spread(kind, rng, (GROUPS, len(PARAMETERS), n))) for n in SIZES
    }
    each = stats.binom.ppf(1 - MISS / len(SIZES), GROUPS, FALSE_ALARM_RATE)
    assert max(alarms.values()) <= each, alarms
    total = GROUPS * len(SIZES)
    assert sum(alarms.values()) <= stats.binom.ppf(1 - MISS, total, FALSE_ALARM_RATE), alarms


def test_a_fixed_threshold_would_not_hold_the_rate() -> None:
    """The simulation can see a wrong rule: 4 robust sd (the rule before) in groups of 8."""
    rng = np.random.default_rng(21)
    values, _ = _spread("uniform", rng, (GROUPS, len(PARAMETERS), 8))
    z, _ = robust_z(values)
    named = int(np.count_nonzero((np.abs(z) > 4.0).any(axis=(1, 2))))
    assert named > stats.binom.ppf(1 - MISS, GROUPS, FALSE_ALARM_RATE) * 10


def _hot_unit_named(n: int, factor: float, rng: np.random.Generator, groups: int = 2000) -> (
    tuple[float, int]
):  # fmt: skip
    """The share of groups of ``n`` naming their unit 0, R_s times ``factor``, and the
    other drives named; R_s within +-5% (uniform) and estimated with an se of 1.2%."""
    true = rng.uniform(0.95, 1.05, (groups, n))
    true[:, 0] *= factor
    se = R_S_SE * true
    z, _ = robust_z(true + se * rng.standard_normal(true.shape), se)
    named = np.abs(z) > outlier_threshold(n)
    return float(np.mean(named[:, 0])), int(np.count_nonzero(named[:, 1:]))


def test_a_hot_winding_is_named_in_a_group_of_50() -> None:
    share, others = _hot_unit_named(50, 1.3, np.random.default_rng(22))
    assert share >= 0.99 and others == 0


def test_a_gross_fault_is_named_in_a_group_of_8_and_a_hot_winding_is_not() -> None:
    """In a group of 8 the spread is known too poorly (threshold 30.7) for +30%: the rule
    says so rather than naming ordinary drives; R_s three times its group's is named."""
    rng = np.random.default_rng(23)
    share, others = _hot_unit_named(8, 3.0, rng)
    assert share >= 0.98 and others == 0
    share, others = _hot_unit_named(8, 1.3, rng)
    assert share <= 0.01 and others == 0


def test_the_threshold_falls_as_the_spread_becomes_known() -> None:
    thresholds = [outlier_threshold(n) for n in range(MIN_GROUP, 100)]
    assert all(a >= b for a, b in itertools.pairwise(thresholds))
    assert outlier_threshold(MIN_GROUP - 1) == math.inf
    # many drives: the spread is known, the threshold is the normal's Bonferroni quantile
    # (which grows slowly with the drives: more chances)
    normal = stats.norm.ppf(1 - FALSE_ALARM_RATE / (2 * len(PARAMETERS) * 10_000))
    assert normal < outlier_threshold(10_000) < 1.02 * normal


def test_robust_z_of_groups_is_robust_z_of_each() -> None:
    rng = np.random.default_rng(24)
    values = rng.uniform(0.9, 1.1, (3, 12))
    values[1, 4] = np.nan
    se = rng.uniform(0.0, 0.02, values.shape)
    z, median = robust_z(values, se)
    for row in range(3):
        alone, middle = robust_z(values[row], se[row])
        np.testing.assert_array_equal(z[row], alone)
        assert median[row] == middle
    assert np.isnan(z[1, 4])


def test_summarize_names_only_the_hot_unit() -> None:
    """The rule as the summary applies it, on a table of two groups: 50 units (one hot)
    and 8 (one hot); only the first group's hot unit is named, by R_s."""
    rng = np.random.default_rng(25)
    columns: dict[str, list[object]] = {name: [] for name in SUMMARY_COLUMNS}
    errors = dict(zip(SUMMARY_COLUMNS[5::2], SUMMARY_COLUMNS[6::2], strict=True))
    nominal = dict(zip(errors, [0.6, 7e-3, 0.33, 2.0], strict=True))  # R_s, L_s, phi_pm, V
    for group, count in (("big", 50), ("small", 8)):
        for unit in range(count):
            for key, value in zip(["path", "drive", "group", "verdict", "error"],
                                  [f"{group}/{unit}.csv", f"{group}-{unit:02d}", group,
                                   "learned", ""], strict=True):  # fmt: skip
                columns[key].append(value)
            for column, center in nominal.items():
                true = center * rng.uniform(0.95, 1.05) * (1.3 if column == "R_s_ohm"
                                                          and unit == 0 else 1.0)  # fmt: skip
                se = R_S_SE * true
                columns[column].append(true + se * rng.standard_normal())
                columns[errors[column]].append(se)
    summary = summarize(columns)
    assert [(o.drive, o.parameter) for o in summary.outliers] == [("big-00", "R_s_ohm")]
    assert summary.outliers[0].z > outlier_threshold(50)
    assert dict(summary.group_sizes) == {"big": 50, "small": 8}
