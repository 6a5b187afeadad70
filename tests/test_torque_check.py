"""The interior commissioning's torque check reads the steady torque over whole turns.

The true torque of a drive with dead time ripples at six times the electrical speed; its
mean over a part of a turn holds part of the ripple. ``DriveRecord.steady_torque`` takes
the mean over the whole turns of the record's second half, and ``check_samples`` makes
the check long enough to hold two of them.
"""

from __future__ import annotations

import numpy as np
import pytest

from selftune.learn import Trajectory
from selftune.sim import DriveRecord
from selftune.tuning._interior import CHECK_LIMIT, CHECK_TURNS, check_samples

H = 1e-4


def _record(electrical_speed: float, samples: int, with_angle: bool = True) -> DriveRecord:
    """A record whose torque is 2 N m with a six-step ripple of 0.1 N m and the angle a
    drive logs (wrapped to one turn)."""
    t = H * np.arange(samples + 1)
    angle = np.mod(electrical_speed * t + 0.3, 2.0 * np.pi)
    torque = 2.0 + 0.1 * np.sin(6.0 * (electrical_speed * t + 0.3))
    log = Trajectory(
        t, np.zeros((samples + 1, 2)), np.zeros((samples, 2)),
        angle=angle if with_angle else None,
    )  # fmt: skip
    zeros = np.zeros((samples, 2))
    return DriveRecord(log, np.zeros((samples + 1, 2)), zeros, zeros, torque)


def test_the_mean_over_whole_turns_leaves_the_ripple_out() -> None:
    """At 28 rad/s over 0.1 s the second half holds 0.22 turn: its plain mean is off by
    a part of the ripple; over 0.9 s it holds two whole turns and their mean is 2 N m to
    the sampling's rounding."""
    short = _record(28.0, 1000)
    half = short.torque[500:]
    assert abs(np.mean(half) - 2.0) > 1e-3
    assert short.steady_torque() == pytest.approx(np.mean(half))  # less than a turn
    long = _record(28.0, check_samples(0.4, 28.0, H))
    assert long.steady_torque() == pytest.approx(2.0, abs=2e-4)
    plain = float(np.mean(long.torque[long.torque.shape[0] // 2 :]))
    assert abs(long.steady_torque() - 2.0) < abs(plain - 2.0)


def test_without_an_angle_the_second_half_is_averaged() -> None:
    record = _record(700.0, 4000, with_angle=False)
    assert record.steady_torque() == pytest.approx(np.mean(record.torque[2000:]))


@pytest.mark.parametrize(
    ("electrical_speed", "seconds"),
    [
        (1000.0, 0.4),  # 32 turns in the second half: the least length
        (28.0, 2.0 * CHECK_TURNS * 2.0 * np.pi / 28.0),  # two turns in the second half
        (-28.0, 2.0 * CHECK_TURNS * 2.0 * np.pi / 28.0),  # either direction
        (1.0, CHECK_LIMIT),  # the limit
        (0.0, CHECK_LIMIT),  # standstill
    ],
)
def test_the_check_holds_two_turns_in_its_second_half(
    electrical_speed: float, seconds: float
) -> None:
    assert check_samples(0.4, electrical_speed, H) == round(seconds / H)
