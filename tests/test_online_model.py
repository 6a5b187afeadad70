"""The running drive's model from moments with forgetting (selftune.learn.online).

Truth: plants simulated here sample by sample (numpy only), and scipy's least squares on
the whole data with the same weights.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from example_counts import examples
from selftune.learn.online import ForgettingMoments, OnlineModel

AD = np.array([[0.98, 0.05], [-0.05, 0.97]])
BD = np.array([[0.012, 0.0], [0.001, 0.011]])
ED = np.array([[0.0, 0.002], [-0.01, 0.0]])


def _plant(
    samples: int, seed: int, noise: float = 0.0, process: float = 0.0, Ad: np.ndarray = AD
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(measured x, true x, a, w) of the plant under white inputs; w held steps."""
    rng = np.random.default_rng(seed)
    a = rng.uniform(-10, 10, (samples, 2))
    w = np.column_stack([np.ones(samples), np.repeat(rng.uniform(-5, 5, samples // 100 + 1),
                                                     100)[:samples]])  # fmt: skip
    x = np.zeros((samples + 1, 2))
    for k in range(samples):
        x[k + 1] = Ad @ x[k] + BD @ a[k] + ED @ w[k] + process * rng.standard_normal(2)
    measured = x + noise * rng.standard_normal(x.shape)
    return measured, x, a, w


def _fed(
    model: OnlineModel, x: np.ndarray, a: np.ndarray, w: np.ndarray, cuts: list[int]
) -> OnlineModel:
    """Feed rows 0..N (x has N + 1 rows; the last row's input is never used) in chunks."""
    a = np.vstack([a, np.zeros((1, a.shape[1]))])
    w = np.vstack([w, w[-1:]])
    edges = [0, *sorted(set(cuts)), x.shape[0]]
    for start, stop in itertools.pairwise(edges):
        model.add(x[start:stop], a[start:stop], w[start:stop])
    return model


@examples(20, quick=5)
@given(st.lists(st.integers(1, 1999), max_size=30))
def test_any_chunking_gives_the_same_moments(cuts: list[int]) -> None:
    x, _, a, w = _plant(2000, 1, noise=0.01)
    whole = _fed(OnlineModel(1e-4, (0.05,), 2, 2, 2), x, a, w, [])
    chunked = _fed(OnlineModel(1e-4, (0.05,), 2, 2, 2), x, a, w, cuts)
    np.testing.assert_allclose(
        chunked.moments[0].cross, whole.moments[0].cross, rtol=1e-10, atol=1e-12
    )
    np.testing.assert_allclose(
        chunked.moments[0].second, whole.moments[0].second, rtol=1e-10, atol=1e-12
    )
    assert chunked.moments[0].count == whole.moments[0].count == 1999


def test_the_moments_are_weighted_instrumental_variables() -> None:
    """Theta equals the weighted IV solution computed directly."""
    rng = np.random.default_rng(2)
    z, zeta, y = rng.normal(size=(300, 3)), rng.normal(size=(300, 3)), rng.normal(size=(300, 2))
    moments = ForgettingMoments(0.99, 3, 2)
    moments.add(zeta[:120], z[:120], y[:120])
    moments.add(zeta[120:], z[120:], y[120:])
    weights = 0.99 ** np.arange(299, -1, -1)
    Theta_direct = np.linalg.solve((zeta * weights[:, None]).T @ z, (zeta * weights[:, None]).T @ y)
    Theta, _, _ = moments.estimate()
    np.testing.assert_allclose(Theta, Theta_direct, rtol=1e-10)


def test_noise_free_data_give_the_plant() -> None:
    x, _, a, w = _plant(3000, 3)
    model = _fed(OnlineModel(1e-4, (1.0,), 2, 2, 2), x, a, w, [700, 1500]).model()
    np.testing.assert_allclose(model.Ad, AD, atol=1e-9)
    np.testing.assert_allclose(model.Bd, BD, atol=1e-9)
    np.testing.assert_allclose(model.Ed, ED, atol=1e-9)


def test_measurement_noise_does_not_bias_the_estimate() -> None:
    """Least squares on noisy states is biased (errors in variables); the instruments'
    estimate is not: its error is within 4 of its own standard errors, where ordinary
    least squares' is far beyond."""
    x, _, a, w = _plant(200_000, 4, noise=0.05)
    model = _fed(OnlineModel(1e-4, (1e6,), 2, 2, 2), x, a, w, []).model()
    assert model.covariance is not None
    se = np.sqrt(np.diag(model.covariance))
    truth = np.concatenate([AD, BD, ED], axis=1).ravel(order="F")
    z_scores = (model.parameters - truth) / se
    assert np.max(np.abs(z_scores)) < 4.0
    Z = np.hstack([x[:-1], a, w])
    ls = np.linalg.lstsq(Z, x[1:], rcond=None)[0].T.ravel(order="F")
    assert np.max(np.abs(ls - truth) / se) > 10.0


def test_the_standard_errors_mean_what_they_say() -> None:
    """Over 200 seeds with white equation errors, about 68% of the parameters' errors
    are within one stated standard error (binomial spread: 62-74%)."""
    truth = np.concatenate([AD, BD, ED], axis=1).ravel(order="F")
    scores = []
    for seed in range(200):
        x, _, a, w = _plant(1500, 100 + seed, process=0.01)
        model = _fed(OnlineModel(1e-4, (0.05,), 2, 2, 2), x, a, w, [500]).model()
        assert model.covariance is not None
        scores.append((model.parameters - truth) / np.sqrt(np.diag(model.covariance)))
    within = np.mean(np.abs(np.array(scores)) <= 1.0)
    assert 0.62 <= within <= 0.74, within


def test_forgetting_follows_a_changed_plant() -> None:
    """After Ad changes, the estimate reaches the new plant within a few memories."""
    changed = AD * 0.99
    x1, _, a1, w1 = _plant(4000, 5)
    x2, _, a2, w2 = _plant(4000, 6, Ad=changed)
    model = OnlineModel(1e-4, (0.02,), 2, 2, 2)  # 200 samples of memory
    _fed(model, x1, a1, w1, [])
    np.testing.assert_allclose(model.model().Ad, AD, atol=1e-9)
    _fed(model, x2, a2, w2, [])  # 4000 samples: 20 memories; e^-20 of the old left
    np.testing.assert_allclose(model.model().Ad, changed, atol=1e-6)


def test_a_bad_forgetting_factor_is_refused() -> None:
    with pytest.raises(ValueError, match="forgetting"):
        ForgettingMoments(1.5, 2, 2)


def test_the_moment_of_the_dead_time_short_pulses_leave_out_is_kept_in_any_chunking() -> None:
    """With the inverter's bus given, each memory keeps ``sum_k w_k zeta_k c_k'`` over
    its transitions (``c_k`` the signs' part short pulses do not carry, the instruments
    ``[x_(k-1), a_k, w_k, s(x_(k-1))]``, every sign at row k's angle): the same whether fed
    in one chunk or many, as the direct weighed sum, forgotten with the other moments
    (a restart's share scales it); rows off the voltage limit add nothing."""
    from selftune.learn.evidence._dead_time import phase_signs
    from selftune.learn.evidence._pulses import lost_signs

    rng = np.random.default_rng(3)
    rows, bus, v, advance = 3000, 100.0, 1.0, 0.02
    x = rng.normal(0.0, 5.0, (rows, 2))
    turn = rng.uniform(-np.pi, np.pi, rows)
    size = np.where(rng.random(rows) < 0.3, bus / np.sqrt(3.0), rng.uniform(0.0, 50.0, rows))
    a = np.column_stack([size * np.cos(turn), size * np.sin(turn)])
    w = np.column_stack([np.ones(rows), np.repeat(rng.uniform(-5, 5, rows // 100), 100)])
    angle = 0.05 * np.arange(rows)

    def fed(cuts: list[int]) -> OnlineModel:
        model = OnlineModel(1e-4, (0.05, 0.2), 2, 2, 2, True, (advance, bus), v)
        for start, stop in itertools.pairwise([0, *cuts, rows]):
            model.add(x[start:stop], a[start:stop], w[start:stop], angle[start:stop])
        return model

    whole, chunked = fed([]), fed([7, 100, 101, 1333, 2500])
    k = np.arange(1, rows - 1)  # the transitions: a row before and after
    zeta = np.column_stack([x[k - 1], a[k], w[k], phase_signs(x[k - 1], angle[k])])
    lost = lost_signs(x[k], a[k], angle[k], advance, bus, v)
    assert 0.05 < np.mean(np.any(lost != 0.0, axis=1)) < 0.3
    assert not np.any(lost[size[k] < 50.0])
    for memory, again in zip(whole.moments, chunked.moments, strict=True):
        weights = memory.forgetting ** np.arange(k.size - 1, -1, -1)
        direct = (zeta * weights[:, None]).T @ lost
        np.testing.assert_allclose(memory.omitted, direct, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(again.omitted, direct, rtol=1e-10, atol=1e-12)
    memory = whole.moments[0]
    kept = memory.omitted.copy()
    memory.forget(0.1)
    np.testing.assert_allclose(memory.omitted, 0.1 * kept, rtol=1e-15)
