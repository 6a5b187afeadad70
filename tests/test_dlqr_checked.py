"""The Riccati solve without re-checking weights already checked gives the same law.

Truth: :func:`~selftune.core.dlqr` with its checks, on the same augmented plants and
weights (the identify-then-design path skips them only for the digital cost of a
checked problem).
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from selftune.core import dlqr
from selftune.errors import UnsolvableError
from selftune.learn import LearningProblem
from selftune.learn.evidence._discrete_model import DiscreteModel
from selftune.learn.learners._identify import design_digital

H, W_E = 1e-4, 471.0


def _plant(R_s: float, L_s: float) -> tuple[np.ndarray, np.ndarray]:
    A = np.array([[-R_s / L_s, W_E], [-W_E, -R_s / L_s]])
    Ad = scipy.linalg.expm(A * H)
    return Ad, np.linalg.solve(A, Ad - np.eye(2)) / L_s


def _problem() -> LearningProblem:
    return LearningProblem(1e3 * np.eye(2), np.eye(2), C=np.eye(2), F=-np.eye(2),
                           integral_action=True)  # fmt: skip


@pytest.mark.parametrize("delay", [0, 1, 2])
def test_the_checked_solve_gives_the_same_gain_and_value(delay: int) -> None:
    """On motors from 0.2 to 2 ohm and 2 to 20 mH, with 0 to 2 samples of delay and
    integral action: K and P equal, not near."""
    problem = _problem()
    loop = problem.loop(H, delay)
    rng = np.random.default_rng(delay)
    for R_s, L_s in zip(rng.uniform(0.2, 2.0, 6), rng.uniform(2e-3, 2e-2, 6), strict=True):
        plant = _plant(R_s, L_s)
        weights = loop.weights(problem.Q, problem.R)
        Az, Bz = loop.augmented(*plant)
        K, P = dlqr(Az, Bz, weights.Qz, weights.Rz, weights.Nz)
        K_checked, P_checked = dlqr(Az, Bz, weights.Qz, weights.Rz, weights.Nz, checked=True)
        np.testing.assert_array_equal(K_checked, K)
        np.testing.assert_array_equal(P_checked, P)
        design = design_digital(DiscreteModel.given(*plant, np.zeros((2, 2)), H), problem, delay)
        Kz, Pz = loop.optimum(plant, weights)
        np.testing.assert_array_equal(loop.gain(design.law), Kz)
        np.testing.assert_array_equal(design.P, Pz)


def test_the_checked_solve_still_refuses_an_unstabilizable_plant() -> None:
    """The stabilizability check stays: the same message with the checks skipped."""
    A, B = np.diag([1.5, 0.5]), np.array([[0.0], [1.0]])
    with pytest.raises(UnsolvableError) as full:
        dlqr(A, B, np.eye(2), np.eye(1))
    with pytest.raises(UnsolvableError) as checked:
        dlqr(A, B, np.eye(2), np.eye(1), checked=True)
    assert str(checked.value) == str(full.value)
    assert "not stabilizable" in str(full.value)
