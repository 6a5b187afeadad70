"""The value of one policy on a stack of plants, solved as one batch.

Truth: scipy's discrete Lyapunov solver (:func:`scipy.linalg.solve_discrete_lyapunov`) on
each closed loop, to the accuracy the Kronecker system's conditioning allows; the
one-plant :func:`~selftune.core.dpolicy_value` (the batch must give what it gives, and
flag where it raises); and the one-plant augmentations and values of the sampled loop.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import scipy.linalg

from selftune.core import (
    ControlLaw,
    delay_augmented,
    dpolicy_value,
    dpolicy_values,
    integrator_augmented,
)
from selftune.errors import InputError, UnsolvableError
from selftune.loop import SampledLoop

EPS = np.finfo(float).eps


def _stable_stack(
    rng: np.random.Generator, count: int, n: int, m: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Plants ``(A, B)`` and a gain K that leaves ``A - BK`` with spectral radius in
    [0.3, 0.97] on each (A scaled after the gain is drawn)."""
    K = 0.3 * rng.standard_normal((m, n))
    B = rng.standard_normal((count, n, m))
    A = rng.standard_normal((count, n, n))
    closed = A - B @ K
    radii = np.max(np.abs(np.linalg.eigvals(closed)), axis=1)
    target = rng.uniform(0.3, 0.97, count)
    A = closed * (target / radii)[:, None, None] + B @ K
    return A, B, K


