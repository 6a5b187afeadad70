"""Output-error identification: the consistent fit of the exact discrete model under noise.

Measured states carry white noise, ``x~_k = x_k + v_k``; the logged inputs are exact (they
are what the controller computed). Least squares on ``x~_(k+1) = Ad x~_k + ...`` is then
biased (errors in variables: ``x~_k`` is a regressor). Output error fits the model's
SIMULATION from the logged inputs to the measurements::

    minimize  sum_k (x~_k - xhat_k)' W (x~_k - xhat_k),
    xhat_(k+1) = Ad xhat_k + Bd a_k + Ed w_k,   xhat_first = x0 (one per log)

At the true model the residual is the noise itself, independent of the gradient (which
depends on past inputs only, even in closed loop), so the fit is consistent, and the
maximum-likelihood one for Gaussian noise with ``W`` the inverse noise covariance, which
is estimated from the residuals as the fit iterates. Gauss-Newton with the exact
sensitivities (one more linear recursion per parameter, propagated together by
:mod:`._propagation`; a long log's block by block), damped (Levenberg-Marquardt).

The model may be the unstructured ``[Ad, Bd, Ed]`` or a structured one (a few physical
parameters mapped to the matrices, e.g. a PMSM's R_s, L_s and flux at a known speed:
:class:`SpmsmStructure`). The plant must be stable (the simulation runs open loop over
the whole log); otherwise the least-squares model is kept and the quality says so.
"""

from __future__ import annotations

from collections.abc import Callable, Generator, Iterator, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ...core import Array
from ...errors import InputError
from ..data._trajectory import Trajectory
from . import _propagation
from ._alignment import applied_inputs
from ._discrete_model import DiscreteModel
from ._incremental_structure import IncrementalStructure
from ._ipmsm_structure import IpmsmStructure
from ._propagation import (
    _chained,
    _Jacobian,
    _Request,
    _run_searches,
    simulate_model,
)
from ._propagation import _Log as _Log
from ._rounding import at_rounding, noise_root, resolution_floor
from ._spmsm_structure import SpmsmStructure

__all__ = [
    "IpmsmStructure",
    "MotorStructure",
    "OutputErrorFit",
    "SpmsmStructure",
    "Structure",
    "fit_output_error",
    "simulate_model",
    "simulated_trajectories",
]

#: A structure maps physical parameters to ``(Ad, Bd, Ed)``.
Structure = Callable[[Array], tuple[Array, Array, Array]]

#: A PMSM's structure: the surface motor's, the interior one's, or the incremental one.
MotorStructure = SpmsmStructure | IpmsmStructure | IncrementalStructure


def _logs(episodes: Sequence[Trajectory], shift: int) -> list[_Log]:
    logs = []
    for episode in episodes:
        a, first = applied_inputs(episode, shift)
        count = min(a.shape[0], episode.num_samples - first)
        w = np.zeros((episode.num_samples, 0)) if episode.w is None else episode.w
        logs.append(
            _Log(x=episode.x[first : first + count + 1], a=a[:count], w=w[first : first + count])
        )
    return logs


@dataclass(frozen=True)
class OutputErrorFit:
    """The output-error model, its noise estimate and its parameter covariance.

    Attributes
    ----------
    model : DiscreteModel
        The fitted ``(Ad, Bd, Ed)``; its residuals are the output errors.
    parameters : ndarray, shape (p,)
        The fitted parameters (``vec([Ad, Bd, Ed])`` or the structure's).
    parameter_covariance : ndarray, shape (p, p)
        Their covariance: the inverse Fisher information under the estimated noise, made
        robust to output errors that are not white (Newey-West).
    noise_covariance : ndarray, shape (n, n)
        The measurement-noise covariance estimated from the output errors, unit^2.
    simulated : tuple of ndarray
        The noise-free simulated states ``xhat`` of each log (aligned with the data used).
    residuals : tuple of ndarray
        The output errors ``x~ - xhat`` of each log.
    iterations : int
        Gauss-Newton iterations.
    structure : SpmsmStructure or IpmsmStructure or None
        The structure fitted (None: every entry of ``[Ad, Bd, Ed]``).
    correlation_inflation : float
        How much larger the robust variances are than white output errors would give
        (the largest ratio of the diagonals): about 1 when the model explains the data
        up to white noise; well above it when the output errors are correlated in time,
        i.e. the model misses an effect.
    """

    model: DiscreteModel
    parameters: Array
    parameter_covariance: Array
    noise_covariance: Array
    simulated: tuple[Array, ...]
    residuals: tuple[Array, ...]
    iterations: int
    structure: MotorStructure | None = None
    correlation_inflation: float = 1.0

    def matrices(self, parameters: Array) -> tuple[Array, Array, Array]:
        """``(Ad, Bd, Ed)`` of parameters of this fit's kind.

        Parameters
        ----------
        parameters : ndarray, shape (p,)
            Parameters like :attr:`parameters`.
        """
        if self.structure is not None:
            return self.structure(parameters)
        n, m, q = self.model.n, self.model.Bd.shape[1], self.model.Ed.shape[1]
        return _unstructured(parameters, n, m, q)


