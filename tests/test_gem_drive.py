"""gym-electric-motor as a plant (:class:`selftune.sim._gem.GemDrive`) against the exact drives.

Agreement found (paper motor, 100 rad/s, h = 100 us, 500 samples, K = 20 pi V/A, 1 V
uniform exploration; GEM 3.0.3 with scipy's dop853 at rtol = atol = 1e-14):

- currents vs SimulatedDrive (expm): 1.3e-15 of their peak (4.5e-15 at 1000 rad/s,
  1.6e-14 at 10000); GEM's default dopri5 2.7e-13 (6e-8 at 1000 rad/s), its Euler 3.9e-3;
- one-sample delay, a law with a past input and integral action, vs RealisticDrive with
  the dq hold: 1.7e-15; at no load 1.3e-15;
- off-policy session, torque-only reference perturbation: K and U equal the session on
  SimulatedDrive to 4e-10 (the regression amplifies the 1e-15 differences in the data by
  about 1e5); against the continuous optimum 2.7e-5 (K) and 2.6e-5 (U), the learner's
  own floor at 10 kHz (worst of seeds 0-7: 5.7e-5 and 2.6e-5). With the paper's
  perturbation of the back-EMF channel the session refuses (ConvergenceError: P not
  positive definite): GEM's back-EMF is the motor's own and cannot follow ``w_1``.

About 6,500 GEM steps per second with dop853 (8,800 with dopri5, 14,000 with Euler).
"""

from __future__ import annotations

import importlib
from typing import Any

import numpy as np
import pytest
from numpy.typing import NDArray

pytest.importorskip("gym_electric_motor")

from selftune import SPMSM, InputError
from selftune.core import ControlLaw
from selftune.learn import Trajectory
from selftune.model import solve_optimal_regulation
from selftune.sim import SimulatedDrive, constant, uniform
from selftune.sim._gem import GemDrive
from selftune.sim._realistic import DriveSettings, RealisticDrive
from selftune.tuning import TuningSettings, offpolicy

Array = NDArray[np.float64]
MOTOR = SPMSM.paper()
SPEED = 100.0  # rad/s, GEM's default held speed
H = 1e-4  # s, GEM's default tau (10 kHz)
SAMPLES = 500
K0 = 20.0 * np.pi * np.eye(2)  # V/A: K0 h / L_s = 0.1, a stable sampled loop
X = np.array([[0.0, 0.0], [0.0, 2.0 / (3.0 * MOTOR.p * MOTOR.phi_pm)]])
W = np.array([MOTOR.p * SPEED * MOTOR.phi_pm, 10.0])  # [p speed phi_pm (V), T* (N m)]

#: dop853 keeps each step's local error under ~1e-14 of the state; the closed loop
#: contracts by about K0 h / L_s = 0.1 per step, so errors add up to at most ~10 local
#: ones: 1e-13 of the peak current. Measured: 1.3e-15 (roundoff).
CURRENT_TOLERANCE = 1e-13


def _peak_error(gem: Trajectory, exact: Trajectory, gain: Array) -> None:
    """Currents within CURRENT_TOLERANCE of their peak; voltages within what the gain
    makes of that (plus GEM's roundoff in turning dq volts to duty cycles and back)."""
    current_bound = CURRENT_TOLERANCE * float(np.max(np.abs(exact.x)))
    np.testing.assert_allclose(gem.x, exact.x, rtol=0.0, atol=current_bound)
    voltage_bound = float(np.linalg.norm(gain, 2)) * current_bound + 1e-15 * 1000.0
    np.testing.assert_allclose(gem.u, exact.u, rtol=0.0, atol=voltage_bound)
    assert gem.w is not None and exact.w is not None
    np.testing.assert_array_equal(gem.w, exact.w)
    np.testing.assert_array_equal(gem.t, exact.t)


def test_gem_gives_the_exact_currents_of_the_ideal_drive() -> None:
    law = ControlLaw.regulator(K0, X, np.zeros((2, 2)))
    options: dict[str, Any] = {
        "num_samples": SAMPLES,
        "exploration": uniform(1.0),
        "seed": 3,
    }
    gem = GemDrive(MOTOR, SPEED, H).run(law, constant(W), **options)
    exact = SimulatedDrive(MOTOR, SPEED, H).run(law, constant(W), **options)
    assert float(np.max(np.abs(exact.x))) > 5.0  # the loop moved: a real comparison
    _peak_error(gem, exact, K0)


def test_gem_at_no_load_is_the_ideal_drive_at_no_load() -> None:
    law = ControlLaw.regulator(K0, np.zeros((2, 1)), np.zeros((2, 1)))
    options: dict[str, Any] = {
        "num_samples": SAMPLES,
        "exploration": uniform(1.0),
        "seed": 5,
    }
    gem = GemDrive(MOTOR, SPEED, H).run_no_load(law, **options)
    exact = SimulatedDrive(MOTOR, SPEED, H).run_no_load(law, **options)
    assert gem.w is not None and gem.w.shape == (SAMPLES + 1, 1)
    _peak_error(gem, exact, K0)


