"""Self-tuning torque control of a surface PMSM: the paper's Algorithms 1-3 and off-policy.

The learner knows only what a drive engineer knows without a motor model -- the pole
pairs ``p``, the held mechanical speed, the torque reference, the cost weights and (for
Algorithms 1 and 2) the magnet flux -- and sees only the trajectories a drive returns.
The drive is :class:`SimulatedDrive` here (exact simulation of the motor); any object
with the same ``run`` and ``run_no_load`` methods (a real drive's logger) works.

Known-flux regulation form (PAPER_NOTES.md section 1): ``w = [p speed phi_pm, T*]``,
``C = I``, ``E = 0``, ``F = [[0, 0], [0, -2/(3 p phi_pm)]]``, so ``X* = -F`` is known and
the customized data equation has 11 unknowns ``Theta = [vecs(P); vec(K); vec((D+AX*)'P)]``.

- :func:`algorithm1` -- one step: episodes with exploration on the inputs and a constant
  reference. P and K are learned, but with a constant ``w`` the exogenous block has rank
  n = 2 of n q = 4 (rank 9 of 11): the feedforward U cannot be learned (pitfall 3).
- :func:`algorithm2` -- two steps: as Algorithm 1 until ``Theta_1 = [vecs(P); vec(K)]``
  settles, then episodes with the reference perturbed by ``w_d(t)`` and no exploration,
  solving eq. 13 for ``Theta_2 = vec((D + AX*)'P)`` with ``Theta_1`` known.
- :func:`algorithm3` -- unknown flux: a no-load step (``T* = 0``, ``w = [p speed]``)
  learns P, K, B and ``D'P``, hence ``L_s = 1/B_ii`` and ``phi_pm = -D_2 L_s``; then
  Algorithm 2 with the identified F.
- :func:`offpolicy` -- one batch of data with exploration and the perturbed reference
  together, reused for every policy-iteration step (Jiang & Jiang 2012).

:func:`evaluate` compares a result with the model-based optimum (for evaluation only).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Literal, Protocol

import numpy as np
from numpy.typing import NDArray

from ._validation import as_matrix, as_vector, check_positive_definite, positive_finite
from .data_equation import interval_moments
from .errors import ConvergenceError, InputError
from .learning import (
    IterationRecord,
    estimated_B,
    feedforward,
    learn_output_regulation,
    policy_step,
    solutions_of_output_equation,
)
from .motor import SPMSM
from .regulation import ModelBasedSolution, policy_value, solve_optimal_regulation
from .simulate import ExogenousSignal, Exploration, constant, held, prbs, simulate, uniform
from .trajectory import Trajectory
from .vectorize import theta_sizes, unpack_theta, vec, vecs

__all__ = [
    "Drive",
    "SimulatedDrive",
    "TuningEvaluation",
    "TuningIteration",
    "TuningResult",
    "TuningSettings",
    "algorithm1",
    "algorithm2",
    "algorithm3",
    "closed_loop_response",
    "evaluate",
    "known_flux_form",
    "offpolicy",
    "run_algorithm",
]

Array = NDArray[np.float64]
AlgorithmName = Literal["1", "2", "3", "offpolicy"]
Perturbation = Literal["paper", "torque"]

#: The paper's reference perturbation (Sec. V), w_d(t) = [sin(1000 t), 0.1 cos(3000 t)].
PAPER_PERTURBATION = ((1.0, 1000.0, 0.0), (0.1, 3000.0, 0.5 * np.pi))


def reference_perturbation(t: Array, kind: Perturbation) -> Array:
    """``w_d(t)``, shape (len(t), 2): the paper's on both channels, or on the torque only.

    ``"paper"``: ``[sin(1000 t), 0.1 cos(3000 t)]``. ``"torque"``: ``[0, 0.1 cos(3000 t)]``
    -- a drive can move its torque reference but not the back-EMF ``p speed phi_pm``.
    """
    t = np.asarray(t, dtype=float)
    columns = [
        amplitude * np.sin(frequency * t + phase)
        for amplitude, frequency, phase in PAPER_PERTURBATION
    ]
    if kind == "torque":
        columns[0] = np.zeros_like(t)
    return np.column_stack(columns)


def known_flux_form(
    pole_pairs: int, speed: float, torque: float, phi_pm: float
) -> tuple[Array, Array, Array, Array]:
    """``(C, E, F, w)`` of the known-flux torque-regulation form (eq. 8): what the learner knows.

    The same C, E, F as :meth:`SPMSM.regulation_problem`, and ``w`` as
    :meth:`SPMSM.exogenous`, built from the values a drive engineer has.
    """
    reference = SPMSM(R_s=1.0, L_s=1.0, phi_pm=phi_pm, p=pole_pairs)
    problem = reference.regulation_problem(speed)
    return problem.C, problem.E, problem.F, reference.exogenous(speed, torque)


@dataclass(frozen=True)
class TuningSettings:
    """Settings of a self-tuning session: the paper's (Sec. V), but for ``input_hold``.

    :meth:`paper` gives the paper's exactly.

    Attributes
    ----------
    speed : float
        Held mechanical speed, rad/s.
    torque : float
        Torque reference T*, N m.
    Q, R : ndarray
        Cost weights (5): ``Q = 1e3 I`` (PAPER_NOTES erratum 1), ``R = I``.
    sampling : float
        Sampling period, s (10 us).
    episode_length : float
        Length of each on-policy episode, s (5 ms); also the off-policy batch length.
    K0 : ndarray
        Initial stabilizing feedback (``20 pi I``, V/A).
    exploration : float
        Amplitude of the uniform exploration on each input, V (1 V).
    perturbation : {"paper", "torque"}
        Reference perturbation of Algorithm 2 and off-policy (Algorithm 3 always uses
        ``"torque"``, see :func:`reference_perturbation`).
    input_hold : int
        The drive's controller updates u every ``input_hold`` samples (2; the paper's
        experiment, :meth:`paper`, is 1: every sample). With 2 or more the learner
        integrates the data to fourth order instead of second
        (:mod:`selftune.data_equation`): on 300 random motors (R_s 0.1-3 ohm, L_s 3-100 mH,
        5-200 rad/s) Algorithms 2, 3 and off-policy then all met Theta 1e-5 and U 1e-4,
        where one-sample holds missed on 21% of 150.
    feedforward_exploration : bool
        Keep the input exploration on during Algorithm 2's second step (True). The paper
        turns it off; but that step solves eq. 13 for the exogenous block alone, with
        Theta_1 known, so exploration only adds excitation: at low speed the reference
        perturbation alone barely moves i_d, and U came out 1.8e-5 off instead of 5e-9.
    no_load_hold : int
        Algorithm 3's no-load step explores with a PRBS of amplitude ``exploration`` held
        this many samples (10, i.e. 100 us): at no load nothing else excites the d-axis,
        and white noise moves i_d by milliamps only, where the O(h^2) quadrature error is
        about 3e-4 of the signal; a held PRBS brings it to about 1e-5.
    interval : int
        Samples per regression interval.
    max_iterations : int
        Upper bound on iterations (episodes) of the on-policy algorithms, and on
        policy-iteration steps off-policy.
    feedback_tolerance : float
        epsilon_1: relative change of Theta_1 below which the feedforward is learned.
    tolerance : float
        epsilon_2: relative change of Theta at which the algorithms stop.
    seed : int
        Seed of the exploration (episode j uses ``seed + j``).
    """

    speed: float = 10.0
    torque: float = 10.0
    Q: Array = field(default_factory=lambda: 1e3 * np.eye(2))
    R: Array = field(default_factory=lambda: np.eye(2))
    sampling: float = 1e-5
    episode_length: float = 5e-3
    K0: Array = field(default_factory=lambda: 20.0 * np.pi * np.eye(2))
    exploration: float = 1.0
    perturbation: Perturbation = "paper"
    input_hold: int = 2
    feedforward_exploration: bool = True
    no_load_hold: int = 10
    interval: int = 10
    max_iterations: int = 20
    feedback_tolerance: float = 1e-4
    tolerance: float = 1e-6
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("sampling", "episode_length", "exploration"):
            object.__setattr__(self, name, positive_finite(getattr(self, name), name))
        for name in ("feedback_tolerance", "tolerance"):
            object.__setattr__(self, name, positive_finite(getattr(self, name), name))
        object.__setattr__(self, "speed", float(as_vector(self.speed, "speed", 1)[0]))
        object.__setattr__(self, "torque", float(as_vector(self.torque, "torque", 1)[0]))
        Q = check_positive_definite(as_matrix(self.Q, "Q", (2, 2)), "Q")
        R = check_positive_definite(as_matrix(self.R, "R", (2, 2)), "R")
        object.__setattr__(self, "Q", Q)
        object.__setattr__(self, "R", R)
        object.__setattr__(self, "K0", as_matrix(self.K0, "K0", (2, 2)))
        if self.perturbation not in ("paper", "torque"):
            raise InputError(
                f"perturbation: must be 'paper' or 'torque', got {self.perturbation!r}"
            )
        for name in ("input_hold", "no_load_hold", "interval", "max_iterations"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise InputError(f"{name}: must be a whole number >= 1, got {value!r}")
        if self.samples_per_episode < 2:
            raise InputError(
                f"episode_length: {self.episode_length} s is less than two samples of "
                f"{self.sampling} s"
            )

    @classmethod
    def paper(cls, **changes: object) -> TuningSettings:
        """The paper's Section V exactly: the defaults with the input changing every sample
        (``input_hold = 1``) and the reference perturbed on both channels; ``changes``
        override fields."""
        settings: TuningSettings = replace(cls(input_hold=1), **changes)  # type: ignore[arg-type]
        return settings

    @property
    def samples_per_episode(self) -> int:
        """Samples in one episode (and in the off-policy batch)."""
        return round(self.episode_length / self.sampling)

    def regression_interval(self, unknowns: int = 11) -> int:
        """Samples per regression interval: ``interval``, made a multiple of ``input_hold``
        (so no hold is split) and shortened if an episode would give fewer than three rows
        per unknown."""
        hold = self.input_hold
        interval = max(hold, -(-self.interval // hold) * hold)
        while interval > hold and self.samples_per_episode // interval < 3 * unknowns:
            interval -= hold
        return interval


class Drive(Protocol):
    """A drive in torque-control mode that runs episodes and returns what it measured."""

    @property
    def pole_pairs(self) -> int:
        """Number of pole pairs (nameplate)."""
        ...

    @property
    def sampling(self) -> float:
        """Sampling period, s."""
        ...

    def run(
        self,
        K: Array,
        X: Array,
        U: Array,
        reference: ExogenousSignal,
        *,
        num_samples: int,
        exploration: Exploration | None,
        seed: int,
        assumed_flux: float | None = None,
    ) -> Trajectory:
        """One episode from rest under ``u = -K (x - X w) + U w + rho`` (known-flux form)."""
        ...

    def run_no_load(
        self, K: Array, *, num_samples: int, exploration: Exploration | None, seed: int
    ) -> Trajectory:
        """One episode at no load (``T* = 0``), ``u = -K x + rho``, ``w = [p speed]``."""
        ...


@dataclass(frozen=True)
class SimulatedDrive:
    """A motor held at a speed by a load machine, simulated exactly (the test bench).

    It stands in for a real drive: the algorithms only call :meth:`run` and
    :meth:`run_no_load` and only read the trajectories they return. Episodes start from
    rest (``x(0) = 0``).

    Parameters
    ----------
    motor : SPMSM
        The true motor.
    speed : float
        Held mechanical speed, rad/s.
    sampling : float
        Sampling period, s.
    input_hold : int
        The controller updates u every ``input_hold`` samples (1: every sample).
    """

    motor: SPMSM
    speed: float
    sampling: float
    input_hold: int = 1

    @property
    def pole_pairs(self) -> int:
        """Number of pole pairs."""
        return self.motor.p

    def run(
        self,
        K: Array,
        X: Array,
        U: Array,
        reference: ExogenousSignal,
        *,
        num_samples: int,
        exploration: Exploration | None,
        seed: int,
        assumed_flux: float | None = None,
    ) -> Trajectory:
        """One episode of the known-flux form, ``x' = A x + B u + D w``.

        ``reference`` is the controller's ``w = [p speed phi, T*]`` (held). When the
        controller assumes a flux ``assumed_flux`` other than the true one, the back-EMF
        the motor produces is ``D w`` with the true flux, i.e. ``D diag(phi/assumed, 1) w``;
        this is exact only while ``w_1`` is constant, so the first channel must not be
        perturbed then.
        """
        problem = self.motor.regulation_problem(self.speed)
        D = problem.D
        if assumed_flux is not None and assumed_flux != self.motor.phi_pm:
            D = D @ np.diag([self.motor.phi_pm / assumed_flux, 1.0])
            values = reference.values(np.arange(num_samples + 1) * self.sampling)
            if np.ptp(values[:, 0]) > 0.0:
                raise InputError(
                    "reference: with an assumed flux, the back-EMF channel w_1 must be "
                    "constant (perturb the torque reference only)"
                )
        return simulate(
            problem.A,
            problem.B,
            D=D,
            exogenous=reference,
            K=K,
            X=X,
            U=U,
            exploration=exploration,
            h=self.sampling,
            num_samples=num_samples,
            seed=seed,
            input_hold=self.input_hold,
        )

    def run_no_load(
        self, K: Array, *, num_samples: int, exploration: Exploration | None, seed: int
    ) -> Trajectory:
        """One no-load episode (eq. 15): ``w = [p speed]``, ``T* = 0``, ``u = -K x + rho``."""
        problem = self.motor.no_load_problem(self.speed)
        return simulate(
            problem.A,
            problem.B,
            D=problem.D,
            exogenous=constant(self.motor.no_load_exogenous(self.speed)),
            K=K,
            exploration=exploration,
            h=self.sampling,
            num_samples=num_samples,
            seed=seed,
            input_hold=self.input_hold,
        )


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


def _relative_change(new: Array, old: Array | None) -> float:
    if old is None:
        return float("inf")
    return float(np.linalg.norm(new - old)) / max(float(np.linalg.norm(new)), 1e-300)


def _unknowns(episode: Trajectory) -> int:
    n, m, q = episode.n, episode.m, episode.q
    return sum(theta_sizes(n, m, q))


#: Currents beyond this (A) mean the applied policy does not stabilize the sampled loop.
DIVERGED_CURRENT = 1e6


def _checked(episode: Trajectory, K: Array, settings: TuningSettings) -> Trajectory:
    """Raise a clear error if an episode's currents diverged (the policy is unstable)."""
    peak = float(np.max(np.abs(episode.x)))
    if peak > DIVERGED_CURRENT:
        gain = np.array2string(K, precision=4, separator=", ", max_line_width=200)
        raise ConvergenceError(
            f"the currents diverged (|i| reached {peak:.3g} A in {episode.duration * 1e3:g} ms) "
            f"under the feedback K = {gain} V/A "
            f"applied every {settings.input_hold} sample(s) of {settings.sampling:g} s: it does "
            "not stabilize the sampled loop; choose a smaller K0 (e.g. about L_s times the "
            "wanted bandwidth in rad/s) or input_hold = 1"
        )
    return episode