def _unstructured(theta: Array, n: int, m: int, q: int) -> tuple[Array, Array, Array]:
    M = theta.reshape((n, n + m + q), order="F")
    return M[:, :n], M[:, n : n + m], M[:, n + m :]


def fit_output_error(
    episodes: Sequence[Trajectory],
    shift: int,
    start: DiscreteModel,
    structure: MotorStructure | None = None,
    max_iterations: int = 60,
    resolution: float = 0.0,
    stable: bool = True,
) -> OutputErrorFit | None:
    """Fit the discrete model by output error, starting from ``start``.

    Parameters
    ----------
    episodes : sequence of Trajectory
        The logs.
    shift : int
        The alignment of the logged inputs (:func:`selftune.learn.check_alignment`).
    start : DiscreteModel
        The least-squares model to start from.
    structure : SpmsmStructure or IpmsmStructure, optional
        Fit only the structure's parameters instead of every entry of ``[Ad, Bd, Ed]``.
    max_iterations : int
        Upper bound on Gauss-Newton iterations.
    resolution : float
        The log's relative precision (e.g. 6e-8 for float32 values): the noise of each
        state is taken to be at least its rounding (:func:`resolution_floor`).
    stable : bool
        Return only a stable model (a model of the plant). False: any finite fit, for
        its output errors alone (a comparison of models); its parameters' covariance is
        then the asymptotic one, not bootstrapped on a short log.

    Returns
    -------
    OutputErrorFit or None
        None when the fit is not finite, or (with ``stable``) the plant is not stable (the
        open-loop simulation would diverge).
    """
    radius = float(np.max(np.abs(np.linalg.eigvals(start.Ad))))
    if radius >= 1.0 - 1e-9:
        # noise can push the least-squares model of a stable plant just past the limit:
        # start inside it; an unstable plant stays unstable and is left to least squares
        start = replace(start, Ad=start.Ad * (1.0 - 1e-3) / radius)
    logs = _logs(episodes, shift)
    n, m, q = start.n, start.Bd.shape[1], start.Ed.shape[1]
    matrices: Callable[[Array], tuple[Array, Array, Array]]
    if structure is None:
        theta = np.concatenate([start.Ad, start.Bd, start.Ed], axis=1).ravel(order="F")

        def unstructured(values: Array) -> tuple[Array, Array, Array]:
            return _unstructured(values, n, m, q)

        matrices = unstructured
    else:
        references = structure.references
        if (n, m, q) != (2, 2, references + (2 if structure.dead_time else 0)):
            raise InputError(
                f"structure: the PMSM structure needs n = m = 2 and {references} reference"
                f" channels ({'the known-flux form' if references == 2 else 'w_1, i_d*, i_q*'})"
            )
        theta = structure.initial(start)
        matrices = structure
    stacked_x = np.concatenate([log.x for log in logs])
    floor = resolution_floor(stacked_x, resolution)
    fit = _gauss_newton(
        logs, theta, matrices, structure is not None, max_iterations, start.h, floor
    )
    if not np.all(np.isfinite(fit.model.Ad)):
        return None
    fit = replace(fit, structure=structure)
    if not stable:
        return fit
    if float(np.max(np.abs(np.linalg.eigvals(fit.model.Ad)))) >= 1.0:
        return None  # an unstable plant: its open-loop simulation is no model of the data
    from ._bootstrap import SHORT_LOG, bootstrapped, slowest_time_constant  # no cycle

    duration = start.h * sum(log.a.shape[0] for log in logs)
    short = duration < SHORT_LOG * slowest_time_constant(fit.model.Ad, start.h)
    # output errors at the log's rounding (noise-free data) leave the linearization exact
    # to rounding: the fit's nonlinearity enters with the noise squared, and the refits
    # would only resample rounding
    if short and not at_rounding(list(fit.residuals), floor):
        fit = bootstrapped(fit, logs, matrices, structure is not None, floor)
    return fit


