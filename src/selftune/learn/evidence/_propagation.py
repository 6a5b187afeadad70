"""The output-error model's simulations and sensitivities, of one search or several at once.

The output-error fit (:mod:`._output_error`) needs, at each point it tries, the logs'
simulations from the logged inputs and the simulations' sensitivities to the parameters
and the initial states: linear recursions propagated by
:func:`selftune.core._propagate.propagate_uniform`. Its search is a generator of those
requests (:class:`_Request`), so that several searches (the refits of a bootstrap) run
side by side, each of their steps one propagation with a plant per search
(:func:`_run_searches`); one search alone propagates with its plant's map shared, one
BLAS product a step.
"""

from __future__ import annotations

from collections.abc import Generator, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...core import Array
from ...core._propagate import plant_last, propagate_uniform

__all__ = ["BLOCK_TRANSITIONS", "sensitivity_blocks", "simulate_model"]


@dataclass(frozen=True)
class _Log:
    """One log's aligned data: measured states ``x~_first .. x~_(last+1)``, the applied
    inputs and held references of the transitions."""

    x: Array
    a: Array
    w: Array

    def one_step_residuals(self, matrices: tuple[Array, Array, Array]) -> Array:
        """``x~_(k+1) - Ad x~_k - Bd a_k - Ed w_k`` (T, n): what the model does not predict
        of each next measured state from the measured one (``Ed``'s columns: ``w``'s
        first ones, which may be all of them)."""
        Ad, Bd, Ed = matrices
        q = Ed.shape[1]
        return self.x[1:] - self.x[:-1] @ Ad.T - self.a @ Bd.T - self.w[:, :q] @ Ed.T


def simulate_model(matrices: tuple[Array, Array, Array], x0: Array, a: Array, w: Array) -> Array:
    """``xhat`` (T + 1, n) of ``xhat_(k+1) = Ad xhat_k + Bd a_k + Ed w_k`` from ``x0``.

    Parameters
    ----------
    matrices : (Ad, Bd, Ed)
        The discrete model.
    x0 : ndarray, shape (n,)
        Initial state.
    a : ndarray, shape (T, m)
        Applied inputs.
    w : ndarray, shape (T, q)
        Held references.
    """
    return _simulations([(matrices, x0, _Log(x=x0[np.newaxis], a=a, w=w))])[0]


def _transition(models: Sequence[tuple[Array, Array, Array]], columns: int) -> Array:
    """The one-step map (plants last) of ``columns`` propagated columns per model: shared
    by all (one BLAS product a step) when there is one model."""
    if len(models) == 1:
        return plant_last(models[0][0][np.newaxis])
    return plant_last(np.repeat(np.stack([Ad for Ad, _, _ in models]), columns, axis=0))


def _simulations(plants: Sequence[tuple[tuple[Array, Array, Array], Array, _Log]]) -> list[Array]:
    """:func:`simulate_model` of several models, initial states and logs of one length at
    once (propagated together, one plant each): ``xhat`` (T + 1, n) of each."""
    models = [mats for mats, _, _ in plants]
    forcing = np.stack([log.a @ Bd.T + log.w @ Ed.T for (_, Bd, Ed), _, log in plants], axis=2)
    x0 = np.stack([x0 for _, x0, _ in plants], axis=1)
    x = propagate_uniform(_transition(models, 1), forcing, x0)
    return [np.asarray(x[:, :, index]) for index in range(len(plants))]


def _sensitivities(
    plants: Sequence[tuple[tuple[Array, Array, Array], _Log, Array]],
    start: Array | None = None,
) -> list[Array]:
    """``d xhat_k / d vec([Ad, Bd, Ed])`` and ``d xhat_k / d x0`` (T + 1, n, p + n) of
    several models, logs of one length and their simulations ``xhat``, propagated
    together; ``start``: their first row (n, p + n) when the log is the later part of a
    longer one (default: zero and the identity)."""
    n = plants[0][0][0].shape[0]
    size = n + plants[0][1].a.shape[1] + plants[0][1].w.shape[1]
    columns = n * size + n
    # d(Ad x + Bd a + Ed w)/d vec(M)[j n + i] = e_i v_j, v = [xhat, a, w]: forcing (T, n,
    # n size), and none for the initial state's n columns, which start at the identity
    # instead of zero; all propagated together (the columns are independent: the same
    # numbers as apart)
    forcing = np.zeros((plants[0][1].a.shape[0], n, len(plants) * columns))
    first_rows = np.zeros((n, len(plants) * columns))
    for index, (_, log, xhat) in enumerate(plants):
        v = np.hstack([xhat[:-1], log.a, log.w])  # (T, n + m + q)
        first = index * columns
        for i in range(n):
            forcing[:, i, first + i : first + n * size : n] = v
        if start is None:
            first_rows[:, first + n * size : first + columns] = np.eye(n)
        else:
            first_rows[:, first : first + columns] = start
    models = [mats for mats, _, _ in plants]
    S = propagate_uniform(_transition(models, columns), forcing, first_rows)
    return [S[:, :, index * columns : (index + 1) * columns] for index in range(len(plants))]


