"""A surface PMSM's parameters read off the running model, and a change in them detected.

The online model's ``vec([Ad, Bd, Ed])`` (:mod:`._model`) has 12-16 entries; a surface
PMSM at a known electrical speed has 3-4 parameters (``R_s``, ``L_s``, the back-EMF
ratio ``kappa = phi_pm / phi_assumed`` and the dead-time voltage ``v``;
:class:`~selftune.learn.SpmsmStructure`). They are the parameters whose structured model
is nearest the unstructured one (Gauss-Newton from the last estimate), with the sandwich
covariance ``(J' W J)^-1 J' W C W J (J' W J)^-1`` (``C`` the entries' covariance). The
weight ``W`` is two-stage least squares' (:meth:`~._moments.ForgettingMoments.instrument_weight`),
made of the data's own moments. Weighing by the inverse of ``C`` would be efficient where
``C`` is known well; from a short memory (200 samples against 12 entries) its small
eigenvalues are not (the entries' errors were within their standard errors, rms 0.7-1.0,
while their Mahalanobis distance averaged 62 against its 12). Weighing each entry by its
own variance alone (the default without ``W``) throws away what the data say about
combinations: the steady state pins ``Bd`` and ``Ed`` together far better than either,
and on an ideal drive the diagonal weight left R_s 80 times, the flux 25 times less
certain than the instruments' weight (0.085 ohm against 0.001 ohm, 2 s of data).

A change (a loose connection adding resistance, a demagnetized magnet) is told from
drift by the recent transitions' errors against the slow model, scored along each
parameter's direction (:class:`ChangeWatch`).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.stats
from numpy.typing import NDArray

from ...core import Array
from ...errors import InputError
from ..evidence._discrete_model import DiscreteModel
from ..evidence._spmsm_structure import SpmsmStructure
from ._moments import block_diagonal

__all__ = ["ChangeTest", "ChangeWatch", "PhysicalEstimate", "physical_estimate"]

#: Gauss-Newton iterations from the last estimate, at most (the model moves little
#: between looks).
ITERATIONS = 3

#: A Gauss-Newton step below this share of every parameter's standard error ends the
#: iterations: the next is smaller by orders (on the servo drive the second step was
#: 4e-4 standard errors at the median, 0.013 at the 99th percentile, the third 3e-9).
CONVERGED = 0.01

#: Relative step of the finite-difference Jacobian.
_STEP = 1e-6


@dataclass(frozen=True)
class PhysicalEstimate:
    """A surface PMSM's parameters and their covariance.

    Attributes
    ----------
    theta : ndarray, shape (3,) or (4,)
        ``[R_s (ohm), L_s (H), kappa]`` and, with dead time, ``v`` (V).
    covariance : ndarray, shape (p, p)
        Their covariance.
    sensitivities : ndarray, shape (entries, p)
        ``d vec([Ad, Bd, Ed]) / d theta`` (column-major ``vec``) near ``theta``: the
        directions in which each parameter moves the model.
    gain : ndarray, shape (p, entries), optional
        ``d theta / d vec([Ad, Bd, Ed])`` of the fit: how the estimate follows a change
        of the model it was fitted to.
    """

    theta: Array
    covariance: Array
    sensitivities: Array
    gain: Array | None = None

    @property
    def standard_errors(self) -> Array:
        """The parameters' standard errors, in their units."""
        return np.sqrt(np.maximum(np.diag(self.covariance), 0.0))

    def doubted(self, doubt: Array) -> PhysicalEstimate:
        """The same estimate with ``doubt`` added to its covariance as independent
        standard errors, one a parameter (in their units)."""
        covariance = self.covariance + np.diag(np.asarray(doubt, dtype=float) ** 2)
        return PhysicalEstimate(self.theta, covariance, self.sensitivities, self.gain)


