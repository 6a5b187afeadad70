"""An encoder's angle (whole counts) read to better than a count: its count found, its
rounding averaged out for the dead-time model's phase signs, and a held part's speed
read off the least-squares line through it with an error that covers the rounding."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from selftune import SPMSM
from selftune.bench import ONLINE_MOTORS, markdown_ramp, measure_ramp_draws
from selftune.bench._online import _config as online_config
from selftune.core import ControlLaw
from selftune.learn import Trajectory
from selftune.learn._speeds import speed_errors, speed_segments
from selftune.learn.evidence._encoder import (
    AVERAGED_COUNTS,
    angle_count,
    read_angle,
    rounding_cycles,
    unwrapped,
)
from selftune.learn.online import OnlineModel
from selftune.sim import DriveSettings, RealisticDrive, held, uniform

H = 1e-4
ROWS = 5000


def encoder_angle(counts_a_row: float, offset: float, count: float, rows: int = ROWS) -> np.ndarray:
    """The wrapped angle of a rotor turning ``counts_a_row`` counts a row from ``offset``
    (counts), as an encoder of one ``count`` (rad) reads it (rounded), and the truth."""
    truth = count * (offset + counts_a_row * np.arange(rows))
    return np.angle(np.exp(1j * np.round(truth / count) * count)), truth


def as_log(angle: np.ndarray) -> Trajectory:
    rows = angle.size
    return Trajectory(
        t=H * np.arange(rows), x=np.zeros((rows, 2)), u=np.zeros((rows - 1, 2)), angle=angle
    )


rates = st.floats(0.05, 30.0).filter(lambda r: abs(r - round(r)) > 0.02)
encoders = st.sampled_from([256, 1024, 4096, 16384, 65536])
poles = st.integers(1, 20)


@settings(max_examples=60, deadline=None)
@given(rate=rates, offset=st.floats(0.0, 1.0), counts=encoders, p=poles)
@example(rate=24.484813945939887, offset=0.5, counts=65536, p=1)  # 7 digits: 0.01 counts
def test_an_encoders_count_is_found(rate: float, offset: float, counts: int, p: int) -> None:
    count = 2 * np.pi * p / counts
    if rate * count > 0.5 * np.pi:  # more than a quarter turn a row: not an angle sampled
        return
    angle, _ = encoder_angle(rate, offset, count)
    found = angle_count(angle)
    assert found is not None and found == pytest.approx(count, rel=1e-6)
    # as a log writes it, to 7 significant digits
    written = np.array([float(f"{value:.7g}") for value in angle])
    assert angle_count(written) == pytest.approx(count, rel=1e-3)


def test_an_exact_angle_has_no_count() -> None:
    t = H * np.arange(ROWS)
    held = np.angle(np.exp(1j * (0.3 + 1234.5 * t)))
    rippled = np.angle(np.exp(1j * (0.3 + 1234.5 * t + 0.01 * np.sin(2 * np.pi * 50 * t))))
    noisy = held + 1e-4 * np.random.default_rng(0).standard_normal(ROWS)
    # 0.05 rad a row, summed: the steps differ in their last bits only, whole numbers of
    # one bit (28% of the online tuner's 100-row chunks were read as an encoder's of 7e-15)
    chunk = -1.5486677646162783 + np.cumsum(np.r_[0.0, np.full(99, 0.05)])
    for angle in (held, rippled, noisy, chunk):
        assert angle_count(angle) is None
        assert read_angle(angle) is angle  # read as it is


@settings(max_examples=60, deadline=None)
@given(rate=rates, offset=st.floats(0.0, 1.0), p=poles)
@example(rate=1.5, offset=0.375, p=1)  # every other row rounds alike: an offset stays
def test_an_encoders_rounding_is_averaged_out(rate: float, offset: float, p: int) -> None:
    """Where the rounding runs through 16 counts or more over the log (as the rows sample
    it), the angle read is within a tenth of a count of the truth in its deviation, where
    the rounding's is 0.29, and nowhere a quarter of a count off (the first and last rows
    read the line through the window at their end: the first row's own window would be
    its count as logged). Where it runs through fewer (1.5 counts a row from a whole
    count: every other row rounds the same way, and no window tells that offset from the
    angle), nowhere more than half a count, as logged."""
    count = 2 * np.pi * p / 4096
    if rate * count > 0.5 * np.pi:
        return
    angle, truth = encoder_angle(rate, offset, count)
    read = read_angle(angle)
    error = np.angle(np.exp(1j * (read - truth))) / count
    raw = np.angle(np.exp(1j * (angle - truth))) / count
    assert float(np.std(raw)) > 0.2  # the counts' rounding is there (0.29 at most rates)
    if rounding_cycles(unwrapped(angle), count) < AVERAGED_COUNTS:
        assert float(np.max(np.abs(error))) <= 0.5 + 1e-6
        return
    assert float(np.sqrt(np.mean(error**2))) < 0.1
    assert float(np.max(np.abs(error))) < 0.25


def test_a_held_speeds_error_covers_an_encoders_rounding() -> None:
    """Over 300 held speeds rounded to counts (0.05 to 30 counts a row, random offsets),
    a part's speed is within 3 of its standard errors of the truth every time, its
    standard error at most a count over the part's length; read off the part's two ends,
    it was off by up to a count over its length, 5 to 10 of the standard errors the
    blocks' scatter gave, and a held 47 rad/s was cut into five parts."""
    rng = np.random.default_rng(7)
    count = 2 * np.pi * 9 / 4096
    z = []
    for _ in range(300):
        rate = float(np.exp(rng.uniform(np.log(0.05), np.log(30.0))))
        angle, _ = encoder_angle(rate, float(rng.uniform()), count)
        log = as_log(angle)
        segments = speed_segments(log)
        assert len(segments) == 1
        (_, _, speed), (error,) = segments[0], speed_errors(log, segments)
        truth = rate * count / H
        assert error < 1.01 * count / (H * (ROWS - 1))  # at most a count over the part
        z.append((speed - truth) / error)
    assert float(np.max(np.abs(z))) < 3.0, np.max(np.abs(z))


