"""The paper's on-policy Algorithms 1, 2 and 3: a new episode from the drive each iteration.

Known-flux regulation form (PAPER_NOTES.md section 1): ``w = [p speed phi_pm, T*]``,
``C = I``, ``E = 0``, ``F = [[0, 0], [0, -2/(3 p phi_pm)]]``, so ``X* = -F`` is known and
the customized data equation has 11 unknowns ``Theta = [vecs(P); vec(K); vec((D+AX*)'P)]``.

- :func:`algorithm1` -- one step: episodes with exploration on the inputs and a constant
  reference. P and K are learned, but with a constant ``w`` the exogenous block has rank
  n = 2 of n q = 4 (rank 9 of 11): the feedforward U cannot be learned (pitfall 3).
- :func:`algorithm2` -- two steps: as Algorithm 1 until ``Theta_1 = [vecs(P); vec(K)]``
  settles, then episodes with the reference perturbed by ``w_d(t)``, solving eq. 13 for
  ``Theta_2 = vec((D + AX*)'P)`` with ``Theta_1`` known.
- :func:`algorithm3` -- unknown flux: a no-load step (``T* = 0``, ``w = [p speed]``)
  learns P, K, B and ``D'P``, hence ``L_s = 1/B_ii`` and ``phi_pm = -D_2 L_s``; then
  Algorithm 2 with the identified F.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..core import Array, theta_sizes, unpack_theta, vec, vecs
from ..errors import ConvergenceError
from ..learn import IterationRecord, estimated_B, feedforward
from ..sim import constant, held, prbs, uniform
from ._drive import Drive
from ._episodes import iteration_record, known_form, learning_step, relative_change, settled
from ._knowledge import reference_perturbation
from ._results import TuningIteration, TuningResult
from ._settings import Perturbation, TuningSettings

__all__ = ["algorithm1", "algorithm2", "algorithm3"]

#: Why Algorithm 1 cannot learn the feedforward (said in its result's notes).
_RANK_NOTE = (
    "rank {rank} of {unknowns}: with a constant reference the exogenous block (D + AX)'P is "
    "not identifiable (its q columns per state are collinear), so K and P are learned but "
    "the feedforward U is not (U keeps its initial value); Algorithm 2 perturbs the "
    "reference to learn it"
)


@dataclass
class _Session:
    """The state of an on-policy session as it runs: the policy applied, the history,
    the data used, and the changes of Theta that decide when it has settled."""

    drive: Drive
    settings: TuningSettings
    phi_pm: float
    K: Array
    history: list[TuningIteration] = field(default_factory=list)
    seconds: float = 0.0
    previous_theta: Array | None = None
    previous_change: float = float("inf")
    previous_theta1: Array | None = None
    previous_change1: float = float("inf")
    X: Array = field(init=False)
    w: Array = field(init=False)
    U: Array = field(init=False)

    def __post_init__(self) -> None:
        self.X, self.w = known_form(self.drive, self.settings, self.phi_pm)
        self.U = np.zeros((2, 2))

    def feedback_episode(self, j: int) -> tuple[IterationRecord, bool]:
        """Run episode j (constant reference, exploration on the inputs) and learn from it.

        Returns the step's record and whether ``Theta_1 = [vecs(P); vec(K)]`` has settled.
        """
        settings = self.settings
        episode = self.drive.run(
            self.K,
            self.X,
            self.U,
            constant(self.w),
            num_samples=settings.samples_per_episode,
            exploration=uniform(settings.exploration),
            seed=settings.seed + j,
            assumed_flux=self.phi_pm,
        )
        self.seconds += episode.duration
        record = learning_step(
            episode, self.K, settings, self.X, allow_deficient=("M",), iteration=j
        )
        size_P, size_K, _ = theta_sizes(2, 2, 2)
        theta1 = record.theta[: size_P + size_K]
        change1 = relative_change(theta1, self.previous_theta1)
        feedback_settled = settled(
            change1, self.previous_change1, settings.feedback_tolerance, settings
        )
        self.previous_theta1, self.previous_change1 = theta1, change1
        return record, feedback_settled

    def feedforward_episode(self, j: int, kind: Perturbation) -> IterationRecord:
        """Run episode j with the reference perturbed by ``w_d(t)`` and solve eq. 13 for
        the exogenous block, with P and K of the last feedback step known."""
        settings, w = self.settings, self.w
        last = self.history[-1]

        def perturbed(t: Array) -> Array:
            return w + reference_perturbation(t, kind)

        episode = self.drive.run(
            self.K,
            self.X,
            self.U,
            held(perturbed),
            num_samples=settings.samples_per_episode,
            exploration=uniform(settings.exploration) if settings.feedforward_exploration else None,
            seed=settings.seed + j,
            assumed_flux=self.phi_pm,
        )
        self.seconds += episode.duration
        known = {"P": vecs(last.P), "K": vec(last.K)}
        return learning_step(episode, self.K, settings, self.X, known=known, iteration=j)

    def record(
        self, record: IterationRecord, step: str, U: Array, previous_theta: Array | None
    ) -> TuningIteration:
        """The iteration of ``record`` under the policy applied now, leaving ``U`` in force;
        its change is measured from ``previous_theta``."""
        return iteration_record(
            record,
            step=step,
            K_applied=self.K,
            U_applied=self.U,
            U=U,
            previous_theta=previous_theta,
            data_seconds=self.seconds,
        )

    def result(self, algorithm: str, converged: bool, feedforward_learned: bool) -> TuningResult:
        """The session's result from its last iteration."""
        last = self.history[-1]
        notes: tuple[str, ...] = ()
        deficient = [h for h in self.history if h.step == "feedback" and h.rank < h.unknowns]
        if algorithm == "1" and not feedforward_learned and deficient:
            notes = (_RANK_NOTE.format(rank=deficient[-1].rank, unknowns=deficient[-1].unknowns),)
        return TuningResult(
            algorithm=algorithm,
            K=last.K,
            P=last.P,
            X=self.X,
            U=last.U,
            theta=last.theta,
            B=estimated_B(last.P, last.K, self.settings.R),
            w=self.w,
            history=tuple(self.history),
            data_seconds=self.seconds,
            converged=converged,
            feedforward_learned=feedforward_learned,
            notes=notes,
        )