def physical_estimate(
    model: DiscreteModel,
    structure: SpmsmStructure,
    start: Array,
    iterations: int = ITERATIONS,
    weight: Array | None = None,
) -> PhysicalEstimate:
    """The structure's parameters nearest the model (see the module).

    Parameters
    ----------
    model : DiscreteModel
        The online model, with its covariance.
    structure : SpmsmStructure
        The motor's structure at its speed and sampling period.
    start : ndarray
        The parameters to start from (the last estimate, or ``structure.initial``).
    iterations : int
        Gauss-Newton iterations at most: fewer where a step is below :data:`CONVERGED`
        of every standard error.
    weight : ndarray, shape (entries, entries), optional
        The weight on the entries' misfit (default: each entry's inverse variance).
    """
    if model.covariance is None:
        raise InputError("model: a covariance is needed to weigh its entries")
    target = model.parameters
    if weight is None:
        variances = np.diag(model.covariance)
        floor = max(float(np.max(variances)), 1e-300) * 1e-24
        weight = np.diag(1.0 / np.maximum(variances, floor))
    theta = np.asarray(start, dtype=float).copy()

    for _ in range(iterations):
        steps = _STEP * np.maximum(np.abs(theta), 1e-6)
        # theta and its steps in one evaluation: rows of vec([Ad, Bd, Ed]) (column-major)
        stacked = np.concatenate(
            structure.stack(np.vstack([theta, theta + steps[:, None] * np.eye(theta.size)])),
            axis=2,
        )
        value, *stepped = stacked.transpose(0, 2, 1).reshape(stacked.shape[0], -1)
        J = ((np.asarray(stepped) - value) / steps[:, np.newaxis]).T
        weighed = J.T @ weight
        gain = np.linalg.solve(weighed @ J, weighed)  # d theta / d entries
        step = gain @ (target - value)
        theta = theta + step
        covariance = gain @ model.covariance @ gain.T
        bound = CONVERGED * np.sqrt(np.maximum(covariance.diagonal(), 0.0))
        if (np.abs(step) <= bound).all():
            break
    return PhysicalEstimate(theta, covariance, J, gain)


@dataclass(frozen=True)
class ChangeTest:
    """The parameters' scores in the recent transitions (:class:`ChangeWatch`).

    Attributes
    ----------
    scores : ndarray
        Each parameter's score in its standard deviations (0 mean, 1 sd while the plant
        is the reference).
    threshold : float
        The largest score's bound: the two-sided normal quantile of ``false_alarm / p``.
    changed : bool
        Whether some score's size exceeds the threshold.
    """

    scores: Array
    threshold: float
    changed: bool


