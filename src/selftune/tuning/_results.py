"""The typed outcome of a self-tuning session and of each of its iterations."""

from __future__ import annotations

from dataclasses import dataclass, field

from ..core import Array, ControlLaw, WithLaw
from ..learn import JudgedPlants, LearnedController, Quality

__all__ = ["TuningIteration", "TuningResult"]


@dataclass(frozen=True)
class TuningIteration:
    """One iteration of a self-tuning session.

    Attributes
    ----------
    iteration : int
        j, from 0.
    step : str
        ``"feedback"`` (exploration on the inputs, Theta learned with the M block as the
        data allow), ``"feedforward"`` (Algorithm 2's second step), ``"no-load"``
        (Algorithm 3's first step) or ``"off-policy"``.
    K_applied : ndarray, shape (2, 2)
        ``K_j``, the feedback applied (and evaluated) in this iteration.
    U_applied : ndarray, shape (2, q)
        ``U_j``, the feedforward applied.
    theta : ndarray
        Theta after this iteration.
    P : ndarray
        ``P_j``, the learned value of ``K_j``.
    K : ndarray
        ``K_(j+1)``.
    U : ndarray
        ``U_(j+1)``, the feedforward in force after this iteration.
    rank, unknowns : int
        Rank and size of the iteration's regression.
    change : float
        Relative change of Theta from the previous iteration (inf at first).
    data_seconds : float
        Motor data used so far, s.
    """

    iteration: int
    step: str
    K_applied: Array
    U_applied: Array
    theta: Array
    P: Array
    K: Array
    U: Array
    rank: int
    unknowns: int
    change: float
    data_seconds: float


@dataclass(frozen=True)
class TuningResult(WithLaw):
    """The outcome of a self-tuning session (learned quantities only; no model used).

    A session either returns a result the data support, with its :attr:`quality`, or
    raises an error that says why not; there is no "not converged" result.

    Attributes
    ----------
    algorithm : str
        ``"1"``, ``"2"``, ``"3"`` or ``"offpolicy"``.
    law : ControlLaw
        The learned controller, as a drive runs it (``law.equations()`` says which).
    P : ndarray
        Its learned value matrix.
    B : ndarray
        Estimated input matrix (B, or Bd of the exact discrete model for the digital
        target).
    w : ndarray
        The operating point's ``w = [p speed phi, T*]`` (with the identified flux for
        Algorithm 3).
    history : tuple of TuningIteration
        The policy-iteration steps.
    data_seconds : float
        Motor data used in all, s.
    feedforward_learned : bool
        False when the data could not determine the feedforward (Algorithm 1).
    quality : Quality
        The verdict on the result from all the session's data
        (:class:`selftune.learn.Quality`).
    target : str
        ``"continuous"`` (the paper's controller) or ``"digital"`` (the optimum of the
        sampled loop with the drive's delay).
    theta : ndarray or None
        Final Theta of the continuous data equation (None for the digital target).
    identified : dict
        Algorithm 3: ``{"phi_pm": ..., "phi_pm_se": ...}`` (Wb) and, with the dead time
        modelled, ``"dead_time_voltage"`` (V per phase); empty otherwise.
    notes : tuple of str
        What the user should know about the result (e.g. why U is not learned).
    learned : LearnedController or None
        The learning result the verdict came with (its evidence: the report's figures,
        :func:`selftune.report.write_learn_report`).
    """

    algorithm: str
    law: ControlLaw
    P: Array
    B: Array
    w: Array
    history: tuple[TuningIteration, ...]
    data_seconds: float
    feedforward_learned: bool
    quality: Quality
    target: str = "continuous"
    theta: Array | None = None
    identified: dict[str, float] = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    learned: LearnedController | None = field(default=None, repr=False, compare=False)

    @property
    def judged(self) -> JudgedPlants | None:
        """The estimated plants the verdict judged the law on (the learning result's:
        :attr:`selftune.learn.LearnedController.judged`), or None."""
        return None if self.learned is None else self.learned.judged

    @property
    def rank(self) -> int:
        """Rank of the last regression of the feedback step."""
        feedback = [item for item in self.history if item.step != "feedforward"]
        return (feedback or list(self.history))[-1].rank

    @property
    def unknowns(self) -> int:
        """Unknowns of the last feedback regression (11 for the motor's Theta)."""
        feedback = [item for item in self.history if item.step != "feedforward"]
        return (feedback or list(self.history))[-1].unknowns
