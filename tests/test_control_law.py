"""The control law every part of selftune shares: shapes, names, and the command it gives."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from selftune import InputError
from selftune.core import ControlLaw, state_names


def test_state_names_follow_the_documented_order() -> None:
    assert state_names(2, 2, 2, 1) == (
        "x1", "x2", "u1[k-2]", "u2[k-2]", "u1[k-1]", "u2[k-1]", "z1",
    )  # fmt: skip


@given(
    st.integers(1, 4), st.integers(1, 3), st.integers(1, 3), st.integers(0, 2), st.integers(0, 99)
)
def test_command_equals_the_written_law(n: int, m: int, q: int, history: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    K = rng.normal(size=(m, n + history * m))
    X, U = rng.normal(size=(n, q)), rng.normal(size=(m, q))
    C, F, K_i = rng.normal(size=(1, n)), rng.normal(size=(1, q)), rng.normal(size=(m, 1))
    law = ControlLaw(K, X, U, history=history, K_i=K_i, C=C, F=F, h=1e-4)
    x, w = rng.normal(size=n), rng.normal(size=q)
    past, z = rng.normal(size=(history, m)), rng.normal(size=1)
    deviation = np.concatenate([x - X @ w, *(past[j] - U @ w for j in range(history))])
    expected = U @ w - K @ deviation - K_i @ z
    np.testing.assert_allclose(law.command(x, w, past, z), expected, rtol=1e-12, atol=1e-12)
    assert len(law.state) == n + history * m + 1


def test_regulator_is_the_continuous_law() -> None:
    K, X, U = np.eye(2), np.ones((2, 1)), np.array([[2.0], [3.0]])
    law = ControlLaw.regulator(K, X, U)
    x, w = np.array([1.0, -1.0]), np.array([0.5])
    np.testing.assert_allclose(law.command(x, w, np.zeros((0, 2))), -K @ (x - X @ w) + U @ w)
    assert law.history == 0 and law.K_i is None and "K_i" not in law.equations()


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        ({"K": np.eye(2), "X": np.ones((3, 1)), "U": np.ones((2, 1))}, "X: expected 2 rows"),
        ({"K": np.ones((2, 3)), "X": np.ones((1, 1)), "U": np.ones((2, 1)), "history": 2},
         "K: has 3 columns, too few"),
        ({"K": np.eye(2), "X": np.ones((2, 1)), "U": np.ones((2, 1)), "K_i": np.ones((2, 1))},
         "K_i: integral action needs C, F"),
        ({"K": np.eye(2), "X": np.ones((2, 1)), "U": np.ones((2, 1)), "history": -1},
         "history: expected a whole number >= 0"),
    ],
)  # fmt: skip
def test_bad_shapes_are_named(arguments: dict[str, object], message: str) -> None:
    with pytest.raises(InputError, match=message):
        ControlLaw(**arguments)  # type: ignore[arg-type]


@given(st.integers(1, 4), st.integers(1, 3), st.integers(0, 2), st.integers(0, 99))
def test_a_bumpless_integrator_continues_the_command(
    n: int, m: int, history: int, seed: int
) -> None:
    """With as many integrators as inputs (``K_i`` square, invertible) the switched-in law
    computes exactly the old command; with fewer, the nearest it can (least squares)."""
    rng = np.random.default_rng(seed)
    K = rng.normal(size=(m, n + history * m))
    X, U = rng.normal(size=(n, 2)), rng.normal(size=(m, 2))
    C, F = rng.normal(size=(m, n)), rng.normal(size=(m, 2))
    K_i = rng.normal(size=(m, m)) + 3.0 * np.eye(m)
    law = ControlLaw(K, X, U, history=history, K_i=K_i, C=C, F=F, h=1e-4)
    x, w, past = rng.normal(size=n), rng.normal(size=2), rng.normal(size=(history, m))
    command = rng.normal(size=m)
    z = law.bumpless_integrator(x, w, past, command)
    np.testing.assert_allclose(law.command(x, w, past, z), command, rtol=1e-9, atol=1e-9)
    one = ControlLaw(K, X, U, history=history, K_i=K_i[:, :1], C=C[:1], F=F[:1], h=1e-4)
    z_one = one.bumpless_integrator(x, w, past, command)
    residual = one.command(x, w, past, z_one) - command
    assert abs(float((K_i[:, :1].T @ residual)[0])) <= 1e-9 * (1.0 + float(np.abs(command).max()))


def test_a_bumpless_switch_needs_an_integrator() -> None:
    law = ControlLaw.regulator(np.eye(2), np.zeros((2, 1)), np.zeros((2, 1)))
    with pytest.raises(InputError, match="bumpless switch sets the integrator"):
        law.bumpless_integrator(np.zeros(2), np.zeros(1), np.zeros((0, 2)), np.zeros(2))