def _step(
    episode: Trajectory,
    K: Array,
    settings: TuningSettings,
    X: Array,
    *,
    allow_deficient: tuple[str, ...] = (),
    known: dict[str, Array] | None = None,
    iteration: int,
) -> IterationRecord:
    _checked(episode, K, settings)
    moments = interval_moments(episode, settings.regression_interval(_unknowns(episode)))
    return policy_step(
        moments,
        K,
        settings.Q,
        settings.R,
        X=X,
        allow_deficient=allow_deficient,
        known=known,
        iteration=iteration,
    )


def _record(
    record: IterationRecord,
    *,
    step: str,
    K_applied: Array,
    U_applied: Array,
    U: Array,
    previous_theta: Array | None,
    data_seconds: float,
) -> TuningIteration:
    return TuningIteration(
        iteration=record.iteration,
        step=step,
        K_applied=K_applied,
        U_applied=U_applied,
        theta=record.theta,
        P=record.P,
        K=record.K,
        U=U,
        rank=record.regression.rank,
        unknowns=record.regression.unknowns,
        change=_relative_change(record.theta, previous_theta),
        data_seconds=data_seconds,
    )


#: A change that stops shrinking counts as settled when it is below this many epsilon_1.
NOISE_FLOOR_FACTOR = 100.0


