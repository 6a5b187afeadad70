"""Moments of instrumental-variable least squares with exponential forgetting.

The sampled model ``y_k = Theta' z_k + e_k`` (``y_k = x_(k+1)``, ``z_k = [x_k, a_k, w_k]``)
is estimated from moments that a running drive adds to chunk by chunk, each older
sample's weight falling by ``lambda`` per sample, so memory does not grow with run time::

    G = sum_k lambda^(N-1-k) zeta_k z_k',   H = sum_k lambda^(N-1-k) zeta_k y_k',
    Theta = G^-1 H

with instruments ``zeta_k`` uncorrelated with the errors: under measurement noise on the
states, ``x_k`` is a regressor with an error that ``e_k`` shares (errors in variables, a
bias no length of data removes); ``x_(k-1)`` is not (white noise), and follows ``x_k``.
The errors are ``e_k = eta_k + nu_(k+1) - Ad nu_k``: process noise ``eta`` (covariance
``Q``) and measurement noise ``nu`` (covariance ``R``), which enters two transitions, so
consecutive errors correlate (``E[e_k e_(k+1)'] = -R Ad'``). With ``u_k = w_k zeta_k``
(``w_k = lambda^(N-1-k)``) the covariance of ``vec(Theta)`` (column-major) is
``(I (x) G^-1) V (I (x) G^-T)`` with::

    V = Q (x) sum_k u_k u_k'
      + sum_k [R (x) u_k u_k' + Ad R Ad' (x) u_(k+1) u_(k+1)'
               - R Ad' (x) u_k u_(k+1)' - Ad R (x) u_(k+1) u_k']

(the second sum over consecutive pairs: each ``nu_(k+1)`` once, so V is a covariance).
``R`` is read from the errors' lag-one covariance, ``Q`` from what their variance leaves
(each kept positive semidefinite). On a slow plant under measurement noise, consecutive
errors nearly cancel in the sums: counting them white would overstate the errors
(six times in variance on the README's motor at 10 kHz).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from ...core import Array
from ...errors import InputError

__all__ = [
    "ForgettingMoments",
    "add_rows",
    "add_samples",
    "block_diagonal",
    "transposed_covariance",
    "transposed_order",
]


@dataclass
class ForgettingMoments:
    """Running moments of ``(zeta, z, y)`` with forgetting factor ``lambda`` per sample.

    Attributes
    ----------
    forgetting : float
        ``lambda`` in (0, 1]: the weight of a sample falls by it per later sample (1:
        none forgotten). The memory is ``1 / (1 - lambda)`` samples.
    regressors : int
        p, the size of ``z`` (and of ``zeta``); its first n entries are the state whose
        next value is ``y`` (the measurement noise's path through ``Ad``).
    outputs : int
        n, the size of ``y``.

    The moments change through :meth:`add` (or :func:`add_samples`, several memories of
    one stream at once) and :meth:`forget` only: :meth:`estimate` is kept until the next
    of them (a look asks for it twice). They are blocks of two weighed sums of products:
    ``sum w_k [zeta_k; v_k; v_(k-1)] v_k'`` (``v_k = [z_k, y_k]``, ``w_k =
    lambda^(N-1-k)``) and ``sum w_k^2 [zeta_(k-1); zeta_k] [zeta_(k-1); zeta_k]'``.
    """

    forgetting: float
    regressors: int
    outputs: int
    gram: Array = field(init=False, repr=False)  # sum w [zeta; v; v_(k-1)] v'
    gram_squared: Array = field(init=False, repr=False)  # sum w^2 [zeta_(k-1); zeta] [.]'
    first: Array = field(init=False, repr=False)  # the first sample's w^2 zeta zeta' (no pair)
    # sum w zeta c' of an effect the model leaves out, c its two channels (0 where absent)
    omitted: Array = field(init=False, repr=False)
    weight: float = field(init=False, default=0.0)  # sum w
    aged: float = field(init=False, default=0.0)  # sum w age (samples; the newest 0)
    count: int = field(init=False, default=0)  # samples added
    _last: tuple[Array, Array] | None = field(init=False, default=None, repr=False)
    _estimate: tuple[Array, Array, Array] | None = field(init=False, default=None, repr=False)

    def __post_init__(self) -> None:
        if not 0.0 < self.forgetting <= 1.0:
            raise InputError(f"forgetting: expected a factor in (0, 1], got {self.forgetting!r}")
        p, n = self.regressors, self.outputs
        self.gram = np.zeros((3 * p + 2 * n, p + n))
        self.gram_squared = np.zeros((2 * p, 2 * p))
        self.first = np.zeros((p, p))
        self.omitted = np.zeros((p, 2))

    @property
    def cross(self) -> Array:
        """``sum w zeta [z, y]'``, (p, p + n)."""
        return self.gram[: self.regressors]

    @property
    def second(self) -> Array:
        """``sum w [z, y] [z, y]'``, (p + n, p + n)."""
        p, n = self.regressors, self.outputs
        return self.gram[p : 2 * p + n]

    @property
    def second_lagged(self) -> Array:
        """``sum w [z, y]_(k-1) [z, y]_k'``, (p + n, p + n)."""
        p, n = self.regressors, self.outputs
        return self.gram[2 * p + n :]

    @property
    def squared(self) -> Array:
        """``sum u u'`` (``u_k = w_k zeta_k``), (p, p)."""
        p = self.regressors
        return self.gram_squared[p:, p:]

    @property
    def pairs(self) -> Array:
        """``sum [u_(k-1); u_k] [u_(k-1); u_k]'`` over consecutive pairs, each weighed by
        its later sample's weight (``u_(k-1) = lambda w_k zeta_(k-1)``), (2p, 2p)."""
        p = self.regressors
        pairs = self.gram_squared.copy()
        pairs[p:, p:] -= self.first
        pairs[:p] *= self.forgetting
        pairs[:, :p] *= self.forgetting
        return pairs

    def add(self, zeta: Array, z: Array, y: Array) -> None:
        """Add T samples, in time order, forgetting the older ones.

        Parameters
        ----------
        zeta : ndarray, shape (T, p)
            Instruments.
        z : ndarray, shape (T, p)
            Regressors.
        y : ndarray, shape (T, n)
            Outputs.
        """
        add_samples([self], zeta, z, y)

    def forget(self, keep: float) -> None:
        """Scale every moment by ``keep`` in [0, 1] (0: start afresh), as if the samples
        so far were that much older: after a change, the old plant's samples mislead.

        Parameters
        ----------
        keep : float
            The weight left to the samples so far.
        """
        self._estimate = None
        self.gram *= keep
        self.gram_squared *= keep**2
        self.first *= keep**2
        self.omitted *= keep
        self.weight *= keep
        self.aged *= keep

    def add_omitted(self, zeta: Array, omitted: Array, rows: NDArray[np.intp]) -> None:
        """Age :attr:`omitted` by a chunk's T transitions (in time order) and add ``sum_k
        w_k zeta_k c_k'`` over them: the instruments' moment with an effect the model
        leaves out (its error ``M c_k`` moves ``Theta`` by ``G^-1 omitted M'``, ``G`` the
        instruments' cross moment). Called as the transitions come, whether or not the
        other moments have them yet (they are added when read, :mod:`._model`).

        Parameters
        ----------
        zeta : ndarray, shape (T, p)
            The chunk's instruments.
        omitted : ndarray, shape (T, 2)
            ``c_k``.
        rows : ndarray of int
            The transitions where ``c_k`` is not zero (the others add nothing).
        """
        weights, _ = _chunk_weights(self.forgetting, zeta.shape[0])
        self.omitted *= self.forgetting ** zeta.shape[0]
        if rows.size:
            self.omitted += (zeta[rows] * weights[rows, np.newaxis]).T @ omitted[rows]

    @property
    def age(self) -> float:
        """The weights' mean age, samples (the newest sample's is 0): under forgetting
        alone ``lambda / (1 - lambda)``, less while the memory fills. A parameter that
        moves at a steady rate is estimated this many samples late."""
        return self.aged / self.weight if self.weight > 0.0 else 0.0

    @property
    def effective_samples(self) -> float:
        """``(sum w)^2 / sum w^2``-like count of the samples the moments weigh: the sum
        of the weights (1 per recent sample)."""
        return self.weight

    def noise(self, Theta: Array) -> tuple[Array, Array, Array]:
        """The errors' covariance ``Sigma`` and their two sources: the measurement
        noise's covariance ``R`` (from the lag-one covariance ``-R Ad'``) and the process
        noise's ``Q`` (what ``Sigma`` leaves), each positive semidefinite.

        Parameters
        ----------
        Theta : ndarray, shape (p, n)
            The coefficients (the first n rows are ``Ad'``).
        """
        n = self.outputs
        selector, dof, Sigma = self._errors(Theta)
        lagged = selector.T @ self.second_lagged @ selector / dof  # -R Ad'
        Ad = Theta[:n].T
        R = _semidefinite(np.asarray(-np.linalg.solve(Ad, lagged.T)))  # -Ad^-1 (-Ad R)
        return Sigma, R, _semidefinite(Sigma - R - Ad @ R @ Ad.T)

    def _errors(self, Theta: Array) -> tuple[Array, float, Array]:
        """The errors' selector (``e = [z, y] @ selector``), degrees of freedom and
        covariance ``Sigma`` at ``Theta``."""
        selector = np.vstack([-Theta, np.eye(self.outputs)])
        dof = max(self.weight - self.regressors, 1.0)
        return selector, dof, selector.T @ self.second @ selector / dof

    def instrument_weight(self, Theta: Array) -> Array:
        """The weight on ``vec(Theta' - Theta_hat')`` (column-major ``vec`` of
        ``[Ad, Bd, Ed]``) of two-stage least squares: ``Sigma^-1 (x) G' S^-1 G`` in
        ``vec(Theta)``'s order, reordered; ``G`` the instruments' cross moment, ``S``
        their own, ``Sigma`` the errors' covariance at ``Theta``.

        A structured model fitted with it weighs each combination of the entries by how
        much the data say about it, from moments of the data themselves (not from the
        inverse of an estimated covariance, whose small eigenvalues are not known well).

        Parameters
        ----------
        Theta : ndarray, shape (p, n)
            The coefficients the errors are taken at.
        """
        p, n = self.regressors, self.outputs
        G = self.cross[:, :p]
        information = G.T @ np.linalg.solve(self.squared, G)
        inverse = np.linalg.inv(self._errors(Theta)[2])
        # Sigma^-1 (x) information in vec(Theta)'s order is information (x) Sigma^-1 in
        # vec(Theta')'s: the same products, in the order wanted
        weight = information[:, np.newaxis, :, np.newaxis] * inverse[np.newaxis, :, np.newaxis, :]
        return np.asarray(weight.reshape(p * n, p * n), dtype=np.float64)

    def coefficients(self) -> Array:
        """``Theta`` (p, n) alone, from the moments so far (:meth:`estimate` without the
        covariances).

        Raises
        ------
        numpy.linalg.LinAlgError
            If the instruments' moment ``G`` is singular.
        """
        if self._estimate is not None:
            return self._estimate[0].copy()
        p = self.regressors
        return np.asarray(np.linalg.solve(self.cross[:, :p], self.cross[:, p:]), dtype=np.float64)

    def estimate(self) -> tuple[Array, Array, Array]:
        """``Theta`` (p, n), the error covariance ``Sigma`` (n, n) and the covariance of
        ``vec(Theta)`` (column-major), from the moments so far.

        Raises
        ------
        numpy.linalg.LinAlgError
            If the instruments' moment ``G`` is singular (the data do not excite every
            regressor).
        """
        if self._estimate is None:
            self._estimate = self._estimated()
        Theta, Sigma, covariance = self._estimate
        return Theta.copy(), Sigma.copy(), covariance.copy()

    def _estimated(self) -> tuple[Array, Array, Array]:
        """:meth:`estimate`, computed."""
        p = self.regressors
        G = self.cross[:, :p]
        Theta = self.coefficients()
        n = self.outputs
        Sigma, R, Q = self.noise(Theta)
        Ad = Theta[:n].T
        before, after = self.pairs[:p, :p], self.pairs[p:, p:]
        cross = self.pairs[:p, p:]  # sum u_k u_(k+1)'
        # the five Kronecker products of V at once, summed in order (Q, R, Ad R Ad', the pairs)
        left = np.array([Q, R, Ad @ R @ Ad.T, -(R @ Ad.T), -(Ad @ R)])  # (5, n, n)
        right = np.array([self.squared, before, after, cross, cross.T])  # (5, p, p)
        V = np.sum(left[:, :, None, :, None] * right[:, None, :, None, :], axis=0)
        V = V.reshape(n * p, n * p)
        spread = block_diagonal(np.asarray(np.linalg.inv(G), dtype=np.float64), n)
        return Theta, Sigma, np.asarray(spread @ V @ spread.T)


