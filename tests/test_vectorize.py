"""The vectorization conventions against the paper's definitions, written out independently.

The references below are loops over the paper's definitions (Wang 2022, Sec. III-A):
``vec`` stacks columns; ``vecs(P) = [P_11..P_nn, 2P_12, .., 2P_(n-1)n]``;
``vecs_hat(x) = [x_1^2..x_n^2, x_1x_2, .., x_(n-1)x_n]``. They share no code with
:mod:`selftune.core._vectorize`.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from example_counts import at_least
from selftune.core import (
    pack_theta,
    theta_sizes,
    unpack_theta,
    unvec,
    unvecs,
    vec,
    vecs,
    vecs_hat,
    vecs_hat_from_outer,
)

# Bounded, normal floats: the identities below are exact up to rounding, so the
# tolerances are a few ulps of the magnitudes involved.
_FLOATS = st.floats(min_value=-100.0, max_value=100.0, allow_nan=False, allow_subnormal=False)


def _matrices(rows: int, cols: int) -> st.SearchStrategy[np.ndarray]:
    return hnp.arrays(np.float64, (rows, cols), elements=_FLOATS)


@st.composite
def _symmetric(draw: st.DrawFn, max_n: int = 8) -> np.ndarray:
    n = draw(st.integers(min_value=1, max_value=max_n))
    M = draw(_matrices(n, n))
    return 0.5 * (M + M.T)


@st.composite
def _symmetric_and_vector(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray]:
    P = draw(_symmetric())
    x = draw(hnp.arrays(np.float64, (P.shape[0],), elements=_FLOATS))
    return P, x


def _reference_vec(T: np.ndarray) -> np.ndarray:
    rows, cols = T.shape
    return np.array([T[i, j] for j in range(cols) for i in range(rows)])


def _reference_vecs(P: np.ndarray) -> np.ndarray:
    n = P.shape[0]
    diagonal = [P[i, i] for i in range(n)]
    upper = [2.0 * P[i, j] for i in range(n) for j in range(i + 1, n)]
    return np.array(diagonal + upper)


def _reference_vecs_hat(x: np.ndarray) -> np.ndarray:
    n = x.shape[0]
    squares = [x[i] ** 2 for i in range(n)]
    products = [x[i] * x[j] for i in range(n) for j in range(i + 1, n)]
    return np.array(squares + products)


# -- fixed examples: the conventions spelled out ------------------------------------------


def test_vec_stacks_columns() -> None:
    np.testing.assert_array_equal(vec([[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]]), [1, 3, 5, 2, 4, 6])


def test_vecs_puts_diagonal_first_then_doubled_upper_triangle_row_by_row() -> None:
    P = np.array([[1.0, 2.0, 3.0], [2.0, 4.0, 5.0], [3.0, 5.0, 6.0]])
    np.testing.assert_array_equal(vecs(P), [1, 4, 6, 4, 6, 10])


def test_vecs_hat_puts_squares_first_then_products_row_by_row() -> None:
    np.testing.assert_array_equal(vecs_hat([1.0, 2.0, 3.0]), [1, 4, 9, 2, 3, 6])


def test_theta_of_the_motor_has_the_paper_layout() -> None:
    # n = m = q = 2: 3 + 4 + 4 = 11 unknowns (PAPER_NOTES.md section 3).
    assert theta_sizes(2, 2, 2) == (3, 4, 4)
    P = np.array([[1.0, 2.0], [2.0, 3.0]])
    K = np.array([[4.0, 5.0], [6.0, 7.0]])
    M = np.array([[8.0, 9.0], [10.0, 11.0]])
    np.testing.assert_array_equal(pack_theta(P, K, M), [1, 3, 4, 4, 6, 5, 7, 8, 10, 9, 11])


# -- properties against the references ------------------------------------------------------


@given(
    st.integers(min_value=1, max_value=6).flatmap(
        lambda rows: st.integers(min_value=1, max_value=6).flatmap(
            lambda cols: _matrices(rows, cols)
        )
    )
)
def test_vec_matches_definition_and_round_trips(T: np.ndarray) -> None:
    rows, cols = T.shape
    v = vec(T)
    np.testing.assert_array_equal(v, _reference_vec(T))
    np.testing.assert_array_equal(unvec(v, rows, cols), T)
    np.testing.assert_array_equal(vec(unvec(v, rows, cols)), v)


@given(_symmetric())
def test_vecs_matches_definition_and_round_trips(P: np.ndarray) -> None:
    n = P.shape[0]
    v = vecs(P)
    assert v.shape == (n * (n + 1) // 2,)
    np.testing.assert_array_equal(v, _reference_vecs(P))
    # Halving and doubling are exact in binary floating point.
    np.testing.assert_array_equal(unvecs(v, n), P)
    np.testing.assert_array_equal(vecs(unvecs(v, n)), v)


@given(_symmetric())
def test_vecs_reads_only_the_diagonal_and_the_upper_triangle(P: np.ndarray) -> None:
    # As documented: the strictly lower triangle is ignored (garbage there changes nothing).
    garbage = np.tril(np.full(P.shape, 7.0), k=-1)
    np.testing.assert_array_equal(vecs(np.triu(P) + garbage), vecs(P))


@given(
    st.integers(min_value=1, max_value=8).flatmap(
        lambda n: hnp.arrays(np.float64, (n,), elements=_FLOATS)
    )
)
def test_vecs_hat_matches_definition(x: np.ndarray) -> None:
    np.testing.assert_array_equal(vecs_hat(x), _reference_vecs_hat(x))


@at_least(200)
@given(_symmetric_and_vector())
def test_quadratic_form_equals_vecs_hat_dot_vecs(case: tuple[np.ndarray, np.ndarray]) -> None:
    P, x = case
    expected = float(x @ P @ x)
    actual = float(vecs_hat(x) @ vecs(P))
    # Both sides sum n^2 (resp. n(n+1)/2) products of size <= |x|^2 max|P|.
    scale = float(x @ x) * float(np.max(np.abs(P))) * P.shape[0]
    assert abs(actual - expected) <= 1e-13 * max(scale, 1e-300)


@given(
    st.integers(min_value=1, max_value=6).flatmap(
        lambda n: st.integers(min_value=1, max_value=5).flatmap(
            lambda k: hnp.arrays(np.float64, (k, n), elements=_FLOATS)
        )
    )
)
def test_vecs_hat_of_a_stack_is_the_stack_of_vecs_hat(xs: np.ndarray) -> None:
    stacked = vecs_hat(xs)
    assert stacked.shape == (xs.shape[0], xs.shape[1] * (xs.shape[1] + 1) // 2)
    for row, x in zip(stacked, xs, strict=True):
        np.testing.assert_array_equal(row, _reference_vecs_hat(x))


@given(
    st.integers(min_value=1, max_value=8).flatmap(
        lambda n: hnp.arrays(np.float64, (n,), elements=_FLOATS)
    )
)
def test_vecs_hat_from_outer_of_x_x_transpose_is_vecs_hat(x: np.ndarray) -> None:
    np.testing.assert_array_equal(vecs_hat_from_outer(np.outer(x, x)), vecs_hat(x))


@given(
    st.integers(min_value=1, max_value=6).flatmap(
        lambda n: st.tuples(
            hnp.arrays(np.float64, (4, n), elements=_FLOATS),
            hnp.arrays(np.float64, (4,), elements=_FLOATS),
        )
    )
)
def test_vecs_hat_from_outer_is_linear(case: tuple[np.ndarray, np.ndarray]) -> None:
    xs, weights = case
    outers = np.einsum("ki,kj->kij", xs, xs)
    combined = np.einsum("k,kij->ij", weights, outers)
    expected = weights @ vecs_hat(xs)
    scale = float(np.abs(weights) @ np.sum(xs**2, axis=1))
    np.testing.assert_allclose(
        vecs_hat_from_outer(combined), expected, rtol=0, atol=1e-13 * max(scale, 1e-300)
    )
    # A stack of outer products maps to the stack of vecs_hat.
    np.testing.assert_array_equal(vecs_hat_from_outer(outers), vecs_hat(xs))


@given(st.tuples(_symmetric(max_n=6), st.integers(min_value=0, max_value=2**32 - 1)))
def test_vecs_hat_from_outer_dot_vecs_is_the_trace_of_the_product(
    case: tuple[np.ndarray, int],
) -> None:
    # For symmetric S and P: sum_ij S_ij P_ij = trace(S P) = vecs_hat_from_outer(S) @ vecs(P).
    P, seed = case
    S = np.random.default_rng(seed).standard_normal(P.shape)
    S = S + S.T
    scale = float(np.sum(np.abs(S) * np.abs(P)))
    assert abs(vecs_hat_from_outer(S) @ vecs(P) - np.trace(S @ P)) <= 1e-13 * max(scale, 1e-300)


@given(
    st.integers(min_value=1, max_value=6),
    st.integers(min_value=1, max_value=4),
    st.integers(min_value=0, max_value=3),
    st.integers(min_value=0, max_value=2**32 - 1),
)
def test_pack_and_unpack_theta_round_trip(n: int, m: int, q: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    P = rng.standard_normal((n, n))
    P = P + P.T
    K = rng.standard_normal((m, n))
    M = rng.standard_normal((q, n))
    theta = pack_theta(P, K, M)
    assert theta.shape == (sum(theta_sizes(n, m, q)),)
    size_P, size_K, _ = theta_sizes(n, m, q)
    np.testing.assert_array_equal(theta[:size_P], _reference_vecs(P))
    np.testing.assert_array_equal(theta[size_P : size_P + size_K], _reference_vec(K))
    np.testing.assert_array_equal(theta[size_P + size_K :], _reference_vec(M))
    P_back, K_back, M_back = unpack_theta(theta, n, m, q)
    np.testing.assert_array_equal(P_back, P)
    np.testing.assert_array_equal(K_back, K)
    np.testing.assert_array_equal(M_back, M)
    assert M_back.shape == (q, n)


def test_pack_theta_without_m_is_plain_lqr_theta() -> None:
    P = np.array([[2.0, 1.0], [1.0, 3.0]])
    K = np.array([[1.0, 2.0]])
    theta = pack_theta(P, K)
    np.testing.assert_array_equal(theta, [2, 3, 2, 1, 2])
    P_back, K_back, M_back = unpack_theta(theta, n=2, m=1)
    np.testing.assert_array_equal(P_back, P)
    np.testing.assert_array_equal(K_back, K)
    assert M_back.shape == (0, 2)


# -- wrong lengths and shapes -------------------------------------------------------------


@pytest.mark.parametrize("length", [0, 5, 7, 12])
def test_unvec_rejects_wrong_length(length: int) -> None:
    with pytest.raises(ValueError, match="length 6"):
        unvec(np.zeros(length), 2, 3)


def test_unvec_rejects_a_matrix() -> None:
    with pytest.raises(ValueError, match="length 6"):
        unvec(np.zeros((2, 3)), 2, 3)


@pytest.mark.parametrize("length", [0, 5, 7, 9])
def test_unvecs_rejects_wrong_length(length: int) -> None:
    with pytest.raises(ValueError, match="length 6"):
        unvecs(np.zeros(length), 3)


@pytest.mark.parametrize("length", [10, 12, 3, 0])
def test_unpack_theta_rejects_wrong_length(length: int) -> None:
    with pytest.raises(ValueError, match="length 11"):
        unpack_theta(np.zeros(length), n=2, m=2, q=2)


@pytest.mark.parametrize("shape", [(2, 3), (3,), (2, 2, 2)])
def test_vecs_rejects_a_non_square_matrix(shape: tuple[int, ...]) -> None:
    with pytest.raises(ValueError, match="square"):
        vecs(np.ones(shape))


@pytest.mark.parametrize("shape", [(2, 3), (4, 2, 3), (3,)])
def test_vecs_hat_from_outer_rejects_non_square_matrices(shape: tuple[int, ...]) -> None:
    with pytest.raises(ValueError, match="square"):
        vecs_hat_from_outer(np.ones(shape))


def test_vecs_hat_rejects_a_scalar() -> None:
    with pytest.raises(ValueError, match="vector"):
        vecs_hat(1.0)
