"""The output-error fit's ways of saving time and memory change no result beyond rounding.

A log longer than ``BLOCK_TRANSITIONS`` has its sensitivities made and used block by block
(normal equations and Newey-West sums carried over the blocks); refits run side by side,
one propagation a step for all of them. Both must give the fit that holding everything and
fitting one at a time gives, to the rounding the normal equations' conditioning allows.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from selftune.learn.evidence import _propagation
from selftune.learn.evidence._output_error import (
    OutputErrorFit,
    _gauss_newton,
    _Log,
    _search,
    _unstructured,
    simulate_model,
)
from selftune.learn.evidence._propagation import _run_searches

N, M, Q, H = 2, 2, 1, 1e-4
AD = np.array([[0.95, 0.02], [-0.03, 0.9]])
BD = np.array([[0.1, 0.0], [0.01, 0.12]])
ED = np.array([[0.05], [-0.02]])
NOISE = 0.01


def _matrices(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return _unstructured(theta, N, M, Q)


def _noisy_log(samples: int, seed: int) -> _Log:
    """A log of the model above under white inputs, a stepped reference and white noise."""
    rng = np.random.default_rng(seed)
    a = rng.standard_normal((samples, M))
    w = np.repeat(rng.choice([-1.0, 1.0], size=(samples // 50 + 1, Q)), 50, axis=0)[:samples]
    x = simulate_model((AD, BD, ED), np.zeros(N), a, w)
    return _Log(x=x + NOISE * rng.standard_normal(x.shape), a=a, w=w)


def _start() -> np.ndarray:
    theta = np.concatenate([AD, BD, ED], axis=1).ravel(order="F")
    return theta * (1.0 + 0.02 * np.sin(np.arange(theta.size)))


def _fit(logs: list[_Log]) -> OutputErrorFit:
    return _gauss_newton(logs, _start(), _matrices, False, 20, H, np.full(N, 1e-12))


def _close(first: np.ndarray, second: np.ndarray, condition: float) -> None:
    """Equal up to rounding amplified by the normal equations' condition number."""
    tolerance = 100 * np.finfo(float).eps * condition
    assert float(np.max(np.abs(first - second))) <= tolerance * float(np.max(np.abs(first)))


def _same_minimum(fit: OutputErrorFit, theta: np.ndarray) -> None:
    """``theta`` is ``fit``'s minimum as far as the search's stopping rule tells: it stops
    when a step lowers the cost by less than 1e-12 of it, and the cost (about the number
    of output errors at the minimum) rises by (dtheta / se)^2 / 2 away from it, so two
    stops differ by at most sqrt(2e-12 cost) standard errors; rounding can move a stop."""
    cost = sum(residual.size for residual in fit.residuals)
    se = np.sqrt(np.diag(fit.parameter_covariance))
    assert float(np.max(np.abs(theta - fit.parameters) / se)) <= np.sqrt(2e-12 * cost)


@pytest.mark.parametrize("block", [97, 1000])
def test_a_long_log_fitted_block_by_block_gives_the_fit_held_whole(
    monkeypatch: pytest.MonkeyPatch, block: int
) -> None:
    logs = [_noisy_log(3000, 1), _noisy_log(1200, 2)]
    whole = _fit(logs)
    assert whole.iterations > 1  # the search moved, with steps from the normal equations
    monkeypatch.setattr(_propagation, "BLOCK_TRANSITIONS", block)
    blocks = _fit(logs)
    _same_minimum(whole, blocks.parameters)
    condition = whole.model.condition
    _close(whole.parameter_covariance, blocks.parameter_covariance, condition)
    _close(whole.noise_covariance, blocks.noise_covariance, condition)
    assert blocks.correlation_inflation == pytest.approx(whole.correlation_inflation, rel=1e-9)


def test_searches_side_by_side_give_the_fits_one_at_a_time() -> None:
    draws = [[_noisy_log(1500, seed)] for seed in (3, 4, 5, 6)]
    floor = np.full(N, 1e-12)
    searches = [_search(logs, _start(), (_matrices, False), 20, floor) for logs in draws]
    for logs, (theta, *_) in zip(draws, _run_searches(searches), strict=True):
        _same_minimum(_fit(logs), theta)


def test_the_adp_rows_summed_block_by_block_are_the_same(monkeypatch: pytest.MonkeyPatch) -> None:
    """The digital ADP's regression rows made a few intervals at a time (as a long log's
    are) give the same controller, bit for bit: each interval's sum is over the same
    rows."""
    import selftune
    import selftune.learn.learners._digital as digital
    from selftune.learn import LearningOptions, LearningProblem, learn_controller

    root = Path(__file__).resolve().parents[1] / "examples" / "data"
    log = selftune.load_trajectory(root / "drive_log.csv")
    F = np.array([[0.0, 0.0], [0.0, -2 / (3 * 3 * 0.35)]])
    problem = LearningProblem(1e3 * np.eye(2), np.eye(2), C=np.eye(2), F=F, integral_action=True)
    options = LearningOptions(
        target="digital", input_delay=1, logged_input="commanded", dead_time=True
    )
    whole = learn_controller(log, problem, np.eye(2), options)
    monkeypatch.setattr(digital, "ROW_BLOCK", 97)
    blocked = learn_controller(log, problem, np.eye(2), options)
    np.testing.assert_array_equal(blocked.K, whole.K)
    np.testing.assert_array_equal(blocked.U, whole.U)


def test_a_structure_at_its_domains_edge_has_a_forward_difference_jacobian() -> None:
    """A structure that has no model below zero in its first parameter (an inductance) and
    a point within one difference step of zero: the Jacobian's column is the forward
    difference there, the others central, and each agrees with the derivative in closed
    form (a search on a 25 uH motor with 2 V of dead time reached such a point and the
    step below it raised an input error on the user's behalf)."""
    from selftune.errors import InputError
    from selftune.learn.evidence._output_error import _jacobian_map

    def structure(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        inductance, gain = float(theta[0]), float(theta[1])
        if not inductance > 0.0:
            raise InputError(f"L_d: must be positive, got {inductance:.4g} H")
        return (
            np.array([[1.0 - gain * inductance]]),
            np.array([[gain**2 * inductance]]),
            np.zeros((1, 1)),
        )

    theta = np.array([5e-10, 3.0])  # the first step is 1e-9: below zero
    jacobian = _jacobian_map(structure, theta, structured=True)
    assert jacobian is not None
    # vec([Ad, Bd, Ed]) = [1 - g L, g^2 L, 0]: linear in L, so one-sided differences are exact
    exact = np.array([[-theta[1], -theta[0]], [theta[1] ** 2, 2.0 * theta[1] * theta[0]], [0, 0]])
    np.testing.assert_allclose(jacobian, exact, rtol=1e-5, atol=1e-12)
