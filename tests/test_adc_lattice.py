"""The ADC's steps read from logged dq currents, and simulated.

Truth: phase currents quantized here by hand, turned to dq with complex exponentials
(independent of the library's transforms), as a drive that measures two or three phases
would log them.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import selftune
from example_counts import examples
from selftune.core import ControlLaw
from selftune.errors import TooLittleData
from selftune.learn import (
    LearnedController,
    LearningOptions,
    LearningProblem,
    Trajectory,
    learn_controller,
)
from selftune.learn.evidence._adc import LATTICE_TOLERANCE, current_lattice
from selftune.sim import DriveSettings, RealisticDrive, held, uniform

#: The phases' directions in the complex plane.
_TURNS = np.exp(2j * np.pi * np.arange(3) / 3)


def _phases(x: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Phase currents of dq currents (amplitude-invariant), by complex exponentials."""
    stationary = (x[:, 0] + 1j * x[:, 1]) * np.exp(1j * angle)
    return np.real(stationary[:, None] * np.conj(_TURNS)[None, :])


def _dq(phases: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """dq currents of phase currents: the space vector (2/3) sum i_x e^(j 2 pi x / 3)."""
    stationary = (2.0 / 3.0) * phases @ _TURNS
    rotor = stationary * np.exp(-1j * angle)
    return np.column_stack([rotor.real, rotor.imag])


def _drive_currents(samples: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """True dq currents (a few amperes, varying) and angles of a spinning motor."""
    rng = np.random.default_rng(seed)
    angle = 0.06 * np.arange(samples) + rng.uniform(0, 2 * np.pi)
    x = np.column_stack(
        [np.cumsum(rng.normal(0, 0.05, samples)), 3.0 + np.cumsum(rng.normal(0, 0.05, samples))]
    )
    return x, angle


def _measured(
    x: np.ndarray, angle: np.ndarray, step: float, phases: int, noise: float, seed: int
) -> np.ndarray:
    """What a drive logs: noisy phases rounded to the ADC's steps (mid-tread), two or
    three of them measured, turned to dq."""
    rng = np.random.default_rng(seed)
    sensed = _phases(x, angle) + noise * rng.standard_normal((x.shape[0], 3))
    rounded = np.round(sensed / step) * step
    if phases == 2:
        rounded[:, 2] = -rounded[:, 0] - rounded[:, 1]
    return _dq(rounded, angle)


@examples(20, quick=5)
@given(
    st.floats(np.log10(5e-3), np.log10(0.2)),
    st.sampled_from([2, 3]),
    st.floats(0.0, 0.5),
    st.integers(0, 10**6),
)
def test_steps_found_whatever_the_phases_measured(
    log_step: float, phases: int, noise_steps: float, seed: int
) -> None:
    """The step is found to 1e-6 of itself, and how many phases are measured."""
    step = 10.0**log_step
    x, angle = _drive_currents(5000, seed)
    measured = _measured(x, angle, step, phases, noise_steps * step, seed + 1)
    lattice = current_lattice(measured, angle)
    assert lattice is not None
    assert abs(lattice.step - step) <= 1e-6 * step
    assert lattice.measured == ("two" if phases == 2 else "three")


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_no_lattice_in_currents_off_one(seed: int) -> None:
    """Unquantized currents, and quantized ones filtered after the ADC, are on none."""
    x, angle = _drive_currents(5000, seed)
    noisy = x + 0.01 * np.random.default_rng(seed).standard_normal(x.shape)
    assert current_lattice(noisy, angle) is None
    quantized = _measured(x, angle, 0.0244, 3, 0.001, seed)
    filtered = 0.5 * (quantized[1:] + quantized[:-1])
    assert current_lattice(filtered, angle[1:]) is None


def test_log_rounding_keeps_the_lattice() -> None:
    """A CSV written to 7 significant digits keeps the steps within the tolerance."""
    x, angle = _drive_currents(5000, 7)
    measured = _measured(x, angle, 0.0244140625, 3, 0.0, 8)
    rounded = np.array([[float(f"{value:.7g}") for value in row] for row in measured])
    lattice = current_lattice(rounded, angle)
    assert lattice is not None
    assert abs(lattice.step - 0.0244140625) <= LATTICE_TOLERANCE * 0.0244140625


@pytest.mark.parametrize("phases", [2, 3])
def test_simulated_measurement_is_the_drives(phases: int) -> None:
    """The lattice's measurement of the true currents, with the same noise, is the
    drive's log; the noise before the ADC is recovered from the errors' covariance."""
    step, noise = 0.05, 0.03
    x, angle = _drive_currents(20000, 11)
    measured = _measured(x, angle, step, phases, noise, 12)
    lattice = current_lattice(measured, angle)
    assert lattice is not None
    drawn = np.random.default_rng(12).standard_normal((x.shape[0], 3)) * noise
    simulated = lattice.measure(x, angle, drawn)
    # the step is found to 1e-9 of itself: rounding differs only at exact half steps
    assert np.mean(np.all(np.isclose(simulated, measured, atol=1e-9), axis=1)) > 0.999
    error = measured - x
    R = np.cov(error.T)
    # the rms of 20,000 draws is known to ~1%; the uniform rounding taken out amplifies it
    assert lattice.noise_sd(R) == pytest.approx(noise, rel=0.05)


def _readme_learned(log: Trajectory) -> LearnedController:
    """The README's example problem learned from ``log`` (dead time on)."""
    F = np.array([[0.0, 0.0], [0.0, -2 / (3 * 3 * 0.35)]])
    problem = LearningProblem(Q=1e3 * np.eye(2), R=np.eye(2), C=np.eye(2), F=F,
                              integral_action=True)  # fmt: skip
    options = LearningOptions(target="digital", input_delay=1, logged_input="commanded",
                              dead_time=True)  # fmt: skip
    return learn_controller(log, problem, np.eye(2), options)


def _readme_drive_log(noise: float, adc: bool) -> Trajectory:
    """0.4 s of the README's drive (hardware-like: 2 V of dead time, a 12-bit ADC over
    +-50 A) with ``noise`` A rms per phase, with or without its ADC."""
    motor = selftune.SPMSM(R_s=0.6, L_s=8e-3, phi_pm=0.35, p=3)
    settings = replace(DriveSettings.hardware_like(h=1e-4), logged_input="commanded",
                       current_noise=noise)  # fmt: skip
    if not adc:
        settings = replace(settings, adc_bits=None, adc_range=None)
    drive = RealisticDrive(motor, 50.0, 1e-4, settings)
    law = ControlLaw.regulator(np.eye(2), np.array([[0.0, 0.0], [0.0, 2 / (3 * 3 * 0.35)]]),
                               np.array([[0.0, 0.0], [1.0, 0.0]]))  # fmt: skip
    reference = held(
        lambda t: np.column_stack([np.full_like(t, 52.5), 5.0 * np.sign(np.sin(200 * t))])
    )
    return drive.run(law, reference, num_samples=4000, exploration=uniform(10.8), seed=3)


def test_coarse_steps_are_simulated_and_stated_fine_ones_are_not() -> None:
    """24.4 mA steps under 2 mA of noise are simulated as rounding and the quality says
    so; under the README's 10 mA (steps 2.4 noise deviations) Gaussian noise of their
    variance is simulated, as without an ADC."""
    coarse = _readme_learned(_readme_drive_log(0.002, adc=True)).quality.notes
    assert any("0.0244 A steps" in note for note in coarse), coarse
    for noise, adc in ((0.01, True), (0.01, False)):
        notes = _readme_learned(_readme_drive_log(noise, adc)).quality.notes
        assert any("signs near zero" in note for note in notes)
        assert not any("A steps" in note for note in notes), (noise, adc, notes)


def test_a_refusal_on_coarse_steps_names_the_adc() -> None:
    """The corpus's 48 V motor (48.8 mA steps, 2 mA of noise) refused at 0.05 s: the
    message names the ADC's steps and the noise before them, not only the length. (At
    0.1 s it is learned, within 2.6 standard errors of the digital optimum: the phase
    currents the ADC reads as exactly 0 no longer take the rounding's signs in the
    dead-time model, whose noise had made the standard error of K 6%.)"""
    from selftune.bench._corpus import MOTORS, CorpusLog, recorded
    from selftune.bench._refusals import _known, _options

    motor = next(motor for motor in MOTORS if motor.name_text == "48 V")
    log = CorpusLog(motor, "realistic drive", 160_002, 2.09e-3, 0.813)
    problem, K0 = _known(motor.experiment)
    with pytest.raises(TooLittleData) as refusal:
        learn_controller(recorded(log, 1000), problem, K0, _options("adp"))
    message = str(refusal.value)
    assert "the currents are whole 48.8 mA steps of an ADC with" in message
    # 2 mA under 48.8 mA steps is below what 2,000 samples resolve: "no noise the errors
    # show" (the rounding's variance is 50 times the noise's)
    assert "before it: its rounding is a fixed function of the current" in message
