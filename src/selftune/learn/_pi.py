"""The PI equivalent of a learned law: the firmware's structure, as close as it comes.

A drive's firmware runs, per axis, a PI on the current error with decoupling::

    u_d = U_d w - k_p,d (i_d - i_d*) - c_dq (i_q - i_q*) - k_i,d z_d
    u_q = U_q w - k_p,q (i_q - i_q*) - c_qd (i_d - i_d*) - k_i,q z_q

i.e. a :class:`~selftune.core.ControlLaw` whose ``K`` on the currents is
``diag(k_p) + cross`` (``cross``: the off-diagonal entries, the decoupling), whose gain on
the past voltages is zero (a PI does not feed back the voltages it computed before;
the drive's delay stays in the loop), and whose ``K_i = diag(k_i)`` (each integrator
drives its own axis). :func:`pi_control_law` builds it.

**Fixed**: the feedforward ``U`` and the steady-state map ``X`` of the learned law (the
reference channels and the back-EMF feedforward stay as learned), ``C``, ``F``, h and
the delay. **Fitted**: ``k_p`` (m), the m(m-1) cross terms and ``k_i`` (m), to minimize
the cost the learned law minimizes (Q, R, Q_i; the digital cost of the sampled loop with
its delay for the digital target, the continuous cost for the continuous one) on the
plant the learner estimated (the output-error model of the data, never the true plant),
summed over a step of 1 A of current error on each axis in turn, the past voltages and
the integrators at their steady state: ``trace(P S)``, ``P`` the law's value
(:meth:`~selftune.loop.SampledLoop.value`), ``S`` the identity on the currents and zero
elsewhere (the standard criterion of a structured gain, which weighs every axis alike;
a single reference step excites one direction only and leaves the other gains free).
The fit starts from the projection of the learned law onto the structure (its ``K`` on
the currents, the diagonal of ``K_i``), halved until it stabilizes the estimated plant
if it does not, and runs L-BFGS-B on the gains scaled by the projection's size (central
differences, every point of a gradient in one solve,
:meth:`~selftune.loop.SampledLoop.values`). The excess cost is the PI's cost over the
learned law's on the same plant, minus 1 (the learned law is the optimum there, up to
what the learner left: the excess is near zero where the optimum is itself a PI, e.g.
a motor at standstill without delay).

The PI is then put to the verdict's stability test: the spectral radius of its sampled
loop (with the drive's delay) on the fitted model and on every plausible model the
learned law was judged on, against the same largest radius
(:class:`~selftune.learn.JudgedPlants`). A PI that fails it is reported as such, never
as fine.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import minimize

from ..core import Array, ControlLaw, as_matrix, as_vector, continuous_from_discrete
from ..errors import InputError, SelftuneError, UnsolvableError
from ..loop import LoopWeights, SampledLoop
from ._problem import LearningProblem
from ._result import JudgedPlants
from .verdict._quality import closed_loop_radii

__all__ = ["PIEquivalent", "pi_control_law", "pi_equivalent", "pi_equivalent_or_reason"]

#: Halvings of the projected gains tried before the fit gives up finding a stabilizing
#: start.
START_HALVINGS = 30

#: The fit's tolerance on the normalized cost and its gradient, its bound on iterations,
#: and the step of its central differences in the scaled gains.
FIT_TOLERANCE = 1e-9
FIT_ITERATIONS = 200
FIT_STEP = 1e-6


def pi_control_law(
    k_p: ArrayLike,
    cross: ArrayLike,
    X: ArrayLike,
    U: ArrayLike,
    *,
    k_i: ArrayLike | None = None,
    C: ArrayLike | None = None,
    F: ArrayLike | None = None,
    h: float | None = None,
    history: int = 0,
) -> ControlLaw:
    """The per-axis PI with decoupling as the law a drive runs (see the module docstring).

    Parameters
    ----------
    k_p : array_like, shape (m,)
        Proportional gain of each axis, V/A.
    cross : array_like, shape (m, m)
        The decoupling: the gain of each input on the other axes' current errors, V/A;
        its diagonal must be zero.
    X : array_like, shape (m, q)
        Steady-state map (the current references ``X w``).
    U : array_like, shape (m, q)
        Feedforward map.
    k_i : array_like, shape (m,), optional
        Integral gain of each axis, V/(A s) (with C, F and h).
    C, F : array_like, optional
        The regulated error ``e = C x + F w`` the integrators integrate.
    h : float, optional
        Sampling period of the integrators, s.
    history : int
        d: the law's columns for the past voltages (all zero; default none).

    Returns
    -------
    ControlLaw

    Raises
    ------
    InputError
        If the shapes do not fit, or ``cross`` has a nonzero diagonal.
    """
    gains = as_vector(k_p, "k_p")
    m = gains.shape[0]
    coupling = as_matrix(cross, "cross", (m, m))
    if np.any(np.diag(coupling) != 0.0):
        raise InputError("cross: the decoupling acts across axes; its diagonal must be zero")
    K = np.hstack([np.diag(gains) + coupling, np.zeros((m, history * m))])
    K_i = None if k_i is None else np.diag(as_vector(k_i, "k_i", m))
    return ControlLaw(K, X, U, history=history, K_i=K_i, C=C, F=F, h=h)


@dataclass(frozen=True)
class PIEquivalent:
    """The PI with decoupling closest to a learned law (see the module docstring).

    Attributes
    ----------
    law : ControlLaw
        The PI as a drive runs it (:func:`pi_control_law`; the learned law's history,
        with zero gain on the past voltages).
    k_p : ndarray, shape (m,)
        Proportional gains, V/A.
    k_i : ndarray, shape (m,), or None
        Integral gains, V/(A s); None for a learned law without integral action.
    cross : ndarray, shape (m, m)
        The decoupling gains (zero diagonal), V/A.
    cost : float
        The PI's cost on the estimated plant (``trace(P S)``).
    learned_cost : float
        The learned law's cost there.
    radii : ndarray
        The spectral radius of the PI's sampled loop on each judged plant, the fitted
        model first.
    largest_radius : float
        The largest radius the verdict accepts.
    """

    law: ControlLaw
    k_p: Array
    k_i: Array | None
    cross: Array
    cost: float
    learned_cost: float
    radii: Array
    largest_radius: float

    @property
    def excess_cost(self) -> float:
        """The PI's cost over the learned law's on the estimated plant, minus 1."""
        return self.cost / self.learned_cost - 1.0

    @property
    def unstable(self) -> int:
        """The judged plants on which the PI's loop exceeds :attr:`largest_radius`."""
        return int(np.sum(self.radii > self.largest_radius))

    @property
    def stable(self) -> bool:
        """Whether the PI passes the verdict's stability test on every judged plant."""
        return self.unstable == 0

    def document(self) -> dict[str, object]:
        """The PI for a JSON document."""
        return {
            "k_p": self.k_p,
            "k_i": self.k_i,
            "cross": self.cross,
            "excess_cost": self.excess_cost,
            "cost": self.cost,
            "learned_cost": self.learned_cost,
            "stable": self.stable,
            "spectral_radius": float(self.radii[0]),
            "largest_plausible_radius": float(np.max(self.radii)),
            "largest_radius": self.largest_radius,
            "plausible_models": int(self.radii.size),
            "unstable_models": self.unstable,
            "control_law": self.law.document(),
        }

    def lines(self, inputs: list[str], states: list[str]) -> list[str]:
        """The PI as report lines.

        Parameters
        ----------
        inputs : list of str
            Names of the inputs (one per axis).
        states : list of str
            Names of the currents, in the same order.
        """
        text = [
            "PI equivalent (per-axis PI with decoupling, fitted to the learned law's cost on "
            "the estimated plant; U and X kept, no feedback of past voltages):",
            f"  k_p (V/A): {_listed(inputs, self.k_p)}",
        ]
        if self.k_i is not None:
            text.append(f"  k_i (V/(A s)): {_listed(inputs, self.k_i)}")
        couplings = [
            f"{inputs[row]} on {states[column]} {self.cross[row, column]:.6g}"
            for row in range(self.cross.shape[0])
            for column in range(self.cross.shape[1])
            if row != column
        ]
        text.append("  cross (V/A, u = ... - cross e): " + ", ".join(couplings))
        size = self.radii.size
        if self.stable:
            verdict = (
                f"stable on the estimated plant and {size - 1} plausible ones (spectral "
                f"radius up to {float(np.max(self.radii)):.6f})"
            )
        else:
            verdict = (
                f"NOT STABLE with margin on {self.unstable} of {size} plausible plants "
                f"(spectral radius up to {float(np.max(self.radii)):.6f}, limit "
                f"{self.largest_radius:.6f}): do not run it"
            )
        text.append(f"  excess cost over the learned law {self.excess_cost:+.2%}; {verdict}")
        return text


