"""The ideal drive runs every law the library learns, checked against the augmented state.

Truth: the closed loop of a digital law on the exactly sampled plant is an LTI system in
an augmented state (the state with the past input, or with the integrator). Its
transition matrices are written out here by hand from the law's equations
(:mod:`selftune.core._control_law`), the plant sampled by scipy's ``expm`` (Van Loan), and
run by ``scipy.signal.dlsim``; the drive must give the same samples.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.signal import dlsim

from selftune import SPMSM
from selftune.core import Array, ControlLaw
from selftune.learn import Trajectory
from selftune.sim import ExogenousSignal, SimulatedDrive, held, simulate, simulate_loop, uniform

MOTOR = SPMSM.paper()
SPEED = 10.0
SAMPLING = 1e-4
SAMPLES = 300
SEED = 7


def _sampled_plant() -> tuple[Array, Array, Array]:
    """``(Ad, Bd, Ed)`` of the motor's regulation problem at SAMPLING, by scipy."""
    problem = MOTOR.regulation_problem(SPEED)
    n, m, q = 2, 2, problem.D.shape[1]
    M = np.zeros((n + m + q, n + m + q))
    M[:n, :n], M[:n, n : n + m], M[:n, n + m :] = problem.A, problem.B, problem.D
    exp = expm(M * SAMPLING)
    return exp[:n, :n], exp[:n, n : n + m], exp[:n, n + m :]


def _reference() -> ExogenousSignal:
    w_base = MOTOR.exogenous(speed=SPEED, torque=5.0)
    return held(lambda t: w_base + np.column_stack([0.0 * t, 2.0 * np.sin(300.0 * t)]))


def _drive_run(law: ControlLaw) -> tuple[Trajectory, Array, Array]:
    """The drive's trajectory, and the reference and exploration it used (N + 1 and N rows)."""
    drive = SimulatedDrive(MOTOR, SPEED, SAMPLING)
    reference = _reference()
    data = drive.run(law, reference, num_samples=SAMPLES, exploration=uniform(2.0), seed=SEED)
    t = SAMPLING * np.arange(SAMPLES + 1)
    rho = uniform(2.0).sample(t, 2, np.random.default_rng(SEED))
    return data, reference.values(t), rho


def _augmented_run(Phi: Array, Gamma_w: Array, Gamma_rho: Array, w: Array, rho: Array) -> Array:
    """``xi_(k+1) = Phi xi_k + Gamma_w w_k + Gamma_rho rho_k`` from rest, by dlsim."""
    size = Phi.shape[0]
    inputs = np.hstack([w[:-1], rho])
    _, _, xi = dlsim(
        (Phi, np.hstack([Gamma_w, Gamma_rho]), np.eye(size), np.zeros((size, inputs.shape[1])), 1),
        inputs,
        x0=np.zeros(size),
    )
    final = Phi @ xi[-1] + Gamma_w @ w[-2] + Gamma_rho @ rho[-1]
    return np.vstack([xi, final])


def _tolerance(values: Array) -> float:
    """Rounding of two orderings of the same sums: each sample adds a few eps of the
    values' size, which the contracting loop does not amplify; N samples bound the sum."""
    return SAMPLES * np.finfo(float).eps * float(np.abs(values).max())


def test_digital_law_with_one_past_input_matches_augmented_state() -> None:
    """``u_k = U w - K_x (x_k - X w) - K_u (u_(k-1) - U w) + rho_k``, applied at once:
    the state ``[x_k; u_(k-1)]`` evolves by a matrix written out from the law."""
    Ad, Bd, Ed = _sampled_plant()
    K_x = 0.5 * MOTOR.L_s / SAMPLING * np.eye(2)
    K_u = np.array([[0.3, 0.05], [-0.05, 0.3]])
    X = np.array([[0.0, 0.0], [0.0, 1.0 / (1.5 * MOTOR.p * MOTOR.phi_pm)]])
    U = np.array([[0.0, 0.0], [1.0, MOTOR.R_s / (1.5 * MOTOR.p * MOTOR.phi_pm)]])
    law = ControlLaw(np.hstack([K_x, K_u]), X, U, history=1)
    L = U + K_x @ X + K_u @ U  # u_k = -K_x x_k - K_u u_(k-1) + L w_k + rho_k
    Phi = np.block([[Ad - Bd @ K_x, -Bd @ K_u], [-K_x, -K_u]])
    assert np.abs(np.linalg.eigvals(Phi)).max() < 1.0
    Gamma_w = np.vstack([Bd @ L + Ed, L])
    Gamma_rho = np.vstack([Bd, np.eye(2)])
    data, w, rho = _drive_run(law)
    xi = _augmented_run(Phi, Gamma_w, Gamma_rho, w, rho)
    np.testing.assert_allclose(data.x, xi[:, :2], rtol=0.0, atol=_tolerance(xi[:, :2]))
    np.testing.assert_allclose(data.u, xi[1:, 2:], rtol=0.0, atol=_tolerance(xi[1:, 2:]))
    assert np.abs(xi[:, 2:]).max() > 1.0  # the past input matters: the check is not vacuous