def add_samples(memories: Sequence[ForgettingMoments], zeta: Array, z: Array, y: Array) -> None:
    """Add T samples of one stream to several memories at once (one product for all).

    Each memory ends as if its :meth:`~ForgettingMoments.add` had been called; memories
    fed the same stream so far (the same last sample) share the work.

    Parameters
    ----------
    memories : sequence of ForgettingMoments
        The memories, of the same sizes.
    zeta : ndarray, shape (T, p)
        Instruments.
    z : ndarray, shape (T, p)
        Regressors.
    y : ndarray, shape (T, n)
        Outputs.
    """
    count = z.shape[0]
    if count == 0 or not memories:
        return
    last = memories[0]._last
    sharing = [m for m in memories if _same_last(m._last, last)]
    if len(sharing) < len(memories):  # fed different streams: one group per stream
        add_samples(sharing, zeta, z, y)
        add_samples([m for m in memories if m not in sharing], zeta, z, y)
        return
    v = np.concatenate([z, y], axis=1)
    if last is None:  # row k's sample before it: none (zeros) before the very first
        last = (np.zeros((1, zeta.shape[1])), np.zeros((1, v.shape[1])))
    left = np.concatenate([zeta, v, np.concatenate([last[1], v[:-1]])], axis=1)
    pair = np.concatenate([np.concatenate([last[0], zeta[:-1]]), zeta], axis=1)
    add_rows(memories, left, pair)


