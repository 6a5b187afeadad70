"""Certifying a controller before a running drive switches to it.

A candidate (the digital optimum of the model the recent data give) replaces the law in
force only if, on every plausible plant (the estimate, then models drawn from its
parameters' covariance, as the batch verdict draws them:
:func:`~selftune.learn.verdict._verdict.plausible_models`):

- its sampled loop is stable with the batch verdict's margin
  (:func:`~selftune.learn.verdict._quality.largest_radius`), and
- its cost is lower than the law in force's by more than the spread of that saving over
  the plausible plants: the saving ``1 - J_candidate / J_current`` of a step of the
  reference from rest (``zeta_0' P zeta_0``, :meth:`~selftune.loop.SampledLoop.step_from_rest`),
  its mean over the plants above its standard deviation. A law in force that some
  plausible plant makes unstable saves everything there.

The estimated plant is tried first: a candidate that saves less than the least worth a
switch there keeps the law in force without the sweep (most looks, once tuned).
Anything else keeps the law in force, and the certificate says why.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...core import Array, ControlLaw
from ...errors import InputError
from ...loop import LoopWeights, SampledLoop
from ..evidence._discrete_model import DiscreteModel
from ..evidence._spmsm_structure import SpmsmStructure
from ..verdict._quality import closed_loop_radii, closed_loop_radius, largest_radius
from ..verdict._verdict import plausible_models
from ._physical import PhysicalEstimate

__all__ = ["Certificate", "certify"]


@dataclass(frozen=True)
class Certificate:
    """Whether a candidate law may replace the one in force, and why.

    Attributes
    ----------
    certified : bool
        Stable with margin on every plausible plant and cheaper beyond its uncertainty.
    reason : str
        What decided it, in words.
    radii : ndarray
        The candidate's loop's spectral radii on the plausible plants (the estimate first).
    limit : float
        The largest radius accepted.
    saving : float
        The mean over the plausible plants of ``1 - J_candidate / J_current``.
    saving_spread : float
        Its standard deviation over them.
    """

    certified: bool
    reason: str
    radii: Array
    limit: float
    saving: float
    saving_spread: float


def _savings(
    loop: SampledLoop,
    models: list[DiscreteModel],
    laws: tuple[ControlLaw, ControlLaw],
    weights: LoopWeights,
    zeta0: Array,
) -> Array:
    """``1 - J_candidate / J_current`` on each model, ``J = zeta_0' P zeta_0`` (1 where the
    law in force does not stabilize it; J infinite where a law does not): both laws on
    all the models in one solve."""
    count = len(models)
    plants = [(model.Ad, model.Bd) for model in models]
    P, radii = loop.values(plants + plants, [laws[0]] * count + [laws[1]] * count, weights)
    costs = np.array([zeta0 @ value @ zeta0 if radius < 1.0 else np.inf
                      for value, radius in zip(P, radii, strict=True)])  # fmt: skip
    new, old = costs[:count], costs[count:]
    savings = np.ones(count)
    finite = np.isfinite(old)
    savings[finite] = 1.0 - new[finite] / old[finite]
    return savings


def certify(
    candidate: ControlLaw,
    current: ControlLaw,
    estimate: PhysicalEstimate,
    structure: SpmsmStructure,
    loop: SampledLoop,
    weights: tuple[Array, Array],
    w: Array,
    least_saving: float = 0.0,
) -> Certificate:
    """The certificate of ``candidate`` against ``current`` (see the module).

    Parameters
    ----------
    candidate, current : ControlLaw
        The proposed law and the law in force (the loop's delay and integrator).
    estimate : PhysicalEstimate
        The plant's parameters and their covariance.
    structure : SpmsmStructure
        The parameters' map to ``(Ad, Bd, Ed)`` (one parameter vector, or a stack).
    loop : SampledLoop
        The drive's loop: sampling period, delay, integral action and its weight.
    weights : (Q, R)
        The continuous cost's weights (the digital cost of :meth:`SampledLoop.weights`).
    w : ndarray, shape (q,)
        The reference whose step from rest the costs compare.
    least_saving : float
        The least mean saving worth a switch (a fraction of the law in force's cost):
        a switch for less only adds a transient.
    """
    Ad, Bd, Ed = structure(estimate.theta)
    nominal = DiscreteModel.given(Ad, Bd, Ed, loop.h)
    radius = closed_loop_radius(nominal, candidate, loop.input_delay)
    limit = largest_radius(radius)
    cost = loop.weights(*weights, "digital")
    zeta0 = loop.step_from_rest(candidate.X, candidate.U, w)
    first = (
        float(_savings(loop, [nominal], (candidate, current), cost, zeta0)[0])
        if radius < 1.0
        else 0.0
    )
    if radius < 1.0 and not first > least_saving:  # no sweep needed to keep the law
        reason = (
            f"the step's cost on the estimated plant changes by {-first:+.3%}, not beyond "
            f"{least_saving:.3%} (the least worth a switch): the law in force stays"
        )
        return Certificate(False, reason, np.array([radius]), limit, first, float("nan"))
    try:
        models = plausible_models(
            nominal, structure, estimate.theta, estimate.covariance, stacked=structure.stack
        )
    except InputError as failure:  # a plant the parameters' spread allows is not a motor
        reason = (
            f"the plants the estimate's standard errors allow include no motor ({failure}): "
            "the data do not pin the plant down; the law in force stays"
        )
        return Certificate(False, reason, np.array([radius]), limit, first, float("nan"))
    radii = np.concatenate([[radius], closed_loop_radii(models[1:], candidate, loop.input_delay)])
    if not np.all(radii <= limit):
        unstable = int(np.sum(~(radii <= limit)))
        reason = (
            f"not stable with margin on {unstable} of {radii.size} plausible plants "
            f"(spectral radius up to {float(np.max(radii)):.6f}, at most {limit:.6f})"
        )
        return Certificate(False, reason, radii, limit, float("nan"), float("nan"))
    swept = _savings(loop, models[1:], (candidate, current), cost, zeta0)
    savings = np.concatenate([[first], swept])
    saving, spread = float(np.mean(savings)), float(np.std(savings, ddof=1))
    certified = saving > max(spread, least_saving)
    change = "falls" if saving > 0.0 else "rises" if saving < 0.0 else "changes"
    reason = (
        f"stable with margin on all {radii.size} plausible plants; the step's cost "
        f"{change} by {abs(saving):.3%} (spread {spread:.3%})"
        + (
            ""
            if certified
            else f", not beyond its uncertainty and {least_saving:.3%} (the least worth a "
            "switch): the law in force stays"
        )
    )
    return Certificate(certified, reason, radii, limit, saving, spread)
