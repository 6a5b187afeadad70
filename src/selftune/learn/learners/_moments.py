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

With integral action (:mod:`._servo`) the state is augmented with ``z_e``, the integral
of the regulated error ``e = C x + F w`` (the control law's ``z``), which the logs do not
hold: the learner computes it, from 0 at each episode's start, so that it is the exact
integral of the interpolant the moments use, and ``x`` below stands for ``[x; z_e]``:

- in a sample whose input changes at both ends, ``e`` is linear (the state's linear
  interpolant), so ``z_e`` grows by the trapezoid ``h (e_a + e_b) / 2`` and inside the
  sample is the quadratic ``z_e(s) = z_a (1 - s/h) + z_b s/h + v (s/h) (1 - s/h)``,
  ``v = -h (e_b - e_a) / 2``, which the moments integrate exactly (second order in h,
  like the state's);
- inside a hold, each sample's increment is the integral of the hold's quadratic through
  three sample points (paired samples add up to Simpson's rule: fourth order), and
  ``z_e`` at the sample points enters the three-point stencils like the state;
- ``z_e`` is continuous where a held ``w`` steps (``e`` jumps, its integral does not).

With a discount rate ``gamma`` (1/s, :mod:`._servo`) every moment of an interval starting
at ``t0`` carries the weight ``g(s) = exp(-gamma (s - t0))``, and ``psi_P`` sums
``g(t_(k+1)) z z'(t_(k+1)-) - g(t_k) z z'(t_k+)``. The weight is integrated exactly
against the same interpolants: outside holds with the moments
``int_0^1 tau^p exp(-gamma h tau) dtau`` (p = 0..4), so the rows are exact wherever the
undiscounted ones are (a state linear inside each sample); inside holds the stencils
integrate ``g z z'``. ``gamma = 0`` is the undiscounted quadrature above, unchanged to the
last bit.

Everything above is linear in three per-interval moments of ``z = [x; w]`` --
``int z z'``, ``int z u'`` and the sum of within-sample changes of ``z z'`` -- which are
computed once per data set and discount (:func:`interval_moments`); a regression for any
``K_j`` and ``X`` is then a few small matrix products (``selftune.learn.regression``). That
is what makes the off-policy iteration (one batch of data reused for every j) cheap.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ...core import Array, as_matrix, finite_float, positive_integer
from ...errors import InputError
from ..data._trajectory import Trajectory, as_trajectories

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
        State, input and exogenous dimensions (n counts the r integrator states).
    instruments : IntervalMoments or None
        The same moments of noise-free states simulated from the same inputs (an
        output-error model's, :mod:`..evidence._output_error`): the regressions built from them are
        instruments, uncorrelated with the measurement noise (:func:`solve_regression`).
    r : int
        Integrator states: the last r of the n states are ``z_e``, the integral of the
        regulated error (0 without integral action).
    discount : float
        The discount rate ``gamma`` of the weights ``exp(-gamma (s - t0))``, 1/s (0: none).
    """

    zz: Array
    zu: Array
    dzz: Array
    duration: Array
    n: int
    m: int
    q: int
    instruments: IntervalMoments | None = None
    r: int = 0
    discount: float = 0.0

    def with_instruments(self, instruments: IntervalMoments) -> IntervalMoments:
        """These moments with ``instruments`` attached (same intervals).

        Parameters
        ----------
        instruments : IntervalMoments
            Moments of simulated noise-free states over the same intervals.
        """
        if instruments.zz.shape != self.zz.shape:
            raise InputError(
                f"instruments: {instruments.intervals} intervals, but the data have "
                f"{self.intervals}"
            )
        if (instruments.r, instruments.discount) != (self.r, self.discount):
            raise InputError(
                f"instruments: {instruments.r} integrator states and discount "
                f"{instruments.discount:g} 1/s, but the data have {self.r} and "
                f"{self.discount:g} 1/s"
            )
        return replace(self, instruments=instruments)

    def without_integrator(self) -> IntervalMoments:
        """The moments of the plant's own state and ``w``: the integrator states dropped.

        Returns
        -------
        IntervalMoments
            With ``r = 0`` (and the instruments' likewise).
        """
        if not self.r:
            return self
        kept = np.r_[0 : self.n - self.r, self.n : self.n + self.q]
        return replace(
            self,
            zz=self.zz[:, kept][:, :, kept],
            zu=self.zu[:, kept],
            dzz=self.dzz[:, kept][:, :, kept],
            n=self.n - self.r,
            r=0,
            instruments=None if self.instruments is None else self.instruments.without_integrator(),
        )

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


def _integrator_states(
    x: Array, w: tuple[Array, Array], integral: Array, output: Array, single: Array
) -> tuple[Array, Array]:
    """``z_e`` at the sample points and its bubble ``v`` in each sample.

    ``z_e`` starts at 0 and grows by each sample's integral of ``e = [C, F] [x; w]``
    (``output``), taken from ``integral``, the per-sample integrals of ``[x; w]``.
    Outside holds (``single`` = h/6 there, 0 inside) ``z_e`` is the quadratic of the module
    docstring, ``v = -h (e_b - e_a) / 2``; inside holds ``v = 0``.
    """
    w_start, w_end = w
    increments = integral @ output.T
    z = np.vstack([np.zeros((1, output.shape[0])), np.cumsum(increments, axis=0)])
    e_start = np.hstack([x[:-1], w_start]) @ output.T
    e_end = np.hstack([x[1:], w_end]) @ output.T
    bubble = -3.0 * single * (e_end - e_start)  # -h/2 (e_b - e_a) outside holds, else 0
    return z, bubble


def _exponential_moments(c: Array) -> Array:
    """``m_p = int_0^1 tau^p exp(-c tau) dtau`` for p = 0..4, shape (5, N), for c >= 0.

    A series for c <= 1 (25 terms: exact to rounding), the upward recurrence
    ``m_p = (p m_(p-1) - exp(-c)) / c`` above (it loses at most a factor 4!/c^4 < 24).
    """
    small = c <= 1.0
    powers = np.arange(5)[:, None]
    series = np.zeros((5, c.shape[0]))
    term = np.ones_like(c)
    for k in range(25):
        series += term / (powers + k + 1)
        term = term * (-c) / (k + 1)
    large = np.where(small, 1.0, c)
    decay = np.exp(-large)
    recurrence = [-np.expm1(-large) / large]
    for p in range(1, 5):
        recurrence.append((p * recurrence[-1] - decay) / large)
    return np.where(small, series, np.array(recurrence))


def _terms(
    ends: tuple[Array, Array, Array], nodes: list[Array], rules: tuple[Array, Array]
) -> tuple[list[tuple[Array, Array]], Array]:
    """The undiscounted quadrature: the pairs (left, right) whose products
    ``sum_k left_k right_k'`` add up to ``int z z'`` over the samples (before
    symmetrization), and each sample's ``int z``.

    Outside holds, for ``z`` linear from a to b plus the bubble ``v tau (1 - tau)``::

        int z z' = h/6 ((2a + b) a' + (a + 2b) b') + h/12 (v (a + b)' + (a + b) v') + h/30 v v'
        int z   = h/2 (a + b) + h/6 v

    (``single`` is h/6 there and 0 inside holds); inside holds, the three-point stencils.
    """
    (start, end, bubble), (single, weights) = ends, rules
    terms = [((2.0 * start + end) * single, start), ((start + 2.0 * end) * single, end)]
    integral = 3.0 * single * (start + end)
    for i, node in enumerate(nodes):
        terms.append((node * weights[:, i : i + 1], node))
        integral = integral + node * weights[:, i : i + 1]
    if np.any(bubble):
        terms += [(bubble * single, start + end), (bubble * single / 5.0, bubble)]
        integral = integral + bubble * single
    return terms, integral


def _discounted_terms(
    ends: tuple[Array, Array, Array],
    nodes: list[Array],
    stencils: tuple[NDArray[np.bool_], NDArray[np.intp], Array],
    t: Array,
    timing: tuple[int, float],
) -> tuple[list[tuple[Array, Array]], Array, Array, Array]:
    """:func:`_terms` with the weight ``g(s) = exp(-gamma (s - t0))`` (t0: the start of the
    sample's interval), and g at each sample's start and end.

    Outside holds the integrals are exact for the same interpolant (linear plus bubble)
    times g: with ``phi = (1 - tau, tau, tau (1 - tau))`` the weights are
    ``h g(t_k) int_0^1 exp(-gamma h tau) phi_i phi_j dtau``, from the moments
    ``m_p = int_0^1 tau^p exp(-gamma h tau) dtau``. Inside holds the stencils integrate
    ``g z z'``, g taken at the stencil points.
    """
    (start, end, bubble), (in_hold, points, weights) = ends, stencils
    interval, discount = timing
    h = np.diff(t)
    index = np.arange(h.shape[0])
    origin = t[(index // interval) * interval]
    at_start = np.exp(-discount * (t[:-1] - origin))
    at_end = np.exp(-discount * (t[1:] - origin))
    m = _exponential_moments(discount * h)
    scale = ((~in_hold) * h * at_start)[:, None]
    pairs = {  # int_0^1 exp(-c tau) phi_i phi_j dtau
        "aa": m[0] - 2 * m[1] + m[2],
        "ab": m[1] - m[2],
        "bb": m[2],
        "va": m[1] - 2 * m[2] + m[3],
        "vb": m[2] - m[3],
        "vv": m[2] - 2 * m[3] + m[4],
    }
    weight = {name: scale * value[:, None] for name, value in pairs.items()}
    terms = [
        (start * weight["aa"], start),
        (start * 2.0 * weight["ab"], end),
        (end * weight["bb"], end),
        (bubble * 2.0 * weight["va"], start),
        (bubble * 2.0 * weight["vb"], end),
        (bubble * weight["vv"], bubble),
    ]
    integral = scale * (
        start * (m[0] - m[1])[:, None] + end * m[1][:, None] + bubble * pairs["ab"][:, None]
    )
    for i, node in enumerate(nodes):
        at_node = np.exp(-discount * (t[points[:, i]] - origin))
        left = node * (weights[:, i] * at_node)[:, None]
        terms.append((left, node))
        integral = integral + left
    return terms, integral, at_start, at_end


def _episode_moments(
    episode: Trajectory,
    interval: int,
    held: bool,
    output: Array | None,
    discount: float,
) -> tuple[Array, ...]:
    """The per-interval moments of one episode: ``int z z'``, ``int z u'`` and the
    within-sample changes of ``z z'`` (with the integrator's and the discount's terms).

    One pass builds every moment from the same per-sample stencils; it stays one function
    (about 65 lines) because its parts share a dozen per-sample arrays that splitting it
    would pass back and forth.
    """
    h = np.diff(episode.t)
    count = h.shape[0]
    x = episode.x
    w_start, w_end, w_points = _w_columns(episode, held)
    # Samples in no hold: exact integrals for z linear from a to b, u held; samples inside
    # a hold: the quadratic through three of the hold's points (_quadratic_stencils),
    # applied to z z' and to z (see _terms).
    in_hold, points, weights = _quadratic_stencils(episode.t, _holds(episode, held))
    single = (~in_hold)[:, None] * (h[:, None] / 6.0)

    def values(states: Array) -> tuple[Array, Array, list[Array]]:
        """z = [states; w] at each sample's start, end and stencil points (a held w is
        the sample's own value throughout its hold)."""
        start = np.hstack([states[:-1], w_start])
        end = np.hstack([states[1:], w_end])
        nodes = [
            np.hstack([states[points[:, i]], w_start if held else w_points[points[:, i]]])
            for i in range(3)
        ]
        return start, end, nodes

    start, end, nodes = values(x)
    bubble = np.zeros_like(start)
    if output is not None:
        # z_e appended to the state, with its bubble outside holds (module docstring)
        plain = _terms((start, end, bubble), nodes, (single, weights))[1]
        z, v = _integrator_states(x, (w_start, w_end), plain, output, single)
        start, end, nodes = values(np.hstack([x, z]))
        bubble = np.zeros_like(start)
        bubble[:, x.shape[1] : x.shape[1] + z.shape[1]] = v
    if discount:
        terms, integral, at_start, at_end = _discounted_terms(
            (start, end, bubble), nodes, (in_hold, points, weights), episode.t,
            (interval, discount),
        )  # fmt: skip
    else:
        terms, integral = _terms((start, end, bubble), nodes, (single, weights))
    # Summed over each interval's samples by batched matrix products (no N x p x p array);
    # samples are padded to whole intervals with zero rows, which add nothing.
    intervals = -(-count // interval)
    padding = intervals * interval - count

    def grouped(rows: Array) -> Array:
        padded = np.concatenate([rows, np.zeros((padding, *rows.shape[1:]))])
        return padded.reshape(intervals, interval, *rows.shape[1:])

    size = start.shape[1]
    zz = sum(
        (grouped(left).transpose(0, 2, 1) @ grouped(right) for left, right in terms),
        np.zeros((intervals, size, size)),
    )
    zz = 0.5 * (zz + zz.transpose(0, 2, 1))
    zu = grouped(integral).transpose(0, 2, 1) @ grouped(episode.u)
    a, b = grouped(start), grouped(end)
    if discount:
        a_weighted, b_weighted = grouped(start * at_start[:, None]), grouped(end * at_end[:, None])
        dzz = b_weighted.transpose(0, 2, 1) @ b - a_weighted.transpose(0, 2, 1) @ a
    else:
        dzz = b.transpose(0, 2, 1) @ b - a.transpose(0, 2, 1) @ a
    return zz, zu, dzz, grouped(h[:, None]).sum(axis=1)[:, 0]


def interval_moments(
    data: Trajectory | Sequence[Trajectory],
    interval: int = 10,
    *,
    w_kind: WKind = "held",
    integrator: tuple[ArrayLike, ArrayLike] | None = None,
    discount: float = 0.0,
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
    integrator : (C, F), optional
        Integral action: the state is augmented with ``z_e``, the integral of
        ``e = C x + F w`` (C: r x n, F: r x q), computed from the data from 0 at each
        episode's start (see the module docstring).
    discount : float
        The discount rate ``gamma`` >= 0, 1/s: the moments carry the weight
        ``exp(-gamma (s - t0))`` over each interval ``[t0, t0 + dt]`` (0: undiscounted).

    Returns
    -------
    IntervalMoments
        With ``n`` the plant's state dimension plus r.
    """
    interval = positive_integer(interval, "interval")
    if w_kind not in ("held", "exosystem"):
        raise InputError(f"w_kind: must be 'held' or 'exosystem', got {w_kind!r}")
    discount = finite_float(discount, "discount")
    if discount < 0.0:
        raise InputError(f"discount: must be a rate >= 0 (1/s), got {discount!r}")
    held = w_kind == "held"
    episodes = as_trajectories(data)
    first = episodes[0]
    output = None
    if integrator is not None:
        C = as_matrix(integrator[0], "C", (None, first.n))
        F = as_matrix(integrator[1], "F", (C.shape[0], first.q))
        output = np.hstack([C, F])
    parts = [
        _episode_moments(episode, int(interval), held, output, discount) for episode in episodes
    ]
    r = 0 if output is None else output.shape[0]
    return IntervalMoments(
        zz=np.concatenate([part[0] for part in parts]),
        zu=np.concatenate([part[1] for part in parts]),
        dzz=np.concatenate([part[2] for part in parts]),
        duration=np.concatenate([part[3] for part in parts]),
        n=first.n + r,
        m=first.m,
        q=first.q,
        r=r,
        discount=discount,
    )
