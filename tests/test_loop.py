"""The sampled loop's algebra against independent truth.

Oracles: the law stepped sample by sample with :meth:`ControlLaw.command` on the plant
(the closed loop), the stage costs summed along that simulation (a law's value), and
python-control's ``dlqr``/``lqr`` with SLICOT on augmented matrices built here by hand
(the optimum). Random plants, delays of 0-2 samples, with and without an integrator.
"""

from __future__ import annotations

import control
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from example_counts import examples
from selftune.core import ControlLaw
from selftune.errors import InputError, UnsolvableError
from selftune.loop import SampledLoop

Array = np.ndarray
SEEDS = st.integers(min_value=0, max_value=2**32 - 1)


def _plant(rng: np.random.Generator, n: int, m: int, q: int) -> tuple[Array, Array, Array]:
    """A random sampled plant with spectral radius below 1.05 (mildly unstable at most)."""
    Ad = rng.standard_normal((n, n))
    Ad *= rng.uniform(0.3, 1.05) / np.max(np.abs(np.linalg.eigvals(Ad)))
    return Ad, rng.standard_normal((n, m)), rng.standard_normal((n, q))


def _by_hand(Ad: Array, Bd: Array, d: int, C: Array | None, h: float) -> tuple[Array, Array]:
    """``(Az, Bz)`` over ``[x; u_(k-d); ...; u_(k-1); z]``, written out independently."""
    n, m = Bd.shape
    r = 0 if C is None else C.shape[0]
    size = n + d * m + r
    Az, Bz = np.zeros((size, size)), np.zeros((size, m))
    Az[:n, :n] = Ad
    if d == 0:
        Bz[:n] = Bd
    else:
        Az[:n, n : n + m] = Bd
        for block in range(d - 1):  # u_(k-d+1+block) moves down one slot
            rows = slice(n + block * m, n + (block + 1) * m)
            Az[rows, n + (block + 1) * m : n + (block + 2) * m] = np.eye(m)
        Bz[n + (d - 1) * m : n + d * m] = np.eye(m)
    if C is not None:
        Az[size - r :, :n] = h * C
        Az[size - r :, size - r :] = np.eye(r)
    return Az, Bz


def _law(rng: np.random.Generator, n: int, m: int, q: int, d: int, r: int, h: float) -> ControlLaw:
    scale = 0.2
    K = scale * rng.standard_normal((m, n + d * m))
    X, U = rng.standard_normal((n, q)), rng.standard_normal((m, q))
    if not r:
        return ControlLaw(K, X, U, history=d)
    C, F = rng.standard_normal((r, n)), rng.standard_normal((r, q))
    K_i = scale * rng.standard_normal((m, r))
    return ControlLaw(K, X, U, history=d, K_i=K_i, C=C, F=F, h=h)


@examples(40, quick=10)
@given(seed=SEEDS, d=st.integers(0, 2), integral=st.booleans())
def test_the_closed_loop_is_the_law_stepped_on_the_plant(seed: int, d: int, integral: bool) -> None:
    rng = np.random.default_rng(seed)
    n, m, q, h = int(rng.integers(1, 4)), int(rng.integers(1, 3)), 2, 1e-3
    r = int(rng.integers(1, m + 1)) if integral else 0
    Ad, Bd, Ed = _plant(rng, n, m, q)
    law = _law(rng, n, m, q, d, r, h)
    loop = SampledLoop.of_law(law, h)
    A_cl, B_w = loop.closed_loop((Ad, Bd), law, Ed)
    x, past, z = rng.standard_normal(n), rng.standard_normal((d, m)), rng.standard_normal(r)
    for _ in range(5):
        w = rng.standard_normal(q)
        state = np.concatenate([x, past.ravel(), z])
        u = law.command(x, w, past, z if r else None)
        applied = past[0] if d else u
        x_next = Ad @ x + Bd @ applied + Ed @ w
        z_next = z + h * (law.C @ x + law.F @ w) if r else z
        past = np.vstack([past[1:], u]) if d else past
        expected = np.concatenate([x_next, past.ravel(), z_next])
        np.testing.assert_allclose(A_cl @ state + B_w @ w, expected, rtol=1e-12, atol=1e-12)
        x, z = x_next, z_next


@examples(30, quick=10)
@given(seed=SEEDS, d=st.integers(0, 2), integral=st.booleans())
def test_the_optimum_is_slicots_on_the_augmented_plant(seed: int, d: int, integral: bool) -> None:
    rng = np.random.default_rng(seed)
    n, m, h = int(rng.integers(1, 4)), int(rng.integers(1, 3)), 1e-3
    Ad, Bd, _ = _plant(rng, n, m, 1)
    Q, R = np.diag(rng.uniform(0.5, 2.0, n)), np.diag(rng.uniform(0.5, 2.0, m))
    C = np.eye(m, n) if integral and n >= m else None
    Q_i = np.eye(m) if C is not None else None
    F = None if C is None else np.zeros((m, 1))
    loop = SampledLoop(h, d, C=C, F=F, Q_i=Q_i)
    Az, Bz = _by_hand(Ad, Bd, d, C, h)
    Qz = np.zeros_like(Az)
    Qz[:n, :n] = h * Q
    if C is not None:
        Qz[-m:, -m:] = h * np.eye(m)
    try:
        Kz, P = loop.optimum((Ad, Bd), loop.weights(Q, R))
    except UnsolvableError:  # e.g. an integrator the inputs cannot drive: SLICOT agrees
        with pytest.raises((ValueError, np.linalg.LinAlgError, control.ControlArgument)):
            control.dlqr(Az, Bz, Qz, h * R, method="slycot")
        return
    K_ref, P_ref, _ = control.dlqr(Az, Bz, Qz, h * R, method="slycot")
    condition = np.linalg.cond(np.asarray(P_ref)) if np.linalg.norm(P_ref) else 1.0
    bar = 1e-12 * max(condition, 1.0) * np.linalg.cond(h * R + Bz.T @ P_ref @ Bz)
    assert np.linalg.norm(Kz - K_ref) <= max(bar, 1e-9) * np.linalg.norm(K_ref) + 1e-300
    assert np.linalg.norm(P - P_ref) <= max(bar, 1e-9) * np.linalg.norm(P_ref)