def pi_equivalent(
    law: ControlLaw,
    problem: LearningProblem,
    judged: JudgedPlants,
    target: Literal["continuous", "digital"] = "digital",
) -> PIEquivalent:
    """The PI with decoupling that comes closest to ``law`` (see the module docstring).

    Parameters
    ----------
    law : ControlLaw
        The learned law (one state per input: the currents; with integral action one
        integrator per input).
    problem : LearningProblem
        The cost the law minimizes (Q, R and the integral weight).
    judged : JudgedPlants
        The estimated plants (:attr:`selftune.learn.LearnedController.judged`).
    target : {"continuous", "digital"}
        The cost the law minimizes: the continuous one, or the digital cost of the
        sampled loop with the delay.

    Returns
    -------
    PIEquivalent

    Raises
    ------
    InputError
        If the law has no reference, not one current per input, or (with integral
        action) not one integrator per input.
    UnsolvableError
        If no scaling of the projected gains stabilizes the estimated plant.
    """
    n, m, r = law.n, law.m, law.r
    if law.q == 0 or n != m or r not in (0, m):
        raise InputError(
            "law: a PI equivalent needs a reference (a [regulation] table), one state per "
            f"input and one integrator per input or none; this law has n = {n}, m = {m}, "
            f"r = {r}, q = {law.q}"
        )
    model = judged.models[0]
    delay = judged.input_delay if target == "digital" else 0
    if target == "digital":
        loop, plant = problem.loop(model.h, delay), (model.Ad, model.Bd)
    else:
        A, B, _ = continuous_from_discrete(model.Ad, model.Bd, model.h)
        loop, plant = problem.loop(0.0, 0), (A, B)
    weights = loop.weights(problem.Q, problem.R, "digital")
    S = np.zeros((loop.size(n, m),) * 2)
    S[:n, :n] = np.eye(n)

    def build(theta: Array) -> ControlLaw:
        return pi_control_law(
            theta[:m], _cross(theta[m : m * m], m), law.X, law.U,
            k_i=None if r == 0 else theta[m * m :], C=law.C, F=law.F, h=law.h,
            history=law.history,
        )  # fmt: skip

    def cost(candidate: ControlLaw) -> float:
        return _cost(loop, plant, candidate, weights, S)

    learned_cost = cost(law)
    if not np.isfinite(learned_cost):
        raise UnsolvableError("law: does not stabilize the estimated plant; no PI is fitted")
    start = _projection(law)
    for _ in range(START_HALVINGS):
        if np.isfinite(cost(build(start))):
            break
        start = 0.5 * start
    else:
        raise UnsolvableError(
            "PI: no scaling of the learned law's PI gains stabilizes the estimated plant"
        )
    scale = _scales(start, m, r)

    def costs(points: Array) -> Array:
        """The normalized cost at each row of scaled gains (a sampled loop's in one
        solve)."""
        laws = [build(start + scale * point) for point in points]
        if loop.continuous:
            return np.array([cost(each) for each in laws]) / learned_cost
        values, radii = loop.values([plant] * len(laws), laws, weights)
        totals = np.einsum("kij,ij->k", values, S) / learned_cost
        return np.where((radii < 1.0) & np.isfinite(totals), totals, np.inf)

    def objective(p: Array) -> tuple[float, Array]:
        """The cost and its gradient (central differences, one solve)."""
        steps = FIT_STEP * np.eye(p.size)
        values = costs(np.vstack([p, p + steps, p - steps]))
        if not np.all(np.isfinite(values)):
            return float(values[0]), np.zeros(p.size)
        return float(values[0]), (values[1 : p.size + 1] - values[p.size + 1 :]) / (2 * FIT_STEP)

    fitted = minimize(
        objective, np.zeros(start.size), jac=True, method="L-BFGS-B",
        options={"ftol": FIT_TOLERANCE, "gtol": FIT_TOLERANCE, "maxiter": FIT_ITERATIONS},
    )  # fmt: skip
    candidates = np.vstack([np.zeros(start.size), np.asarray(fitted.x, dtype=float)])
    best = start + scale * candidates[int(np.argmin(costs(candidates)))]
    pi = build(best)
    radii = closed_loop_radii(judged.models, pi, judged.input_delay)
    return PIEquivalent(
        law=pi,
        k_p=best[:m].copy(),
        k_i=None if r == 0 else best[m * m :].copy(),
        cross=_cross(best[m : m * m], m),
        cost=cost(pi),
        learned_cost=learned_cost,
        radii=radii,
        largest_radius=judged.largest_radius,
    )


