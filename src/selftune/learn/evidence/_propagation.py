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

from collections.abc import Generator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...core import Array
from ...core._propagate import plant_last, propagate_uniform

__all__ = ["simulate_model"]


@dataclass(frozen=True)
class _Log:
    """One log's aligned data: measured states ``x~_first .. x~_(last+1)``, the applied
    inputs and held references of the transitions."""

    x: Array
    a: Array
    w: Array


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


def _sensitivities(plants: Sequence[tuple[tuple[Array, Array, Array], _Log, Array]]) -> list[Array]:
    """``d xhat_k / d vec([Ad, Bd, Ed])`` and ``d xhat_k / d x0`` (T + 1, n, p + n) of
    several models, logs of one length and their simulations ``xhat``, propagated
    together."""
    n = plants[0][0][0].shape[0]
    size = n + plants[0][1].a.shape[1] + plants[0][1].w.shape[1]
    columns = n * size + n
    # d(Ad x + Bd a + Ed w)/d vec(M)[j n + i] = e_i v_j, v = [xhat, a, w]: forcing (T, n,
    # n size), and none for the initial state's n columns, which start at the identity
    # instead of zero; all propagated together (the columns are independent: the same
    # numbers as apart)
    forcing = np.zeros((plants[0][1].a.shape[0], n, len(plants) * columns))
    start = np.zeros((n, len(plants) * columns))
    for index, (_, log, xhat) in enumerate(plants):
        v = np.hstack([xhat[:-1], log.a, log.w])  # (T, n + m + q)
        first = index * columns
        for i in range(n):
            forcing[:, i, first + i : first + n * size : n] = v
        start[:, first + n * size : first + columns] = np.eye(n)
    models = [mats for mats, _, _ in plants]
    S = propagate_uniform(_transition(models, columns), forcing, start)
    return [S[:, :, index * columns : (index + 1) * columns] for index in range(len(plants))]


@dataclass(frozen=True)
class _Request:
    """What a search asks for: the logs' simulations of ``mats`` from the initial states
    ``given`` (``sensitivities`` false), or the sensitivities along the simulations
    ``given``; the answer is one array per log."""

    mats: tuple[Array, Array, Array]
    given: list[Array]
    sensitivities: bool


def _answers(requests: Sequence[tuple[_Request, list[_Log]]]) -> list[list[Array]]:
    """The answers to the requests of several searches (each with its logs): requests of
    one kind whose logs have the same lengths are propagated together, one plant each."""
    answers: list[list[Array]] = [[] for _ in requests]
    groups: dict[tuple[bool, tuple[int, ...]], list[int]] = {}
    for index, (request, logs) in enumerate(requests):
        key = (request.sensitivities, tuple(log.a.shape[0] for log in logs))
        groups.setdefault(key, []).append(index)
    for (sensitivities, lengths), members in groups.items():
        for which in range(len(lengths)):  # the logs, one at a time
            if sensitivities:
                results = _sensitivities(
                    [(requests[k][0].mats, requests[k][1][which], requests[k][0].given[which])
                     for k in members]
                )  # fmt: skip
            else:
                results = _simulations(
                    [(requests[k][0].mats, requests[k][0].given[which], requests[k][1][which])
                     for k in members]
                )  # fmt: skip
            for k, result in zip(members, results, strict=True):
                answers[k].append(result)
    return answers


def _run_searches(
    searches: Sequence[tuple[Generator[_Request, list[Array], Any], list[_Log]]],
) -> list[Any]:
    """Run searches (each with its logs) side by side to their ends, answering the
    requests of all of them at once (:func:`_answers`); their return values."""
    results: list[Any] = [None] * len(searches)
    pending: dict[int, _Request] = {}
    for index, (search, _) in enumerate(searches):
        try:
            pending[index] = next(search)
        except StopIteration as stop:
            results[index] = stop.value
    while pending:
        order = list(pending)
        answers = _answers([(pending[index], searches[index][1]) for index in order])
        for index, answer in zip(order, answers, strict=True):
            try:
                pending[index] = searches[index][0].send(answer)
            except StopIteration as stop:
                results[index] = stop.value
                del pending[index]
    return results
