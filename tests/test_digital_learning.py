"""The digital target learned from samples, exactly: discrete-time ADP and identify-then-design.

Truth: the model-based digital optimum (selftune.model.solve_digital_regulation, itself
checked against python-control's dlqr with SLICOT in test_digital_model.py) and the
continuous optimum. The data come from an independent sampled loop with a computation
delay (tests/sampled_loops.py). On noise-free zero-order-hold data both learners are exact
at any sampling period; the paper's continuous learner keeps its quadrature floor.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from example_counts import examples
from sampled_loops import Loop, steps_and_sines
from selftune import SPMSM, ConsistencyError, RegulationProblem, solve_optimal_regulation
from selftune.core import delay_augmented, discretize, dlqr
from selftune.learn import LearningOptions, LearningProblem, Trajectory, learn_controller
from selftune.model import solve_digital_regulation

Q, R = 1e3 * np.eye(2), np.eye(2)


def relative(value: np.ndarray, truth: np.ndarray) -> float:
    return float(np.linalg.norm(value - truth) / np.linalg.norm(truth))


def gentle_K0(motor: SPMSM, h: float) -> np.ndarray:
    """A stabilizing initial controller: 1.25% of the deadbeat gain L_s / h."""
    return 0.0125 * motor.L_s / h * np.eye(2)


def motor_logs(
    motor: SPMSM, speed: float, h: float, delay: int, seed: int, samples: int = 1500
) -> tuple[RegulationProblem, Trajectory, Trajectory]:
    problem = motor.regulation_problem(speed)
    loop = Loop(problem.A, problem.B, problem.D, h, gentle_K0(motor, h), -problem.F)
    base = motor.exogenous(speed, 5.0)
    rng = np.random.default_rng(seed)
    exploration = rng.uniform(-10.0, 10.0, size=(samples, 2))
    applied, commanded = loop.run(delay, steps_and_sines(base, 2.0), exploration)
    return problem, applied, commanded


def knowledge(
    problem: RegulationProblem, K0: np.ndarray, integral: bool = False
) -> tuple[LearningProblem, np.ndarray]:
    """What the learner knows: the problem, and the K0 the data were taken under."""
    return LearningProblem(Q, R, C=np.eye(2), F=problem.F, integral_action=integral), K0


motors = st.builds(
    SPMSM,
    R_s=st.floats(0.1, 3.0),
    L_s=st.floats(0.003, 0.1),
    phi_pm=st.floats(0.05, 1.0),
    p=st.integers(1, 6),
)


@pytest.mark.slow  # 12 motors x 4 learnings; the quicker tests here run each method and log kind
@settings(max_examples=12)
@given(
    motors,
    st.floats(0.05, 1.0),
    st.sampled_from([1e-4, 5e-5]),
    st.sampled_from([0, 1]),
    st.integers(0, 1000),
)
def test_digital_optimum_learned_exactly_on_motors(
    motor: SPMSM, speed_fraction: float, h: float, delay: int, seed: int
) -> None:
    speed = speed_fraction * 2000.0 / motor.p  # up to 2,000 rad/s electrical
    problem, applied, commanded = motor_logs(motor, speed, h, delay, seed)
    truth = solve_digital_regulation(problem, Q, R, h, input_delay=delay)
    known = knowledge(problem, gentle_K0(motor, h))
    for method in ("adp", "identify"):
        for logged, log in (("applied", applied), ("commanded", commanded)):
            options = LearningOptions(
                target="digital", method=method, input_delay=delay, logged_input=logged
            )
            learned = learn_controller(log, *known, options)
            assert learned.state == truth.state
            assert relative(learned.K, truth.K) < 1e-9, (method, logged)
            assert relative(learned.P, truth.P) < 1e-9, (method, logged)
            assert relative(learned.U, truth.U) < 1e-9, (method, logged)


def test_continuous_target_exact_by_identification_and_floored_by_quadrature() -> None:
    motor = SPMSM(R_s=0.6, L_s=8e-3, phi_pm=0.35, p=3)
    problem, applied, _ = motor_logs(motor, 50.0, 1e-4, 0, seed=3, samples=3000)
    optimum = solve_optimal_regulation(problem, Q, R)
    known = knowledge(problem, gentle_K0(motor, 1e-4))
    identified = learn_controller(applied, *known, LearningOptions(method="identify"))
    assert relative(identified.K, optimum.K) < 1e-9
    assert relative(identified.U, optimum.U) < 1e-9
    paper = learn_controller(applied, *known, LearningOptions(method="adp"))
    # the continuous data equation's O(h^2) quadrature leaves a floor far above rounding
    assert 1e-7 < relative(paper.K, optimum.K) < 1e-2


def well_excited_plant(n: int, m: int, seed: int) -> tuple[np.ndarray, np.ndarray] | None:
    """A random stable plant whose inputs reach every state (the controllability Gramian's
    condition below 1e4), so that white exploration excites every quadratic monomial."""
    rng = np.random.default_rng(seed)
    A = -np.diag(rng.uniform(0.5, 3.0, n)) + 0.3 * rng.normal(size=(n, n))
    A -= max(0.0, float(np.max(np.linalg.eigvals(A).real)) + 0.5) * np.eye(n)
    B = rng.normal(size=(n, m))
    gramian = scipy.linalg.solve_continuous_lyapunov(A, -B @ B.T)
    if np.linalg.cond(gramian) > 1e4:
        return None
    return A, B


@examples(15, quick=5)  # up to 12 states: 91 monomials, two learners each
@given(st.integers(1, 6), st.integers(1, 3), st.sampled_from([0, 1, 2]), st.integers(0, 10**6))
def test_plain_state_feedback_on_random_plants(n: int, m: int, delay: int, seed: int) -> None:
    plant = well_excited_plant(n, m, seed)
    assume(plant is not None)
    assert plant is not None
    A, B = plant
    rng = np.random.default_rng(seed + 1)
    h = 0.05 / float(np.max(np.abs(np.linalg.eigvals(A))))
    loop = Loop(A, B, np.zeros((n, 0)), h, np.zeros((m, n)), np.zeros((n, 0)))
    count = 4000
    applied, _ = loop.run(delay, lambda t: np.zeros((t.shape[0], 0)), rng.normal(size=(count, m)))
    Qx = np.eye(n)
    known = (LearningProblem(Qx, np.eye(m)), np.zeros((m, n)))
    exact = discretize(A, B, h)
    Az, Bz = delay_augmented(exact.Ad, exact.Bd, delay)
    Qz = np.zeros_like(Az)
    Qz[:n, :n] = h * Qx
    K_true, P_true = dlqr(Az, Bz, Qz, h * np.eye(m))
    for method in ("adp", "identify"):
        options = LearningOptions(target="digital", method=method, input_delay=delay)
        learned = learn_controller(applied, *known, options)
        assert relative(learned.K, K_true) < 1e-9, method
        assert relative(learned.P, P_true) < 1e-9, method


def test_a_commanded_log_stated_as_applied_is_refused_with_the_shift() -> None:
    motor = SPMSM(R_s=0.9, L_s=3e-3, phi_pm=0.1, p=4)
    problem, _, commanded = motor_logs(motor, 200.0, 1e-4, 1, seed=5)
    known = knowledge(problem, gentle_K0(motor, 1e-4))
    for target in ("continuous", "digital"):
        with pytest.raises(ConsistencyError, match=r"1 sample later.*commanded.*input_delay = 1"):
            learn_controller(commanded, *known, LearningOptions(target=target, input_delay=1))
    auto = learn_controller(
        commanded, *known, LearningOptions(target="digital", input_delay=1, logged_input="auto")
    )
    assert auto.alignment.shift == 1 and auto.alignment.detected_shift == 1


def test_integral_action_learned_exactly() -> None:
    motor = SPMSM(R_s=0.6, L_s=8e-3, phi_pm=0.35, p=3)
    h = 1e-4
    problem, applied, _ = motor_logs(motor, 50.0, h, 1, seed=7, samples=2500)
    known = knowledge(problem, gentle_K0(motor, h), integral=True)
    exact = discretize(problem.A, problem.B, h)
    Az, Bz = delay_augmented(exact.Ad, exact.Bd, 1)
    size = Az.shape[0]
    A_aug = np.zeros((size + 2, size + 2))
    A_aug[:size, :size] = Az
    A_aug[size:, :2] = h * np.eye(2)
    A_aug[size:, size:] = np.eye(2)
    B_aug = np.vstack([Bz, np.zeros((2, 2))])
    Q_aug = np.zeros_like(A_aug)
    Q_aug[:2, :2] = h * Q
    Q_aug[size:, size:] = h * known[0].integral_weight  # type: ignore[operator]
    K_true, _ = dlqr(A_aug, B_aug, Q_aug, h * R)
    for method in ("adp", "identify"):
        options = LearningOptions(target="digital", method=method, input_delay=1)
        learned = learn_controller(applied, *known, options)
        K = np.hstack([learned.K, learned.law.K_i])  # type: ignore[list-item]
        assert relative(K, K_true) < 1e-8, method
    assert "K_i z_k" in learned.law.equations()