def _settled(
    change: float, previous_change: float, threshold: float, settings: TuningSettings
) -> bool:
    """Whether Theta has settled: it changed by less than ``threshold``, or it stopped
    shrinking below ``NOISE_FLOOR_FACTOR`` epsilon_1. Policy iteration converges
    quadratically, and each on-policy episode brings its own data error; once the
    changes stop shrinking they measure only that error, which more episodes of the same
    kind do not reduce."""
    if change < threshold:
        return True
    return change >= previous_change and change < NOISE_FLOOR_FACTOR * settings.feedback_tolerance


def _known_form(drive: Drive, settings: TuningSettings, phi_pm: float) -> tuple[Array, Array]:
    C, _, F, w = known_flux_form(drive.pole_pairs, settings.speed, settings.torque, phi_pm)
    X, _ = solutions_of_output_equation(C, F)
    return X, w


def _on_policy(
    drive: Drive,
    settings: TuningSettings,
    phi_pm: float,
    *,
    two_step: bool,
    K_start: Array | None = None,
    perturbation: Perturbation | None = None,
    algorithm: str,
    history_prefix: tuple[TuningIteration, ...] = (),
    seconds_before: float = 0.0,
) -> TuningResult:
    """Algorithms 1 (``two_step=False``) and 2 (``two_step=True``), as the paper runs them."""
    X, w = _known_form(drive, settings, phi_pm)
    n, m, q = 2, 2, 2
    size_P, size_K, _ = theta_sizes(n, m, q)
    K = settings.K0 if K_start is None else K_start
    U = np.zeros((m, q))
    samples = settings.samples_per_episode
    history: list[TuningIteration] = list(history_prefix)
    seconds = seconds_before
    previous_theta: Array | None = None
    previous_theta1: Array | None = None
    previous_change = previous_change1 = float("inf")
    converged = False
    feedforward_learned = False
    start = len(history)
    kind = perturbation or settings.perturbation
    for j in range(start, start + settings.max_iterations):
        seed = settings.seed + j
        episode = drive.run(
            K,
            X,
            U,
            constant(w),
            num_samples=samples,
            exploration=uniform(settings.exploration),
            seed=seed,
            assumed_flux=phi_pm,
        )
        seconds += episode.duration
        record = _step(episode, K, settings, X, allow_deficient=("M",), iteration=j)
        P, K_next, M = unpack_theta(record.theta, n, m, q)
        theta1 = record.theta[: size_P + size_K]
        change1 = _relative_change(theta1, previous_theta1)
        feedback_settled = _settled(
            change1, previous_change1, settings.feedback_tolerance, settings
        )
        previous_theta1, previous_change1 = theta1, change1
        if not two_step:
            # Only an identified M gives U; with rank lacking in the M block (a constant
            # reference) U keeps its value, as in the paper, instead of a wrong matrix.
            identified = "M" not in record.regression.deficient_blocks
            U_next = feedforward(P, K_next, M, settings.R) if feedback_settled and identified else U
            item = _record(
                record,
                step="feedback",
                K_applied=K,
                U_applied=U,
                U=U_next,
                previous_theta=previous_theta,
                data_seconds=seconds,
            )
            history.append(item)
            previous_theta = record.theta
            U = U_next
            if _settled(item.change, previous_change, settings.tolerance, settings):
                converged = True
                break
            previous_change = item.change
            K = K_next
            continue
        item = _record(
            record,
            step="feedback",
            K_applied=K,
            U_applied=U,
            U=U,
            previous_theta=previous_theta,
            data_seconds=seconds,
        )
        if not feedback_settled:
            history.append(item)
            previous_theta = record.theta
            K = K_next
            continue
        # Second step (eq. 13): perturb the reference, no exploration, Theta_1 known.
        base = w

        def perturbed(t: Array, base: Array = base, kind: Perturbation = kind) -> Array:
            return base + reference_perturbation(t, kind)

        episode2 = drive.run(
            K,
            X,
            U,
            held(perturbed),
            num_samples=samples,
            exploration=uniform(settings.exploration) if settings.feedforward_exploration else None,
            seed=seed,
            assumed_flux=phi_pm,
        )
        seconds += episode2.duration
        record2 = _step(
            episode2,
            K,
            settings,
            X,
            known={"P": vecs(P), "K": vec(K_next)},
            iteration=j,
        )
        _, _, M2 = unpack_theta(record2.theta, n, m, q)
        U_next = feedforward(P, K_next, M2, settings.R)
        feedforward_learned = True
        history.append(item)
        item2 = _record(
            record2,
            step="feedforward",
            K_applied=K,
            U_applied=U,
            U=U_next,
            previous_theta=previous_theta if previous_theta is not None else record.theta,
            data_seconds=seconds,
        )
        history.append(item2)
        change = _relative_change(record2.theta, previous_theta)
        previous_theta = record2.theta
        U = U_next
        if _settled(change, previous_change, settings.tolerance, settings):
            converged = True
            break
        previous_change = change
        K = K_next
    last = history[-1]
    notes: list[str] = []
    if not two_step:
        deficient = [h for h in history if h.rank < h.unknowns]
        if deficient:
            notes.append(
                f"rank {deficient[-1].rank} of {deficient[-1].unknowns}: with a constant "
                "reference the exogenous block (D + AX)'P is not identifiable (its q columns "
                "per state are collinear), so K and P are learned but the feedforward U is "
                "not (U keeps its initial value); Algorithm 2 perturbs the reference to "
                "learn it"
            )
    P_last, K_last = last.P, last.K
    return TuningResult(
        algorithm=algorithm,
        K=K_last,
        P=P_last,
        X=X,
        U=last.U,
        theta=last.theta,
        B=estimated_B(P_last, K_last, settings.R),
        w=w,
        history=tuple(history),
        data_seconds=seconds,
        converged=converged,
        feedforward_learned=feedforward_learned,
        notes=tuple(notes),
    )


