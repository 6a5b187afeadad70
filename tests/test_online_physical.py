"""A surface PMSM's parameters read off the running model, and a change detected.

Truth: the library's realistic drive (PWM, dead time, ADC, noise: a simulation the
structure's code does not share) for the estimates; for the change test, a dq motor
simulated here with scipy's matrix exponential, its resistance stepped.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.linalg

import selftune
from selftune.core import ControlLaw
from selftune.learn import SpmsmStructure
from selftune.learn.online import ChangeWatch, OnlineModel, physical_estimate
from selftune.sim import DriveSettings, RealisticDrive, held, uniform

MOTOR = selftune.SPMSM(R_s=0.6, L_s=8e-3, phi_pm=0.35, p=3)
SPEED, TORQUE, H = 50.0, 5.0, 1e-4
LEVELS = np.array([1.0, 1 / 3, -1 / 3, -1.0])


def _drive_log(seed: int, samples: int) -> selftune.Trajectory:
    """The README's drive, hardware-like (2 V of dead time, 10 mA, a 12-bit ADC)."""
    settings = replace(DriveSettings.hardware_like(h=H), logged_input="commanded")
    drive = RealisticDrive(MOTOR, SPEED, H, settings)
    w = MOTOR.exogenous(SPEED, TORQUE)
    F = MOTOR.regulation_problem(SPEED).F

    def reference(t: np.ndarray) -> np.ndarray:
        level = LEVELS[np.floor(t / 0.01).astype(int) % LEVELS.size]
        return np.column_stack([np.full_like(t, w[0]), level * TORQUE])

    law = ControlLaw.regulator(np.eye(2), -F, np.array([[0.0, 0.0], [1.0, 0.0]]))
    return drive.run(law, held(reference), num_samples=samples, exploration=uniform(10.8),
                     seed=seed)  # fmt: skip


def _fed(model: OnlineModel, log: selftune.Trajectory, chunk: int) -> OnlineModel:
    """The log's rows in chunks; the commanded voltage of row k - 1 is applied in row k."""
    applied = np.vstack([np.zeros((1, 2)), log.u[:-1]])
    rows = log.x.shape[0] - 1
    assert log.angle is not None
    for start in range(0, rows, chunk):
        stop = min(start + chunk, rows)
        model.add(log.x[start:stop], applied[start:stop], log.w[start:stop],
                  log.angle[start:stop])  # fmt: skip
    return model


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_parameters_are_within_their_errors_on_a_realistic_drive(seed: int) -> None:
    """1 s: R_s, L_s, kappa and the dead-time voltage within 3 standard errors."""
    model = _fed(OnlineModel(H, (10.0,), 2, 2, 2, dead_time=True), _drive_log(seed, 10_000), 100)
    structure = SpmsmStructure(MOTOR.p * SPEED, H, dead_time=True, hold="stationary")
    fitted = model.model()
    estimate = physical_estimate(fitted, structure, structure.initial(fitted))
    truth = np.array([MOTOR.R_s, MOTOR.L_s, 1.0, 2.0])
    scores = (estimate.theta - truth) / estimate.standard_errors
    assert np.all(np.abs(scores) < 3.0), scores