def _jacobian_map(
    matrices: Callable[[Array], tuple[Array, Array, Array]], theta: Array, structured: bool
) -> Array | None:
    """``d vec([Ad, Bd, Ed]) / d theta`` for a structure (central differences); None for
    the unstructured model (the identity).

    Where the step below a parameter leaves the structure's domain (an inductance within
    a step of zero, which a search may reach on data that do not fix it: a 25 uH motor
    on 48 V with 2 V of dead time), that column is the forward difference instead."""
    if not structured:
        return None

    def flat(point: Array) -> Array:
        return np.concatenate(matrices(point), axis=1).ravel(order="F")

    columns = []
    for index in range(theta.shape[0]):
        step = 1e-6 * max(abs(float(theta[index])), 1e-3)
        plus, minus = theta.copy(), theta.copy()
        plus[index] += step
        minus[index] -= step
        high = flat(plus)
        try:
            columns.append((high - flat(minus)) / (2 * step))
        except InputError:
            columns.append((high - flat(theta)) / step)
    return np.column_stack(columns)


#: The current point's output errors, Jacobians and simulations (one of each per log).
_Current = tuple[list[Array], list[_Jacobian], list[Array]]

#: A search yields requests, is sent their answers and returns the parameters, the
#: initial states, its iterations and what :func:`_finish` can reuse (None: nothing).
_Search = Generator[_Request, list[Array], tuple[Array, list[Array], int, _Current | None]]


def _residuals_and_jacobian(
    logs: list[_Log],
    mats: tuple[Array, Array, Array],
    x0s: list[Array],
    chain: Array | None,
    known: list[Array] | None = None,
) -> Generator[_Request, list[Array], _Current]:
    """Per log: the output errors, their Jacobian and the simulation at ``(mats, x0s)``;
    ``known``: the simulations there, when :func:`_cost` has just made them."""
    simulated = (yield _Request(mats, logs, x0s, False)) if known is None else known
    limit = _propagation.BLOCK_TRANSITIONS
    short = [index for index, log in enumerate(logs) if log.a.shape[0] <= limit]
    held: dict[int, Array] = {}
    if short:
        sensitivities = yield _Request(
            mats, [logs[index] for index in short], [simulated[index] for index in short], True
        )
        held = dict(zip(short, sensitivities, strict=True))
    residuals, jacobians = [], []
    for index, (log, xhat) in enumerate(zip(logs, simulated, strict=True)):
        S = held.get(index)
        J = None if S is None else _chained(S, chain)
        residuals.append(log.x - xhat)
        jacobians.append(_Jacobian(J, (mats, log, xhat), chain))
    return residuals, jacobians, simulated


def simulation_spread(fit: OutputErrorFit, logs: list[_Log], x0s: list[Array]) -> Array:
    """The rms over the logs' samples of the standard deviation of the fit's simulated
    states under its parameter covariance (linearized), per state (n,), in the states'
    unit.

    Parameters
    ----------
    fit : OutputErrorFit
        The fit.
    logs : list of _Log
        Logs of the fit's kind (its exogenous channels).
    x0s : list of ndarray
        Their initial states.
    """
    chain = _jacobian_map(fit.matrices, fit.parameters, fit.structure is not None)
    mats = fit.matrices(fit.parameters)
    [(_, jacobians, _)] = _run_searches([_residuals_and_jacobian(logs, mats, x0s, chain)])
    p, C = fit.parameters.shape[0], fit.parameter_covariance
    total, count = np.zeros(fit.model.n), 0
    for jacobian in jacobians:
        for J in jacobian.blocks():
            total += np.einsum("kia,ab,kib->i", J[:, :, :p], C, J[:, :, :p])
            count += J.shape[0]
    return np.sqrt(total / max(count, 1))