def test_integral_law_matches_augmented_state() -> None:
    """``u_k = U w - K (x_k - X w) - K_i z_k + rho_k``, ``z_(k+1) = z_k + h (C x_k + F w_k)``:
    the state ``[x_k; z_k]`` evolves by a matrix written out from the law."""
    Ad, Bd, Ed = _sampled_plant()
    K = 0.4 * MOTOR.L_s / SAMPLING * np.eye(2)
    X = np.zeros((2, 2))
    U = np.zeros((2, 2))
    C = np.eye(2)
    F = np.array([[0.0, 0.0], [0.0, -1.0 / (1.5 * MOTOR.p * MOTOR.phi_pm)]])
    K_i = 40.0 * MOTOR.R_s * np.eye(2)
    law = ControlLaw(K, X, U, K_i=K_i, C=C, F=F, h=SAMPLING)
    Phi = np.block([[Ad - Bd @ K, -Bd @ K_i], [SAMPLING * C, np.eye(2)]])
    assert np.abs(np.linalg.eigvals(Phi)).max() < 1.0
    Gamma_w = np.vstack([Ed, SAMPLING * F])
    Gamma_rho = np.vstack([Bd, np.zeros((2, 2))])
    data, w, rho = _drive_run(law)
    xi = _augmented_run(Phi, Gamma_w, Gamma_rho, w, rho)
    np.testing.assert_allclose(data.x, xi[:, :2], rtol=0.0, atol=_tolerance(xi[:, :2]))
    u = -xi[:-1, :2] @ K.T - xi[:-1, 2:] @ K_i.T + rho
    np.testing.assert_allclose(data.u, u, rtol=0.0, atol=_tolerance(u))
    assert np.abs(xi[:-1, 2:] @ K_i.T).max() > 1.0  # the integrator acts: not vacuous


@pytest.mark.parametrize("hold", [1, 3])
def test_regulator_runs_as_simulate(hold: int) -> None:
    """A regulator ``u = -K (x - X w) + U w`` gives what :func:`simulate` gives, also with
    the controller at a third of the sampling rate."""
    problem = MOTOR.regulation_problem(SPEED)
    K = 0.3 * MOTOR.L_s / SAMPLING * np.eye(2)
    X = np.array([[0.0, 0.0], [0.0, 0.5]])
    U = np.array([[0.0, 0.1], [1.0, 0.2]])
    drive = SimulatedDrive(MOTOR, SPEED, SAMPLING, input_hold=hold)
    reference = _reference()
    data = drive.run(
        ControlLaw.regulator(K, X, U),
        reference,
        num_samples=SAMPLES,
        exploration=uniform(2.0),
        seed=SEED,
    )
    expected = simulate(
        problem.A, problem.B, D=problem.D, exogenous=reference,
        K=K, X=X, U=U, exploration=uniform(2.0), h=SAMPLING, num_samples=SAMPLES,
        seed=SEED, input_hold=hold,
    )  # fmt: skip
    np.testing.assert_allclose(data.x, expected.x, rtol=0.0, atol=_tolerance(expected.x))
    np.testing.assert_allclose(data.u, expected.u, rtol=0.0, atol=_tolerance(expected.u))
    np.testing.assert_array_equal(data.w, expected.w)


def test_digital_loop_with_a_delay_matches_augmented_state() -> None:
    """With a computation delay of one sample, ``x_(k+1) = Ad x_k + Bd u_(k-1) + Ed w_k``
    under the law with one past input: the state ``[x_k; u_(k-1)]`` again, the applied and
    the computed logs one row apart."""
    Ad, Bd, Ed = _sampled_plant()
    K_x = 0.2 * MOTOR.L_s / SAMPLING * np.eye(2)
    K_u = np.array([[0.2, 0.05], [-0.05, 0.2]])
    X = np.array([[0.0, 0.0], [0.0, 1.0 / (1.5 * MOTOR.p * MOTOR.phi_pm)]])
    U = np.array([[0.0, 0.0], [1.0, MOTOR.R_s / (1.5 * MOTOR.p * MOTOR.phi_pm)]])
    law = ControlLaw(np.hstack([K_x, K_u]), X, U, history=1)
    L = U + K_x @ X + K_u @ U
    Phi = np.block([[Ad, Bd], [-K_x, -K_u]])
    assert np.abs(np.linalg.eigvals(Phi)).max() < 1.0
    Gamma_w = np.vstack([Ed, L])
    Gamma_rho = np.vstack([np.zeros((2, 2)), np.eye(2)])
    problem = MOTOR.regulation_problem(SPEED)
    reference = _reference()
    logs = simulate_loop(
        (problem.A, problem.B, problem.D),
        law,
        reference,
        h=SAMPLING,
        num_samples=SAMPLES,
        delay=1,
        exploration=uniform(2.0),
        seed=SEED,
    )
    t = SAMPLING * np.arange(SAMPLES + 1)
    rho = uniform(2.0).sample(t, 2, np.random.default_rng(SEED))
    xi = _augmented_run(Phi, Gamma_w, Gamma_rho, reference.values(t), rho)
    np.testing.assert_allclose(logs.applied.x, xi[:, :2], rtol=0.0, atol=_tolerance(xi[:, :2]))
    u = xi[:, 2:]
    np.testing.assert_allclose(logs.applied.u, u[:-1], rtol=0.0, atol=_tolerance(u))
    np.testing.assert_allclose(logs.commanded.u, u[1:], rtol=0.0, atol=_tolerance(u))
    assert np.abs(u).max() > 1.0
