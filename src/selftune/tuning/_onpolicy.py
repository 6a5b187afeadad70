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
- :func:`algorithm3` -- unknown flux: the flux is identified first (:mod:`._flux`; the
  paper's no-load step confounds an inverter's dead time with back-EMF), then Algorithm 2
  (or, for the digital target or integral action, the off-policy learner) with it.

Algorithms 1 and 2 learn the paper's controller: the continuous target, without integral
action. Each episode is read with the drive's delay (:func:`._learning.aligned`); the
result is judged on all the session's episodes (:func:`selftune.learn.assess`), and a
session that does not settle raises instead of returning.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..core import Array, ControlLaw, theta_sizes, unpack_theta, vec, vecs
from ..errors import ConvergenceError, InputError
from ..learn import IterationRecord, Trajectory, assess, estimated_B, feedforward
from ..sim import constant, held, uniform
from ._drive import Drive
from ._episodes import iteration_record, known_form, learning_step, relative_change, settled
from ._flux import identify_flux
from ._knowledge import reference_perturbation
from ._learning import aligned, check_drive, learning_options, learning_problem
from ._offpolicy import offpolicy
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


def _paper_controller_only(settings: TuningSettings, algorithm: str) -> None:
    """Algorithms 1 and 2 learn the paper's controller; say what learns the others."""
    if settings.target != "continuous" or settings.integral_action:
        what = "integral action" if settings.integral_action else "the digital target"
        raise InputError(
            f"algorithm: Algorithm {algorithm} learns the paper's controller (continuous "
            f"target, no integral action); {what} is learned by algorithm 'offpolicy' or '3'"
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
    episodes: list[Trajectory] = field(default_factory=list)
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
            ControlLaw.regulator(self.K, self.X, self.U),
            constant(self.w),
            num_samples=settings.samples_per_episode,
            exploration=uniform(settings.exploration),
            seed=settings.seed + j,
            assumed_flux=self.phi_pm,
        )
        episode = self.collected(episode)
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
            return w + reference_perturbation(t, kind, settings.torque)

        episode = self.drive.run(
            ControlLaw.regulator(self.K, self.X, self.U),
            held(perturbed),
            num_samples=settings.samples_per_episode,
            exploration=uniform(settings.exploration) if settings.feedforward_exploration else None,
            seed=settings.seed + j,
            assumed_flux=self.phi_pm,
        )
        episode = self.collected(episode)
        known = {"P": vecs(last.P), "K": vec(last.K)}
        return learning_step(episode, self.K, settings, self.X, known=known, iteration=j)

    def collected(self, episode: Trajectory) -> Trajectory:
        """The episode aligned with the drive's delay, and kept for the verdict."""
        episode = aligned(episode, self.drive)
        self.seconds += episode.duration
        self.episodes.append(episode)
        return episode

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

    def result(self, algorithm: str, feedforward_learned: bool) -> TuningResult:
        """The session's result from its last iteration, judged on all its episodes."""
        last = self.history[-1]
        notes: tuple[str, ...] = ()
        deficient = [h for h in self.history if h.step == "feedback" and h.rank < h.unknowns]
        if algorithm == "1" and not feedforward_learned and deficient:
            notes = (_RANK_NOTE.format(rank=deficient[-1].rank, unknowns=deficient[-1].unknowns),)
        law = ControlLaw.regulator(last.K, self.X, last.U)
        problem = learning_problem(self.drive, self.settings, self.phi_pm)
        options = replace(
            learning_options(self.drive, self.settings, target="continuous"),
            logged_input="applied",  # the episodes are aligned already
        )
        if feedforward_learned:
            judged = assess(law, self.episodes, problem, options, P=last.P)
        else:  # a constant reference: judge K on the back-EMF channel alone
            judged = assess(
                ControlLaw.regulator(last.K, self.X[:, :1], last.U[:, :1]),
                [
                    Trajectory(e.t, e.x, e.u, e.w[:, :1], angle=e.angle)
                    for e in self.episodes
                    if e.w is not None
                ],
                problem.with_F(None if problem.F is None else problem.F[:, :1]),
                options, P=last.P, feedforward=False,
            )  # fmt: skip
        return TuningResult(
            algorithm=algorithm,
            law=law,
            P=last.P,
            B=estimated_B(last.P, last.K, self.settings.R),
            w=self.w,
            history=tuple(self.history),
            data_seconds=self.seconds,
            feedforward_learned=feedforward_learned,
            quality=judged.verdict,
            theta=last.theta,
            notes=notes,
            judged=judged.judged,
        )

    def unsettled(self, algorithm: str) -> ConvergenceError:
        """The error of a session that did not settle within its iterations."""
        change = self.history[-1].change if self.history else float("inf")
        return ConvergenceError(
            f"Algorithm {algorithm}: Theta did not settle in {self.settings.max_iterations} "
            f"iterations (last relative change {change:.3g}, tolerance "
            f"{self.settings.tolerance:g}); each episode's data may be too noisy or too short "
            "for the tolerance: use longer episodes, more exploration, or algorithm 'offpolicy'"
        )