#: Rounds of re-estimating the noise weight W; Levenberg-Marquardt runs within each.
WEIGHT_ROUNDS = 3


def _cost(
    logs: list[_Log],
    matrices: Callable[[Array], tuple[Array, Array, Array]],
    point: tuple[Array, list[Array]],
    weight: Array,
) -> Generator[_Request, list[Array], tuple[float, list[Array]]]:
    """The weighted output-error cost at ``(theta, x0s)`` and the simulations of the logs
    there: infinite (and no simulations) where the parameters give no model (a
    structure's non-physical values, an overflowing discretization), so that the search
    never steps there."""
    theta, x0s = point
    try:
        mats = matrices(theta)
    except (InputError, np.linalg.LinAlgError):
        return float("inf"), []
    simulated = yield _Request(mats, logs, x0s, False)
    residuals = [log.x - xhat for log, xhat in zip(logs, simulated, strict=True)]
    return _weighted(residuals, weight), simulated


def _weighted(residuals: list[Array], weight: Array) -> float:
    """``sum_k r_k' W r_k`` over the logs' output errors; infinite if not finite."""
    total = 0.0
    for r in residuals:
        total += float(np.einsum("ki,ij,kj->", r, weight, r))
    return total if np.isfinite(total) else float("inf")


def _search(
    logs: list[_Log],
    theta: Array,
    kind: tuple[Callable[[Array], tuple[Array, Array, Array]], bool],
    max_iterations: int,
    floor: Array,
) -> _Search:
    """Levenberg-Marquardt on the parameters and every log's initial state: a step is kept
    only if it lowers the cost (else the damping grows), with the noise weight
    re-estimated from the output errors between rounds (iteratively reweighted). ``kind``:
    the parameters' map to ``(Ad, Bd, Ed)`` and whether it is a structure's. A generator
    of what it needs propagated (:func:`_run_searches`)."""
    matrices, structured = kind
    n, p = logs[0].x.shape[1], theta.shape[0]
    x0s = [log.x[0].copy() for log in logs]
    iterations = 0
    # the residuals, Jacobians and simulations at (theta, x0s) when known (None: stale)
    current: _Current | None = None
    for _ in range(WEIGHT_ROUNDS):
        if current is None:
            chain = _jacobian_map(matrices, theta, structured)
            current = yield from _residuals_and_jacobian(logs, matrices(theta), x0s, chain)
        residuals, jacobians, _ = current
        root = noise_root(np.concatenate(residuals), floor)  # W = root' root
        weight, damping = root.T @ root, 1e-4
        cost = _weighted(residuals, weight)  # the residuals are those at (theta, x0s)
        equations = None  # the normal equations at (theta, x0s) under this weight
        while iterations < max_iterations:
            iterations += 1
            if equations is None:  # a retry with more damping has them already
                equations = _normal_equations(residuals, jacobians, root, p)
            step = _step(equations, damping)
            trial = theta + step[:p]
            trial_x0s = [x0 + step[p + i * n : p + (i + 1) * n] for i, x0 in enumerate(x0s)]
            trial_cost, simulated = yield from _cost(logs, matrices, (trial, trial_x0s), weight)
            if trial_cost >= cost:
                damping *= 10.0
                if damping > 1e8:
                    break
                continue
            improvement = (cost - trial_cost) / max(cost, 1e-300)
            theta, x0s, cost, damping = trial, trial_x0s, trial_cost, max(damping / 10, 1e-12)
            current = None
            if improvement < 1e-12:
                break
            chain = _jacobian_map(matrices, theta, structured)
            current = yield from _residuals_and_jacobian(
                logs, matrices(theta), x0s, chain, simulated
            )
            residuals, jacobians, _ = current
            equations = None
            if at_rounding(residuals, floor):
                break
        if at_rounding(residuals, floor):
            break
    return theta, x0s, iterations, current


