"""The least-squares regression of the data equation, with its excitation diagnostics.

A :class:`Regression` is ``Psi Theta = b``: one row per interval (or sample), its columns
in named blocks (``"P"``, ``"K"``, ``"M"`` for the continuous-time data equation of
:mod:`._moments`; other learners name their own blocks). :func:`solve_regression` checks
the rank of each block before it solves, so too little excitation is an
:class:`~selftune.errors.ExcitationError` that says which block lacks rank and what to
change in the experiment, never a silently wrong Theta.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from ...core import RANK_TOLERANCE, Array, theta_sizes, vecs_hat_from_outer
from ...errors import InputError, NotExciting, NumericalFailure, TooShort
from ._moments import IntervalMoments

__all__ = [
    "BLOCK_ADVICE",
    "Regression",
    "RegressionSolution",
    "regression",
    "solve_regression",
]

#: What to change in the experiment when a block of the regression lacks rank.
BLOCK_ADVICE = {
    "P": "the state is not excited enough: use longer data, more exploration on the inputs, "
    "or start away from the equilibrium",
    "K": "the inputs are not excited enough: add exploration noise on every input "
    "(e.g. uniform or PRBS), independent across inputs",
    "M": "the exogenous signal w is (nearly) constant or its channels move together: "
    "perturb the reference (e.g. a sampled-and-held w_d(t) with independent channels)",
}


@dataclass(frozen=True)
class Regression:
    """A stacked linear regression ``Psi Theta = b`` whose columns come in named blocks.

    Attributes
    ----------
    Psi : ndarray, shape (rows, unknowns)
        Columns ordered as the blocks.
    b : ndarray, shape (rows,)
        Right-hand side.
    block_sizes : mapping of str to int
        The blocks in column order and the number of columns of each.
    instruments : ndarray, shape (rows, unknowns), optional
        The same rows built from noise-free simulated states: with them
        :func:`solve_regression` is the instrumental-variable (two-stage least-squares)
        estimate, consistent under white measurement noise in ``Psi`` and ``b``.
    """

    Psi: Array
    b: Array
    block_sizes: Mapping[str, int] = field(default_factory=dict)
    instruments: Array | None = None

    @property
    def blocks(self) -> dict[str, slice]:
        """Column range of each block."""
        blocks: dict[str, slice] = {}
        start = 0
        for name, size in self.block_sizes.items():
            blocks[name] = slice(start, start + size)
            start += size
        return blocks


def _vec_stack(M: Array) -> Array:
    """``vec`` of each matrix of a stack (column-major), shape (count, rows * cols)."""
    return M.transpose(0, 2, 1).reshape(M.shape[0], -1)


def regression(
    moments: IntervalMoments,
    K: Array,
    Q: Array,
    R: Array,
    X: Array | None = None,
) -> Regression:
    """Rows of the continuous-time data equation for the policy ``K`` (= ``K_j``).

    Theta is ``[vecs(P_j); vec(K_(j+1)); vec(M)]``, with the M block present when the
    data carry an exogenous signal (q > 0).

    Parameters
    ----------
    moments : IntervalMoments
        The data.
    K : ndarray, shape (m, n)
        Policy being evaluated.
    Q, R : ndarray
        Cost weights.
    X : ndarray, shape (n, q), optional
        ``xbar = x - X w`` (default ``X = 0``, i.e. ``xbar = x``).

    Returns
    -------
    Regression
        Blocks ``"P"``, ``"K"`` and (q > 0) ``"M"``.
    """
    rows = _rows(moments, K, Q, R, X)
    if moments.instruments is None:
        return rows
    return replace(rows, instruments=_rows(moments.instruments, K, Q, R, X).Psi)


def _rows(moments: IntervalMoments, K: Array, Q: Array, R: Array, X: Array | None) -> Regression:
    n, m, q = moments.n, moments.m, moments.q
    X = np.zeros((n, q)) if X is None else X
    T = np.hstack([np.eye(n), -X])  # xbar = T z
    xx = T @ moments.zz @ T.T
    xu = T @ moments.zu
    dxx = T @ moments.dzz @ T.T
    weight = Q + K.T @ R @ K
    columns = [
        vecs_hat_from_outer(dxx),
        -2.0 * _vec_stack(R @ (xu.transpose(0, 2, 1) + K @ xx)),
    ]
    if q:
        wx = moments.zz[:, n:, :] @ T.T
        columns.append(-2.0 * _vec_stack(wx))
    b = -np.einsum("ab,kab->k", weight, xx)
    size_P, size_K, size_M = theta_sizes(n, m, q)
    sizes = {"P": size_P, "K": size_K} | ({"M": size_M} if q else {})
    return Regression(Psi=np.hstack(columns), b=b, block_sizes=sizes)


@dataclass(frozen=True)
class RegressionSolution:
    """The least-squares solution of a regression, with its excitation diagnostics.

    Attributes
    ----------
    theta : ndarray, shape (unknowns,)
        The whole solution (known blocks as given).
    rank : int
        Numerical rank of the (column-scaled) regression matrix of the solved blocks.
    unknowns : int
        Number of solved-for unknowns.
    rows : int
        Number of rows (intervals).
    block_ranks : dict[str, int]
        Rank each solved block adds to the blocks before it.
    block_sizes : dict[str, int]
        Number of unknowns of each solved block.
    condition : float
        Ratio of the largest to the smallest kept singular value (column-scaled).
    residual : float
        Relative residual ``||Psi theta - b|| / ||b||``.
    """

    theta: Array
    rank: int
    unknowns: int
    rows: int
    block_ranks: dict[str, int]
    block_sizes: dict[str, int]
    condition: float
    residual: float

    @property
    def deficient_blocks(self) -> list[str]:
        """Blocks whose columns are not all identifiable from the data."""
        return [name for name, rank in self.block_ranks.items() if rank < self.block_sizes[name]]


def _rank(singular_values: NDArray[np.floating]) -> int:
    if singular_values.size == 0 or singular_values[0] == 0.0:
        return 0
    return int(np.sum(singular_values > RANK_TOLERANCE * singular_values[0]))


def _without_known(
    problem: Regression, known: Mapping[str, Array]
) -> tuple[Array, Array, Array, dict[str, slice]]:
    """The columns left to solve for, the right-hand side with the known blocks moved to
    it, the solved columns' indices in Theta, and the solved blocks' column ranges."""
    all_blocks = problem.blocks
    for name, values in known.items():
        if name not in all_blocks:
            raise InputError(f"known: no block {name!r} (blocks: {', '.join(all_blocks)})")
        size = all_blocks[name].stop - all_blocks[name].start
        if np.shape(values) != (size,):
            raise InputError(f"known[{name!r}]: expected length {size}, got {np.shape(values)}")
    free = [name for name in all_blocks if name not in known]
    if not free:
        raise InputError("known: every block is given; nothing to solve for")
    b = problem.b.copy()
    for name, values in known.items():
        b -= problem.Psi[:, all_blocks[name]] @ np.asarray(values, dtype=float)
    columns = np.concatenate([np.arange(all_blocks[n].start, all_blocks[n].stop) for n in free])
    blocks: dict[str, slice] = {}
    start = 0
    for name in free:
        size = all_blocks[name].stop - all_blocks[name].start
        blocks[name] = slice(start, start + size)
        start += size
    return problem.Psi[:, columns], b, columns, blocks


def _block_ranks(triangular: Array, blocks: dict[str, slice]) -> dict[str, int]:
    """Rank each block adds to those before it, from the leading columns of the R factor."""
    size = triangular.shape[0]
    ranks: dict[str, int] = {}
    previous = 0
    for name, columns in blocks.items():
        stop = columns.stop
        cumulative = _rank(np.linalg.svd(triangular[: min(stop, size), :stop], compute_uv=False))
        ranks[name] = cumulative - previous
        previous = cumulative
    return ranks


_ABSURD = "the data hold non-finite or absurdly large values, or the policy is unstable"


def _factor(
    Psi: Array, b: Array, blocks: dict[str, slice]
) -> tuple[Array, Array, Array, dict[str, int]]:
    """Column scales, the triangular factor and projected right-hand side, and block ranks.

    Rows that are not finite (the data overflowed the data equation), or a factorization
    that fails, are a :class:`~selftune.errors.NumericalFailure` (an InputError): absurd
    data, never a result.
    """
    if not (np.all(np.isfinite(Psi)) and np.all(np.isfinite(b))):
        raise NumericalFailure(
            f"the data equation overflowed (not finite): {_ABSURD}", what="data equation"
        )
    rows, unknowns = Psi.shape
    try:
        with np.errstate(over="raise", invalid="raise"):
            scale = np.linalg.norm(Psi, axis=0)
        scale[scale == 0.0] = 1.0
        # One triangular factor makes everything small. With [Psi / scale, b] = Q [R, c],
        # the first k columns have the singular values of R[:k, :k] (each block's rank
        # from one factorization), and the least-squares solution is that of
        # R theta = c. Q is never formed (LAPACK's R-only QR of the tall matrix is the
        # one pass over the rows).
        stacked = np.column_stack([Psi / scale, b])
        factor = scipy.linalg.qr(stacked, mode="r", check_finite=False)[0]
        size = min(rows, unknowns)
        triangular, projected = factor[:size, :unknowns], factor[:size, unknowns]
        return scale, triangular, projected, _block_ranks(triangular, blocks)
    except (np.linalg.LinAlgError, FloatingPointError, ValueError) as exc:
        raise NumericalFailure(
            f"the regression could not be solved ({exc}): {_ABSURD}", what="factorization"
        ) from None


def _projected(
    problem: Regression, Psi: Array, b: Array, free_columns: Array
) -> tuple[Array, Array]:
    """Without instruments, the rows as they are; with instruments Z, the rows projected on
    Z's column space, ``Q_Z' Psi`` and ``Q_Z' b`` (``Z = Q_Z R_Z``): their least-squares
    solution is the two-stage least-squares (instrumental-variable) estimate."""
    if problem.instruments is None:
        return Psi, b
    Z = problem.instruments[:, free_columns]
    scale = np.linalg.norm(Z, axis=0)
    scale[scale == 0.0] = 1.0
    Q_Z = scipy.linalg.qr(Z / scale, mode="economic", check_finite=False)[0]
    return Q_Z.T @ Psi, Q_Z.T @ b


def solve_regression(
    problem: Regression,
    *,
    allow_deficient: Sequence[str] = (),
    known: Mapping[str, Array] | None = None,
) -> RegressionSolution:
    """Solve ``Psi Theta = b`` in the least-squares sense, after checking excitation.

    Columns are scaled to unit norm before the SVD, so the rank test does not depend on
    units. Blocks named in ``allow_deficient`` may lack rank; their part of Theta is then
    the minimum-norm one (the paper's Algorithm 1 does this with the M block) and
    :attr:`RegressionSolution.deficient_blocks` says so.

    Parameters
    ----------
    problem : Regression
        The rows.
    allow_deficient : sequence of str
        Blocks that may lack rank.
    known : mapping of str to ndarray, optional
        Blocks already learned (their part of Theta, e.g. ``{"P": vecs(P), "K": vec(K)}``):
        their columns move to the right-hand side and only the other blocks are solved
        for -- the paper's eq. 13 (Algorithm 2, second step). The returned theta is still
        the whole vector, with the known parts as given.

    Returns
    -------
    RegressionSolution
        With instruments (:attr:`Regression.instruments`), the instrumental-variable
        estimate; its residual is that of the measured rows.

    Raises
    ------
    TooShort
        If there are fewer rows than unknowns (an ExcitationError).
    NotExciting
        If a block not in ``allow_deficient`` lacks rank (an ExcitationError): the message
        gives the rank found, the rank needed, the block, and what to change in the
        experiment.
    NumericalFailure
        If the rows are not finite (the data overflowed the data equation) or the
        factorization fails (an SVD that does not converge): non-finite or absurdly large
        data, never a result.
    """
    Psi_full, b_full, free_columns, blocks = _without_known(problem, dict(known or {}))
    Psi, b = _projected(problem, Psi_full, b_full, free_columns)
    rows, unknowns = Psi_full.shape
    if rows < unknowns and not allow_deficient:
        raise TooShort(
            f"only {rows} regression intervals for {unknowns} unknowns: use longer data or a "
            f"shorter interval (at least {unknowns} intervals are needed)",
            samples=rows,
            samples_needed=unknowns,
        )
    scale, triangular, projected, block_ranks = _factor(Psi, b, blocks)
    try:
        left, singular_values, right = np.linalg.svd(triangular, full_matrices=False)
    except np.linalg.LinAlgError as exc:
        raise NumericalFailure(
            f"the regression could not be solved ({exc}): {_ABSURD}", what="factorization"
        ) from None
    block_sizes = {name: columns.stop - columns.start for name, columns in blocks.items()}
    rank = _rank(singular_values)
    for name in blocks:
        if block_ranks[name] < block_sizes[name] and name not in allow_deficient:
            advice = BLOCK_ADVICE.get(name, "excite the plant more (longer data, more exploration)")
            raise NotExciting(
                f"the regression has rank {rank} of {unknowns} needed: the {name} block adds "
                f"rank {block_ranks[name]} of {block_sizes[name]} ({rows} intervals); {advice}",
                rank=rank,
                rank_needed=unknowns,
                block=name,
            )
    kept = singular_values[:rank]
    solved = right[:rank].T @ ((left[:, :rank].T @ projected) / kept) / scale
    if not np.all(np.isfinite(solved)):
        raise NumericalFailure(
            f"the regression's solution is not finite: {_ABSURD}", what="solution"
        )
    norm_b = float(np.linalg.norm(b_full))
    residual = float(np.linalg.norm(Psi_full @ solved - b_full)) / norm_b if norm_b > 0 else 0.0
    theta = np.empty(problem.Psi.shape[1])
    theta[free_columns] = solved
    for name, values in (known or {}).items():
        theta[problem.blocks[name]] = values
    return RegressionSolution(
        theta=theta,
        rank=rank,
        unknowns=unknowns,
        rows=rows,
        block_ranks=block_ranks,
        block_sizes=block_sizes,
        condition=float(kept[0] / kept[-1]) if rank else float("inf"),
        residual=residual,
    )