def _dq_motor(samples: int, seed: int, R_s: np.ndarray, noise: float) -> tuple[np.ndarray, ...]:
    """A surface PMSM in dq under a held dq voltage (exact by the matrix exponential),
    the resistance per sample given; a proportional current loop with exploration whose
    command is applied a sample later (a digital drive's delay). Rows: the measured
    current, the voltage applied over the sample and w."""
    rng = np.random.default_rng(seed)
    L, w_e, emf = MOTOR.L_s, MOTOR.p * SPEED, MOTOR.p * SPEED * MOTOR.phi_pm
    x, rows, pending = np.zeros(2), [], np.zeros(2)
    maps: dict[float, np.ndarray] = {}
    for k in range(samples):
        R = float(R_s[k])
        if R not in maps:
            A = np.array([[-R / L, w_e, 0.0], [-w_e, -R / L, -emf / L], [0.0, 0.0, 0.0]])
            block = np.zeros((5, 5))
            block[:3, :3] = A
            block[:2, 3:] = np.eye(2) / L
            maps[R] = scipy.linalg.expm(block * H)
        measured = x + noise * rng.standard_normal(2)
        torque = TORQUE * LEVELS[(k // 100) % LEVELS.size]
        target = np.array([0.0, 2.0 * torque / (3.0 * MOTOR.p * MOTOR.phi_pm)])
        applied = pending
        pending = 5.0 * (target - measured) + rng.uniform(-10.8, 10.8, 2)
        rows.append((measured, applied, torque))
        x = (maps[R] @ np.concatenate([x, [1.0], applied]))[:2]
    measured = np.array([row[0] for row in rows])
    applied = np.array([row[1] for row in rows])
    w = np.column_stack([np.full(samples, emf), [row[2] for row in rows]])
    return measured, applied, w


def _watched(R_s: np.ndarray, seed: int, false_alarm: float) -> list[bool]:
    """The change watch over 500 transitions, every 100 samples, against the 1 s model
    (its reference renewed every 0.1 s from 0.2 s on)."""
    x, a, w = _dq_motor(R_s.size, seed, R_s, 0.01)
    structure = SpmsmStructure(MOTOR.p * SPEED, H, hold="rotor")
    model, watch = OnlineModel(H, (1.0,), 2, 2, 2), ChangeWatch(500, false_alarm)
    alarms, start = [], np.array([0.5, 7e-3, 1.0])
    for k in range(0, R_s.size, 100):
        test = watch.add(*model.add(x[k : k + 100], a[k : k + 100], w[k : k + 100]))
        if test is not None:
            alarms.append(test.changed)
        if k >= 2000 and k % 1000 == 0:
            estimate = physical_estimate(model.model(), structure, start)
            start = estimate.theta
            Theta, _, covariance = model.moments[0].estimate()
            noise = model.moments[0].noise(Theta)
            watch.reference(Theta, noise, estimate.sensitivities, covariance)
    return alarms


@pytest.mark.parametrize("seed", [3, 7])
def test_the_false_alarms_are_as_stated(seed: int) -> None:
    """5 s without a change, about 480 windows at a 1% false-alarm probability each:
    about 1% alarm (overlapping windows are correlated, so the count spreads wider than
    a binomial's: at most 3% is asked; without the window's end terms in the variance
    it was 40%)."""
    alarms = _watched(np.full(50_000, MOTOR.R_s), seed, 0.01)
    assert np.mean(alarms) <= 0.03, np.mean(alarms)


@pytest.mark.parametrize("seed", [2, 7, 9])
def test_a_resistance_step_is_detected_within_50_ms(seed: int) -> None:
    """R_s +20% at 2 s (a loose connection), 10 mA of noise, 1-3 A: no alarm before at a
    1e-4 false-alarm probability, an alarm within 50 ms after (measured: in the chunk of
    the step, 0-10 ms, on four seeds)."""
    R_s = np.full(30_000, MOTOR.R_s)
    R_s[20_000:] *= 1.2
    alarms = _watched(R_s, seed, 1e-4)
    # the first test is of the chunk after the first reference (at 0.2 s): alarms[i] is
    # the chunk starting at sample 2,100 + 100 i
    step = (20_000 - 2_100) // 100
    assert not any(alarms[:step])
    assert any(alarms[step : step + 5])


def test_a_renewed_reference_scores_the_whole_window_again() -> None:
    """Every chunk of a window is scored against one reference: after a look renews it,
    the test is a fresh watch's on the same chunks with the new reference (before, the
    window kept chunks scored against the last reference; where their loads cancelled,
    the variance missed the two references' difference and a warming motor alarmed)."""
    x, a, w = _dq_motor(4_000, 5, np.full(4_000, MOTOR.R_s), 0.01)
    structure = SpmsmStructure(MOTOR.p * SPEED, H, hold="rotor")
    model, watch = OnlineModel(H, (1.0,), 2, 2, 2), ChangeWatch(500, 1e-4)

    def renewed(target: ChangeWatch) -> None:
        estimate = physical_estimate(model.model(), structure, np.array([0.5, 7e-3, 1.0]))
        Theta, _, covariance = model.moments[0].estimate()
        target.reference(Theta, model.moments[0].noise(Theta), estimate.sensitivities,
                         covariance)  # fmt: skip

    def chunk(k: int) -> tuple[np.ndarray, ...]:
        return model.add(x[k : k + 100], a[k : k + 100], w[k : k + 100])

    for k in range(0, 2_000, 100):
        chunk(k)
    renewed(watch)
    held = [chunk(k) for k in range(2_000, 2_400, 100)]
    first = [watch.add(*rows) for rows in held]
    renewed(watch)
    fresh = ChangeWatch(500, 1e-4)
    renewed(fresh)
    held.append(chunk(2_400))
    kept = watch.add(*held[-1])
    alone = [fresh.add(*rows) for rows in held][-1]
    assert kept is not None and alone is not None and first[-1] is not None
    np.testing.assert_allclose(kept.scores, alone.scores, rtol=1e-12, atol=0)
    assert not np.allclose(kept.scores, first[-1].scores, rtol=1e-6, atol=0)