class ChangeWatch:
    """A change in the plant's parameters watched on every transition: each parameter's
    score in the recent transitions' errors against a reference model.

    The reference (the slow model) has coefficients ``Theta``; the errors of the last
    ``window`` transitions are ``e_k = y_k - Theta' z_k = eta_k + nu_(k+1) - Ad nu_k``
    (process noise of covariance ``Q``, measurement noise of covariance ``R``). Parameter
    j moves the model along ``M_j = d[Ad, Bd, Ed] / d theta_j``
    (:attr:`PhysicalEstimate.sensitivities`). Its score is ``g_j = sum_k u_k' e_k`` with
    ``u_k = Sigma^-1 M_j zeta_k``: the instruments, so that the noise in ``z_k`` does not
    bias it. While the plant is the reference, ``g_j`` has mean 0 and variance::

        sum_k u_k' Q u_k + sum_j c_j' R c_j + a' C a

    - ``c_j = u_(j-1) - Ad' u_j``: each measurement ``nu_j`` enters two errors. The
      window's first and last measurement enter one: ``c = -Ad' u_first`` and
      ``c = u_last``. Where ``u`` varies slowly these two are most of the sum; the rest
      nearly cancels (left out, the variance was 7 times too small).
    - ``a' C a``: the reference's own uncertainty, with ``a = vec(sum_k z_k u_k')`` and
      ``C`` the covariance of ``vec(Theta)``. It is coherent over the window: while the
      currents hold still, it is what is left.

    A change of parameter i moves the mean of ``g_j`` by ``S_ji = sum_k u_k' M_i z_k``
    times the change (``z_k`` the regressors). A drift is not a change: the reference
    may be behind the plant by up to ``allowance_i`` in each parameter (the fastest
    drift heating gives, times the slow memory: the estimate's lag), which adds
    ``sum_i (S_ji allowance_i)^2`` to the variance. The directions are not orthogonal:
    while the current holds one level, ``R_s i_q`` and the back-EMF are one constant, and
    a flux 0.07% behind moved the resistance's score by 3 of its standard deviations at
    a third of the torque (false alarms every few seconds of a warming motor). Nor is
    what the model leaves out (the carrier's ripple): a change smaller than ``least_j``
    in parameter j alone is not one, which adds ``(S_jj least_j)^2`` (on a 1,200 rad/s
    motor under carrier PWM, the inductance, known to 0.04%, alarmed every few seconds
    without it). The alarm
    is raised when some ``|g_j| / sd_j`` exceeds the two-sided normal quantile
    of ``false_alarm / p``; it is false with probability at most ``false_alarm`` per
    window of transitions.

    Parameters
    ----------
    window : int
        Transitions the scores sum over.
    false_alarm : float
        The probability of a false alarm per window, in (0, 1).
    """

    def __init__(self, window: int, false_alarm: float) -> None:
        if not 0.0 < false_alarm < 1.0:
            raise InputError(f"false_alarm: expected a probability in (0, 1), got {false_alarm!r}")
        self.window = int(window)
        self.false_alarm = false_alarm
        self._reference: _Reference | None = None
        # per chunk, oldest first, side by side: the directions' scores, variances within
        # it (interior measurements and the process noise), loads, first and last u,
        # shifts; the window's chunks are rows _first to _end of one array (summed in one
        # call), and their transitions
        self._parts = np.empty((0, 0))
        self._first = self._end = 0
        self._counts: deque[int] = deque()
        self._rows: deque[tuple[Array, Array, Array]] = deque()  # the window's chunks
        self._held = 0  # the window's transitions

    def reference(
        self,
        Theta: Array,
        noise: tuple[Array, Array, Array],
        sensitivities: Array,
        covariance: Array,
        allowance: Array | None = None,
        least: Array | None = None,
    ) -> None:
        """Watch from now against a model: the window's chunks are scored again against it.

        A window's scores are against one reference. Its variance takes the reference's
        uncertainty as one error over the whole window (``a' C a``); chunks scored
        against the last reference and the new one carry two errors, which that term
        misses where their loads cancel: on a warming motor under a 4,096-count
        encoder's commissioning, the first chunk after a look moved the resistance's
        score from -0.17 to -4.47 standard deviations (a false alarm at 4.21). Nor does
        the window start empty: a chunk alone holds one current level, where a flux
        behind the plant reads as a resistance change (a flux falling 1%/s alarmed at
        the first chunk after three looks in 4 s).

        Parameters
        ----------
        Theta : ndarray, shape (p, n)
            The reference model's coefficients (``y = Theta' z``; the first n rows
            ``Ad'``).
        noise : (Sigma, R, Q)
            Its errors' covariance, measurement and process noise
            (:meth:`~._moments.ForgettingMoments.noise`).
        sensitivities : ndarray, shape (p n, parameters)
            ``d vec(Theta') / d theta`` (column-major ``vec`` of ``[Ad, Bd, Ed]``).
        covariance : ndarray, shape (p n, p n)
            The covariance of ``vec(Theta)`` (column-major).
        allowance : ndarray, shape (parameters,), optional
            How far behind a drifting plant the reference may be, in each parameter's
            unit (default: not at all).
        least : ndarray, shape (parameters,), optional
            The least change of each parameter alone that is a change, in its unit
            (default: any).
        """
        n = Theta.shape[1]
        directions = [column.reshape((n, -1), order="F") for column in sensitivities.T]
        # each direction's instruments-to-score map, M_j' Sigma^-1, made once per reference
        Sigma_inverse = np.linalg.inv(noise[0])

        count = len(directions)
        allowance = np.zeros(count) if allowance is None else np.asarray(allowance, float)
        least = np.zeros(count) if least is None else np.asarray(least, float)
        # a score's drift variance, sum_k (S_jk allowance_k)^2 + (S_jj least_j)^2, is
        # sum_k S_jk^2 weights_jk
        weights = np.tile(allowance**2, (count, 1))
        weights[np.diag_indices(count)] += least**2
        stacked = np.hstack([M.T for M in directions])
        self._reference = _Reference(
            Theta, np.hstack([M.T @ Sigma_inverse for M in directions]),
            block_diagonal(Theta[:n].T, count), block_diagonal(noise[1], count),
            block_diagonal(np.ones((n, 1)), count), covariance,
            _threshold(self.false_alarm, count), np.hstack([Theta, stacked]),
            _part_map(Theta.shape[0], n, count, noise[2], noise[1]), weights,
        )  # fmt: skip
        rows = list(self._rows)
        self._empty()
        for chunk in rows:
            self._score(self._reference, *chunk)

    def reference_off(self) -> None:
        """Stop watching until the next reference (after a change, the old one is wrong)."""
        self._reference = None
        self._empty()

    def _empty(self) -> None:
        """The window without transitions."""
        self._first = self._end = self._held = 0
        self._counts.clear()
        self._rows.clear()

    def add(self, zeta: Array, z: Array, y: Array) -> ChangeTest | None:
        """Score the transitions; the test over the window, or None without a reference.

        Parameters
        ----------
        zeta, z, y : ndarray
            Instruments (T, p), regressors (T, p) and next states (T, n).
        """
        reference = self._reference
        if reference is None or z.shape[0] == 0:
            return None
        self._score(reference, zeta, z, y)
        return self._test(reference)

    def _score(self, reference: _Reference, zeta: Array, z: Array, y: Array) -> None:
        """A chunk's part of the window against ``reference``, its rows kept (a new
        reference scores them again)."""
        T, n = z.shape[0], reference.Theta.shape[1]
        fitted = z @ reference.fitted  # every row's z_k' Theta and (every M_j z_k)'
        errors = y - fitted[:, :n]
        u = zeta @ reference.maps  # row k: every direction's u_k' = (Sigma^-1 M_j zeta_k)'
        paths = u[:-1] - u[1:] @ reference.Ad  # c_j' for the chunk's interior measurements
        # one product for the scores, the loads, the shifts and the process noise's
        # variance: sum_k u_k [e_k', z_k', (every M_j z_k)', u_k'], direction j's rows
        # j n to j n + n - 1; with sum_j c_j c_j' and the first and last u, one more
        # gives the chunk's part (_part_map)
        products = u.T @ np.concatenate([errors, z, fitted[:, n:], u], axis=1)
        sums = np.concatenate([products.ravel(), (paths.T @ paths).ravel(), u[0], u[-1]])
        self._part(T, reference.part.shape[1])[:] = sums @ reference.part
        self._rows.append((zeta, z, y))

    def _test(self, reference: _Reference) -> ChangeTest:
        """The test over the window's parts."""
        (p, n), directions = reference.Theta.shape, reference.sums.shape[1]
        loads = 2 * directions + directions * p * n  # where the loads end
        edges = loads + 2 * directions * n  # where the first and last u end
        window = self._parts[self._first : self._end]  # (chunks, ...)
        total = window.sum(axis=0)
        load = total[2 * directions : loads].reshape(directions, p * n)
        uncertain = ((load @ reference.covariance) * load).sum(axis=1)
        # the measurements between chunks, and the window's first and last
        middle = loads + directions * n
        firsts, lasts = window[:, loads:middle] @ reference.Ad, window[:, middle:edges]
        drift = (np.square(total[edges:].reshape(directions, directions)) * reference.drift).sum(
            axis=1
        )
        joins = np.concatenate([firsts[:1], lasts[-1:], lasts[:-1] - firsts[1:]])
        joined = ((joins @ reference.R) * joins).sum(axis=0) @ reference.sums
        spread = total[directions : 2 * directions] + joined
        spread += uncertain
        spread += drift
        z_scores = total[:directions] / np.sqrt(np.maximum(spread, 1e-300))
        threshold = reference.threshold
        return ChangeTest(z_scores, threshold, bool(np.abs(z_scores).max() > threshold))

    def _part(self, transitions: int, size: int) -> Array:
        """A new chunk's row at the window's end (the chunks that fall out of the window
        dropped), to be filled."""
        if self._end == self._parts.shape[0] or self._parts.shape[1] != size:
            held = self._parts[self._first : self._end] if self._parts.shape[1] == size else None
            count = 0 if held is None else held.shape[0]
            grown = np.empty((max(2 * count, 64), size))
            if held is not None:
                grown[:count] = held
            self._parts, self._first, self._end = grown, 0, count
        self._counts.append(transitions)
        self._held += transitions
        while self._held - self._counts[0] >= self.window:
            self._held -= self._counts.popleft()
            self._rows.popleft()
            self._first += 1
        self._end += 1
        return self._parts[self._end - 1]