def _gauss_newton(
    logs: list[_Log],
    theta: Array,
    matrices: Callable[[Array], tuple[Array, Array, Array]],
    structured: bool,
    max_iterations: int,
    h: float,
    floor: Array,
) -> OutputErrorFit:
    """The fit of :func:`_search` from ``theta``."""
    [(theta, x0s, iterations, current)] = _run_searches(
        [_search(logs, theta, (matrices, structured), max_iterations, floor)]
    )
    return _finish(logs, theta, matrices, structured, x0s, h, iterations, floor, current=current)


def _whitened(
    residuals: list[Array], jacobians: list[_Jacobian], root: Array, p: int
) -> Iterator[tuple[int, Array, Array]]:
    """Per log and block of its rows: the log's index, the whitened residuals (B, n) and
    Jacobian (B, n, p + logs n), every log's initial state its own columns."""
    n, count = residuals[0].shape[1], len(residuals)
    for index, (r, jacobian) in enumerate(zip(residuals, jacobians, strict=True)):
        row = 0
        for J in jacobian.blocks():
            full = np.zeros((J.shape[0], n, p + count * n))
            full[:, :, :p] = J[:, :, :p]
            full[:, :, p + index * n : p + (index + 1) * n] = J[:, :, p:]
            rows = r[row : row + J.shape[0]]
            row += J.shape[0]
            yield index, rows @ root.T, np.einsum("ij,kjl->kil", root, full)


def _normal_equations(
    residuals: list[Array], jacobians: list[_Jacobian], root: Array, p: int
) -> tuple[Array, Array]:
    """``J'J`` and ``J'r`` of the whitened output errors for (theta, x0 of every log),
    summed over groups of blocks of up to :data:`~._propagation.BLOCK_TRANSITIONS` rows
    (one product over all the logs when they are short)."""
    normal: Array | None = None
    gradient: Array | None = None
    group: list[tuple[Array, Array]] = []
    parts = _whitened(residuals, jacobians, root, p)
    for last, (_, r, J) in _marked_last(parts):
        group.append((r, J))
        if last or sum(J.shape[0] for _, J in group) >= _propagation.BLOCK_TRANSITIONS:
            J_all = np.vstack([J.reshape(-1, J.shape[2]) for _, J in group])
            r_all = np.concatenate([r.reshape(-1) for r, _ in group])
            products = J_all.T @ J_all, J_all.T @ r_all
            if normal is None or gradient is None:
                normal, gradient = products
            else:
                normal, gradient = normal + products[0], gradient + products[1]
            group = []
    assert normal is not None and gradient is not None
    return normal, gradient


def _step(equations: tuple[Array, Array], damping: float) -> Array:
    """The damped Gauss-Newton step from the normal equations ``(J'J, J'r)``."""
    normal = equations[0].copy()
    normal += damping * np.diag(np.diag(normal))
    return np.asarray(np.linalg.solve(normal, equations[1]))


def _marked_last(parts: Iterator[tuple[int, Array, Array]]) -> Iterator[tuple[bool, Any]]:
    """The parts, each with whether it is the last."""
    previous = next(parts)
    for part in parts:
        yield False, previous
        previous = part
    yield True, previous


