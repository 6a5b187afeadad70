"""The data equation: regression rows of Jiang & Jiang (2012) and Gao & Jiang (2016).

For a plant ``x' = A x + B u + D w`` and any applied input ``u``, along the data, with
``xbar = x - X w``, a policy ``K_j``, its value ``P_j`` and ``K_(j+1) = R^-1 B' P_j``,
over an interval ``[t, t + dt]``::

    xbar'P_j xbar |_t^(t+dt) = - int xbar'(Q + K_j'R K_j) xbar
                               + 2 int (u + K_j xbar)' R K_(j+1) xbar
                               + 2 int w' M xbar,          M = (D + A X - X E)' P_j

i.e. ``[psi_P, psi_K, psi_M] Theta = psi_b`` with ``Theta = [vecs(P_j); vec(K_(j+1)); vec(M)]``
(see :mod:`selftune.vectorize`)::

    psi_P = sum of the within-sample changes of vecs_hat(xbar)
    psi_K = -2 vec(R int (u + K_j xbar) xbar')'
    psi_M = -2 vec(int w xbar')'
    psi_b = -<Q + K_j'R K_j, int xbar xbar'>

Quadrature, consistent with how the data were made (PAPER_NOTES.md section 4):

- ``u`` is held over each sample, so ``int u xbar'`` is ``u_k`` times the integral of
  ``xbar``; the ``K_j xbar`` part is integrated as the state-dependent term it is;
- inside a sample whose input changes at both ends, the state is interpolated linearly
  between its samples, and every integral is exact for that interpolant (second order
  in the sampling period h);
- inside a hold -- consecutive samples with the same input (and the same held ``w``),
  read off the data, e.g. a controller updating every second sample -- the state is
  analytic, and each sample is integrated with the quadratic through three of the hold's
  sample points; paired samples then add up to Simpson's rule (fourth order in h; an odd
  hold's last sample is third order);
- a held ``w`` (E = 0) is constant inside each sample and ``xbar`` jumps where ``w``
  steps: ``psi_P`` sums the within-sample changes and leaves the jumps out, which keeps
  the equation exact (the ``-X w'`` term of pitfall 2 never appears);
- a continuous ``w`` (E != 0, the exosystem state) is interpolated like the state.

Everything above is linear in three per-interval moments of ``z = [x; w]`` --
``int z z'``, ``int z u'`` and the sum of within-sample changes of ``z z'`` -- which are
computed once per data set (:func:`interval_moments`); a regression for any ``K_j`` and
``X`` is then a few small matrix products (:func:`regression`). That is what makes the
off-policy iteration (one batch of data reused for every j) cheap.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from .errors import ExcitationError, InputError
from .trajectory import Trajectory, as_trajectories
from .vectorize import theta_sizes, vecs_hat_from_outer

__all__ = [
    "BLOCK_ADVICE",
    "IntervalMoments",
    "Regression",
    "RegressionSolution",
    "interval_moments",
    "regression",
    "solve_regression",
]

Array = NDArray[np.float64]

#: Relative singular-value threshold of the rank tests of the regression.
RANK_TOLERANCE = 1e-9

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
class IntervalMoments:
    """Per-interval moments of ``z = [x; w]`` from which every regression row is formed.

    Attributes
    ----------
    zz : ndarray, shape (intervals, n + q, n + q)
        ``int z z' dt`` over each interval.
    zu : ndarray, shape (intervals, n + q, m)
        ``int z u' dt`` over each interval.
    dzz : ndarray, shape (intervals, n + q, n + q)
        Sum over the interval's samples of ``z z'`` at the end of the sample minus at its
        start (a held ``w`` jumps at sample instants; the jumps are left out).
    duration : ndarray, shape (intervals,)
        Length of each interval, s.
    n, m, q : int
        State, input and exogenous dimensions.
    """

    zz: Array
    zu: Array
    dzz: Array
    duration: Array
    n: int
    m: int
    q: int

    @property
    def intervals(self) -> int:
        """Number of intervals, i.e. of regression rows."""
        return int(self.duration.shape[0])


def _holds(episode: Trajectory, held: bool) -> NDArray[np.bool_]:
    """``continues[k]``: sample k + 1 is in the same hold as sample k (u and a held w equal)."""
    same = np.all(episode.u[1:] == episode.u[:-1], axis=1)
    if held and episode.w is not None:
        count = episode.num_samples
        same &= np.all(episode.w[1:count] == episode.w[: count - 1], axis=1)
    return same


def _quadratic_stencils(
    t: Array, continues: NDArray[np.bool_]
) -> tuple[NDArray[np.bool_], NDArray[np.intp], Array]:
    """Three-point stencils inside holds, and their weights for each sample's integral.

    Inside a hold (a run of samples over which u and a held w do not change) the state is
    analytic, so the quadratic through three of the hold's sample points integrates it
    to third order per sample. Samples are paired -- (first, second), (third, fourth), ...
    -- and both of a pair use the same three points, so a pair's sum is Simpson's rule
    (fourth order); the last sample of an odd hold uses the three points ending with it.

    Returns
    -------
    in_hold : bool array (N,)
        Samples inside a hold of two or more samples.
    points : int array (N, 3)
        The stencil's sample-point indices (meaningful where ``in_hold``).
    weights : array (N, 3)
        ``int over the sample of f = sum_i weights[k, i] f(t[points[k, i]])`` for f
        quadratic.
    """
    count = t.shape[0] - 1
    index = np.arange(count)
    run_start = np.concatenate([[True], ~continues])
    start_of = np.maximum.accumulate(np.where(run_start, index, 0))
    run_id = np.cumsum(run_start) - 1
    run_length = np.bincount(run_id)[run_id]
    position = index - start_of
    in_hold = run_length >= 2
    forward = in_hold & (position % 2 == 0) & (position < run_length - 1)
    first = np.where(forward, index, index - 1)
    first = np.clip(first, 0, max(count - 2, 0))
    points = first[:, None] + np.arange(3)[None, :]
    points = np.minimum(points, count)
    h1 = t[points[:, 1]] - t[points[:, 0]]
    h2 = t[points[:, 2]] - t[points[:, 1]]
    total = np.where(in_hold, h1 + h2, 1.0)
    h1 = np.where(in_hold, h1, 1.0)
    h2 = np.where(in_hold, h2, 1.0)
    # Integral over [t0, t1] (forward) of the quadratic through (t0, t1, t2), and by time
    # reversal over [t1, t2] (backward).
    forward_weights = np.column_stack(
        [
            h1 * (h1 / 3.0 + h2 / 2.0) / total,
            h1 * (total / 2.0 - h1 / 3.0) / h2,
            -(h1**3) / (6.0 * total * h2),
        ]
    )
    backward_weights = np.column_stack(
        [
            -(h2**3) / (6.0 * total * h1),
            h2 * (total / 2.0 - h2 / 3.0) / h1,
            h2 * (h2 / 3.0 + h1 / 2.0) / total,
        ]
    )
    weights = np.where(forward[:, None], forward_weights, backward_weights)
    weights[~in_hold] = 0.0
    return in_hold, points, weights


def _episode_moments(episode: Trajectory, interval: int, held: bool) -> tuple[Array, ...]:
    h = np.diff(episode.t)
    count = h.shape[0]
    x = episode.x
    if episode.w is None:
        w_start = w_end = np.zeros((count, 0))
        w_points = np.zeros((count + 1, 0))
    else:
        w = episode.w
        if held:
            w_start = w[:count]
            w_end = w_start
            w_points = w  # unused for held signals (each sample uses its own value)
        else:
            if w.shape[0] != count + 1:
                raise InputError(
                    f"Trajectory.w: with a non-zero E, w must be the exosystem state at all "
                    f"{count + 1} sample times, got {w.shape[0]} rows"
                )
            w_start, w_end, w_points = w[:-1], w[1:], w
    start = np.hstack([x[:-1], w_start])
    end = np.hstack([x[1:], w_end])
    # Samples in no hold: exact integrals for z linear from a to b, u held:
    #   int z z' = h/6 (2 a a' + 2 b b' + a b' + b a') = h/6 ((2a + b) a' + (a + 2b) b')
    #   int z   = h/2 (a + b)
    # Samples inside a hold: the quadratic through three of the hold's points
    # (_quadratic_stencils), applied to z z' and to z.
    in_hold, points, weights = _quadratic_stencils(episode.t, _holds(episode, held))
    single = (~in_hold)[:, None] * (h[:, None] / 6.0)
    terms = [((2.0 * start + end) * single, start), ((start + 2.0 * end) * single, end)]
    integral = 3.0 * single * (start + end)
    for i in range(3):
        # z at the stencil point; a held w is the sample's own value throughout its hold.
        z_i = np.hstack([x[points[:, i]], w_start if held else w_points[points[:, i]]])
        terms.append((z_i * weights[:, i : i + 1], z_i))
        integral = integral + z_i * weights[:, i : i + 1]
    # Summed over each interval's samples by batched matrix products (no N x p x p array);
    # samples are padded to whole intervals with zero rows, which add nothing.
    intervals = -(-count // interval)
    padding = intervals * interval - count

    def grouped(rows: Array) -> Array:
        padded = np.concatenate([rows, np.zeros((padding, *rows.shape[1:]))])
        return padded.reshape(intervals, interval, *rows.shape[1:])

    zz = sum(
        (grouped(left).transpose(0, 2, 1) @ grouped(right) for left, right in terms),
        np.zeros((intervals, start.shape[1], start.shape[1])),
    )
    zz = 0.5 * (zz + zz.transpose(0, 2, 1))
    zu = grouped(integral).transpose(0, 2, 1) @ grouped(episode.u)
    a, b = grouped(start), grouped(end)
    dzz = b.transpose(0, 2, 1) @ b - a.transpose(0, 2, 1) @ a
    return zz, zu, dzz, grouped(h[:, None]).sum(axis=1)[:, 0]


def interval_moments(
    data: Trajectory | Sequence[Trajectory], interval: int = 10, *, held: bool = True
) -> IntervalMoments:
    """The per-interval moments of one trajectory or of several episodes.

    Parameters
    ----------
    data : Trajectory or sequence of Trajectory
        The samples; several episodes (e.g. restarts) each contribute their own intervals.
    interval : int
        Samples per regression interval (the last interval of an episode may be shorter).
    held : bool
        True when ``w`` is held over each sample (E = 0); False when ``w`` is the
        continuous exosystem state sampled at every sample time (E != 0).

    Returns
    -------
    IntervalMoments
    """
    if isinstance(interval, bool) or not isinstance(interval, int | np.integer) or interval < 1:
        raise InputError(f"interval: must be a whole number of samples >= 1, got {interval!r}")
    episodes = as_trajectories(data)
    parts = [_episode_moments(episode, int(interval), held) for episode in episodes]
    first = episodes[0]
    return IntervalMoments(
        zz=np.concatenate([part[0] for part in parts]),
        zu=np.concatenate([part[1] for part in parts]),
        dzz=np.concatenate([part[2] for part in parts]),
        duration=np.concatenate([part[3] for part in parts]),
        n=first.n,
        m=first.m,
        q=first.q,
    )


@dataclass(frozen=True)
class Regression:
    """The stacked data equation ``Psi Theta = b`` for one policy ``K_j`` and one ``X``.

    Attributes
    ----------
    Psi : ndarray, shape (intervals, unknowns)
        Columns ordered as Theta: the P block, the K block, then the M block.
    b : ndarray, shape (intervals,)
    n, m, q : int
        Dimensions; ``q = 0`` when the exogenous block is left out.
    """

    Psi: Array
    b: Array
    n: int
    m: int
    q: int

    @property
    def blocks(self) -> dict[str, slice]:
        """Column ranges of the blocks ``"P"``, ``"K"`` and ``"M"`` (if q > 0)."""
        size_P, size_K, size_M = theta_sizes(self.n, self.m, self.q)
        blocks = {"P": slice(0, size_P), "K": slice(size_P, size_P + size_K)}
        if size_M:
            blocks["M"] = slice(size_P + size_K, size_P + size_K + size_M)
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
    *,
    exogenous: bool = True,
) -> Regression:
    """Rows of the data equation for the policy ``K`` (the ``K_j`` being evaluated).

    Parameters
    ----------
    moments : IntervalMoments
    K : ndarray, shape (m, n)
        Policy being evaluated.
    Q, R : ndarray
        Cost weights.
    X : ndarray, shape (n, q), optional
        ``xbar = x - X w`` (default ``X = 0``, i.e. ``xbar = x``).
    exogenous : bool
        Include the M block (requires q > 0). Without it, the rows are those of plain
        LQR learning (Jiang & Jiang 2012) and ``w`` must be zero in the data.
    """
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
    if exogenous and q:
        wx = moments.zz[:, n:, :] @ T.T
        columns.append(-2.0 * _vec_stack(wx))
    b = -np.einsum("ab,kab->k", weight, xx)
    return Regression(Psi=np.hstack(columns), b=b, n=n, m=m, q=q if exogenous else 0)


@dataclass(frozen=True)
class RegressionSolution:
    """The least-squares solution of a regression, with its excitation diagnostics.

    Attributes
    ----------
    theta : ndarray, shape (unknowns,)
    rank : int
        Numerical rank of the (column-scaled) regression matrix.
    unknowns : int
    rows : int
    block_ranks : dict[str, int]
        Rank each block adds to the blocks before it (P, then K, then M).
    block_sizes : dict[str, int]
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


