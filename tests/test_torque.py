"""The paper's algorithms on the paper's motor and on motors built at random.

Truth: the model-based optimum (tested against python-control elsewhere) and the motor's
true flux and inductance. The algorithms only see what a drive returns.
"""

from __future__ import annotations

import dataclasses
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from example_counts import examples
from selftune import SPMSM, ConvergenceError, InputError
from selftune.report import Reproduction, evaluate, steady_state
from selftune.sim import SimulatedDrive
from selftune.tuning import TuningSettings, algorithm1, run_algorithm

PAPER = SPMSM.paper()


@pytest.fixture(scope="module")
def paper_results(reproduction: Reproduction) -> dict[str, object]:
    """Each algorithm's result with the paper's settings: the session's ``reproduce(0)``
    ran them (``TuningSettings.paper()``, seed 0), so they are not run again."""
    paper = TuningSettings.paper()
    for field in dataclasses.fields(paper):
        assert np.array_equal(
            getattr(reproduction.settings, field.name), getattr(paper, field.name)
        )
    return {
        name: (reproduction.results[name], reproduction.settings)
        for name in ("1", "2", "3", "offpolicy")
    }


@pytest.mark.parametrize("name", ["2", "3", "offpolicy"])
def test_paper_motor_targets(paper_results: dict, name: str) -> None:  # type: ignore[type-arg]
    result, paper_settings = paper_results[name]
    evaluation = evaluate(result, PAPER, paper_settings)
    assert evaluation.final_theta_error < 1e-5
    assert evaluation.U_error < 1e-4
    assert evaluation.K_error < 1e-5
    # the verdict on noise-free data: stable with margin, errors stated at the data's level
    assert result.quality.stability_margin > 0.0
    assert result.quality.K_relative_se < 1e-4
    if name == "3":
        assert abs(result.identified["phi_pm"] / PAPER.phi_pm - 1) < 1e-4


def test_algorithm1_learns_feedback_but_not_feedforward(paper_results: dict) -> None:  # type: ignore[type-arg]
    result, paper_settings = paper_results["1"]
    evaluation = evaluate(result, PAPER, paper_settings)
    assert evaluation.K_error < 1e-5
    assert all(item.rank == 9 and item.unknowns == 11 for item in result.history)
    assert evaluation.U_error > 0.1
    assert evaluation.final_theta_error > 0.1
    assert not result.feedforward_learned
    assert any("rank 9 of 11" in note and "feedforward" in note for note in result.notes)
    # K is learned: the true value of its feedback meets the learned one (Fig. 5, upper);
    # U is not: the torque settles off T* (Fig. 5, lower).
    assert evaluation.learned_cost[-1] == pytest.approx(evaluation.true_cost[-1], rel=1e-4)
    steady = steady_state(PAPER, paper_settings, result.K, result.X, result.U, result.w)
    assert steady is not None and abs(float(PAPER.torque(steady[1])) - 10.0) > 0.1


def test_algorithm2_true_and_learned_cost_meet(paper_results: dict) -> None:  # type: ignore[type-arg]
    result, paper_settings = paper_results["2"]
    evaluation = evaluate(result, PAPER, paper_settings)
    final_policy = evaluate(result, PAPER, paper_settings).optimum
    x_bar0 = -final_policy.X @ PAPER.exogenous(10.0, 10.0)
    assert x_bar0 @ result.P @ x_bar0 == pytest.approx(x_bar0 @ final_policy.P @ x_bar0, rel=1e-6)
    assert evaluation.learned_cost[-1] == pytest.approx(evaluation.true_cost[-1], rel=1e-4)


def test_off_policy_uses_far_less_data(paper_results: dict) -> None:  # type: ignore[type-arg]
    # The documented claim (docs/bench.md): off-policy reaches 1e-4 on K and U from a batch
    # of a few dozen samples, at least 50 times less motor data than Algorithm 2 needs.
    algorithm2, paper_settings = paper_results["2"]
    batch = replace(paper_settings, episode_length=40 * paper_settings.h, interval=1)
    result = run_algorithm("offpolicy", PAPER, batch)
    evaluation = evaluate(result, PAPER, batch)
    assert evaluation.K_error < 1e-4 and evaluation.U_error < 1e-4
    assert result.data_seconds * 50 <= algorithm2.data_seconds