def _weights(rng: np.random.Generator, n: int, m: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Q psd (rank n - 1), R pd, and a cross weight small enough for the joint psd."""
    G = rng.standard_normal((n, n - 1))
    Q = G @ G.T + np.eye(n)
    R = np.eye(m) + 0.1 * np.diag(rng.uniform(size=m))
    N = 0.05 * rng.standard_normal((n, m))
    return Q, R, N


def _oracle(
    A: np.ndarray, B: np.ndarray, K: np.ndarray, Q: np.ndarray, R: np.ndarray, N: np.ndarray
) -> tuple[np.ndarray, float]:
    """scipy's solution of ``P = Acl' P Acl + W`` and the relative accuracy its Kronecker
    system's conditioning allows (a few n^2 epsilons times its condition number)."""
    closed = A - B @ K
    W = Q - N @ K - K.T @ N.T + K.T @ R @ K
    n = A.shape[0]
    condition = np.linalg.cond(np.eye(n * n) - np.kron(closed.T, closed.T))
    return scipy.linalg.solve_discrete_lyapunov(closed.T, W), 10.0 * n * n * EPS * condition


@pytest.mark.parametrize(("n", "m"), [(2, 1), (4, 2), (6, 2), (8, 2), (11, 3)])
def test_the_batch_gives_each_plants_value(n: int, m: int) -> None:
    """Random stable closed loops (6 to 8 states as the drive's, 11: the bilinear solve):
    each plant's value is the one-plant one, equal, and scipy's to its conditioning."""
    rng = np.random.default_rng(n * 10 + m)
    A, B, K = _stable_stack(rng, 12, n, m)
    Q, R, N = _weights(rng, n, m)
    P, radii = dpolicy_values(A, B, K, Q, R, N)
    assert P.shape == (12, n, n) and np.all(radii < 1.0)
    for i in range(12):
        np.testing.assert_array_equal(P[i], dpolicy_value(A[i], B[i], K, Q, R, N))
        expected, accuracy = _oracle(A[i], B[i], K, Q, R, N)
        scale = float(np.max(np.abs(expected)))
        np.testing.assert_allclose(P[i], expected, rtol=0.0, atol=accuracy * scale)
        np.testing.assert_array_equal(P[i], P[i].T)


def _stiff_plant() -> tuple[np.ndarray, np.ndarray]:
    """A closed loop whose entries span six decades beside a mode at 1 - 1e-6 (an
    integrator beside fast currents): scipy warns about its Kronecker system."""
    A = np.array([[0.5, 1e3, 0.0], [0.0, 0.9, 1e3], [0.0, 0.0, 1.0 - 1e-6]])
    return A, np.zeros((3, 1))


def test_a_stiff_plant_in_the_stack_is_solved_as_alone() -> None:
    """Where scipy warns about one Kronecker system, every plant is solved as alone (the
    bilinear solve checked where its own warns): equal to the one-plant values, and the
    stiff one's Stein residual at rounding of its terms."""
    A_stiff, B_stiff = _stiff_plant()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", scipy.linalg.LinAlgWarning)
        scipy.linalg.solve_discrete_lyapunov(A_stiff.T, np.eye(3))
    assert caught, "the stiff plant no longer makes scipy warn: the test tests nothing"
    rng = np.random.default_rng(7)
    A, B, _ = _stable_stack(rng, 4, 3, 1)
    A = np.concatenate([A[:2], A_stiff[np.newaxis], A[2:]])
    B = np.concatenate([B[:2], B_stiff[np.newaxis], B[2:]])
    K, Q, R = np.zeros((1, 3)), np.eye(3), np.eye(1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", scipy.linalg.LinAlgWarning)
        P, radii = dpolicy_values(A, B, K, Q, R)
        for i in range(5):
            np.testing.assert_array_equal(P[i], dpolicy_value(A[i], B[i], K, Q, R))
    assert np.all(radii < 1.0)
    stiff = P[2]
    terms = np.abs(A_stiff.T) @ np.abs(stiff) @ np.abs(A_stiff) + np.abs(stiff) + 1.0
    residual = np.abs(A_stiff.T @ stiff @ A_stiff - stiff + Q)
    assert np.all(residual <= 100.0 * EPS * terms)


def test_an_unstable_closed_loop_is_flagged_not_raised() -> None:
    """The plants the gain does not stabilize: radius >= 1 and an infinite value where
    the one-plant value raises; the others' values unchanged by them."""
    rng = np.random.default_rng(3)
    A, B, K = _stable_stack(rng, 6, 4, 2)
    unstable = [1, 4]
    for i, factor in zip(unstable, [1.5, 1.01], strict=True):
        A[i] = (A[i] - B[i] @ K) * factor / np.max(np.abs(np.linalg.eigvals(A[i] - B[i] @ K)))
        A[i] += B[i] @ K
    Q, R, N = _weights(rng, 4, 2)
    P, radii = dpolicy_values(A, B, K, Q, R, N)
    for i in range(6):
        if i in unstable:
            assert radii[i] >= 1.0 and np.all(np.isinf(P[i]))
            with pytest.raises(UnsolvableError, match="spectral radius of A - BK"):
                dpolicy_value(A[i], B[i], K, Q, R, N)
        else:
            assert radii[i] < 1.0
            np.testing.assert_array_equal(P[i], dpolicy_value(A[i], B[i], K, Q, R, N))
    stable = [i for i in range(6) if i not in unstable]
    P_stable, _ = dpolicy_values(A[stable], B[stable], K, Q, R, N)
    np.testing.assert_array_equal(P_stable, P[stable])


def test_the_weights_and_shapes_are_checked_as_for_one_plant() -> None:
    """The weights' messages are the one-plant ones; a stack of the wrong shape, or a
    plant with a NaN in it, is refused naming it."""
    rng = np.random.default_rng(5)
    A, B, K = _stable_stack(rng, 3, 3, 1)
    Q, R = np.eye(3), np.eye(1)
    with pytest.raises(InputError) as one:
        dpolicy_value(A[0], B[0], K, Q, -R)
    with pytest.raises(InputError) as batch:
        dpolicy_values(A, B, K, Q, -R)
    assert str(batch.value) == str(one.value)
    with pytest.raises(InputError, match="stacks of p >= 1 plants"):
        dpolicy_values(A[0], B[0], K, Q, R)
    with pytest.raises(InputError, match="stacks of p >= 1 plants"):
        dpolicy_values(A, B[:2], K, Q, R)
    A[2, 1, 1] = np.nan
    with pytest.raises(InputError, match="A: contains NaN"):
        dpolicy_values(A, B, K, Q, R)


def _motor_plants(count: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Sampled dq plants of motors around 0.6 ohm, 8 mH at 471 rad/s, and last one no
    motor: the first one's Ad times 1.5, which no law of the first one holds."""
    h, w_e = 1e-4, 471.0
    rng = np.random.default_rng(2)
    plants = []
    for R_s, L_s in zip(rng.uniform(0.5, 0.7, count), rng.uniform(7e-3, 9e-3, count),
                        strict=True):  # fmt: skip
        A = np.array([[-R_s / L_s, w_e], [-w_e, -R_s / L_s]])
        Ad = scipy.linalg.expm(A * h)
        plants.append((Ad, np.linalg.solve(A, Ad - np.eye(2)) / L_s))
    plants.append((1.5 * plants[0][0], plants[0][1]))
    return plants


def _law(loop: SampledLoop, plant: tuple[np.ndarray, np.ndarray]) -> ControlLaw:
    """The digital optimum of the loop on one plant."""
    Kz, _ = loop.optimum(plant, loop.weights(1e3 * np.eye(2), np.eye(2)))
    return loop.law(Kz, np.eye(2), np.zeros((2, 2)))


def test_the_loop_augments_a_stack_as_each_plant() -> None:
    """The delay and integrator augmentations of a stack are each plant's, equal."""
    plants = _motor_plants(5)
    A, B = np.array([p[0] for p in plants]), np.array([p[1] for p in plants])
    for d in (0, 1, 2):
        Az, Bz = delay_augmented(A, B, d)
        for i, (Ad, Bd) in enumerate(plants):
            one = delay_augmented(Ad, Bd, d)
            np.testing.assert_array_equal(Az[i], one[0])
            np.testing.assert_array_equal(Bz[i], one[1])
        C = np.hstack([np.eye(2), np.zeros((2, Az.shape[-1] - 2))])
        for h in (None, 1e-4):
            Ai, Bi = integrator_augmented(Az, Bz, C, h)
            for i in range(len(plants)):
                one = integrator_augmented(Az[i], Bz[i], C, h)
                np.testing.assert_array_equal(Ai[i], one[0])
                np.testing.assert_array_equal(Bi[i], one[1])


def test_the_loops_values_are_each_plants_value() -> None:
    """SampledLoop.values: each plant's :meth:`value` (equal), and the loop's radii
    (:meth:`spectral_radii`); the unstable plant's cost infinite where value raises."""
    loop = SampledLoop(1e-4, 1, C=np.eye(2), F=-np.eye(2), Q_i=np.eye(2))
    plants = _motor_plants(6)
    law = _law(loop, plants[0])
    weights = loop.weights(1e3 * np.eye(2), np.eye(2))
    P, radii = loop.values(plants, law, weights)
    np.testing.assert_array_equal(radii, loop.spectral_radii(plants, law))
    assert radii[-1] >= 1.0 and np.all(radii[:-1] < 1.0)
    for i, plant in enumerate(plants[:-1]):
        np.testing.assert_array_equal(P[i], loop.value(plant, law, weights))
    assert np.all(np.isinf(P[-1]))
    with pytest.raises(UnsolvableError):
        loop.value(plants[-1], law, weights)
    with pytest.raises(InputError, match="sampled loop"):
        SampledLoop(0.0).values(plants, law, weights)


def test_one_gain_per_plant_gives_each_plants_value() -> None:
    """A stack of gains, one per plant: each plant's value under its own gain, equal;
    a stack of gains of the wrong shape is refused."""
    rng = np.random.default_rng(9)
    A, B, K = _stable_stack(rng, 5, 4, 2)
    Q, R, N = _weights(rng, 4, 2)
    gains = np.array([K * factor for factor in (1.0, 0.98, 1.02, 0.99, 1.01)])
    P, radii = dpolicy_values(A, B, gains, Q, R, N)
    for i in range(5):
        if radii[i] < 1.0:
            np.testing.assert_array_equal(P[i], dpolicy_value(A[i], B[i], gains[i], Q, R, N))
        else:
            assert np.all(np.isinf(P[i]))
    with pytest.raises(InputError, match="one per plant"):
        dpolicy_values(A, B, gains[:3], Q, R, N)


def test_the_loop_values_one_law_per_plant() -> None:
    """SampledLoop.values with a law per plant: each pair's value; as many laws as
    plants, or refused."""
    loop = SampledLoop(1e-4, 1, C=np.eye(2), F=-np.eye(2), Q_i=np.eye(2))
    plants = _motor_plants(3)[:3]
    laws = [_law(loop, plant) for plant in plants]
    weights = loop.weights(1e3 * np.eye(2), np.eye(2))
    P, radii = loop.values(plants + plants, laws + laws[::-1], weights)
    pairs = list(zip(plants + plants, laws + laws[::-1], strict=True))
    for i, (plant, law) in enumerate(pairs):
        assert radii[i] < 1.0
        np.testing.assert_array_equal(P[i], loop.value(plant, law, weights))
    with pytest.raises(InputError, match="2 laws for 3 plants"):
        loop.values(plants, laws[:2], weights)
