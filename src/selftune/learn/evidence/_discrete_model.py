"""The exact discrete model of sampled data, fitted by least squares.

With the input held over each sample (zero-order hold) and ``w`` held too (E = 0), the
samples of ``x' = A x + B u + D w`` satisfy exactly::

    x_(k+1) = Ad x_k + Bd a_k + Ed w_k

where ``a_k`` is the input APPLIED during ``[t_k, t_(k+1))``. :func:`fit_discrete_model`
fits ``[Ad, Bd, Ed]`` to the transitions of a log by least squares: exact on noise-free
data at any sampling period, whatever the excitation as long as the regressors have full
rank. It is the model behind the input-alignment check (:mod:`._alignment`), the quality
verdict and identify-then-design (:mod:`..learners._identify`); the ADP learners do not use it to
learn.

Under white measurement noise on x the fit is biased (errors in variables: ``x_k`` is a
regressor); :mod:`..learners._identify` refines it by output error.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from ...core import RANK_TOLERANCE, Array
from ...errors import NotExciting, NumericalFailure, TooShort

__all__ = [
    "DiscreteModel",
    "Transitions",
    "fit_discrete_model",
    "lack_of_rank",
    "regressor_names",
    "tied_columns",
]


@dataclass(frozen=True)
class Transitions:
    """Sample-to-sample transitions ``(x_k, a_k, w_k) -> x_(k+1)`` of one or more logs.

    Attributes
    ----------
    x : ndarray, shape (T, n)
        State at the start of each transition.
    x_next : ndarray, shape (T, n)
        State at its end.
    a : ndarray, shape (T, m)
        Input applied during it.
    w : ndarray, shape (T, q)
        Exogenous signal held during it (q may be 0).
    h : float
        Sampling period, s.
    """

    x: Array
    x_next: Array
    a: Array
    w: Array
    h: float

    @property
    def count(self) -> int:
        """T, the number of transitions."""
        return int(self.x.shape[0])

    @property
    def regressors(self) -> Array:
        """``[x_k, a_k, w_k]`` row by row, shape (T, n + m + q)."""
        return np.hstack([self.x, self.a, self.w])


@dataclass(frozen=True)
class DiscreteModel:
    """A fitted ``x_(k+1) = Ad x_k + Bd a_k + Ed w_k``.

    Attributes
    ----------
    Ad : ndarray, shape (n, n)
        State transition over one sample.
    Bd : ndarray, shape (n, m)
        Effect of the applied input.
    Ed : ndarray, shape (n, q)
        Effect of the held exogenous signal.
    h : float
        Sampling period, s.
    residual_rms : ndarray, shape (n,)
        Root mean square of the one-step residual of each state, in the state's unit.
    relative_residual : float
        ``||residual|| / ||x_(k+1) - x_k||`` over all transitions: 0 on exact data.
    condition : float
        Condition number of the column-scaled regressor matrix.
    transitions : int
        Number of transitions fitted.
    covariance : ndarray or None
        Covariance of ``vec([Ad, Bd, Ed])`` (column-major) for white one-step residuals
        (``kron((Z'Z)^-1, Sigma)``); under measurement noise on the states the estimate
        itself is biased, so this is a lower bound there.
    """

    Ad: Array
    Bd: Array
    Ed: Array
    h: float
    residual_rms: Array
    relative_residual: float
    condition: float
    transitions: int
    covariance: Array | None = None

    @classmethod
    def given(cls, Ad: Array, Bd: Array, Ed: Array, h: float) -> DiscreteModel:
        """A model given, not fitted (no residual, no transitions, no covariance).

        Parameters
        ----------
        Ad, Bd, Ed : ndarray
            The matrices.
        h : float
            Sampling period, s.
        """
        return cls(Ad, Bd, Ed, h, np.zeros(Ad.shape[0]), 0.0, 1.0, 0)

    def matrices(self, parameters: Array) -> tuple[Array, Array, Array]:
        """``(Ad, Bd, Ed)`` from ``vec([Ad, Bd, Ed])`` of this model's shapes.

        Parameters
        ----------
        parameters : ndarray
            ``vec([Ad, Bd, Ed])``, column-major.
        """
        n, m = self.n, self.Bd.shape[1]
        M = parameters.reshape((n, -1), order="F")
        return M[:, :n], M[:, n : n + m], M[:, n + m :]

    @property
    def parameters(self) -> Array:
        """``vec([Ad, Bd, Ed])``, column-major."""
        return np.concatenate([self.Ad, self.Bd, self.Ed], axis=1).ravel(order="F")

    @property
    def n(self) -> int:
        """State dimension."""
        return int(self.Ad.shape[0])

    def predict(self, transitions: Transitions) -> Array:
        """One-step predictions ``Ad x_k + Bd a_k + Ed w_k``, shape (T, n).

        Parameters
        ----------
        transitions : Transitions
            The data to predict.
        """
        return np.asarray(
            transitions.x @ self.Ad.T + transitions.a @ self.Bd.T + transitions.w @ self.Ed.T
        )


def regressor_names(n: int, m: int, q: int) -> tuple[str, ...]:
    """The names of the regressors ``[x_k, a_k, w_k]``: ``x1..xn, u1..um, w1..wq``.

    Parameters
    ----------
    n, m, q : int
        Numbers of states, inputs and exogenous channels.
    """
    return (
        *(f"x{i + 1}" for i in range(n)),
        *(f"u{i + 1}" for i in range(m)),
        *(f"w{i + 1}" for i in range(q)),
    )


def lack_of_rank(rank: int, size: int, names: tuple[str, ...], columns: tuple[int, ...]) -> str:
    """The message of transitions that lack rank: the regressors that move together.

    Parameters
    ----------
    rank, size : int
        The rank found and the number of regressors.
    names : tuple of str
        The regressors' names (:func:`regressor_names`, and any appended channels').
    columns : tuple of int
        The regressors that move together (:func:`tied_columns`).
    """
    return (
        f"the transitions have rank {rank} of {size} ({', '.join(names)}): "
        f"{', '.join(names[i] for i in columns)} do not vary independently of each other "
        "(a combination of them is the same in every sample); add exploration on every "
        "input and perturb the reference"
    )


def tied_columns(null_rows: Array) -> tuple[int, ...]:
    """The columns a regression's null space involves: those whose weight in some null
    direction is at least a tenth of that direction's largest (column-scaled regressors).

    Parameters
    ----------
    null_rows : ndarray, shape (k, size)
        Orthonormal directions of the (numerical) null space, one per row.
    """
    weights = np.abs(null_rows) / np.max(np.abs(null_rows), axis=1, keepdims=True)
    return tuple(int(i) for i in np.flatnonzero(np.max(weights, axis=0) >= 0.1))


def fit_discrete_model(transitions: Transitions) -> DiscreteModel:
    """Least-squares fit of ``[Ad, Bd, Ed]`` to transitions.

    Columns are scaled to unit norm before the rank test, so it does not depend on units.

    Parameters
    ----------
    transitions : Transitions
        The data, e.g. from :func:`selftune.learn.aligned_transitions`.

    Returns
    -------
    DiscreteModel

    Raises
    ------
    TooShort
        If there are fewer transitions than regressors (an ExcitationError).
    NotExciting
        If the regressors lack rank (an ExcitationError): the data do not excite every
        state, input and exogenous channel independently.
    NumericalFailure
        If the data are not finite (an InputError).
    """
    Z = transitions.regressors
    Y = transitions.x_next
    count, size = Z.shape
    if not (np.all(np.isfinite(Z)) and np.all(np.isfinite(Y))):
        raise NumericalFailure("the data are not finite", what="data")
    if count < size:
        raise TooShort(
            f"only {count} transitions for {size} regressors (states, inputs and exogenous "
            f"channels): use longer data (at least {size} samples)",
            samples=count,
            samples_needed=size,
        )
    scale = np.linalg.norm(Z, axis=0)
    scale[scale == 0.0] = 1.0
    Q_, R_ = scipy.linalg.qr(Z / scale, mode="economic", check_finite=False)
    _, singular, Vh = np.linalg.svd(R_)
    rank = int(np.sum(singular > RANK_TOLERANCE * singular[0])) if singular[0] > 0 else 0
    n, m = transitions.x.shape[1], transitions.a.shape[1]
    if rank < size:
        columns = tied_columns(Vh[rank:])
        raise NotExciting(
            lack_of_rank(rank, size, regressor_names(n, m, size - n - m), columns),
            rank=rank,
            rank_needed=size,
            block=None,
            columns=columns,
        )
    theta = scipy.linalg.solve_triangular(R_, Q_.T @ Y, check_finite=False) / scale[:, None]
    residual = Y - Z @ theta
    inverse_R = scipy.linalg.solve_triangular(R_, np.eye(size), check_finite=False) / scale[:, None]
    spread = np.atleast_2d(np.cov(residual.T)) if count > size else np.zeros((n, n))
    change = np.linalg.norm(Y - transitions.x)
    return DiscreteModel(
        Ad=theta[:n].T.copy(),
        Bd=theta[n : n + m].T.copy(),
        Ed=theta[n + m :].T.copy(),
        h=transitions.h,
        residual_rms=np.sqrt(np.mean(residual**2, axis=0)),
        relative_residual=float(np.linalg.norm(residual) / change) if change > 0 else 0.0,
        condition=float(singular[0] / singular[-1]),
        transitions=count,
        covariance=np.kron(inverse_R @ inverse_R.T, spread),
    )
