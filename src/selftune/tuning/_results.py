"""The typed outcome of a self-tuning session and of each of its iterations."""

from __future__ import annotations

from dataclasses import dataclass, field

from ..core import Array

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
class TuningResult:
    """The outcome of a self-tuning session (learned quantities only; no model used).

    Attributes
    ----------
    algorithm : str
        ``"1"``, ``"2"``, ``"3"`` or ``"offpolicy"``.
    K, P, X, U : ndarray
        The learned controller ``u = -K (x - X w) + U w`` and value matrix.
    theta : ndarray
        Final Theta.
    B : ndarray
        Estimated input matrix.
    w : ndarray
        The operating point's ``w = [p speed phi, T*]`` (with the identified flux for
        Algorithm 3).
    history : tuple of TuningIteration
    data_seconds : float
        Motor data used in all, s.
    converged : bool
    feedforward_learned : bool
        False when the data could not determine the feedforward (Algorithm 1).
    identified : dict
        Algorithm 3: ``{"phi_pm": ..., "L_s": ...}`` (Wb, H); empty otherwise.
    notes : tuple of str
        What the user should know about the result (e.g. why U is not learned).
    """

    algorithm: str
    K: Array
    P: Array
    X: Array
    U: Array
    theta: Array
    B: Array
    w: Array
    history: tuple[TuningIteration, ...]
    data_seconds: float
    converged: bool
    feedforward_learned: bool
    identified: dict[str, float] = field(default_factory=dict)
    notes: tuple[str, ...] = ()

    @property
    def rank(self) -> int:
        """Rank of the last regression of the feedback step."""
        feedback = [item for item in self.history if item.step != "feedforward"]
        return (feedback or list(self.history))[-1].rank

    @property
    def unknowns(self) -> int:
        """Unknowns of the full regression (11 for the motor)."""
        return int(self.theta.shape[0])