def algorithm1(drive: Drive, settings: TuningSettings, phi_pm: float) -> TuningResult:
    """The paper's Algorithm 1 (one step), on-policy: a new episode each iteration.

    Parameters
    ----------
    drive : Drive
        The drive (e.g. :class:`selftune.sim.SimulatedDrive`).
    settings : TuningSettings
        The session's settings (continuous target, no integral action).
    phi_pm : float
        The known magnet flux, Wb.

    Returns
    -------
    TuningResult
        K and P converge to the optimum; U does not (``feedforward_learned`` is False and
        ``notes`` says why: rank 9 of 11 with a constant reference).

    Raises
    ------
    InputError
        For the digital target or integral action.
    ConvergenceError
        If Theta does not settle within ``settings.max_iterations``, or the result does
        not stabilize every plant the data allow.
    ConsistencyError, ExcitationError
        When the episodes do not support the result (:func:`selftune.learn.assess`).
    """
    _paper_controller_only(settings, "1")
    check_drive(drive, settings)
    session = _Session(drive, settings, phi_pm, K=settings.K0)
    feedforward_learned = False
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
            return session.result("1", feedforward_learned)
        session.previous_change, session.K = item.change, K_next
    raise session.unsettled("1")


def algorithm2(drive: Drive, settings: TuningSettings, phi_pm: float) -> TuningResult:
    """The paper's Algorithm 2 (two steps), on-policy: a new episode each iteration.

    Parameters
    ----------
    drive : Drive
        The drive (e.g. :class:`selftune.sim.SimulatedDrive`).
    settings : TuningSettings
        The session's settings (continuous target, no integral action).
    phi_pm : float
        The known magnet flux, Wb.

    Returns
    -------
    TuningResult

    Raises
    ------
    InputError, ConvergenceError, ConsistencyError, ExcitationError
        As :func:`algorithm1`.
    """
    _paper_controller_only(settings, "2")
    check_drive(drive, settings)
    session = _Session(drive, settings, phi_pm, K=settings.K0)
    return _two_step(session, settings.perturbation, "2")


def _two_step(session: _Session, kind: Perturbation, algorithm: str) -> TuningResult:
    """Algorithm 2's iterations from the session's state: feedback episodes until
    ``Theta_1`` settles, then a feedforward episode after each feedback episode."""
    settings = session.settings
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
        first = record.theta if previous is None else previous
        session.history.append(session.record(record2, "feedforward", U_next, first))
        change = relative_change(record2.theta, previous)
        session.previous_theta, session.U = record2.theta, U_next
        if settled(change, session.previous_change, settings.tolerance, settings):
            return session.result(algorithm, feedforward_learned=True)
        session.previous_change, session.K = change, K_next
    raise session.unsettled(algorithm)


def algorithm3(drive: Drive, settings: TuningSettings, phi_guess: float) -> TuningResult:
    """Algorithm 3: unknown flux, identified first and told apart from the inverter's
    voltage error.

    Step 1 (:func:`._flux.identify_flux`): one episode of ``settings.flux_length`` seconds
    with the torque reference stepping through positive and negative levels; the exact
    discrete model of the log (output error, with the dead time modelled when
    ``settings.dead_time``) gives the back-EMF per unit of the assumed one, hence
    ``phi_pm``. The paper's no-load step learns ``D`` by ADP instead; on an inverter its
    dead-time voltage passes for back-EMF there (-4% to -7.5% in flux), which is why it is
    replaced (PAPER_NOTES.md).
    Step 2: with the identified flux in F and w, Algorithm 2 from K0 (the paper's
    controller), perturbing the torque reference only (the back-EMF channel is what the
    drive cannot move); or, for the digital target or integral action, the off-policy
    learner.

    Parameters
    ----------
    drive : Drive
        The drive (e.g. :class:`selftune.sim.SimulatedDrive`).
    settings : TuningSettings
        The session's settings.
    phi_guess : float
        A rough flux (the nameplate's), Wb: it sets the test currents and the assumed
        back-EMF of step 1, nothing else.

    Returns
    -------
    TuningResult
        With ``identified = {"phi_pm", "phi_pm_se"}`` (Wb) and, with the dead time
        modelled, ``"dead_time_voltage"`` (V per phase).

    Raises
    ------
    ExcitationError
        If step 1 cannot pin the flux down to :data:`._flux.FLUX_PRECISION` (it says how
        much longer it should be), or as the second step raises.
    ConsistencyError, ConvergenceError
        As the steps raise them.
    """
    check_drive(drive, settings)
    flux = identify_flux(drive, settings, phi_guess)
    identified = flux.as_dict()
    kind: Perturbation = "torque" if settings.perturbation == "paper" else settings.perturbation
    if settings.target == "continuous" and not settings.integral_action:
        session = _Session(drive, settings, flux.phi_pm, K=settings.K0, seconds=flux.seconds)
        second = _two_step(session, kind, "3")
        return replace(second, identified=identified)
    result = offpolicy(
        drive, replace(settings, perturbation=kind), flux.phi_pm, identified=identified,
        algorithm="3",
    )  # fmt: skip
    return replace(result, data_seconds=result.data_seconds + flux.seconds)
