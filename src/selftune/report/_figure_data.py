"""The numbers of the reproduction's figures, from a :class:`~selftune.report.Reproduction`.

Evaluation only, no plotting (:mod:`._figures` draws): nothing here learns; every number
is read from the typed results or obtained by evaluating a learned controller on the
true motor (PAPER_NOTES.md section 1):

- :func:`torque_steps`: the torque step from rest under every controller, the LQR, the
  initial one and each algorithm's (Algorithm 3 acting on its identified flux);
- :func:`steady_torque_offset`: the steady torque error of ``u = -K(x - X w) + U w`` on
  the true motor, N m, in closed form;
- :func:`iteration_series`: per iteration of an algorithm, the parameter error, the
  learned and the true value of its feedback, and the steady torque error of the
  controller it applied.

Names: ``w_true = [p speed phi_pm, T*]`` is the motor's ``w``; a controller's ``w`` may
carry an identified flux instead. ``x_bar0 = -X* w_true`` is the start of every cost,
the motor at rest measured from the true operating point.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..core import Array
from ..learn import Trajectory
from ._evaluate import closed_loop_response, feedback_value, steady_state

if TYPE_CHECKING:
    from ._reproduce import Reproduction

__all__ = [
    "ALGORITHM_KEYS",
    "CONTROLLERS",
    "LABELS",
    "IterationSeries",
    "algorithm_label",
    "coincidence_note",
    "iteration_series",
    "largest_mismatch",
    "offset_text",
    "optimal_value",
    "steady_torque_offset",
    "torque_steps",
    "weight_text",
]

#: The algorithms of the iteration figures, in drawing order.
ALGORITHM_KEYS: tuple[str, ...] = ("1", "2", "3", "offpolicy")

#: Every controller of the torque-step figures, in drawing order (the optimum first,
#: so that the others are drawn over it).
CONTROLLERS: tuple[str, ...] = ("lqr", "initial", *ALGORITHM_KEYS)

#: Each controller's name in the legends.
LABELS: dict[str, str] = {
    "lqr": "LQR (model-based optimum)",
    "initial": "initial (K0, U = 0)",
    "1": "Alg. 1",
    "2": "Alg. 2",
    "3": "Alg. 3",
    "offpolicy": "off-policy",
}

#: A curve within this fraction of the LQR's range from the LQR's is said to coincide.
COINCIDE = 1e-3


def torque_steps(reproduction: Reproduction) -> dict[str, Trajectory]:
    """The torque step from rest under every controller of :data:`CONTROLLERS`.

    The reproduction's own responses (:func:`~selftune.report.reproduce` simulates every
    controller's) are used; one it lacks is simulated on the true motor for as long,
    with the controller's own ``w`` (:meth:`Reproduction.controller`).

    Parameters
    ----------
    reproduction : Reproduction
        What :func:`~selftune.report.reproduce` computed.
    """
    responses = dict(reproduction.responses)
    duration = max(response.duration for response in responses.values())
    for name in CONTROLLERS:
        if name not in responses:
            K, X, U, w = reproduction.controller(name)
            responses[name] = closed_loop_response(
                reproduction.motor, reproduction.settings, K, X, U, w, duration
            )
    return {name: responses[name] for name in CONTROLLERS if name in responses}


def steady_torque_offset(
    reproduction: Reproduction, K: Array, X: Array, U: Array, w: Array
) -> float:
    """Steady torque minus ``T*`` of ``u = -K (x - X w) + U w`` on the true motor, N m.

    The steady state solves ``0 = (A - B K) x + B (U + K X) w + D w_true``; the torque is
    ``1.5 p phi_pm i_q`` with the true flux.

    Parameters
    ----------
    reproduction : Reproduction
        The motor and the operating point.
    K : ndarray, shape (2, 2)
        Feedback gain, V/A.
    X, U : ndarray, shape (2, 2)
        Steady-state map and feedforward of the controller.
    w : ndarray, shape (2,)
        The controller's ``w``.

    Returns
    -------
    float
        The offset, N m; NaN if ``A - B K`` is not Hurwitz (no steady state).
    """
    steady = steady_state(reproduction.motor, reproduction.settings, K, X, U, w)
    if steady is None:
        return float("nan")
    return float(reproduction.motor.torque(steady[1])) - reproduction.settings.torque


def _feedback_value(reproduction: Reproduction, K: Array) -> float:
    """``x_bar0' P_K x_bar0``, the true value of ``u - U* w = -K (x - X* w)`` from rest."""
    return feedback_value(reproduction.motor, reproduction.settings, K)


def optimal_value(reproduction: Reproduction) -> float:
    """``x_bar0' P* x_bar0``: the optimum's cost (5) of the torque step from rest.

    Parameters
    ----------
    reproduction : Reproduction
        What :func:`~selftune.report.reproduce` computed.
    """
    return feedback_value(reproduction.motor, reproduction.settings, reproduction.optimum.K)


@dataclass(frozen=True)
class IterationSeries:
    """One algorithm's iterations, one entry per iteration (numbered from 1).

    Attributes
    ----------
    iteration : ndarray of int
        Iteration numbers, 1-based.
    theta_error : ndarray
        ``||Theta_j - Theta*|| / ||Theta*||`` at the end of the iteration (after its
        feedforward step, where it has one); dimensionless, NaN where not comparable.
    learned_value : ndarray
        ``x_bar(0)' P_j x_bar(0)``: the learned cost-to-go of the feedback ``K_j``
        applied in the iteration (:attr:`TuningEvaluation.learned_cost`), V^2 s.
    true_value : ndarray
        ``x_bar0' P_{K_j} x_bar0``: the true value of that feedback on the true motor,
        with the true feedforward, from rest; what ``P_j`` estimates, V^2 s.
    torque_offset : ndarray
        Steady torque error of the controller ``(K_j, U_j)`` applied in the iteration,
        on the true motor, N m (:func:`steady_torque_offset`).
    """

    iteration: Array
    theta_error: Array
    learned_value: Array
    true_value: Array
    torque_offset: Array