def test_a_delay_a_past_input_and_an_integrator_run_as_the_realistic_drive_does() -> None:
    """The adapter's delay holds the dq voltage, as RealisticDrive's "rotor" hold does."""
    F = np.array([[0.0, 0.0], [0.0, -X[1, 1]]])
    law = ControlLaw(
        K=np.hstack([K0, 0.2 * np.eye(2)]),
        X=X,
        U=np.array([[0.0, 0.0], [1.0, 0.0]]),
        history=1,
        K_i=2000.0 * np.eye(2),
        C=np.eye(2),
        F=F,
        h=H,
    )
    options: dict[str, Any] = {
        "num_samples": SAMPLES,
        "exploration": uniform(1.0),
        "seed": 11,
    }
    gem = GemDrive(MOTOR, SPEED, H, input_delay=1).run(law, constant(W), **options)
    settings = DriveSettings(input_delay=1, voltage_hold="rotor")
    exact = RealisticDrive(MOTOR, SPEED, H, settings).run(law, constant(W), **options)
    np.testing.assert_array_equal(gem.u[0], [0.0, 0.0])  # nothing applied before the first
    _peak_error(gem, exact, law.K)


def test_a_self_tuning_session_on_gem_reaches_the_optimum() -> None:
    """Off-policy on 50 ms of GEM data at 10 kHz: the continuous learner's floor there is
    O(h^2): 2.7e-5 on K and 2.6e-5 on U for seed 0 (5.7e-5 at worst over seeds 0-7), so
    1e-4. The paper's perturbation moves the back-EMF channel, which GEM's motor cannot
    follow (its back-EMF is its own): the torque channel only."""
    settings = TuningSettings(
        speed=SPEED,
        torque=10.0,
        h=H,
        episode_length=0.05,
        K0=K0,
        perturbation="torque",
        input_hold=1,
    )
    result = offpolicy(GemDrive(MOTOR, SPEED, H), settings, MOTOR.phi_pm)
    ideal = offpolicy(SimulatedDrive(MOTOR, SPEED, H), settings, MOTOR.phi_pm)
    optimum = solve_optimal_regulation(MOTOR.regulation_problem(SPEED), settings.Q, settings.R)
    assert result.quality.stability_margin > 0.0

    def relative(a: Array, b: Array) -> float:
        return float(np.linalg.norm(a - b) / np.linalg.norm(b))

    # The same data to 1e-13 (above); the regression amplifies them by about 1e5.
    assert relative(result.K, ideal.K) < 1e-8
    assert relative(result.U, ideal.U) < 1e-8
    assert relative(result.K, optimum.K) < 1e-4
    assert relative(result.U, optimum.U) < 1e-4


def test_a_missing_gem_is_one_line_naming_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    real = importlib.import_module

    def without_gem(name: str, package: str | None = None) -> Any:
        if name.split(".")[0] == "gym_electric_motor":
            raise ModuleNotFoundError(f"No module named {name!r}")
        return real(name, package)

    monkeypatch.setattr(importlib, "import_module", without_gem)
    law = ControlLaw.regulator(K0, X, np.zeros((2, 2)))
    with pytest.raises(InputError) as caught:
        GemDrive(MOTOR, SPEED, H).run(law, constant(W), num_samples=10, exploration=None, seed=0)
    message = str(caught.value)
    assert "\n" not in message
    assert "pip install 'selftune[gem]'" in message


def test_a_command_gem_would_clip_is_refused() -> None:
    law = ControlLaw.regulator(K0, X, np.zeros((2, 2)))
    with pytest.raises(InputError, match="dc_voltage"):
        GemDrive(MOTOR, SPEED, H, dc_voltage=100.0).run(
            law, constant(W), num_samples=SAMPLES, exploration=None, seed=0
        )


def test_a_failed_ode_step_is_refused_and_no_warning_leaks(
    recwarn: pytest.WarningsRecorder,
) -> None:
    """scipy's integrator only warns when it gives up (and returns where it stopped): at
    50 ms samples and 1000 rad/s the rotor turns 100 rad within one, too far for dop853's
    500 steps at 1e-14."""
    law = ControlLaw.regulator(np.zeros((2, 2)), X, np.zeros((2, 2)))
    drive = GemDrive(MOTOR, 1000.0, 0.05, dc_voltage=1e4)
    with pytest.raises(InputError, match="h: GEM's ODE solver failed within sample 0"):
        drive.run(law, constant(W), num_samples=3, exploration=None, seed=0)
    assert not recwarn.list


@pytest.mark.parametrize(
    ("field", "value"),
    [("speed", float("nan")), ("h", 0.0), ("dc_voltage", -1.0), ("input_delay", -1),
     ("ode_solver", "rk4")],
)  # fmt: skip
def test_invalid_fields_are_named(field: str, value: object) -> None:
    given: dict[str, Any] = {"motor": MOTOR, "speed": SPEED, "h": H, field: value}
    with pytest.raises(InputError, match=rf"^{field}:"):
        GemDrive(**given)
