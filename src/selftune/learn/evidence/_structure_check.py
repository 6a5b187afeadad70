"""The structure's check: a structured output-error fit against the unstructured fit of
the same logs, by their likelihood ratio (:func:`structure_statistic`). Far in the
chi-square tail the structure does not hold, or its search stopped in a wrong minimum
(:func:`check_structure`); see :mod:`._evidence`.
"""

from __future__ import annotations

import numpy as np
import scipy.special

from ...errors import ConfigurationMismatch, ConsistencyError
from ..data._trajectory import Trajectory
from ._alignment import Alignment
from ._output_error import OutputErrorFit, fit_output_error

__all__ = ["check_structure", "structure_statistic"]


def structure_statistic(fit: OutputErrorFit, free: OutputErrorFit) -> tuple[float, int]:
    """The likelihood-ratio statistic of a structured output-error fit against the
    unstructured one of the same logs, and its degrees of freedom.

    ``N (log det Sigma_structured - log det Sigma_free)`` over the ``N`` output errors: a
    chi-square variable with as many degrees of freedom as the structure removes when it
    holds (the structured model is one of the free ones) and the noise is Gaussian;
    large when the structure misses what the data show, or its fit stopped in a wrong
    minimum.

    Parameters
    ----------
    fit : OutputErrorFit
        The structured fit.
    free : OutputErrorFit
        Every entry of ``[Ad, Bd, Ed]`` fitted to the same logs.
    """
    count = sum(residual.shape[0] for residual in fit.residuals)
    ratio = np.linalg.slogdet(fit.noise_covariance)[1] - np.linalg.slogdet(free.noise_covariance)[1]
    return count * float(ratio), int(free.parameters.size - fit.parameters.size)


def check_structure(
    episodes: list[Trajectory],
    alignment: Alignment,
    fit: OutputErrorFit | None,
    precision: tuple[float, float],
    dead_time: bool,
) -> None:
    """Refuse a structured fit that explains the logs worse than the unstructured model
    (:func:`structure_statistic` beyond the chi-square quantile at the test's level), or
    that cannot be compared with one.

    Parameters
    ----------
    episodes : list of Trajectory
        The logs as fitted.
    alignment : Alignment
        Their inputs' alignment and its least-squares model.
    fit : OutputErrorFit or None
        The structured fit (None: it failed).
    precision : (float, float)
        The logs' relative rounding and the test's level (the tail's probability).
    dead_time : bool
        Whether the dead-time model is fitted (see below).

    With ``dead_time`` the output errors are correlated in time by the dead-time model's
    own approximation near zero current (tolerated, see :data:`INFLATION_LIMIT`), which
    the unstructured model absorbs more of: the statistic is divided by the fit's
    correlation inflation, as a likelihood ratio under correlated errors is (measured on
    hardware-like logs of 0.5 s: 38-87 for 12 degrees of freedom, inflation 4-7, where the
    results were within 1 standard error)."""
    resolution, level = precision
    free = None
    title = "structured" if fit is None or fit.structure is None else fit.structure.title
    if fit is not None:
        free = fit_output_error(
            episodes, alignment.shift, alignment.model, None, resolution=resolution, stable=False
        )
    if fit is None or free is None:
        raise ConsistencyError(
            f"structure: the {title} fit cannot be checked against an unstructured model of "
            "these data (an output-error fit that is not finite, or an unstable structured "
            "one: too few or too noisy samples); structure = 'none' does not need the check"
        )
    statistic, freedom = structure_statistic(fit, free)
    if dead_time:
        statistic /= max(fit.correlation_inflation, 1.0)
    threshold = float(scipy.special.chdtri(freedom, level))
    if statistic > threshold:
        raise ConfigurationMismatch(
            f"structure: the {title} model explains the data worse than an unstructured one "
            f"(likelihood-ratio statistic {statistic:.4g}, threshold {threshold:.4g} for "
            f"{freedom} degrees of freedom); likely causes: its fit stopped in a wrong "
            "minimum (too few or too noisy samples), or the drive is not what the structure "
            "assumes (electrical_speed, voltage_hold, dead_time); structure = 'none' "
            "assumes none of it",
            key="structure",
        )