@dataclass(frozen=True)
class _Reference:
    """A change watch's reference in the forms a chunk needs: every direction's ``u_k'``
    side by side in one row (direction j's in columns ``j n`` to ``j n + n - 1``), so the
    n x n matrices act on them block by block."""

    Theta: Array
    maps: Array  # (p, j n): [M_1' Sigma^-1, M_2' Sigma^-1, ...]
    Ad: Array  # I (x) Ad: a row of u's times it is each direction's (Ad' u)'
    R: Array  # I (x) R
    sums: Array  # (j n, j): sums each direction's n columns
    covariance: Array
    threshold: float
    fitted: Array  # (p, n + j n): [Theta, M_1', M_2', ...]: z_k' times it is z_k' Theta
    # and every (M_j z_k)'
    part: Array  # a chunk's sums to its part (_part_map)
    drift: Array  # (j, j): the drift variance's weights on the squared shifts


def _part_map(p: int, n: int, directions: int, Q: Array, R: Array) -> Array:
    """The map from a chunk's sums, ``[vec(P), vec(sum_j c_j c_j'), u_first, u_last]``
    (``P = sum_k u_k [e_k', z_k', (every M_j z_k)', u_k']``, row-major ``vec``), to its
    part of the window: each direction's score, variance within the chunk (``u' Q u`` and
    ``c' R c``), loads ``vec(sum z_k u_k')``, the first and last ``u``, and the shifts
    (score j's response to parameter i)."""
    ones, noise_rows, noise_columns, shape = _part_places(p, n, directions)
    M = np.zeros(shape)
    M[ones] = 1.0
    M[noise_rows, noise_columns] = np.concatenate(
        [np.tile(Q.ravel(), directions), np.tile(R.ravel(), directions)]
    )
    return M


