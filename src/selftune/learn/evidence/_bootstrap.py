"""The output-error fit's covariance on logs too short for its linearization.

The parameters' covariance of :mod:`._output_error` is the inverse Fisher information
(made robust): exact to first order, which needs the log to pin the model down well.
On a log shorter than the plant's slowest time constant, the simulation over the whole
log makes the fit strongly nonlinear in ``Ad``, and that covariance falls short:
measured on 40 seeds of a 49 ms log of a motor whose time constant is 0.2 s, the
parameters' errors were 1.3-1.8 times their standard errors (0.85-1.1 times on 0.25 s).

On such logs a parametric bootstrap measures the covariance instead: the fitted model's
noise-free simulation plus fresh noise of the estimated covariance, refitted
:data:`BOOTSTRAP_DRAWS` times from the fit (seeded: the verdict is reproducible),
conditional on the logged inputs. Each parameter's variance is the larger of the two.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ...core import Array
from ._output_error import OutputErrorFit, _gauss_newton, _Log

__all__ = ["BOOTSTRAP_DRAWS", "SHORT_LOG", "bootstrapped", "slowest_time_constant"]

#: Refits of the bootstrap.
BOOTSTRAP_DRAWS = 24

#: A log shorter than this many of the plant's slowest time constants is short.
SHORT_LOG = 1.0

#: Gauss-Newton iterations of each refit (it starts at the fit, a step or two away).
REFIT_ITERATIONS = 12


def slowest_time_constant(Ad: Array, h: float) -> float:
    """``-h / ln |lambda|`` of the eigenvalue of ``Ad`` nearest the unit circle, s.

    Parameters
    ----------
    Ad : ndarray, shape (n, n)
        The sampled plant (stable).
    h : float
        Sampling period, s.
    """
    radius = float(np.max(np.abs(np.linalg.eigvals(Ad))))
    if radius <= 0.0:
        return 0.0
    if radius >= 1.0:
        return float("inf")
    return -h / float(np.log(radius))


def bootstrapped(
    fit: OutputErrorFit,
    logs: list[_Log],
    matrices: Callable[[Array], tuple[Array, Array, Array]],
    structured: bool,
    floor: Array,
) -> OutputErrorFit:
    """``fit`` with each parameter's variance at least the bootstrap's (see the module).

    Parameters
    ----------
    fit : OutputErrorFit
        The fit of ``logs``.
    logs : list of _Log
        The data it was fitted to.
    matrices : callable
        Its parameters' map to ``(Ad, Bd, Ed)``.
    structured : bool
        Whether the map is a structure's.
    floor : ndarray, shape (n,)
        The states' rounding floor.
    """
    rng = np.random.default_rng(20261123)
    noise_root = np.linalg.cholesky(fit.noise_covariance)
    draws = []
    for _ in range(BOOTSTRAP_DRAWS):
        fresh = [
            _Log(x=xhat + rng.standard_normal(xhat.shape) @ noise_root.T, a=log.a, w=log.w)
            for xhat, log in zip(fit.simulated, logs, strict=True)
        ]
        refit = _gauss_newton(
            fresh, fit.parameters.copy(), matrices, structured, REFIT_ITERATIONS,
            fit.model.h, floor,
        )  # fmt: skip
        if np.all(np.isfinite(refit.parameters)):
            draws.append(refit.parameters)
    if len(draws) < BOOTSTRAP_DRAWS // 2:
        return fit
    spread = np.var(np.array(draws), axis=0, ddof=1)
    linear = np.maximum(np.diag(fit.parameter_covariance), 1e-300)
    scale = np.sqrt(np.maximum(1.0, spread / linear))
    covariance = fit.parameter_covariance * np.outer(scale, scale)
    return OutputErrorFit(
        model=fit.model,
        parameters=fit.parameters,
        parameter_covariance=covariance,
        noise_covariance=fit.noise_covariance,
        simulated=fit.simulated,
        residuals=fit.residuals,
        iterations=fit.iterations,
        structure=fit.structure,
        correlation_inflation=fit.correlation_inflation,
    )