@examples(25, quick=10)
@given(seed=SEEDS, d=st.integers(0, 2))
def test_a_laws_value_is_its_summed_digital_cost(seed: int, d: int) -> None:
    rng = np.random.default_rng(seed)
    n, m, h = 2, 1, 1e-3
    Ad, Bd, _ = _plant(rng, n, m, 1)
    Ad *= 0.7 / max(np.max(np.abs(np.linalg.eigvals(Ad))), 1e-12)
    law = ControlLaw(
        0.05 * rng.standard_normal((m, n + d * m)), np.zeros((n, 1)), np.zeros((m, 1)), history=d
    )
    loop = SampledLoop(h, d)
    A_cl, _ = loop.closed_loop((Ad, Bd), law)
    if np.max(np.abs(np.linalg.eigvals(A_cl))) > 0.95:
        return  # too slow to sum to convergence in the steps below
    Q, R = np.eye(n), np.eye(m)
    P = loop.value((Ad, Bd), law, loop.weights(Q, R))
    state = rng.standard_normal(n + d * m)
    start, total = state.copy(), 0.0
    for _ in range(3000):
        u = -loop.gain(law) @ state
        total += h * (state[:n] @ Q @ state[:n] + u @ R @ u)
        state = A_cl @ state
    assert start @ P @ start == pytest.approx(total, rel=1e-9)


def test_the_continuous_loop_is_lqr_of_the_integrator_augmented_plant() -> None:
    A = np.array([[-7.3, 20.0], [-20.0, -7.3]])
    B = np.eye(2) / 0.06
    C = np.eye(2)
    loop = SampledLoop(0.0, C=C, F=np.zeros((2, 2)), Q_i=1e6 * np.eye(2))
    Kz, P = loop.optimum((A, B), loop.weights(1e3 * np.eye(2), np.eye(2)))
    A_aug = np.block([[A, np.zeros((2, 2))], [C, np.zeros((2, 2))]])
    B_aug = np.vstack([B, np.zeros((2, 2))])
    Q_aug = np.diag([1e3, 1e3, 1e6, 1e6])
    K_ref, P_ref, _ = control.lqr(A_aug, B_aug, Q_aug, np.eye(2), method="slycot")
    # a backward-stable solver's forward error: machine epsilon times the conditioning
    bar = np.finfo(float).eps * np.linalg.cond(P_ref) * np.linalg.cond(A_aug - B_aug @ K_ref)
    assert np.linalg.norm(Kz - K_ref) <= bar * np.linalg.norm(K_ref)
    assert np.linalg.norm(P - P_ref) <= bar * np.linalg.norm(P_ref)
    law = loop.law(Kz, np.zeros((2, 2)), np.zeros((2, 2)), h=1e-4)
    assert law.K_i is not None and law.h == 1e-4
    np.testing.assert_array_equal(loop.gain(law), Kz)


def test_a_law_that_feeds_back_fewer_past_inputs_has_zero_gain_on_the_older_ones() -> None:
    law = ControlLaw([[1.0, 2.0, 3.0]], np.zeros((2, 0)), np.zeros((1, 0)), history=1)
    np.testing.assert_array_equal(SampledLoop(1e-4, 2).gain(law), [[1.0, 2.0, 0.0, 3.0]])


@pytest.mark.parametrize(
    ("arguments", "key"),
    [
        ({"h": -1e-4}, "h"),
        ({"h": float("nan")}, "h"),
        ({"h": "fast"}, "h"),
        ({"h": 0.0, "input_delay": 1}, "input_delay"),
        ({"h": 1e-4, "input_delay": -1}, "input_delay"),
        ({"h": 1e-4, "hold": "abc"}, "hold"),
        ({"h": 1e-4, "F": np.zeros((2, 2))}, "C"),
        ({"h": 1e-4, "C": np.eye(2)}, "F"),
        ({"h": 1e-4, "C": np.eye(2), "F": np.zeros((2, 1)), "Q_i": -np.eye(2)}, "Q_i"),
    ],
)
def test_bad_loop_facts_name_their_field(arguments: dict[str, object], key: str) -> None:
    with pytest.raises(InputError, match=rf"^{key}:"):
        SampledLoop(**arguments)  # type: ignore[arg-type]


def test_a_law_that_does_not_fit_the_loop_is_refused_by_name() -> None:
    law = ControlLaw(np.ones((1, 4)), np.zeros((2, 0)), np.zeros((1, 0)), history=2)
    with pytest.raises(InputError, match="2 past inputs, the loop delays by 1"):
        SampledLoop(1e-4, 1).gain(law)
    integral = ControlLaw(
        np.ones((1, 2)), np.zeros((2, 1)), np.zeros((1, 1)), K_i=[[1.0]], C=[[1.0, 0.0]],
        F=[[0.0]], h=1e-4,
    )  # fmt: skip
    with pytest.raises(InputError, match="1 integrator states, the loop has 0"):
        SampledLoop(1e-4).gain(integral)
    with pytest.raises(InputError, match="Q_i: the cost of a loop with integral action"):
        SampledLoop.of_law(integral, 1e-4).weights(np.eye(2), [[1.0]])