def _robust_covariance(
    parts: Iterator[tuple[int, Array, Array]], counts: list[int]
) -> tuple[Array, Array]:
    """The parameters' covariance ``H^-1 S H^-1`` (Newey-West): ``H`` the Fisher
    information, ``S`` the long-run covariance of the per-sample scores with Bartlett
    weights. It equals ``H^-1`` for white output errors and stays honest when they are
    not (an effect the model misses, e.g. a voltage ripple): the standard errors then
    grow instead of lying. ``parts``: :func:`_whitened`'s, of logs of ``counts`` rows.
    Also returns ``H``."""
    fisher = long_run = np.zeros((0, 0))
    # per log: its lags L, the running sum of its scores at the block's start and the
    # L + 1 running sums before it (zero before the log)
    done, lags, carry, history = 0, 0, np.zeros((1, 0)), np.zeros((1, 0))
    for index, r, J in parts:
        size = J.shape[2]
        if fisher.size == 0:
            fisher, long_run = np.zeros((size, size)), np.zeros((size, size))
        if done == 0:
            lags = int(min(counts[index] // 10, 4 * counts[index] ** (1 / 3)))
            carry, history = np.zeros((1, size)), np.zeros((lags + 1, size))
        rows = J.reshape(-1, size)
        fisher += rows.T @ rows
        scores = np.matmul(r[:, np.newaxis, :], J)[:, 0, :]  # (B, size)
        done += scores.shape[0]
        if done == counts[index]:  # the log's end: padded with L zeros
            scores, done = np.vstack([scores, np.zeros((lags, size))]), 0
        # Bartlett's weights 1 - |j| / (L + 1) are a box of L + 1 samples correlated with
        # itself, so sum_j w_j sum_k s_(k+j) s_k' = W'W / (L + 1), W the scores summed
        # over every window of L + 1 samples (the log padded with zeros), the differences
        # of their running sum: one product instead of one per lag
        running = np.cumsum(np.vstack([carry, scores]), axis=0)[1:]
        extended = np.vstack([history, running])
        windows = extended[lags + 1 :] - extended[: scores.shape[0]]
        long_run += windows.T @ windows / (lags + 1)
        carry, history = running[-1:], extended[-(lags + 1) :]
    inverse = np.linalg.pinv(fisher)
    return inverse @ long_run @ inverse, fisher


def _finish(
    logs: list[_Log],
    theta: Array,
    matrices: Callable[[Array], tuple[Array, Array, Array]],
    structured: bool,
    x0s: list[Array],
    h: float,
    iterations: int,
    floor: Array,
    current: _Current | None = None,
) -> OutputErrorFit:
    """The fit at ``(theta, x0s)``; ``current``: the residuals, Jacobians and simulations
    there, if the search has them (they are computed otherwise)."""
    mats = matrices(theta)
    if current is None:
        chain = _jacobian_map(matrices, theta, structured)
        [current] = _run_searches([_residuals_and_jacobian(logs, mats, x0s, chain)])
    residuals, jacobians, simulated = current
    stacked = np.concatenate(residuals)
    noise = np.atleast_2d(np.cov(stacked.T))
    noise = noise + np.diag(np.maximum(floor**2 - np.diag(noise), 0.0))
    p = theta.shape[0]
    robust, fisher = _robust_covariance(
        _whitened(residuals, jacobians, noise_root(stacked, floor), p),
        [r.shape[0] for r in residuals],
    )
    white = np.diag(np.linalg.pinv(fisher))[:p]
    ratios = np.diag(robust)[:p] / np.maximum(white, 1e-300)
    changes = np.concatenate([log.x[1:] - log.x[:-1] for log in logs])
    model = DiscreteModel(
        Ad=mats[0],
        Bd=mats[1],
        Ed=mats[2],
        h=h,
        residual_rms=np.sqrt(np.mean(stacked**2, axis=0)),
        relative_residual=float(np.linalg.norm(stacked))
        / max(float(np.linalg.norm(changes)), 1e-300),
        condition=float(np.linalg.cond(fisher)),
        transitions=int(sum(log.a.shape[0] for log in logs)),
    )
    return OutputErrorFit(
        model=model,
        parameters=theta,
        parameter_covariance=robust[:p, :p],  # the initial states are nuisances
        noise_covariance=noise,
        simulated=tuple(simulated),
        residuals=tuple(residuals),
        iterations=iterations,
        correlation_inflation=float(np.max(ratios)) if ratios.size else 1.0,
    )


def simulated_trajectories(
    episodes: Sequence[Trajectory], shift: int, fit: OutputErrorFit
) -> list[Trajectory]:
    """The logs with their states replaced by the fit's noise-free simulation.

    The rows the fit used (those with a known applied input) hold ``xhat``; inputs,
    references and times are the logs' own, so every regression built from these
    trajectories is an instrument for the one built from the logs (same rows, same
    inputs, no measurement noise).

    Parameters
    ----------
    episodes : sequence of Trajectory
        The logs.
    shift : int
        The alignment the fit used.
    fit : OutputErrorFit
        The fitted model and its simulations.

    Returns
    -------
    list of Trajectory
    """
    result = []
    for episode, xhat in zip(episodes, fit.simulated, strict=True):
        _, first = applied_inputs(episode, shift)
        x = episode.x.copy()
        x[first : first + xhat.shape[0]] = xhat
        result.append(Trajectory(t=episode.t, x=x, u=episode.u, w=episode.w))
    return result