def algorithm1(drive: Drive, settings: TuningSettings, phi_pm: float) -> TuningResult:
    """The paper's Algorithm 1 (one step), on-policy: a new episode each iteration.

    Parameters
    ----------
    drive : Drive
        The drive (e.g. :class:`SimulatedDrive`).
    settings : TuningSettings
    phi_pm : float
        The known magnet flux, Wb.

    Returns
    -------
    TuningResult
        K and P converge to the optimum; U does not (``feedforward_learned`` is False and
        ``notes`` says why: rank 9 of 11 with a constant reference).
    """
    return _on_policy(drive, settings, phi_pm, two_step=False, algorithm="1")


def algorithm2(drive: Drive, settings: TuningSettings, phi_pm: float) -> TuningResult:
    """The paper's Algorithm 2 (two steps), on-policy: a new episode each iteration.

    Parameters
    ----------
    drive : Drive
    settings : TuningSettings
    phi_pm : float
        The known magnet flux, Wb.
    """
    return _on_policy(drive, settings, phi_pm, two_step=True, algorithm="2")


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
    """
    n, m, q = 2, 2, 1
    K = settings.K0
    samples = settings.samples_per_episode
    history: list[TuningIteration] = []
    seconds = 0.0
    previous_theta: Array | None = None
    previous_change = float("inf")
    settled = False
    record: IterationRecord | None = None
    for j in range(settings.max_iterations):
        episode = drive.run_no_load(
            K,
            num_samples=samples,
            exploration=prbs(
                settings.exploration, max(1, settings.no_load_hold // settings.input_hold)
            ),
            seed=settings.seed + j,
        )
        seconds += episode.duration
        record = _step(episode, K, settings, np.zeros((n, q)), iteration=j)
        item = _record(
            record,
            step="no-load",
            K_applied=K,
            U_applied=np.zeros((m, q)),
            U=np.zeros((m, q)),
            previous_theta=previous_theta,
            data_seconds=seconds,
        )
        history.append(item)
        previous_theta = record.theta
        K = record.K
        if _settled(item.change, previous_change, settings.feedback_tolerance, settings):
            settled = True
            break
        previous_change = item.change
    assert record is not None
    if not settled:
        raise ConvergenceError(
            f"Algorithm 3, no-load step: Theta did not settle in {settings.max_iterations} "
            f"iterations (last relative change {history[-1].change:.3g})"
        )
    P, K_next, DP = unpack_theta(record.theta, n, m, q)
    B = estimated_B(P, K_next, settings.R)
    D = np.linalg.solve(P, DP.T)
    L_s = 2.0 / float(np.trace(B))
    phi_pm = -float(D[1, 0]) * L_s
    if not (np.isfinite(phi_pm) and phi_pm > 0 and np.isfinite(L_s) and L_s > 0):
        raise ConvergenceError(
            f"Algorithm 3: identified a non-physical phi_pm = {phi_pm:.4g} Wb, "
            f"L_s = {L_s:.4g} H; check the speed and the data"
        )
    second = _on_policy(
        drive,
        settings,
        phi_pm,
        two_step=True,
        K_start=K_next,
        perturbation="torque",
        algorithm="3",
        history_prefix=tuple(history),
        seconds_before=seconds,
    )
    return replace(second, identified={"phi_pm": phi_pm, "L_s": L_s})


def offpolicy(drive: Drive, settings: TuningSettings, phi_pm: float) -> TuningResult:
    """The off-policy variant: one batch of ``episode_length`` seconds, reused throughout.

    The batch is run once under ``K0`` with exploration on the inputs and the perturbed
    reference together; :func:`~selftune.learning.learn_output_regulation` (customized)
    then iterates on it (at least 50 steps allowed) to its 1e-9 relative tolerance.
    """
    X, w = _known_form(drive, settings, phi_pm)
    C, E, F, _ = known_flux_form(drive.pole_pairs, settings.speed, settings.torque, phi_pm)
    kind = settings.perturbation

    def perturbed(t: Array) -> Array:
        return w + reference_perturbation(t, kind)

    U0 = np.zeros((2, 2))
    batch = drive.run(
        settings.K0,
        X,
        U0,
        held(perturbed),
        num_samples=settings.samples_per_episode,
        exploration=uniform(settings.exploration),
        seed=settings.seed,
        assumed_flux=phi_pm,
    )
    _checked(batch, settings.K0, settings)
    learned = learn_output_regulation(
        batch,
        C,
        E,
        F,
        settings.Q,
        settings.R,
        settings.K0,
        interval=settings.regression_interval(),
        max_iterations=max(settings.max_iterations, 50),
        method="customized",
    )
    history: list[TuningIteration] = []
    previous_theta: Array | None = None
    K_applied = settings.K0
    U_applied = U0
    for record in learned.history:
        P, K_next, M = unpack_theta(record.theta, 2, 2, 2)
        U = feedforward(P, K_next, M, settings.R)
        history.append(
            _record(
                record,
                step="off-policy",
                K_applied=K_applied,
                U_applied=U_applied,
                U=U,
                previous_theta=previous_theta,
                data_seconds=batch.duration,
            )
        )
        previous_theta = record.theta
        K_applied, U_applied = K_next, U
    return TuningResult(
        algorithm="offpolicy",
        K=learned.K,
        P=learned.P,
        X=learned.X,
        U=learned.U,
        theta=learned.theta,
        B=learned.B,
        w=w,
        history=tuple(history),
        data_seconds=batch.duration,
        converged=learned.converged,
        feedforward_learned=True,
    )


def run_algorithm(
    name: AlgorithmName, motor: SPMSM, settings: TuningSettings | None = None
) -> TuningResult:
    """Run a self-tuning session on a simulated ``motor`` (the learner is told only p,
    the speed, the torque reference and, except for Algorithm 3, the flux)."""
    settings = TuningSettings() if settings is None else settings
    drive = SimulatedDrive(
        motor=motor,
        speed=settings.speed,
        sampling=settings.sampling,
        input_hold=settings.input_hold,
    )
    if name == "1":
        return algorithm1(drive, settings, motor.phi_pm)
    if name == "2":
        return algorithm2(drive, settings, motor.phi_pm)
    if name == "3":
        return algorithm3(drive, settings)
    if name == "offpolicy":
        return offpolicy(drive, settings, motor.phi_pm)
    raise InputError(f"algorithm: must be 1, 2, 3 or offpolicy, got {name!r}")


@dataclass(frozen=True)
class TuningEvaluation:
    """A :class:`TuningResult` compared with the model-based optimum (evaluation only).

    Attributes
    ----------
    optimum : ModelBasedSolution
    theta_error : ndarray, shape (iterations,)
        ``||Theta_j - Theta*||`` (2-norm) after each iteration.
    learned_cost : ndarray, shape (iterations,)
        ``xbar(0)' P_j xbar(0)``, the learned cost-to-go of ``K_j`` from ``x(0) = 0``.
    true_cost : ndarray, shape (iterations,)
        The true cost of the applied policy ``(K_j, U_j)`` from ``x(0) = 0``: the cost
        (5) of its transient to its own steady state (equal to (5) when the policy
        regulates, i.e. ``U_j = U*``); ``inf`` if it does not stabilize.
    final_theta_error : float
        ``||Theta - Theta*|| / ||Theta*||`` of the result.
    K_error, U_error : float
        ``||K - K*|| / ||K*||`` and ``||U - U*|| / ||U*||``.
    """

    optimum: ModelBasedSolution
    theta_error: Array
    learned_cost: Array
    true_cost: Array
    final_theta_error: float
    K_error: float
    U_error: float


def policy_true_cost(
    motor: SPMSM, settings: TuningSettings, K: Array, X: Array, U: Array, w: Array
) -> float:
    """Cost (5) of the policy ``u = -K (x - X w) + U w`` from rest, to its own steady state."""
    problem = motor.regulation_problem(settings.speed)
    A, B, D = problem.A, problem.B, problem.D
    w_true = motor.exogenous(settings.speed, settings.torque)
    closed_loop = A - B @ K
    if np.max(np.linalg.eigvals(closed_loop).real) >= 0:
        return float("inf")
    # The controller acts on its own w (identified flux for Algorithm 3); the motor on w_true.
    steady = np.linalg.solve(closed_loop, -(B @ (U + K @ X) @ w + D @ w_true))
    value = policy_value(A, B, K, settings.Q, settings.R)
    start = -steady
    return float(start @ value @ start)


def evaluate(result: TuningResult, motor: SPMSM, settings: TuningSettings) -> TuningEvaluation:
    """Compare a self-tuning result with the model-based optimum of ``motor``."""
    optimum = solve_optimal_regulation(
        motor.regulation_problem(settings.speed), settings.Q, settings.R
    )
    theta_star = optimum.theta
    x_bar0 = -result.X @ result.w
    theta_error = []
    learned_cost = []
    true_cost = []
    for item in result.history:
        if item.theta.shape == theta_star.shape:
            theta_error.append(float(np.linalg.norm(item.theta - theta_star)))
        else:
            theta_error.append(float("nan"))  # Algorithm 3's no-load step has 9 unknowns
        x0 = x_bar0 if item.step != "no-load" else np.zeros(2)
        learned_cost.append(float(x0 @ item.P @ x0) if item.step != "no-load" else float("nan"))
        if item.step == "no-load":
            true_cost.append(float("nan"))
        else:
            true_cost.append(
                policy_true_cost(
                    motor, settings, item.K_applied, result.X, item.U_applied, result.w
                )
            )
    norm = float(np.linalg.norm(theta_star))
    return TuningEvaluation(
        optimum=optimum,
        theta_error=np.array(theta_error),
        learned_cost=np.array(learned_cost),
        true_cost=np.array(true_cost),
        final_theta_error=float(np.linalg.norm(result.theta - theta_star)) / norm,
        K_error=float(np.linalg.norm(result.K - optimum.K)) / float(np.linalg.norm(optimum.K)),
        U_error=float(np.linalg.norm(result.U - optimum.U)) / float(np.linalg.norm(optimum.U)),
    )


def closed_loop_response(
    motor: SPMSM,
    settings: TuningSettings,
    K: Array,
    X: Array,
    U: Array,
    w: Array | None = None,
    duration: float = 0.01,
) -> Trajectory:
    """The torque step from rest under ``u = -K (x - X w) + U w`` (evaluation, from the model).

    Parameters
    ----------
    motor : SPMSM
        The true motor.
    settings : TuningSettings
        Speed, torque reference and sampling period.
    K, X, U : ndarray
        The controller.
    w : ndarray, optional
        The controller's ``w`` (default the true ``[p speed phi_pm, T*]``); Algorithm 3's
        controller uses its identified flux.
    duration : float
        Length of the response, s.
    """
    problem = motor.regulation_problem(settings.speed)
    w_true = motor.exogenous(settings.speed, settings.torque)
    w_controller = w_true if w is None else np.asarray(w, dtype=float)
    # The motor's back-EMF is D w_true; the controller acts on its own w.
    scale = np.divide(w_true, w_controller, out=np.ones_like(w_true), where=w_controller != 0.0)
    D = problem.D @ np.diag(scale)
    return simulate(
        problem.A,
        problem.B,
        D=D,
        exogenous=constant(w_controller),
        K=K,
        X=X,
        U=U,
        h=settings.sampling,
        num_samples=round(duration / settings.sampling),
    )
