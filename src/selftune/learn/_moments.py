"""The data equation: regression rows of Jiang & Jiang (2012) and Gao & Jiang (2016).

For a plant ``x' = A x + B u + D w`` and any applied input ``u``, along the data, with
``xbar = x - X w``, a policy ``K_j``, its value ``P_j`` and ``K_(j+1) = R^-1 B' P_j``,
over an interval ``[t, t + dt]``::

    xbar'P_j xbar |_t^(t+dt) = - int xbar'(Q + K_j'R K_j) xbar
                               + 2 int (u + K_j xbar)' R K_(j+1) xbar
                               + 2 int w' M xbar,          M = (D + A X - X E)' P_j

i.e. ``[psi_P, psi_K, psi_M] Theta = psi_b`` with ``Theta = [vecs(P_j); vec(K_(j+1)); vec(M)]``
(see :mod:`selftune.core._vectorize`)::

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
``X`` is then a few small matrix products (``selftune.learn.regression``). That is what makes the
off-policy iteration (one batch of data reused for every j) cheap.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from ..core import Array, positive_integer
from ..errors import InputError
from ._trajectory import Trajectory, as_trajectories

__all__ = ["IntervalMoments", "WKind", "interval_moments"]

#: What the exogenous signal ``w`` of a trajectory is: held over each sample (``E = 0``,
#: a digital reference) or the exosystem state ``w' = E w`` sampled at each sample time.
WKind = Literal["held", "exosystem"]


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


def _w_columns(episode: Trajectory, held: bool) -> tuple[Array, Array, Array]:
    """``w`` at each sample's start and end, and at the sample points (for the stencils).

    A held ``w`` is the sample's own value throughout it; an exosystem state is taken at
    both ends, like the state.
    """
    count = episode.num_samples
    if episode.w is None:
        return np.zeros((count, 0)), np.zeros((count, 0)), np.zeros((count + 1, 0))
    w = episode.w
    if held:
        return w[:count], w[:count], w  # the points are unused for a held signal
    if w.shape[0] != count + 1:
        raise InputError(
            f"Trajectory.w: with a non-zero E, w must be the exosystem state at all "
            f"{count + 1} sample times, got {w.shape[0]} rows"
        )
    return w[:-1], w[1:], w


def _episode_moments(episode: Trajectory, interval: int, held: bool) -> tuple[Array, ...]:
    h = np.diff(episode.t)
    count = h.shape[0]
    x = episode.x
    w_start, w_end, w_points = _w_columns(episode, held)
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
    data: Trajectory | Sequence[Trajectory], interval: int = 10, *, w_kind: WKind = "held"
) -> IntervalMoments:
    """The per-interval moments of one trajectory or of several episodes.

    Parameters
    ----------
    data : Trajectory or sequence of Trajectory
        The samples; several episodes (e.g. restarts) each contribute their own intervals.
    interval : int
        Samples per regression interval (the last interval of an episode may be shorter).
    w_kind : {"held", "exosystem"}
        ``"held"`` when ``w`` is held over each sample (E = 0); ``"exosystem"`` when ``w``
        is the continuous exosystem state sampled at every sample time (E != 0).

    Returns
    -------
    IntervalMoments
    """
    interval = positive_integer(interval, "interval")
    if w_kind not in ("held", "exosystem"):
        raise InputError(f"w_kind: must be 'held' or 'exosystem', got {w_kind!r}")
    held = w_kind == "held"
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
