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
from dataclasses import replace

import numpy as np

from ...core import Array
from ._output_error import OutputErrorFit, _Log, _search
from ._propagation import _run_searches

__all__ = [
    "BOOTSTRAP_DRAWS",
    "SHORT_LOG",
    "bootstrapped",
    "refits",
    "slowest_time_constant",
    "with_spread",
]

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
    noise_root = np.linalg.cholesky(fit.noise_covariance)

    def world(rng: np.random.Generator, count: int) -> list[list[_Log]]:
        return [
            [
                _Log(x=xhat + rng.standard_normal(xhat.shape) @ noise_root.T, a=log.a, w=log.w)
                for xhat, log in zip(fit.simulated, logs, strict=True)
            ]
            for _ in range(count)
        ]

    draws = refits(fit, world, (matrices, structured), floor, BOOTSTRAP_DRAWS)
    if draws is None:
        return fit
    return with_spread(fit, np.var(draws, axis=0, ddof=1))


def refits(
    fit: OutputErrorFit,
    world: Callable[[np.random.Generator, int], list[list[_Log]]],
    kind: tuple[Callable[[Array], tuple[Array, Array, Array]], bool],
    floor: Array,
    count: int,
    start: Array | None = None,
    iterations: int = REFIT_ITERATIONS,
) -> Array | None:
    """The parameters refitted to ``count`` logs drawn from ``world`` (seeded: the verdict
    is reproducible); None if fewer than half are finite.

    Parameters
    ----------
    fit : OutputErrorFit
        The fit the draws start from.
    world : callable
        ``world(rng, count)``: ``count`` draws of the logs from a random generator, in
        turn (each draw's random numbers after the previous one's): what the data would
        be if the fit were true.
    kind : (callable, bool)
        The parameters' map to ``(Ad, Bd, Ed)`` and whether it is a structure's.
    floor : ndarray, shape (n,)
        The states' rounding floor.
    count : int
        Number of draws.
    start : ndarray, shape (p,), optional
        The parameters each refit starts from (default: the fit's).
    iterations : int
        Gauss-Newton iterations of each refit.

    Returns
    -------
    ndarray, shape (draws, p), or None
    """
    rng = np.random.default_rng(20261123)
    origin = fit.parameters if start is None else start
    searches = [_search(logs, origin.copy(), kind, iterations, floor) for logs in world(rng, count)]
    # the refits side by side: each step's propagations of all of them are one
    refitted = [parameters for parameters, *_ in _run_searches(searches)]
    draws = [parameters for parameters in refitted if np.all(np.isfinite(parameters))]
    return np.array(draws) if len(draws) >= count // 2 and len(draws) >= 2 else None


def with_spread(fit: OutputErrorFit, spread: Array, extra: Array | None = None) -> OutputErrorFit:
    """``fit`` with each parameter's variance at least ``spread``'s (the correlations of
    its own covariance kept), plus an ``extra`` covariance.

    Parameters
    ----------
    fit : OutputErrorFit
        The fit.
    spread : ndarray, shape (p,)
        Variances of the parameters measured by refits.
    extra : ndarray, shape (p, p), optional
        A covariance to add (e.g. of a correction's own error).
    """
    linear = np.maximum(np.diag(fit.parameter_covariance), 1e-300)
    scale = np.sqrt(np.maximum(1.0, spread / linear))
    covariance = fit.parameter_covariance * np.outer(scale, scale)
    if extra is not None:
        covariance = covariance + extra
    return replace(fit, parameter_covariance=covariance)
