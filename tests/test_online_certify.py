"""A controller is certified before a running drive switches to it.

Truth: the motor's digital optimum from the model package (solve_digital_regulation on
the motor's sampled plant, which the learner never sees), and laws that are known to
fail: a gain that destabilizes the loop, the law in force itself.
"""

from __future__ import annotations

import numpy as np

import selftune
from selftune.core import ControlLaw
from selftune.learn import LearningProblem, SpmsmStructure
from selftune.learn.online import PhysicalEstimate, certify
from selftune.model import solve_digital_regulation

MOTOR = selftune.SPMSM(R_s=0.6, L_s=8e-3, phi_pm=0.35, p=3)
SPEED, H = 50.0, 1e-4
Q, R = 1e3 * np.eye(2), np.eye(2)
STRUCTURE = SpmsmStructure(MOTOR.p * SPEED, H, hold="rotor")
TRUTH = np.array([MOTOR.R_s, MOTOR.L_s, 1.0])
W = MOTOR.exogenous(SPEED, 5.0)


def _problem() -> LearningProblem:
    F = MOTOR.regulation_problem(SPEED).F
    return LearningProblem(Q, R, C=np.eye(2), F=F, integral_action=True)


def _optimum(theta: np.ndarray) -> ControlLaw:
    """The digital optimum (one-sample delay, integral action) of the motor with R_s and
    L_s as in theta, from the model package."""
    motor = selftune.SPMSM(R_s=float(theta[0]), L_s=float(theta[1]), phi_pm=MOTOR.phi_pm, p=3)
    problem = _problem()
    return solve_digital_regulation(
        motor.regulation_problem(SPEED), Q, R, H, input_delay=1,
        integral_weight=problem.integral_weight, plant=motor.sampled_plant(SPEED, H, "rotor"),
    ).law  # fmt: skip


def _with_gain(law: ControlLaw, factor: float) -> ControlLaw:
    assert law.K_i is not None
    return ControlLaw(factor * law.K, law.X, law.U, law.history, factor * law.K_i, law.C, law.F, H)


def _certificate(candidate: ControlLaw, current: ControlLaw, relative_se: float):  # type: ignore[no-untyped-def]
    estimate = PhysicalEstimate(TRUTH, np.diag((relative_se * TRUTH) ** 2), np.zeros((12, 3)))
    loop = _problem().loop(H, 1)
    return certify(candidate, current, estimate, STRUCTURE, loop, (Q, R), W)


def test_the_optimum_replaces_a_detuned_law() -> None:
    """The optimum of a motor known to 0.5% against the optimum of one whose R_s and L_s
    were 30% off: certified, and it saves cost on every plausible plant."""
    best, detuned = _optimum(TRUTH), _optimum(TRUTH * np.array([1.3, 0.7, 1.0]))
    certificate = _certificate(best, detuned, 0.005)
    assert certificate.certified, certificate.reason
    assert certificate.saving > 0.0
    assert np.all(certificate.radii <= certificate.limit)


def test_a_destabilizing_law_is_refused() -> None:
    best = _optimum(TRUTH)
    certificate = _certificate(_with_gain(best, 40.0), best, 0.005)
    assert not certificate.certified
    assert "not stable with margin" in certificate.reason
    assert np.max(certificate.radii) > 1.0


def test_the_law_in_force_is_not_replaced_by_itself() -> None:
    best = _optimum(TRUTH)
    certificate = _certificate(best, best, 0.005)
    assert not certificate.certified
    assert certificate.saving == 0.0


def test_a_saving_within_the_uncertainty_is_not_taken() -> None:
    """The optimum of a motor known to 20% against one 2% off: the saving is within
    what the plausible plants spread it over, so the law in force stays."""
    best, near = _optimum(TRUTH), _optimum(TRUTH * np.array([1.02, 0.98, 1.0]))
    certificate = _certificate(best, near, 0.2)
    assert not certificate.certified, certificate.reason
    assert "law in force stays" in certificate.reason or "not stable" in certificate.reason