def pi_equivalent_or_reason(
    law: ControlLaw,
    problem: LearningProblem,
    judged: JudgedPlants | None,
    target: Literal["continuous", "digital"] = "digital",
) -> tuple[PIEquivalent | None, str]:
    """:func:`pi_equivalent`, or None and why there is none (for a report).

    Parameters
    ----------
    law, problem, judged, target
        As :func:`pi_equivalent`; ``judged`` None: a result without a verdict's plants.

    Returns
    -------
    (PIEquivalent or None, str)
        The PI and ``""``, or None and the reason.
    """
    if judged is None:
        return None, "the result carries no estimated plant"
    try:
        return pi_equivalent(law, problem, judged, target), ""
    except SelftuneError as exc:
        return None, str(exc)


def _listed(names: list[str], values: Array) -> str:
    """``"u1 21.2, u2 20.9"``."""
    return ", ".join(f"{name} {value:.6g}" for name, value in zip(names, values, strict=True))


def _cross(values: Array, m: int) -> Array:
    """The m x m decoupling matrix of its m(m-1) off-diagonal entries (row by row)."""
    matrix = np.zeros((m, m))
    matrix[~np.eye(m, dtype=bool)] = values
    return matrix


def _projection(law: ControlLaw) -> Array:
    """The learned law's gains in the PI's structure: ``[k_p; cross; k_i]``."""
    K_x = law.K_x
    off = ~np.eye(law.m, dtype=bool)
    parts = [np.diag(K_x), K_x[off]]
    if law.K_i is not None:
        parts.append(np.diag(law.K_i))
    return np.concatenate(parts).astype(float)


def _scales(start: Array, m: int, r: int) -> Array:
    """The size of each parameter's block (the proportional and cross terms share one)."""
    proportional = float(np.max(np.abs(start[: m * m]), initial=0.0)) or 1.0
    scales = np.full(start.size, proportional)
    if r:
        scales[m * m :] = float(np.max(np.abs(start[m * m :]), initial=0.0)) or proportional
    return scales


def _cost(
    loop: SampledLoop,
    plant: tuple[Array, Array],
    law: ControlLaw,
    weights: LoopWeights,
    S: Array,
) -> float:
    """``trace(P S)`` of ``law`` on the loop; inf where it does not stabilize it."""
    try:
        value = loop.value(plant, law, weights)
    except UnsolvableError:
        return float("inf")
    total = float(np.sum(value * S))
    return total if np.isfinite(total) else float("inf")
