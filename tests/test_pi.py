"""The PI equivalent of a learned law (:func:`selftune.learn.pi_equivalent`)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from selftune import SPMSM, InputError
from selftune.config import load_learn_config
from selftune.core import ControlLaw
from selftune.learn import (
    DiscreteModel,
    JudgedPlants,
    LearningOptions,
    LearningProblem,
    learn_controller,
    load_trajectory,
    pi_control_law,
    pi_equivalent,
)
from selftune.model import solve_digital_regulation, solve_optimal_regulation

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "data"
#: The motor examples/data/make_drive_log.py simulates (unknown to the learner).
EXAMPLE_MOTOR, EXAMPLE_SPEED = SPMSM(R_s=0.6, L_s=8e-3, phi_pm=0.35, p=3), 50.0


def _standstill(delay: int) -> tuple[LearningProblem, ControlLaw, JudgedPlants]:
    """A motor at standstill (decoupled axes), its digital servo optimum and its plant."""
    motor, h = SPMSM(R_s=0.6, L_s=8e-3, phi_pm=0.35, p=3), 1e-4
    regulation = motor.regulation_problem(0.0)
    Q, R = 1e3 * np.diag([1.0, 2.0]), np.eye(2)
    problem = LearningProblem(Q, R, C=regulation.C, F=regulation.F, integral_action=True)
    optimum = solve_digital_regulation(
        regulation, Q, R, h, input_delay=delay, integral_weight=problem.integral_weight
    )
    Ad, Bd, Ed = optimum.sampled_plant
    judged = JudgedPlants((DiscreteModel.given(Ad, Bd, Ed, h),), delay, 0.9999)
    return problem, optimum.law, judged


def test_where_the_optimum_is_a_pi_the_pi_equivalent_is_the_optimum() -> None:
    """At standstill without delay the axes are decoupled and the servo optimum is a PI
    per axis: the fit finds it, at no excess cost."""
    problem, law, judged = _standstill(0)
    assert law.K[0, 1] == 0.0 and law.K[1, 0] == 0.0  # a PI indeed
    pi = pi_equivalent(law, problem, judged)
    assert abs(pi.excess_cost) < 1e-9
    np.testing.assert_allclose(pi.k_p, np.diag(law.K), rtol=1e-4)
    np.testing.assert_allclose(pi.k_i, np.diag(law.K_i), rtol=1e-4)
    assert np.max(np.abs(pi.cross)) < 1e-4 * np.max(pi.k_p)
    assert pi.stable and pi.law.history == 0


def test_with_the_delay_the_pi_costs_more_than_the_optimum() -> None:
    """With a delay the optimum feeds back the past voltage, which a PI cannot: the PI
    costs more, and no gain of its structure nearby costs less (a local optimum)."""
    problem, law, judged = _standstill(1)
    pi = pi_equivalent(law, problem, judged)
    assert pi.excess_cost > 1e-6
    assert pi.law.history == 1 and not np.any(pi.law.K[:, 2:])
    for index in range(2):
        for factor in (0.99, 1.01):
            k_p = pi.k_p.copy()
            k_p[index] *= factor
            nearby = pi_control_law(
                k_p, pi.cross, law.X, law.U, k_i=pi.k_i, C=law.C, F=law.F, h=law.h, history=1
            )
            other = pi_equivalent(nearby, problem, judged)  # its own cost is learned_cost
            assert other.learned_cost > pi.cost


def test_the_continuous_target_is_fitted_on_the_continuous_cost() -> None:
    """A continuous-time servo law at standstill is a PI too: found at no excess cost."""
    problem, _, judged = _standstill(0)
    regulation = SPMSM(R_s=0.6, L_s=8e-3, phi_pm=0.35, p=3).regulation_problem(0.0)
    law = solve_optimal_regulation(
        regulation, problem.Q, problem.R, integral_weight=problem.integral_weight, h=1e-4
    ).law
    pi = pi_equivalent(law, problem, judged, target="continuous")
    assert abs(pi.excess_cost) < 1e-9
    np.testing.assert_allclose(pi.k_p, np.diag(law.K), rtol=1e-4)


def test_a_pi_that_fails_the_stability_test_is_said_to() -> None:
    problem, law, judged = _standstill(1)
    strict = replace(judged, largest_radius=0.5)  # no current loop at 10 kHz is this fast
    pi = pi_equivalent(law, problem, strict)
    assert not pi.stable and pi.unstable == 1
    assert pi.document()["stable"] is False
    assert "NOT STABLE" in pi.lines(["u_d", "u_q"], ["i_d", "i_q"])[-1]


def test_a_law_without_a_pi_structure_is_refused() -> None:
    problem, law, judged = _standstill(0)
    regulator = ControlLaw.regulator(law.K, np.zeros((2, 0)), np.zeros((2, 0)))
    with pytest.raises(InputError, match="a PI equivalent needs a reference"):
        pi_equivalent(regulator, problem, judged)
    with pytest.raises(InputError, match="cross: the decoupling acts across axes"):
        pi_control_law([1.0, 1.0], np.eye(2), law.X, law.U)


def test_the_example_logs_pi_is_close_to_the_learned_law_and_to_the_truth() -> None:
    """On the README's log: the PI fitted on the estimated plant costs a few percent more
    than the learned law there, at least the optimum of that plant, and on the true motor
    (evaluation only) about as much more than the true optimum."""
    data = load_trajectory(EXAMPLES / "drive_log.csv")
    config = load_learn_config(EXAMPLES / "learn.toml", data.n, data.m, data.q)
    problem = LearningProblem(
        config.Q, config.R, C=config.C, E=config.E, F=config.F, integral_action=True
    )
    learned = learn_controller(data, problem, config.K0, LearningOptions(**config.options))
    assert learned.judged is not None and len(learned.judged.models) > 1
    pi = pi_equivalent(learned.law, problem, learned.judged)
    assert pi.stable
    assert 0.0 < pi.excess_cost < 0.1
    model = learned.judged.models[0]
    regulation = EXAMPLE_MOTOR.regulation_problem(EXAMPLE_SPEED)
    fitted = solve_digital_regulation(
        regulation, config.Q, config.R, model.h, input_delay=1,
        integral_weight=problem.integral_weight, plant=(model.Ad, model.Bd, model.Ed[:, :2]),
    )  # fmt: skip
    assert pi.cost >= np.trace(fitted.P[:2, :2]) * (1.0 - 1e-9)
    # the truth: the same PI on the true motor, over the true optimum
    true = solve_digital_regulation(
        regulation, config.Q, config.R, model.h, input_delay=1,
        integral_weight=problem.integral_weight,
        plant=EXAMPLE_MOTOR.sampled_plant(EXAMPLE_SPEED, model.h, "stationary"),
    )  # fmt: skip
    loop = problem.loop(model.h, 1)
    value = loop.value(true.sampled_plant[:2], pi.law, loop.weights(config.Q, config.R))
    on_truth = np.trace(value[:2, :2]) / np.trace(true.P[:2, :2]) - 1.0
    assert 0.0 < on_truth < 0.1
    assert on_truth == pytest.approx(pi.excess_cost, rel=0.5)
