"""The log's rounding in the output-error fit: each state's rounding floor, the rule that
stops a fit at rounding, and the output errors' weight (never infinite).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from ...core import Array

__all__ = ["EPS", "ROUNDING_RESIDUAL", "at_rounding", "noise_root", "resolution_floor"]

#: The double precision's unit roundoff.
EPS = float(np.finfo(float).eps)

#: Output errors (rms, per state) within this many times the log's rounding leave a fit
#: nothing to explain: noise-free data stop there instead of iterating on rounding.
ROUNDING_RESIDUAL = 2.0


def resolution_floor(x: Array, relative: float) -> Array:
    """The standard deviation of rounding to ``relative`` precision of each state's values
    (uniform rounding, ``relative max|x| / sqrt(3)``), at least 1e-12 of the states' size.

    Parameters
    ----------
    x : ndarray, shape (T, n)
        The states.
    relative : float
        The log's relative precision (e.g. 6e-8 for float32).
    """
    size = float(np.max(np.abs(x))) if x.size else 1.0
    per_state = relative * np.max(np.abs(x), axis=0) / np.sqrt(3.0)
    return np.asarray(np.maximum(per_state, 1e-12 * max(size, 1e-300)))


def at_rounding(residuals: list[Array], floor: Array) -> bool:
    """Whether every state's rms output error is within :data:`ROUNDING_RESIDUAL` times
    its rounding floor.

    Parameters
    ----------
    residuals : list of ndarray, each shape (T, n)
        The output errors of each log.
    floor : ndarray, shape (n,)
        Each state's rounding floor (:func:`resolution_floor`).
    """
    rms = np.sqrt(np.mean(np.concatenate(residuals) ** 2, axis=0))
    return bool(np.all(rms <= ROUNDING_RESIDUAL * floor))


def noise_root(stacked: Array, floor: Array) -> Array:
    """``root`` with ``root' root`` the inverse of the residuals' covariance, each state's
    variance at least ``floor^2`` (the log's resolution; never zero, so that noise-free
    data weigh finitely).

    Parameters
    ----------
    stacked : ndarray, shape (T, n)
        The output errors of every log, stacked.
    floor : ndarray, shape (n,)
        Each state's rounding floor (:func:`resolution_floor`).
    """
    covariance = np.atleast_2d(np.cov(stacked.T))
    covariance = covariance + np.diag(np.maximum(floor**2 - np.diag(covariance), 0.0))
    try:
        return np.asarray(scipy.linalg.cholesky(np.linalg.inv(covariance)), dtype=np.float64)
    except np.linalg.LinAlgError:
        # output errors that move together (a stiff plant's noise-free log, at rounding):
        # the sample covariance is singular or indefinite by rounding; the root from its
        # eigenvalues, held at the smallest floor and at what the largest can resolve
        values, vectors = np.linalg.eigh(0.5 * (covariance + covariance.T))
        least = max(float(np.min(floor)) ** 2, values.size * EPS * float(np.max(values)))
        return np.asarray(vectors.T / np.sqrt(np.maximum(values, least))[:, None])