def add_rows(memories: Sequence[ForgettingMoments], left: Array, pair: Array) -> None:
    """:func:`add_samples` of rows laid out as the moments' products take them (a caller
    that writes them so saves the copies): memories fed the same stream so far.

    Parameters
    ----------
    memories : sequence of ForgettingMoments
        The memories, of the same sizes, whose last sample is the one before the rows
        (zeros before the very first).
    left : ndarray, shape (T, 3 p + 2 n)
        Rows ``[zeta_k, v_k, v_(k-1)]`` (``v_k = [z_k, y_k]``).
    pair : ndarray, shape (T, 2 p)
        Rows ``[zeta_(k-1), zeta_k]``.
    """
    count, p = left.shape[0], memories[0].regressors
    zeta, v = left[:, :p], left[:, p : p + (left.shape[1] - p) // 2]
    weights, by_row, by_row_squared, ages = _memory_weights(
        tuple(m.forgetting for m in memories), count
    )
    # every memory's weighed sums in one product each: (T, M k)' (T, k')
    sums = _weighed(by_row, left, v)
    sums_squared = _weighed(by_row_squared, pair, pair)
    shared = (zeta[-1:].copy(), v[-1:].copy())
    for index, memory in enumerate(memories):
        memory._estimate = None
        older = memory.forgetting**count
        memory.gram *= older
        memory.gram += sums[index]
        memory.gram_squared *= older**2
        memory.gram_squared += sums_squared[index]
        memory.first *= older**2
        if memory._last is None:  # the very first sample has no pair
            memory.first += weights[index, 0] ** 2 * np.outer(zeta[0], zeta[0])
        memory._last = shared
        total = _chunk_weights(memory.forgetting, count)[1]
        memory.aged = older * (memory.aged + count * memory.weight) + float(weights[index] @ ages)
        memory.weight = older * memory.weight + total
        memory.count += count


@lru_cache(maxsize=8)
def _memory_weights(forgetting: tuple[float, ...], count: int) -> tuple[Array, Array, Array, Array]:
    """Several memories' chunk weights (M, T), as the products take them ((T, M, 1)
    contiguous, and squared), and the samples' ages (read-only)."""
    weights = np.array([_chunk_weights(value, count)[0] for value in forgetting])
    by_row = np.ascontiguousarray(weights.T)[:, :, np.newaxis]
    by_row_squared = np.ascontiguousarray((weights**2).T)[:, :, np.newaxis]
    ages = np.arange(count - 1, -1, -1, dtype=float)
    for array in (weights, by_row, by_row_squared, ages):
        array.setflags(write=False)
    return weights, by_row, by_row_squared, ages


def _weighed(by_row: Array, left: Array, right: Array) -> Array:
    """``sum_k weights[i, k] left_k right_k'`` for every memory i: shape (M, a, b) from
    ``by_row`` (T, M, 1) (the weights, a contiguous (T, M) first: ten times faster at
    1,000 rows), left (T, a), right (T, b), in one matrix product."""
    T, b = right.shape
    scaled = (by_row * right[:, np.newaxis, :]).reshape(T, -1)
    return (left.T @ scaled).reshape(left.shape[1], by_row.shape[1], b).transpose(1, 0, 2)


def _same_last(a: tuple[Array, Array] | None, b: tuple[Array, Array] | None) -> bool:
    """Whether two memories' last samples are the same (the same stream so far)."""
    if a is None or b is None:
        return a is b
    return a is b or (np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1]))


