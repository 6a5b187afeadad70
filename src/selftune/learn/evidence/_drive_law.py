"""The drive's current control law read off its log, to re-run the experiment on a model.

The refits that measure the signs' bias (:mod:`._sign_bias`) simulate what the data would
be if the fitted model were the drive. Replaying the logged voltages open loop does that
only where the plant forgets its past: where the resistance barely damps it (``R_s h /
L`` of 1e-4, a 540 V motor of a few mH rated 0.3 A), the replayed currents' slow part is
the logged voltages' over ``R_s``, which the data fix only to several percent, while the
drive's currents were held by its controller. The bias, an effect of where the currents
cross zero, then moved with every small change of the model (L_q's, on four rounds:
-0.08%, +0.47%, +0.18%, -0.35%).

The law the drive ran is linear in what it measured and computed: a sample that the
alignment says was computed ``L`` samples before it was applied (``L`` the shift, 1 for a
one-sample delay) is, with integral action, decoupling and a delay compensation,

``a_k = A1 a_(k-1) + X0 x~_(k-L) + X1 x~_(k-L-1) + S s_(k-L) + (references, constants)
+ rho_k``,

``s`` the measured currents' running sum (the integrator) and ``rho_k`` the exploration.
Least squares on the log reads the matrices off (:meth:`DriveLaw.of`): the regressors
are known before ``rho_k`` is added, so an exploration that is white is the residual and
the fit is consistent. The world then runs the model under the law with the logged
exploration: its inputs are the logged ones plus the law's answer to its measured
currents' departure from the logged ones (:meth:`DriveLaw.answer`), so that with the
logged currents it applies the logged voltages.

The law is used only where it is one: where its residual is white (an exploration of
sines or a law it does not describe leaves lags correlated; :data:`WHITENESS`) and it
closes a stable loop on the model; else the voltages are replayed open loop.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ...core import Array

__all__ = ["LAGS", "SIGNIFICANCE", "WHITENESS", "DriveLaw"]

#: The integrator's gains are read off only where one of them is beyond this many of its
#: standard errors from zero (else its running sum, never fed back, would hold the loop's
#: eigenvalue 1).
SIGNIFICANCE = 4.0

#: The residual's lags whose correlations must be within :data:`WHITENESS` of zero.
LAGS = 5

#: The largest correlation of the law's residual at lags 1 .. :data:`LAGS`, in standard
#: errors of a white sequence's (``1 / sqrt(T)``), at which the residual is the
#: exploration and the regression the law.
WHITENESS = 5.0


def _regressors(x: Array, a: Array, w: Array, lag: int, integral: bool) -> Array:
    """The law's regressors of ``a_k`` for k = lag + 1 .. T - 1: ``a_(k-1), x~_(k-lag),
    x~_(k-lag-1)``, with ``integral`` ``s_(k-lag)``, the references' running sum and the
    sample's index (an integrator's reference terms), then the references ``w_k`` and 1."""
    T = a.shape[0]
    k = np.arange(lag + 1, T)
    columns = [a[k - 1], x[k - lag], x[k - lag - 1]]
    if integral:
        s = np.cumsum(x[:T], axis=0)
        columns += [s[k - lag], np.cumsum(w, axis=0)[k], k[:, None].astype(float)]
    return np.hstack([*columns, w[k], np.ones((k.size, 1))])


@dataclass(frozen=True)
class DriveLaw:
    """A linear current control law on the deviations from a log (see the module):
    ``gains = [A1, X0, X1, S]`` (m, m + 3 n), the answer at sample k to ``[d_(k-1),
    e_(k-lag), e_(k-lag-1), sum_(k-lag)]``, where ``d`` are its earlier answers, ``e`` the
    measured currents' departures and ``sum`` their running sum (:meth:`answer`).
    """

    gains: Array
    lag: int

    @classmethod
    def of(cls, logs: Sequence[tuple[Array, Array, Array]], lag: int) -> DriveLaw | None:
        """The law read off the logs ``(x~, a, w)`` (T + 1, n), (T, m), (T, q), or None
        where its residual is not white or ``lag`` is negative (see the module).

        Parameters
        ----------
        logs : sequence of (ndarray, ndarray, ndarray)
            Each log's measured currents, applied inputs and references.
        lag : int
            Samples from a measurement to the input computed from it being applied (the
            alignment's shift).
        """
        logs = [log for log in logs if log[1].shape[0] >= lag + 2]
        if lag < 0 or not logs:
            return None
        n, m = logs[0][0].shape[1], logs[0][1].shape[1]
        Y = np.vstack([a[lag + 1 :] for _, a, _ in logs])
        lengths = [a.shape[0] - lag - 1 for _, a, _ in logs]
        Phi = np.vstack([_regressors(x, a, w, lag, True) for x, a, w in logs])
        if Phi.shape[0] < 10 * Phi.shape[1]:
            return None
        theta, se = _least_squares(Phi, Y)
        S = slice(m + 2 * n, m + 3 * n)  # the integrator's gains, within their noise: none
        integral = bool(np.any(np.abs(theta[S]) > SIGNIFICANCE * se[S]))
        if not integral:
            Phi = np.vstack([_regressors(x, a, w, lag, False) for x, a, w in logs])
            theta = _least_squares(Phi, Y)[0]
        if not _white(Y - Phi @ theta, lengths):
            return None
        gains = theta[: m + (3 if integral else 2) * n].T
        return cls(np.hstack([gains, np.zeros((m, 0 if integral else n))]), lag)

    @property
    def shape(self) -> tuple[int, int]:
        """``(m, n)``: the inputs and the states."""
        m = self.gains.shape[0]
        return m, (self.gains.shape[1] - m) // 3

    def start(self, draws: int | None = None) -> tuple[Array, Array, Array]:
        """The history of a run that has not departed: the last answer (m,), the
        departures (lag + 2, n) and their running sums (lag + 1, n), newest first; with
        ``draws``, of that many runs side by side ((draws, m), (lag + 2, draws, n), ...).
        """
        m, n = self.shape
        batch = () if draws is None else (draws,)
        return (
            np.zeros((*batch, m)),
            np.zeros((self.lag + 2, *batch, n)),
            np.zeros((self.lag + 1, *batch, n)),
        )

    def answer(self, history: tuple[Array, Array, Array], departure: Array) -> Array:
        """The law's answer (m,) to the measured currents' departure at this sample (n,),
        ``history`` (:meth:`start`) moved on to it in place; of runs side by side, their
        answers (draws, m) to their departures (draws, n).

        Parameters
        ----------
        history : (ndarray, ndarray, ndarray)
            The run's history, updated.
        departure : ndarray, shape (n,) or (draws, n)
            The measured currents' departure from the log's at this sample, A.
        """
        last, departures, sums = history
        departures[1:] = departures[:-1].copy()
        departures[0] = departure
        sums[1:] = sums[:-1].copy()
        sums[0] = sums[0] + departure
        lag = self.lag
        regressors = np.concatenate(
            [last, departures[lag], departures[lag + 1], sums[lag]], axis=-1
        )
        answer = regressors @ self.gains.T
        last[...] = answer
        return answer

    def closes_stable_loop(self, Ad: Array, Bd: Array) -> bool:
        """Whether the law on the model ``x_(k+1) = Ad x_k + Bd a_k`` is stable.

        Parameters
        ----------
        Ad, Bd : ndarray
            The model's state and input matrices.
        """
        m, n = self.shape
        A1, X0, X1, S = np.split(self.gains, np.cumsum([m, n, n]), axis=1)
        lag, integral = self.lag, bool(np.any(S))
        # the state [x_k .. x_(k-lag-1), a_(k-1), s_(k-lag-1)] moved on a sample (s only
        # where the law integrates: its running sum would hold an eigenvalue 1)
        blocks = lag + 2
        size = blocks * n + m + (n if integral else 0)
        a_row = np.zeros((m, size))  # a_k, with s_(k-lag) = s_(k-lag-1) + x_(k-lag)
        a_row[:, lag * n : (lag + 1) * n] = X0 + S
        a_row[:, (lag + 1) * n : blocks * n] = X1
        a_row[:, blocks * n : blocks * n + m] = A1
        a_row[:, blocks * n + m :] = S[:, : size - blocks * n - m]
        M = np.zeros((size, size))
        M[:n, :n] = Ad
        M[:n] += Bd @ a_row
        M[n : blocks * n, : (blocks - 1) * n] = np.eye((blocks - 1) * n)
        M[blocks * n : blocks * n + m] = a_row
        if integral:
            M[blocks * n + m :, lag * n : (lag + 1) * n] = np.eye(n)
            M[blocks * n + m :, blocks * n + m :] = np.eye(n)
        return bool(np.max(np.abs(np.linalg.eigvals(M))) < 1.0)


def _least_squares(Phi: Array, Y: Array) -> tuple[Array, Array]:
    """The least-squares coefficients of ``Y ~ Phi`` and their standard errors (the
    residual's variance of each output; columns the data leave free have none: inf)."""
    scale = np.maximum(np.std(Phi, axis=0), np.abs(np.mean(Phi, axis=0)))
    scale[scale == 0.0] = 1.0
    U, singular, Vt = np.linalg.svd(Phi / scale, full_matrices=False)
    kept = singular > singular[0] * Phi.shape[0] * np.finfo(float).eps
    inverse = np.where(kept, 1.0 / np.where(kept, singular, 1.0), 0.0)
    theta = (Vt.T * inverse) @ (U.T @ Y) / scale[:, None]
    dof = max(Phi.shape[0] - int(np.sum(kept)), 1)
    variance = np.sum((Y - Phi @ theta) ** 2, axis=0) / dof
    spread = np.sum((Vt.T * inverse) ** 2, axis=1) / scale**2
    free = np.abs(Vt[~kept]).sum(axis=0) > 1e-6 if np.any(~kept) else np.zeros(scale.size, bool)
    se = np.sqrt(np.outer(spread, variance))
    se[free] = np.inf
    return theta, se


def _white(residual: Array, lengths: Sequence[int]) -> bool:
    """Whether each channel's correlations at lags 1 .. :data:`LAGS` (within each log)
    are within :data:`WHITENESS` standard errors of a white sequence's."""
    pieces = np.split(residual, np.cumsum(lengths)[:-1])
    for lag in range(1, LAGS + 1):
        products = sum(np.sum(p[lag:] * p[:-lag], axis=0) for p in pieces if len(p) > lag)
        count = sum(len(p) - lag for p in pieces if len(p) > lag)
        if count < 1:
            return False
        variance = np.mean(residual**2, axis=0)
        if np.any(variance <= 0.0):
            return False
        if np.any(np.abs(products / count / variance) > WHITENESS / np.sqrt(count)):
            return False
    return True