def algorithm1(drive: Drive, settings: TuningSettings, phi_pm: float) -> TuningResult:
    """The paper's Algorithm 1 (one step), on-policy: a new episode each iteration.

    Parameters
    ----------
    drive : Drive
        The drive (e.g. :class:`selftune.sim.SimulatedDrive`).
    settings : TuningSettings
        The session's settings.
    phi_pm : float
        The known magnet flux, Wb.

    Returns
    -------
    TuningResult
        K and P converge to the optimum; U does not (``feedforward_learned`` is False and
        ``notes`` says why: rank 9 of 11 with a constant reference).
    """
    session = _Session(drive, settings, phi_pm, K=settings.K0)
    converged = feedforward_learned = False
    for j in range(settings.max_iterations):
        record, feedback_settled = session.feedback_episode(j)
        P, K_next, M = unpack_theta(record.theta, 2, 2, 2)
        # Only an identified M gives U; with rank lacking in the M block (a constant
        # reference) U keeps its value, as in the paper, instead of a wrong matrix.
        identified = "M" not in record.regression.deficient_blocks
        U_next = session.U
        if feedback_settled and identified:
            U_next, feedforward_learned = feedforward(P, K_next, M, settings.R), True
        item = session.record(record, "feedback", U_next, session.previous_theta)
        session.history.append(item)
        session.previous_theta, session.U = record.theta, U_next
        if settled(item.change, session.previous_change, settings.tolerance, settings):
            converged = True
            break
        session.previous_change, session.K = item.change, K_next
    return session.result("1", converged, feedforward_learned)


def algorithm2(drive: Drive, settings: TuningSettings, phi_pm: float) -> TuningResult:
    """The paper's Algorithm 2 (two steps), on-policy: a new episode each iteration.

    Parameters
    ----------
    drive : Drive
        The drive (e.g. :class:`selftune.sim.SimulatedDrive`).
    settings : TuningSettings
        The session's settings.
    phi_pm : float
        The known magnet flux, Wb.

    Returns
    -------
    TuningResult
    """
    session = _Session(drive, settings, phi_pm, K=settings.K0)
    return _two_step(session, settings.perturbation, "2")