@lru_cache(maxsize=8)
def _chunk_weights(forgetting: float, count: int) -> tuple[Array, float]:
    """A chunk's weights, ``lambda^(T-1), ..., lambda, 1``, and their sum (read-only)."""
    weights = forgetting ** np.arange(count - 1, -1, -1, dtype=float)
    weights.setflags(write=False)
    return weights, float(np.sum(weights))


def transposed_order(p: int, n: int) -> NDArray[np.intp]:
    """Where each entry of ``vec(Theta')`` sits in ``vec(Theta)`` (``Theta`` (p, n), both
    ``vec`` column-major): ``vec(Theta')`` is ``vec(Theta)[order]``; a covariance turns
    with ``[np.ix_(order, order)]``, and back with ``np.argsort(order)``.

    Parameters
    ----------
    p, n : int
        Theta's rows and columns.
    """
    # vec(Theta) index j p + i is Theta[i, j] = Theta'[j, i], vec(Theta') index i n + j
    return np.arange(p * n).reshape(n, p).T.ravel()


def block_diagonal(M: Array, count: int) -> Array:
    """``I (x) M``: ``count`` copies of ``M`` on the diagonal (:func:`numpy.kron` with the
    identity, without its products).

    Parameters
    ----------
    M : ndarray, shape (a, b)
        The block.
    count : int
        The copies.
    """
    (rows, columns), diagonal = M.shape, np.arange(count)
    blocks = np.zeros((count, rows, count, columns))
    blocks[diagonal, :, diagonal, :] = M
    return blocks.reshape(count * rows, count * columns)


def transposed_covariance(covariance: Array, p: int, n: int) -> Array:
    """A covariance of ``vec(Theta)`` (``Theta`` (p, n), column-major) turned into that of
    ``vec(Theta')`` (``covariance[np.ix_(order, order)]`` with :func:`transposed_order`,
    without the index arrays); with p and n swapped, back.

    Parameters
    ----------
    covariance : ndarray, shape (p n, p n)
        The covariance of ``vec(Theta)``.
    p, n : int
        Theta's rows and columns.
    """
    return covariance.reshape(n, p, n, p).transpose(1, 0, 3, 2).reshape(p * n, p * n)


def _semidefinite(M: Array) -> Array:
    """The symmetric part of ``M`` with its negative eigenvalues set to zero."""
    values, vectors = np.linalg.eigh(0.5 * (M + M.T))
    return np.asarray((vectors * np.maximum(values, 0.0)) @ vectors.T)