def _rank(singular_values: Array) -> int:
    if singular_values.size == 0 or singular_values[0] == 0.0:
        return 0
    return int(np.sum(singular_values > RANK_TOLERANCE * singular_values[0]))


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

    ``known`` gives blocks already learned (their part of Theta, e.g.
    ``{"P": vecs(P), "K": vec(K)}``): their columns move to the right-hand side and only
    the other blocks are solved for -- the paper's eq. 13 (Algorithm 2, second step).
    The returned theta is still the whole vector, with the known parts as given.

    Raises
    ------
    ExcitationError
        If there are fewer rows than unknowns, or a block not in ``allow_deficient`` lacks
        rank: the message gives the rank found, the rank needed, the block, and what to
        change in the experiment.
    """
    known = dict(known or {})
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
    free_columns = np.concatenate(
        [np.arange(all_blocks[n].start, all_blocks[n].stop) for n in free]
    )
    Psi = problem.Psi[:, free_columns]
    blocks: dict[str, slice] = {}
    start = 0
    for name in free:
        size = all_blocks[name].stop - all_blocks[name].start
        blocks[name] = slice(start, start + size)
        start += size
    rows, unknowns = Psi.shape
    if rows < unknowns and not allow_deficient:
        raise ExcitationError(
            f"only {rows} regression intervals for {unknowns} unknowns: use longer data or a "
            f"shorter interval (at least {unknowns} intervals are needed)"
        )
    scale = np.linalg.norm(Psi, axis=0)
    scale[scale == 0.0] = 1.0
    scaled = Psi / scale
    # One triangular factor makes everything small. With [scaled, b] = Q [R, c], the first
    # k columns of scaled have the singular values of R[:k, :k] (each block's rank from one
    # factorization), and the least-squares solution is that of R theta = c. Q is never
    # formed (LAPACK's R-only QR of the tall matrix is the one pass over the rows).
    factor = scipy.linalg.qr(np.column_stack([scaled, b]), mode="r", check_finite=False)[0]
    size = min(rows, unknowns)
    triangular, projected = factor[:size, :unknowns], factor[:size, unknowns]
    block_ranks: dict[str, int] = {}
    block_sizes: dict[str, int] = {}
    previous_rank = 0
    for name, columns in blocks.items():
        stop = columns.stop
        leading = triangular[: min(stop, size), :stop]
        cumulative = _rank(np.linalg.svd(leading, compute_uv=False))
        block_ranks[name] = cumulative - previous_rank
        block_sizes[name] = columns.stop - columns.start
        previous_rank = cumulative
    left, singular_values, right = np.linalg.svd(triangular, full_matrices=False)
    rank = _rank(singular_values)
    for name in blocks:
        if block_ranks[name] < block_sizes[name] and name not in allow_deficient:
            raise ExcitationError(
                f"the regression has rank {rank} of {unknowns} needed: the {name} block adds "
                f"rank {block_ranks[name]} of {block_sizes[name]} ({rows} intervals); "
                f"{BLOCK_ADVICE[name]}"
            )
    kept = singular_values[:rank]
    coefficients = right[:rank].T @ ((left[:, :rank].T @ projected) / kept)
    solved = coefficients / scale
    norm_b = float(np.linalg.norm(b))
    residual = float(np.linalg.norm(Psi @ solved - b)) / norm_b if norm_b > 0 else 0.0
    theta = np.empty(problem.Psi.shape[1])
    theta[free_columns] = solved
    for name, values in known.items():
        theta[all_blocks[name]] = values
    condition = float(kept[0] / kept[-1]) if rank else float("inf")
    return RegressionSolution(
        theta=theta,
        rank=rank,
        unknowns=unknowns,
        rows=rows,
        block_ranks=block_ranks,
        block_sizes=block_sizes,
        condition=condition,
        residual=residual,
    )