#: The most transitions of a log whose sensitivities are held whole; a longer log's are
#: made and used block by block, again at each use (held, they take 8 n (p + n) bytes a
#: sample: 290 MB on a 1,000,000-row log of two currents with the dead-time channels).
BLOCK_TRANSITIONS = 2**16


def sensitivity_blocks(mats: tuple[Array, Array, Array], log: _Log, xhat: Array) -> Iterator[Array]:
    """The rows of one log's :func:`_sensitivities`, in consecutive blocks of at most
    :data:`BLOCK_TRANSITIONS` transitions (each block's recursion starts where the last
    one ended; one block is the whole).

    Parameters
    ----------
    mats : (Ad, Bd, Ed)
        The model.
    log : _Log
        The log.
    xhat : ndarray, shape (T + 1, n)
        The model's simulation of it.
    """
    count = log.a.shape[0]
    start = None
    for first in range(0, max(count, 1), BLOCK_TRANSITIONS):
        last = min(first + BLOCK_TRANSITIONS, count)
        part = _Log(x=log.x[first : last + 1], a=log.a[first:last], w=log.w[first:last])
        [S] = _sensitivities([(mats, part, xhat[first : last + 1])], start)
        if last == count:
            yield S
        else:
            start = S[-1]
            yield S[:-1]


@dataclass(frozen=True)
class _Jacobian:
    """One log's Jacobian of its simulation to ``(theta, x0)`` at a point, (T + 1, n,
    p + n): held whole, or (a log longer than :data:`BLOCK_TRANSITIONS`)
    made again, block by block, at each use."""

    held: Array | None
    point: tuple[tuple[Array, Array, Array], _Log, Array]  # (mats, log, xhat)
    chain: Array | None

    def blocks(self) -> Iterator[Array]:
        """Its rows, in consecutive blocks."""
        if self.held is not None:
            yield self.held
            return
        for S in sensitivity_blocks(*self.point):
            yield _chained(S, self.chain)


def _chained(S: Array, chain: Array | None) -> Array:
    """The Jacobian from the sensitivities ``S`` to ``(vec([Ad, Bd, Ed]), x0)``: the
    parameters' columns through ``chain`` (a structure's), the initial state's as they are."""
    n = S.shape[1]
    theta_part, x0_part = S[:, :, :-n], S[:, :, -n:]
    if chain is not None:
        theta_part = theta_part @ chain
    return np.concatenate([theta_part, x0_part], axis=2)


@dataclass(frozen=True)
class _Request:
    """What a search asks for: the simulations of ``logs`` by ``mats`` from the initial
    states ``given`` (``sensitivities`` false), or their sensitivities along the
    simulations ``given``; the answer is one array per log."""

    mats: tuple[Array, Array, Array]
    logs: list[_Log]
    given: list[Array]
    sensitivities: bool


def _answers(requests: Sequence[_Request]) -> list[list[Array]]:
    """The answers to the requests of several searches: requests of one kind whose logs
    have the same lengths are propagated together, one plant each."""
    answers: list[list[Array]] = [[] for _ in requests]
    groups: dict[tuple[bool, tuple[int, ...]], list[int]] = {}
    for index, request in enumerate(requests):
        key = (request.sensitivities, tuple(log.a.shape[0] for log in request.logs))
        groups.setdefault(key, []).append(index)
    for (sensitivities, lengths), members in groups.items():
        for which in range(len(lengths)):  # the logs, one at a time
            group = [requests[index] for index in members]
            # a trial step of a search may give an unstable model whose simulation
            # overflows: its cost is then infinite and the step refused
            # (_output_error._weighted), an expected event, not a numerical warning for the
            # caller (a command takes any warning as a failure: core._numerics)
            with np.errstate(over="ignore", invalid="ignore"):
                if sensitivities:
                    results = _sensitivities(
                        [(r.mats, r.logs[which], r.given[which]) for r in group]
                    )
                else:
                    results = _simulations([(r.mats, r.given[which], r.logs[which]) for r in group])
            for index, result in zip(members, results, strict=True):
                answers[index].append(result)
    return answers


def _run_searches(searches: Sequence[Generator[_Request, list[Array], Any]]) -> list[Any]:
    """Run searches side by side to their ends, answering the requests of all of them at
    once (:func:`_answers`); their return values."""
    results: list[Any] = [None] * len(searches)
    pending: dict[int, _Request] = {}
    for index, search in enumerate(searches):
        try:
            pending[index] = next(search)
        except StopIteration as stop:
            results[index] = stop.value
    while pending:
        order = list(pending)
        answers = _answers([pending[index] for index in order])
        for index, answer in zip(order, answers, strict=True):
            try:
                pending[index] = searches[index].send(answer)
            except StopIteration as stop:
                results[index] = stop.value
                del pending[index]
    return results
