"""What every learner returns: one type for a controller learned from data."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal

from ..core import Array, ControlLaw, WithLaw, pack_theta
from .learners._policy_iteration import IterationRecord, PolicyIterationFacts
from .learners._regression import RegressionSolution

if TYPE_CHECKING:
    from .evidence._alignment import Alignment
    from .evidence._discrete_model import DiscreteModel
    from .evidence._evidence import Evidence
    from .verdict._quality import Quality

__all__ = ["DiscountStage", "Formulation", "JudgedPlants", "LearnedController"]

#: How a continuous-time regulator learner met the regulator equations: with the unique X
#: of ``C X + F = 0`` in one regression family (``"customized"``, the paper's), or with
#: a basis of its solutions and the Sylvester map (``"general"``, Gao & Jiang 2016).
Formulation = Literal["customized", "general"]


@dataclass(frozen=True)
class DiscountStage:
    """Policy iteration at one discount of the continuous servo learner's schedule.

    Attributes
    ----------
    discount : float
        ``gamma``, 1/s (0: undiscounted).
    K : ndarray, shape (m, n + r)
        The converged policy ``K_(j+1)`` over ``xi = [xbar; z]``.
    P : ndarray, shape (n + r, n + r)
        The value at this discount of the last policy evaluated.
    iterations : int
        Policy-iteration steps at this discount.
    rate : float
        ``mu``, the smallest eigenvalue of ``P^-1 W`` (:mod:`selftune.learn.learners._servo`), 1/s:
        the discount may fall by less than this with ``K`` still stabilizing.
    """

    discount: float
    K: Array
    P: Array
    iterations: int
    rate: float


@dataclass(frozen=True)
class JudgedPlants:
    """The sampled plants a verdict judged a law on, and what it asked of the law there.

    Attributes
    ----------
    models : tuple of DiscreteModel
        The model fitted to the data first, then the plausible models drawn from its
        parameters' uncertainty (one model alone where no output-error fit exists).
    input_delay : int
        d, the drive's computation delay the loops were closed with, samples.
    largest_radius : float
        The largest spectral radius the verdict accepts on every one of them
        (:func:`~selftune.learn.verdict._quality.largest_radius`).
    """

    models: tuple[DiscreteModel, ...]
    input_delay: int
    largest_radius: float


@dataclass(frozen=True)
class LearnedController(WithLaw, PolicyIterationFacts):
    """A controller learned from data: what it is, how it was learned, how good it is.

    Every learner returns one: the pipeline :func:`~selftune.learn.learn_controller` (with
    its :class:`~selftune.learn.Quality`), and the learners it runs, used alone
    (:func:`~selftune.learn.learn_lqr`, :func:`~selftune.learn.learn_regulator`,
    :func:`~selftune.learn.learn_servo`, :func:`~selftune.learn.learn_digital_adp`),
    which give no verdict (``quality`` None). ``K``, ``X``, ``U``, ``K_i`` and ``state``
    read off :attr:`law`; ``iterations``, ``rank``, ``unknowns`` and ``rows`` off
    :attr:`history`.

    Attributes
    ----------
    law : ControlLaw
        The controller a drive runs (``u_k = U w_k - K [...] - K_i z_k``).
    P : ndarray
        Its value matrix, over the law's state (:attr:`state`).
    B : ndarray or None
        The estimated input matrix: B (continuous target) or Bd of the exact discrete
        model (digital target); None from the digital ADP learner used alone, which does
        not estimate it.
    history : tuple of IterationRecord
        Policy-iteration steps (empty for identify-then-design).
    quality : Quality or None
        Standard errors, noise, alignment, consistency and stability margin; None from a
        learner used alone, which judges nothing.
    target : {"continuous", "digital"}
        The optimum learned: the paper's continuous-time one or the sampled loop's.
    method : {"adp", "identify"}
        Adaptive dynamic programming or identify-then-design.
    h : float or None
        Sampling period of the data, s (None where a continuous learner was not told).
    input_delay : int
        d, the computation delay the digital target accounts for, samples.
    alignment : Alignment or None
        The alignment of the logged inputs used, and what the data said about it.
    exogenous_block : ndarray or None
        ``M = (D + A X - X E)' P`` (``[D + A X - X E; 0]' P`` with integral action), of the
        continuous regulator learners.
    formulation : {"customized", "general"} or None
        How the continuous regulator learner met the regulator equations.
    stages : tuple of DiscountStage
        The continuous servo learner's discount schedule, the last one undiscounted.
    extra_regressions : tuple of RegressionSolution
        Least-squares solves beside the policy iteration's (the general formulation's, one
        per solution of ``C X = 0`` and a particular solution of ``C X + F = 0``).
    evidence : Evidence or None
        What the logs said (the fitted model, its output errors, the parameters'
        covariance) that the verdict was drawn from; None from a learner used alone. The
        report's figures (:func:`selftune.report.write_learn_report`) are drawn from it.
    judged : JudgedPlants or None
        The estimated plants the verdict judged the law on (None from a learner used
        alone): what a law of another structure is measured on
        (:func:`~selftune.learn.pi_equivalent`).
    """

    law: ControlLaw
    P: Array
    B: Array | None
    history: tuple[IterationRecord, ...] = ()
    quality: Quality | None = None
    target: Literal["continuous", "digital"] = "continuous"
    method: Literal["adp", "identify"] = "adp"
    h: float | None = None
    input_delay: int = 0
    alignment: Alignment | None = None
    exogenous_block: Array | None = None
    formulation: Formulation | None = None
    stages: tuple[DiscountStage, ...] = ()
    extra_regressions: tuple[RegressionSolution, ...] = ()
    evidence: Evidence | None = field(default=None, repr=False, compare=False)
    judged: JudgedPlants | None = field(default=None, repr=False, compare=False)

    @property
    def theta(self) -> Array | None:
        """Theta = ``[vecs(P); vec(K); vec(M)]`` of the learned regulator (the unknowns of
        the continuous data equation, as :attr:`selftune.core.RegulatorSolution.theta`);
        otherwise the last policy-iteration step's; None without one."""
        if self.exogenous_block is not None and self.law.K_i is None:
            return pack_theta(self.P, self.law.K, self.exogenous_block)
        return self.history[-1].theta if self.history else None

    @property
    def verdict(self) -> Quality:
        """:attr:`quality`, which a judged result has (raises otherwise).

        Raises
        ------
        ValueError
            If the result was not judged (a learner used alone gives no verdict).
        """
        if self.quality is None:
            raise ValueError("this result has no verdict: learn_controller or assess gives one")
        return self.quality

    @property
    def discounts(self) -> tuple[float, ...]:
        """The servo schedule's discounts, 1/s, in the order run."""
        return tuple(stage.discount for stage in self.stages)

    @property
    def least_squares_solves(self) -> int:
        """Every least-squares solve: the policy-iteration steps and the extra ones."""
        return len(self.history) + len(self.extra_regressions)