def test_the_drawn_motors_study_runs_with_an_encoder() -> None:
    """``measure_ramp_draws`` logs the angle as an encoder reads it where asked, and says
    so: the first drawn motor (0.09/0.17 mH, 4 pole pairs) on a 4,096-count encoder is
    learned with its inductances and flux within 3 standard errors."""
    study = measure_ramp_draws(1, 11, progress=False, encoder_counts=4096)
    (case,) = study.cases
    assert case.learned, case.refusal_text
    assert case.largest_z < 3.0
    assert "4096-count encoder" in markdown_ramp(study)[0]


def _online_rows(counts: int | None) -> np.ndarray:
    """The online model's regressors (the dead-time channels last) on 0.3 s of the online
    bench's large motor (0.05 ohm, 0.8 mH, 8 pole pairs: the dead time is most of its
    voltage at low current) on the hardware-like drive, the angle logged by an encoder
    of ``counts`` counts a turn (None: the exact angle), fed in chunks of 100 rows."""
    motor, speed, torque = SPMSM(R_s=0.05, L_s=8e-4, phi_pm=0.25, p=8), 20.0, 20.0
    settings = replace(DriveSettings.hardware_like(h=H), logged_input="commanded",
                       encoder_counts=counts)  # fmt: skip
    w = motor.exogenous(speed, torque)
    levels = np.array([1.0, 1 / 3, -1 / 3, -1.0])

    def reference(t: np.ndarray) -> np.ndarray:
        level = levels[np.floor(t / 0.01).astype(int) % levels.size]
        return np.column_stack([np.full_like(t, w[0]), level * torque])

    F = motor.regulation_problem(speed).F
    law = ControlLaw.regulator(np.eye(2), -F, np.array([[0.0, 0.0], [1.0, 0.0]]))
    log = RealisticDrive(motor, speed, H, settings).run(
        law, held(reference), num_samples=3000, exploration=uniform(10.8), seed=1
    )
    assert log.angle is not None
    model = OnlineModel(H, (1.0,), 2, 2, 2, dead_time=True)
    applied = np.vstack([np.zeros((1, 2)), log.u[:-1]])
    return np.concatenate([
        model.add(log.x[k : k + 100], applied[k : k + 100], log.w[k : k + 100],
                  log.angle[k : k + 100])[1]
        for k in range(0, log.x.shape[0] - 1, 100)
    ])  # fmt: skip


def test_the_online_model_reads_an_encoders_angle() -> None:
    """Chunk by chunk, a 1,024-count encoder's angle gives the online model dead-time
    channels as close to the exact angle's as a 16,384-count one (mean difference 0.0037
    and 0.0031; as logged, 0.0215: on the online bench's large motor the tuner's R_s was
    then within one standard error at 2-6% of the looks of a warm-up)."""
    exact = _online_rows(None)[:, -2:]
    coarse, fine = (np.mean(np.abs(_online_rows(n)[:, -2:] - exact)) for n in (1024, 16384))
    assert coarse <= 1.5 * fine, (coarse, fine)


def test_the_online_study_can_log_an_encoders_angle() -> None:
    """``measure_online(..., encoder_counts=N)`` runs every motor's drive, quick or full,
    with the encoder; by default the angle is exact."""
    for index in range(len(ONLINE_MOTORS)):
        for quick in (True, False):
            exact, counted = (online_config(index, quick, n).drive for n in (None, 4096))
            assert exact is not None and exact.encoder_counts is None
            assert counted is not None and counted.encoder_counts == 4096