@lru_cache(maxsize=8)
def _part_places(
    p: int, n: int, directions: int
) -> tuple[tuple[NDArray[np.intp], NDArray[np.intp]], NDArray[np.intp], NDArray[np.intp],
           tuple[int, int]]:  # fmt: skip
    """Where :func:`_part_map` has its ones, and its Q's and R's entries (direction by
    direction, each row-major), and its shape."""
    J, Jn = directions, directions * n
    width = n + p + 2 * Jn  # P's columns
    loads = 2 * J + J * p * n
    edges = loads + 2 * Jn
    rows: list[int] = []
    columns: list[int] = []
    noise_rows: list[int] = []
    noise_columns: list[int] = []
    for j in range(J):
        for a in range(n):
            row = j * n + a
            rows.append(row * width + a)  # the score: the trace of direction j's u' e
            columns.append(j)
            for i in range(J):  # the shift: the trace of u_j' M_i z
                rows.append(row * width + n + p + i * n + a)
                columns.append(edges + j * J + i)
    for j in range(J):  # u' Q u, then c' R c, of direction j
        for a in range(n):
            for b in range(n):
                noise_rows.append((j * n + a) * width + n + p + Jn + j * n + b)
                noise_columns.append(J + j)
    for j in range(J):
        for a in range(n):
            for b in range(n):
                noise_rows.append(Jn * width + (j * n + a) * Jn + j * n + b)
                noise_columns.append(J + j)
    for row in range(Jn):  # the loads
        rows += [row * width + n + i for i in range(p)]
        columns += [2 * J + row * p + i for i in range(p)]
    rows += [Jn * width + Jn * Jn + i for i in range(2 * Jn)]  # the first and last u
    columns += [loads + i for i in range(2 * Jn)]
    return (
        (np.array(rows), np.array(columns)), np.array(noise_rows), np.array(noise_columns),
        (Jn * width + Jn * Jn + 2 * Jn, edges + J * J),
    )  # fmt: skip


@lru_cache(maxsize=8)
def _threshold(false_alarm: float, directions: int) -> float:
    """The largest score's bound: the two-sided normal quantile of ``false_alarm /
    directions`` (the same for every reference)."""
    return float(scipy.stats.norm.isf(0.5 * false_alarm / directions))
