"""The settings of a self-tuning session: the paper's experiment, and how to change it."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Literal

from ..config import ConfigTable, MotorConfig
from ..core import (
    PAPER_EPISODE_LENGTH,
    PAPER_EXPLORATION,
    PAPER_SAMPLING,
    PAPER_SPEED,
    PAPER_TORQUE,
    Array,
    as_matrix,
    as_vector,
    check_positive_definite,
    paper_K0,
    paper_Q,
    paper_R,
    positive_finite,
    positive_integer,
)
from ..errors import DataFileError, InputError

__all__ = ["TUNING_KEYS", "Perturbation", "TuningSettings", "tuning_settings"]

#: Which channels of the reference Algorithm 2 and off-policy perturb (see
#: :func:`~selftune.tuning.reference_perturbation`).
Perturbation = Literal["paper", "torque"]


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
        (:mod:`selftune.learn`): on 300 random motors (R_s 0.1-3 ohm, L_s 3-100 mH,
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

    speed: float = PAPER_SPEED
    torque: float = PAPER_TORQUE
    Q: Array = field(default_factory=paper_Q)
    R: Array = field(default_factory=paper_R)
    sampling: float = PAPER_SAMPLING
    episode_length: float = PAPER_EPISODE_LENGTH
    K0: Array = field(default_factory=paper_K0)
    exploration: float = PAPER_EXPLORATION
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
            object.__setattr__(self, name, positive_integer(getattr(self, name), name))
        object.__setattr__(self, "seed", positive_integer(self.seed, "seed", minimum=0))
        if self.samples_per_episode < 2:
            raise InputError(
                f"episode_length: {self.episode_length} s is less than two samples of "
                f"{self.sampling} s"
            )

    @classmethod
    def paper(cls, **changes: object) -> TuningSettings:
        """The paper's Section V exactly: the defaults with the input changing every sample
        (``input_hold = 1``) and the reference perturbed on both channels; ``changes``
        override fields.

        Parameters
        ----------
        **changes
            Field values that override the paper's.
        """
        settings: TuningSettings = replace(cls(input_hold=1), **changes)  # type: ignore[arg-type]
        return settings

    @property
    def samples_per_episode(self) -> int:
        """Samples in one episode (and in the off-policy batch)."""
        return round(self.episode_length / self.sampling)

    def regression_interval(self, unknowns: int = 11) -> int:
        """Samples per regression interval: ``interval``, made a multiple of ``input_hold``
        (so no hold is split) and shortened if an episode would give fewer than three rows
        per unknown.

        Parameters
        ----------
        unknowns : int, optional
            Number of unknowns of the regression (default 11, the size of Theta).
        """
        hold = self.input_hold
        interval = max(hold, -(-self.interval // hold) * hold)
        while interval > hold and self.samples_per_episode // interval < 3 * unknowns:
            interval -= hold
        return interval


#: Keys of MOTOR.toml's optional [learning] table (``selftune tune``).
TUNING_KEYS = (
    "sampling",
    "episode_length",
    "K0",
    "exploration",
    "input_hold",
    "interval",
    "max_iterations",
)


def tuning_settings(config: MotorConfig, seed: int = 0) -> TuningSettings:
    """The self-tuning settings of a motor file: its operating point, cost and [learning].

    ``[learning]`` may set ``sampling`` (s), ``episode_length`` (s), ``K0`` (2x2, V/A),
    ``exploration`` (V), ``input_hold`` (samples per controller update), ``interval``
    (samples) and ``max_iterations``; absent keys take the defaults of
    :class:`TuningSettings` (the paper's values, but ``input_hold = 2``: the controller at
    half the sampling rate, which lets the learner integrate the data to fourth order).

    Parameters
    ----------
    config : MotorConfig
        The motor file's content.
    seed : int
        Seed of the exploration.

    Returns
    -------
    TuningSettings

    Raises
    ------
    DataFileError
        Naming the file and the key, for an unknown key or a bad value.
    """
    defaults = TuningSettings()
    table = ConfigTable(config.source, "learning", config.learning, TUNING_KEYS)
    try:
        return TuningSettings(
            speed=config.speed,
            torque=config.torque,
            Q=config.Q,
            R=config.R,
            sampling=table.positive("sampling", defaults.sampling),
            episode_length=table.positive("episode_length", defaults.episode_length),
            K0=table.matrix("K0", (2, 2), defaults.K0),
            exploration=table.positive("exploration", defaults.exploration),
            input_hold=table.positive_integer("input_hold", defaults.input_hold),
            interval=table.positive_integer("interval", defaults.interval),
            max_iterations=table.positive_integer("max_iterations", defaults.max_iterations),
            seed=seed,
        )
    except DataFileError:
        raise
    except InputError as exc:
        raise table.error(None, str(exc)) from None