def _per_iteration(values: list[float] | Array, iterations: list[int], pick: str) -> Array:
    """One value per iteration: the ``"last"`` or ``"first"`` record of each."""
    chosen: dict[int, float] = {}
    for iteration, value in zip(iterations, values, strict=True):
        if pick == "last" or iteration not in chosen:
            chosen[iteration] = float(value)
    return np.array([chosen[key] for key in sorted(chosen)])


def iteration_series(reproduction: Reproduction, key: str) -> IterationSeries:
    """The per-iteration numbers of the algorithm ``key`` (:data:`ALGORITHM_KEYS`).

    The theta error is that at the end of each iteration; the value and the torque
    error are those of the controller applied during it (its first record). Records of
    a step with other unknowns (a no-load step) give NaN and are not drawn.

    Parameters
    ----------
    reproduction : Reproduction
        What :func:`~selftune.report.reproduce` computed.
    key : str
        The algorithm.
    """
    result, evaluation = reproduction.results[key], reproduction.evaluations[key]
    history = result.history
    iterations = [item.iteration for item in history]
    norm = float(np.linalg.norm(reproduction.optimum.theta))
    applied = [item.step != "no-load" for item in history]
    true_value = [
        _feedback_value(reproduction, item.K_applied) if use else float("nan")
        for item, use in zip(history, applied, strict=True)
    ]
    torque_offset = [
        steady_torque_offset(reproduction, item.K_applied, result.X, item.U_applied, result.w)
        if use
        else float("nan")
        for item, use in zip(history, applied, strict=True)
    ]
    return IterationSeries(
        iteration=np.array(sorted(set(iterations))) + 1,
        theta_error=_per_iteration(evaluation.theta_error / norm, iterations, "last"),
        learned_value=_per_iteration(evaluation.learned_cost, iterations, "first"),
        true_value=_per_iteration(true_value, iterations, "first"),
        torque_offset=_per_iteration(torque_offset, iterations, "first"),
    )


def largest_mismatch(reproduction: Reproduction) -> float:
    """The largest ``|learned - true| / true`` of the iterations' values (finite ones).

    Parameters
    ----------
    reproduction : Reproduction
        What :func:`~selftune.report.reproduce` computed.
    """
    worst = 0.0
    for key in ALGORITHM_KEYS:
        series = iteration_series(reproduction, key)
        finite = np.isfinite(series.learned_value) & np.isfinite(series.true_value)
        if np.any(finite):
            ratio = np.abs(series.learned_value - series.true_value)[finite]
            worst = max(worst, float(np.max(ratio / series.true_value[finite])))
    return worst


# -- texts of the legends and captions ------------------------------------------------


def coincidence_note(signals: dict[str, Array], unit: str) -> str:
    """Which curves coincide with the LQR's, and how closely (a caption sentence).

    Parameters
    ----------
    signals : dict of str to ndarray
        One signal per controller, ``"lqr"`` among them, on the same samples.
    unit : str
        The signals' unit.
    """
    reference = signals["lqr"]
    span = float(np.ptp(reference)) or 1.0
    distance = {
        name: float(np.max(np.abs(values - reference)))
        for name, values in signals.items()
        if name != "lqr"
    }
    close = {name: value for name, value in distance.items() if value < COINCIDE * span}
    if not close:
        return "No curve coincides with the LQR's (wide green band)."
    names = ", ".join(LABELS[name] for name in close)
    return (
        f"{names}: within {max(close.values()):.1e} {unit} of the LQR (wide green band), so "
        "on it; their dashes alternate and their markers are staggered."
    )


def offset_text(value: float) -> str:
    """A steady torque error for a legend, N m (``0`` below the printed digits).

    Parameters
    ----------
    value : float
        The error, N m (NaN: no steady state).
    """
    if not np.isfinite(value):
        return "none (unstable)"
    return "0" if abs(value) < 5e-4 else f"{value:+.3f}"


def algorithm_label(reproduction: Reproduction, key: str) -> str:
    """An algorithm's legend entry, with what distinguishes it.

    Parameters
    ----------
    reproduction : Reproduction
        What :func:`~selftune.report.reproduce` computed.
    key : str
        The algorithm.
    """
    result = reproduction.results[key]
    label = LABELS[key]
    if result.rank < result.unknowns and not result.feedforward_learned:
        return f"{label} (rank {result.rank} of {result.unknowns}: U not learned)"
    if "phi_pm" in result.identified:
        flux = result.identified["phi_pm"]
        return f"{label} (after identifying $\\varphi_\\mathrm{{pm}}$ = {flux:.5f} Wb)"
    if key == "offpolicy":
        return f"{label} (one batch of {result.data_seconds * 1e3:g} ms of motor data)"
    return label


def weight_text(matrix: Array) -> str:
    """``I`` or ``1000 I`` for a multiple of the identity, else ``diag(..)``.

    Parameters
    ----------
    matrix : ndarray
        A square weight.
    """
    diagonal = np.diag(matrix)
    if np.allclose(matrix, diagonal[0] * np.eye(matrix.shape[0])):
        return "I" if diagonal[0] == 1.0 else f"{diagonal[0]:g} I"
    return "diag(" + ", ".join(f"{value:g}" for value in diagonal) + ")"