def _two_step(session: _Session, kind: Perturbation, algorithm: str) -> TuningResult:
    """Algorithm 2's iterations from the session's state: feedback episodes until
    ``Theta_1`` settles, then a feedforward episode after each feedback episode."""
    settings = session.settings
    converged = feedforward_learned = False
    start = len(session.history)
    for j in range(start, start + settings.max_iterations):
        record, feedback_settled = session.feedback_episode(j)
        P, K_next, _ = unpack_theta(record.theta, 2, 2, 2)
        previous = session.previous_theta
        session.history.append(session.record(record, "feedback", session.U, previous))
        if not feedback_settled:
            session.previous_theta, session.K = record.theta, K_next
            continue
        record2 = session.feedforward_episode(j, kind)
        _, _, M2 = unpack_theta(record2.theta, 2, 2, 2)
        U_next = feedforward(P, K_next, M2, settings.R)
        feedforward_learned = True
        first = record.theta if previous is None else previous
        session.history.append(session.record(record2, "feedforward", U_next, first))
        change = relative_change(record2.theta, previous)
        session.previous_theta, session.U = record2.theta, U_next
        if settled(change, session.previous_change, settings.tolerance, settings):
            converged = True
            break
        session.previous_change, session.K = change, K_next
    return session.result(algorithm, converged, feedforward_learned)


def algorithm3(drive: Drive, settings: TuningSettings) -> TuningResult:
    """The paper's Algorithm 3: unknown flux.

    Step 1, at no load (``T* = 0``, ``w = [p speed]``, ``X = 0``): on-policy iterations
    learn P, K, ``B`` and ``D'P`` (9 unknowns, full rank with a constant ``w``), hence
    ``L_s = 2 / trace(B)`` and ``phi_pm = -D_2 L_s`` with ``D = P^-1 (D'P)'``. It explores
    with a held PRBS (``settings.no_load_hold``) and stops when Theta changes by less
    than ``settings.feedback_tolerance``: it only has to identify the flux.
    Step 2: Algorithm 2 with the identified flux in F and w, starting from the learned K,
    perturbing the torque reference only (the back-EMF channel is what the drive cannot
    move).

    Parameters
    ----------
    drive : Drive
        The drive (e.g. :class:`selftune.sim.SimulatedDrive`).
    settings : TuningSettings
        The session's settings.

    Returns
    -------
    TuningResult
        With ``identified = {"phi_pm": ..., "L_s": ...}`` (Wb, H).
    """
    history, seconds, record = _no_load_step(drive, settings)
    P, K_next, DP = unpack_theta(record.theta, 2, 2, 1)
    B = estimated_B(P, K_next, settings.R)
    D = np.linalg.solve(P, DP.T)
    L_s = 2.0 / float(np.trace(B))
    phi_pm = -float(D[1, 0]) * L_s
    if not (np.isfinite(phi_pm) and phi_pm > 0 and np.isfinite(L_s) and L_s > 0):
        raise ConvergenceError(
            f"Algorithm 3: identified a non-physical phi_pm = {phi_pm:.4g} Wb, "
            f"L_s = {L_s:.4g} H; check the speed and the data"
        )
    session = _Session(drive, settings, phi_pm, K=K_next, history=history, seconds=seconds)
    second = _two_step(session, "torque", "3")
    return replace(second, identified={"phi_pm": phi_pm, "L_s": L_s})


def _no_load_step(
    drive: Drive, settings: TuningSettings
) -> tuple[list[TuningIteration], float, IterationRecord]:
    """Algorithm 3's first step: no-load episodes until Theta settles."""
    n, m, q = 2, 2, 1
    K = settings.K0
    history: list[TuningIteration] = []
    seconds = 0.0
    previous_theta: Array | None = None
    previous_change = float("inf")
    hold = max(1, settings.no_load_hold // settings.input_hold)
    for j in range(settings.max_iterations):
        episode = drive.run_no_load(
            K,
            num_samples=settings.samples_per_episode,
            exploration=prbs(settings.exploration, hold),
            seed=settings.seed + j,
        )
        seconds += episode.duration
        record = learning_step(episode, K, settings, np.zeros((n, q)), iteration=j)
        item = iteration_record(
            record,
            step="no-load",
            K_applied=K,
            U_applied=np.zeros((m, q)),
            U=np.zeros((m, q)),
            previous_theta=previous_theta,
            data_seconds=seconds,
        )
        history.append(item)
        previous_theta, K = record.theta, record.K
        if settled(item.change, previous_change, settings.feedback_tolerance, settings):
            return history, seconds, record
        previous_change = item.change
    raise ConvergenceError(
        f"Algorithm 3, no-load step: Theta did not settle in {settings.max_iterations} "
        f"iterations (last relative change {history[-1].change:.3g})"
    )