motors = st.builds(
    SPMSM,
    R_s=st.floats(0.1, 3.0),
    L_s=st.floats(0.003, 0.1),
    phi_pm=st.floats(0.05, 1.0),
    p=st.integers(1, 6),
)


@pytest.mark.slow  # 40 tunings; test_paper_motor_targets and the tune CLI tests run each algorithm
@examples(40, quick=10)
@given(
    motor=motors,
    speed=st.floats(5.0, 200.0),
    current=st.floats(1.0, 20.0),
    name=st.sampled_from(["2", "3", "offpolicy"]),
    seed=st.integers(0, 1000),
)
def test_targets_hold_on_motors_not_seen(
    motor: SPMSM, speed: float, current: float, name: str, seed: int
) -> None:
    """Algorithms 2, 3 and off-policy meet the issue's targets on random motors, with the
    controller held over two samples (the default of ``selftune tune``)."""
    torque = float(motor.torque(current))
    tuning = TuningSettings(speed=speed, torque=torque, input_hold=2, seed=seed)
    result = run_algorithm(name, motor, tuning)  # type: ignore[arg-type]
    evaluation = evaluate(result, motor, tuning)
    assert evaluation.final_theta_error < 1e-5
    assert evaluation.U_error < 1e-4
    if name == "3":
        assert abs(result.identified["phi_pm"] / motor.phi_pm - 1) < 1e-4


def test_an_unstable_initial_policy_is_named() -> None:
    motor = SPMSM(R_s=0.05, L_s=0.0005, phi_pm=0.02, p=5)
    tuning = TuningSettings(speed=300.0, torque=1.0, input_hold=2)
    with pytest.raises(ConvergenceError, match="smaller K0"):
        run_algorithm("offpolicy", motor, tuning)


def test_settings_are_validated() -> None:
    with pytest.raises(InputError, match="episode_length"):
        TuningSettings(h=1e-3, episode_length=1e-3)
    with pytest.raises(InputError, match="Q"):
        TuningSettings(Q=-np.eye(2))
    with pytest.raises(InputError, match="input_hold"):
        TuningSettings(input_hold=0)


def test_regression_interval_keeps_rows_and_holds() -> None:
    assert TuningSettings().regression_interval() == 10
    assert TuningSettings(input_hold=3).regression_interval() % 3 == 0
    short = TuningSettings(episode_length=1e-3)  # 100 samples
    assert 100 // short.regression_interval() >= 33


def test_the_drive_is_what_the_algorithm_sees() -> None:
    """A drive that records its calls: Algorithm 1 asks only for episodes from rest."""
    calls = []

    class Recording(SimulatedDrive):
        def run(self, *args, **kwargs):  # type: ignore[no-untyped-def]
            calls.append(kwargs["num_samples"])
            return super().run(*args, **kwargs)

    drive = Recording(motor=PAPER, speed=10.0, h=1e-5)
    # three episodes are too few to settle: the session says so instead of returning
    with pytest.raises(ConvergenceError, match="did not settle in 3 iterations"):
        algorithm1(drive, TuningSettings(max_iterations=3), PAPER.phi_pm)
    assert calls == [500, 500, 500]


def test_a_wrong_flux_never_simulates_a_motor_that_does_not_exist() -> None:
    """The drive makes the true back-EMF whatever flux the learner assumes; with a wrong
    flux the back-EMF channel cannot be perturbed, and the drive says so."""
    from dataclasses import replace

    from selftune.tuning import offpolicy

    drive = SimulatedDrive(motor=PAPER, speed=10.0, h=1e-5)
    with pytest.raises(InputError, match="back-EMF channel"):
        offpolicy(drive, TuningSettings(), phi_pm=0.5)
    result = offpolicy(drive, replace(TuningSettings(), perturbation="torque"), phi_pm=0.5)
    # w_1 = p speed 0.5 stands for the true back-EMF p speed 0.46: the learned feedforward
    # produces the true u_e for that back-EMF (torque channel aside).
    optimum = evaluate(result, PAPER, TuningSettings()).optimum
    back_emf_true = optimum.U[:, 0] * PAPER.exogenous(10.0, 10.0)[0]
    learned = result.U[:, 0] * result.w[0]
    assert np.linalg.norm(learned - back_emf_true) < 1e-6 * np.linalg.norm(back_emf_true)
