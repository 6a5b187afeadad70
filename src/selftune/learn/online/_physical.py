"""A surface PMSM's parameters read off the running model, and a change in them detected.

The online model's ``vec([Ad, Bd, Ed])`` (:mod:`._model`) has 12-16 entries; a surface
PMSM at a known electrical speed has 3-4 parameters (``R_s``, ``L_s``, the back-EMF
ratio ``kappa = phi_pm / phi_assumed`` and the dead-time voltage ``v``;
:class:`~selftune.learn.SpmsmStructure`). They are the parameters whose structured model
is nearest the unstructured one, each entry weighed by its own variance (Gauss-Newton
from the last estimate), with the sandwich covariance
``(J' W J)^-1 J' W C W J (J' W J)^-1`` (``W`` the entries' inverse variances, ``C`` their
covariance). Weighing by the whole covariance's inverse would be efficient where it is
known well; from a short memory (200 samples against 12 entries) its small eigenvalues
are not: the entries' errors were within their standard errors (rms 0.7-1.0) while
their Mahalanobis distance averaged 62 against its 12.

A change (a loose connection adding resistance, a demagnetized magnet) is told from
drift by comparing two models of different memories: the fast one follows a step within
a few of its memories, the slow one lags. Each parameter's difference, in standard
errors (``sqrt`` of the sum of both variances), is a standard normal score when nothing
changed; an alarm when the largest exceeds the two-sided ``false_alarm / p`` quantile
(Bonferroni over the p parameters) is false with probability at most ``false_alarm``
per look that sees new data (looks a fast memory apart are nearly independent).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.stats

from ...core import Array
from ...errors import InputError
from ..evidence._discrete_model import DiscreteModel
from ..evidence._spmsm_structure import SpmsmStructure

__all__ = ["ChangeTest", "PhysicalEstimate", "change_test", "physical_estimate"]

#: Gauss-Newton iterations from the last estimate (the model moves little between looks).
ITERATIONS = 3

#: Relative step of the finite-difference Jacobian.
_STEP = 1e-6


@dataclass(frozen=True)
class PhysicalEstimate:
    """A surface PMSM's parameters and their covariance.

    Attributes
    ----------
    theta : ndarray, shape (3,) or (4,)
        ``[R_s (ohm), L_s (H), kappa]`` and, with dead time, ``v`` (V).
    covariance : ndarray, shape (p, p)
        Their covariance.
    """

    theta: Array
    covariance: Array

    @property
    def standard_errors(self) -> Array:
        """The parameters' standard errors, in their units."""
        return np.sqrt(np.maximum(np.diag(self.covariance), 0.0))


def physical_estimate(
    model: DiscreteModel, structure: SpmsmStructure, start: Array, iterations: int = ITERATIONS
) -> PhysicalEstimate:
    """The structure's parameters nearest the model (see the module).

    Parameters
    ----------
    model : DiscreteModel
        The online model, with its covariance.
    structure : SpmsmStructure
        The motor's structure at its speed and sampling period.
    start : ndarray
        The parameters to start from (the last estimate, or ``structure.initial``).
    iterations : int
        Gauss-Newton iterations (one from an estimate close by, as a fast model's from
        the slow one's).
    """
    if model.covariance is None:
        raise InputError("model: a covariance is needed to weigh its entries")
    target = model.parameters
    variances = np.diag(model.covariance)
    weight = np.diag(1.0 / np.maximum(variances, max(float(np.max(variances)), 1e-300) * 1e-24))
    theta = np.asarray(start, dtype=float).copy()

    def entries(parameters: Array) -> Array:
        return np.concatenate(structure(parameters), axis=1).ravel(order="F")

    for _ in range(iterations):
        value = entries(theta)
        steps = _STEP * np.maximum(np.abs(theta), 1e-6)
        J = np.column_stack(
            [(entries(theta + step * unit) - value) / step
             for step, unit in zip(steps, np.eye(theta.size), strict=True)]
        )  # fmt: skip
        normal = J.T @ weight @ J
        theta = theta + np.linalg.solve(normal, J.T @ weight @ (target - value))
    gain = np.linalg.solve(normal, J.T @ weight)  # d theta / d entries
    return PhysicalEstimate(theta, gain @ model.covariance @ gain.T)


@dataclass(frozen=True)
class ChangeTest:
    """The fast model's departure from the slow one.

    Attributes
    ----------
    scores : ndarray
        Each parameter's difference (fast less slow) in its standard errors.
    threshold : float
        The largest score's bound: the two-sided normal quantile of ``false_alarm / p``.
    changed : bool
        Whether some score's size exceeds the threshold.
    """

    scores: Array
    threshold: float
    changed: bool


def change_test(fast: PhysicalEstimate, slow: PhysicalEstimate, false_alarm: float) -> ChangeTest:
    """Whether the parameters changed (see the module).

    Parameters
    ----------
    fast, slow : PhysicalEstimate
        The short- and long-memory estimates.
    false_alarm : float
        The probability of an alarm per look when nothing changed, in (0, 1).
    """
    if not 0.0 < false_alarm < 1.0:
        raise InputError(f"false_alarm: expected a probability in (0, 1), got {false_alarm!r}")
    difference = fast.theta - slow.theta
    scores = difference / np.sqrt(np.diag(fast.covariance) + np.diag(slow.covariance))
    threshold = float(scipy.stats.norm.isf(0.5 * false_alarm / difference.size))
    return ChangeTest(scores, threshold, bool(np.max(np.abs(scores)) > threshold))
