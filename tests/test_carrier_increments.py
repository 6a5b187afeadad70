"""The carrier's pulses against the held model (:func:`carrier_increments`), checked on
the simulator's own carrier PWM: its legs' edges and each pulse's exact response in an
interior motor's rotor frame (:mod:`selftune.sim._salient`), code the learner does not
share."""

from __future__ import annotations

import numpy as np
import pytest

from selftune.core import rotating_hold
from selftune.core._phases import CLARKE
from selftune.learn.evidence._dead_time import phase_sign_values, phase_signs
from selftune.learn.evidence._ipmsm_structure import IpmsmStructure
from selftune.learn.evidence._pulses import carrier_increments
from selftune.sim._pwm import carrier_edges
from selftune.sim._salient import RotorFrame

H = 1e-4


def _simulated(frame: RotorFrame, a: np.ndarray, x: np.ndarray, angle: float, bus: float,
               dead_time: float) -> np.ndarray:  # fmt: skip
    """The simulator's increment of one sample's pulses (the start's current aside)."""
    advance = 0.5 * frame.speed * H
    command = complex(*a) * np.exp(1j * (angle + advance))
    signs = phase_sign_values(x[np.newaxis], np.array([angle]))[0]
    edges = carrier_edges(command, bus, H, dead_time, signs.tolist())
    total = 0j
    for (rise, fall), direction in zip(edges, CLARKE, strict=True):
        if fall > rise:
            total += frame.pulse(rise, fall, bus * complex(direction) * np.exp(-1j * angle))
    return np.array([total.real, total.imag])


@pytest.mark.parametrize("seed", range(6))
def test_the_carriers_pulses_are_the_held_model_plus_the_increments(seed: int) -> None:
    """Drawn interior motors (L_q / L_d 1-3, 25 uH-10 mH, speeds to w_e T = 0.3), voltages
    to the modulation's limit, 0-4 us of dead time: the simulator's increment equals the
    held model's plus :func:`carrier_increments`' to 1e-7 of the increment."""
    rng = np.random.default_rng(seed)
    L_d = 10 ** rng.uniform(np.log10(25e-6), -2)
    L_q = L_d * rng.uniform(1.0, 3.0)
    R_s = L_d * rng.uniform(5.0, 500.0)
    speed = rng.uniform(0.0, 0.3) / H
    bus = rng.choice([48.0, 540.0])
    dead_time = rng.uniform(0.0, 4e-6)
    v = dead_time * bus / H
    theta = np.array([R_s, L_d, L_q, 1.0, v])
    A, B = IpmsmStructure(speed, H, dead_time=True).continuous(theta)
    frame = RotorFrame.build(R_s, L_d, L_q, 0.0, speed, H)
    count = 40
    angle = rng.uniform(-np.pi, np.pi, count)
    x = rng.normal(size=(count, 2))
    a = (
        bus
        / np.sqrt(3)
        * rng.uniform(0.0, 1.0, (count, 1))
        * np.column_stack([np.cos(phase := rng.uniform(-np.pi, np.pi, count)), np.sin(phase)])
    )
    advance = 0.5 * speed * H
    increments = carrier_increments((A, B, H, speed), x, a, (angle, advance, bus, v))
    held = rotating_hold(A, B, H, speed, advance)
    signs = phase_signs(x, angle) @ rotating_hold(A, B, H, speed).T
    model = a @ held.T - v * signs
    simulated = np.array(
        [_simulated(frame, a[k], x[k], float(angle[k]), bus, dead_time) for k in range(count)]
    )
    scale = np.max(np.abs(simulated))
    np.testing.assert_allclose(model + increments, simulated, atol=1e-7 * scale)
    assert np.max(np.abs(increments)) > 1e-5 * scale  # the pulses differ from the hold
