"""The settings of a self-tuning session: the paper's experiment, and how to change it."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np

from ..config import RENAMED_KEYS, ConfigTable, MotorConfig
from ..config._motor_file import LEARNING_KEYS
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
from ..core._validation import LIMITS, check_entries, check_range
from ..errors import DataFileError, InputError
from ..learn import Target
from ..model import IPMSM

__all__ = [
    "DRIVE_DEFAULTS",
    "EXPLORED_RESOLUTIONS",
    "TUNING_KEYS",
    "Perturbation",
    "Target",
    "TuningSettings",
    "default_exploration",
    "explored_current",
    "tuning_settings",
]

#: Which channels of the reference Algorithm 2 and off-policy perturb, and how (see
#: :func:`~selftune.tuning.reference_perturbation`).
Perturbation = Literal["paper", "torque", "steps"]


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
    h : float
        Sampling period, s (10 us).
    episode_length : float
        Length of each on-policy episode, s (5 ms); also the off-policy batch length.
    K0 : ndarray
        Initial stabilizing feedback (``20 pi I``, V/A).
    exploration : float
        Amplitude of the uniform exploration on each input, V (1 V).
    perturbation : {"paper", "torque", "steps"}
        Reference perturbation of Algorithm 2 and off-policy (Algorithm 3 uses
        ``"torque"`` instead of ``"paper"``, see :func:`reference_perturbation`);
        ``"steps"`` reverses the torque, which a drive with an inverter needs.
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
        Upper bound on iterations (episodes) of the on-policy algorithms.
    policy_iterations : int
        Upper bound on the policy-iteration steps of one learning run from a batch
        (off-policy, Algorithm 3's second step on a realistic drive; each discount of the
        servo's schedule counts apart): 50.
    feedback_tolerance : float
        epsilon_1: relative change of Theta_1 below which the feedforward is learned.
    tolerance : float
        epsilon_2: relative change of Theta at which the algorithms stop.
    seed : int
        Seed of the exploration (episode j uses ``seed + j``).
    target : {"continuous", "digital"}
        The controller learned: the paper's continuous-time optimum, or the optimum of
        the sampled loop the drive runs, with its computation delay (needs
        ``input_hold = 1``; Algorithms 1 and 2 learn the continuous one only).
    integral_action : bool
        Learn the optimal servo controller: the state augmented with the integral of
        the current error (zero steady error under a constant voltage error or a drifted
        resistance; needs ``input_hold = 1``; off-policy and Algorithm 3).
    dead_time : bool
        Model an inverter's dead time in the learners' evidence
        (:class:`selftune.learn.LearningOptions`), so that it is neither refused nor
        mistaken for back-EMF; on by default for a realistic drive (MOTOR.toml [drive]).
    flux_length : float
        Length of Algorithm 3's flux step, s (0.2).
    Q_i : ndarray, shape (2, 2), or None
        The weight of the integrated current error (with ``integral_action``), symmetric
        positive definite; None: the learner's default
        (:class:`selftune.learn.LearningProblem`).
    """

    speed: float = PAPER_SPEED
    torque: float = PAPER_TORQUE
    Q: Array = field(default_factory=paper_Q)
    R: Array = field(default_factory=paper_R)
    h: float = PAPER_SAMPLING
    episode_length: float = PAPER_EPISODE_LENGTH
    K0: Array = field(default_factory=paper_K0)
    exploration: float = PAPER_EXPLORATION
    perturbation: Perturbation = "paper"
    input_hold: int = 2
    feedforward_exploration: bool = True
    no_load_hold: int = 10
    interval: int = 10
    max_iterations: int = 20
    policy_iterations: int = 50
    feedback_tolerance: float = 1e-4
    tolerance: float = 1e-6
    seed: int = 0
    target: Target = "continuous"
    integral_action: bool = False
    dead_time: bool = False
    flux_length: float = 0.2
    Q_i: Array | None = None

    def __post_init__(self) -> None:
        for name in ("h", "episode_length", "exploration"):
            value = check_range(positive_finite(getattr(self, name), name), name)
            object.__setattr__(self, name, value)
        for name in ("feedback_tolerance", "tolerance"):
            object.__setattr__(self, name, positive_finite(getattr(self, name), name))
        for name in ("speed", "torque"):
            value = check_range(float(as_vector(getattr(self, name), name, 1)[0]), name)
            object.__setattr__(self, name, value)
        for name in ("Q", "R"):
            matrix = check_entries(as_matrix(getattr(self, name), name, (2, 2)), name)
            object.__setattr__(self, name, check_positive_definite(matrix, name))
        object.__setattr__(self, "K0", check_entries(as_matrix(self.K0, "K0", (2, 2)), "K0"))
        if self.Q_i is not None:
            if self.integral_action is not True:
                raise InputError("Q_i: weighs the integrated error; needs integral_action")
            matrix = check_entries(as_matrix(self.Q_i, "Q_i", (2, 2)), "Q_i")
            object.__setattr__(self, "Q_i", check_positive_definite(matrix, "Q_i"))
        if self.perturbation not in ("paper", "torque", "steps"):
            raise InputError(
                f"perturbation: must be 'paper', 'torque' or 'steps', got {self.perturbation!r}"
            )
        if self.target not in ("continuous", "digital"):
            raise InputError(f"target: must be 'continuous' or 'digital', got {self.target!r}")
        for name in ("integral_action", "dead_time"):
            if not isinstance(getattr(self, name), bool):
                raise InputError(f"{name}: must be True or False, got {getattr(self, name)!r}")
        length = positive_finite(self.flux_length, "flux_length")
        length = check_range(length, "flux_length", "episode_length")
        object.__setattr__(self, "flux_length", length)
        for name in (
            "input_hold",
            "no_load_hold",
            "interval",
            "max_iterations",
            "policy_iterations",
        ):
            object.__setattr__(self, name, positive_integer(getattr(self, name), name))
        object.__setattr__(self, "seed", positive_integer(self.seed, "seed", minimum=0))
        if self.samples_per_episode < 2:
            raise InputError(
                f"episode_length: {self.episode_length} s is less than two samples of {self.h} s"
            )
        self._check_sizes()

    def _check_sizes(self) -> None:
        """Bound the samples per episode, the holds and intervals by an episode, and the
        iterations (:data:`~selftune.core._validation.LIMITS`)."""
        samples = self.samples_per_episode
        if samples > LIMITS["episode_samples"]:
            raise InputError(
                f"episode_length: {self.episode_length:g} s of samples of {self.h:g} s"
                f" is {samples} samples per episode; at most {LIMITS['episode_samples']}"
            )
        for name in ("input_hold", "no_load_hold", "interval"):
            if getattr(self, name) > samples:
                raise InputError(
                    f"{name}: {getattr(self, name)} samples is longer than an episode"
                    f" ({samples} samples of {self.h:g} s)"
                )
        for name in ("max_iterations", "policy_iterations"):
            if getattr(self, name) > LIMITS["iterations"]:
                raise InputError(
                    f"{name}: at most {LIMITS['iterations']}, got {getattr(self, name)}"
                )

    @classmethod
    def paper(cls, **changes: object) -> TuningSettings:
        """The paper's Section V exactly: the defaults with the input changing every sample
        (``input_hold = 1``) and the reference perturbed on both channels; Algorithm 3's
        flux step is one cycle of its reference's steps long (40 ms: the paper's drive is
        noise-free); ``changes`` override fields.

        Parameters
        ----------
        **changes
            Field values that override the paper's.
        """
        paper = cls(input_hold=1, flux_length=0.04)
        settings: TuningSettings = replace(paper, **changes)  # type: ignore[arg-type]
        return settings

    @property
    def samples_per_episode(self) -> int:
        """Samples in one episode (and in the off-policy batch)."""
        return round(self.episode_length / self.h)

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
TUNING_KEYS = LEARNING_KEYS


#: With a [drive] table: K0's default as a fraction of the nameplate's deadbeat gain
#: ``L_s / h`` (gentle enough for a delay of up to two samples), the exploration's as a
#: fraction of the DC-bus voltage (an interior motor's without a [saturation] table:
#: ``interior_exploration_fraction``, raised up to ``interior_exploration_cap`` where its
#: current is small against the measurement's resolution, see
#: :func:`default_exploration`), and the batch length, s.
DRIVE_DEFAULTS = {
    "K0_fraction": 0.0125,
    "exploration_fraction": 0.02,
    "interior_exploration_fraction": 0.03,
    "interior_exploration_cap": 0.10,
    "episode_length": 0.1,
}

#: The least rms current, on each axis, an interior motor's default exploration drives
#: under the default K0 (:func:`explored_current`), in current measurement resolutions
#: (:attr:`~selftune.sim.DriveSettings.current_resolution`): see
#: :func:`default_exploration`.
EXPLORED_RESOLUTIONS = 60.0


def explored_current(motor: IPMSM, h: float, exploration: float) -> Array:
    """The rms d and q currents, A, that a uniform exploration of ``+-exploration`` (V)
    on each axis drives through the nameplate ``motor`` under the default K0 (each axis
    a first-order loop, the cross-coupling and the delay left out): each sample keeps
    ``a = 1 - R_s h / L - K0_fraction`` of the current and adds ``h / L`` times a
    uniform voltage of variance ``exploration^2 / 3``, so the current's variance is
    ``(exploration h / L)^2 / 3 / (1 - a^2)``.

    Parameters
    ----------
    motor : IPMSM
        The nameplate (``R_s``, ohm; ``L_d``, ``L_q``, H).
    h : float
        Sampling period, s.
    exploration : float
        The exploration's amplitude, V.
    """
    L = np.array([motor.L_d, motor.L_q])
    decay = motor.R_s * h / L + DRIVE_DEFAULTS["K0_fraction"]
    return exploration * h / L / np.sqrt(3.0 * decay * (2.0 - decay))


def default_exploration(config: MotorConfig, h: float | None = None) -> float:
    """The exploration a motor file's realistic drive takes unless its ``[learning]``
    sets one, V: :data:`DRIVE_DEFAULTS`' share of the DC bus (the paper's 1 V without a
    bus).

    An interior motor (``L_d != L_q``) without [saturation] explores at 3% of the bus,
    not 2%: its identification separates L_d, L_q and the dead time's voltage, and near
    zero current the noise decides the phase currents' signs, whose dead-time voltage the
    exploration must outweigh. On 30 random interior motors (``measure_interior_draws``,
    seed 13: the hardware-like drive, carrier PWM, 2 V of dead time on 540 V, 0.5 us on
    48 V, 0.5 s of data) the largest standard error of L_d or L_q fell from 0.80% to
    0.31% and the largest error from 0.64% to 0.29%; on 30 others (seed 14) from 1.21%
    to 0.60% and from 0.64% to 0.52%. At 4% a 48 V motor of the 30 was refused (its
    model's output errors correlated with the inputs). A saturating motor keeps 2%: a
    larger exploration spreads each level's currents over more of the saturation
    (:mod:`~._curvature`).

    Where the current that 3% drives (:func:`explored_current`) is under
    :data:`EXPLORED_RESOLUTIONS` of the current measurement's resolution on an axis (a
    large inductance whose resistance damps it, on an ADC coarse for its current), the
    exploration is raised until it is not, to at most 10% of the bus: the inductances'
    standard errors shrink as that ratio grows. On the 30 of seed 13 (ADC steps of 24.4
    mA, 10 mA of noise) six 540 V motors of 8.9-90 mH are raised, to 31.5-54 V; at 5% of
    rated speed the largest error of L_d, L_q or the flux fell from 0.97% to 0.26%
    (drawn 26, 17.7/44.3 mH, 0.24 A rated, to 0.07%; drawn 9, 26.3/65.7 mH, from 0.90%
    to 0.06%), at 30% from 0.64% to 0.24%, at rated speed from 0.29% to 0.18%; no motor
    was refused, and the 48 V motors (whose 1.44 V drives amperes) were not raised. At
    20 resolutions instead of 30 drawn 28 (12/30 mH, raised to 24 V rather than 36 V)
    had L_d's standard error 0.29% at 30% of rated speed, at 30 0.16%. At 60 instead of
    30 the 30 of seed 14 at 5%, 30% and 100% of rated speed had their largest error of
    L_d, L_q or the flux at 0.30%, 0.12% and 0.15% (1.09%, 0.57% and 0.70%: drawn 5,
    16.4/24.6 mH rated 0.25 A, raised from 26 V to 52 V), seed 13's at 0.07%, 0.15% and
    0.07% (0.08%, 0.24%, 0.18%), no motor refused that 30 learned; seed 14's drawn 1
    (4.5/11.3 mH rated 0.28 A) at 5% has its flux 0.13% off at 3.9 standard errors (0.02%
    at 0.4). The exploration's current is then up to 6 times such a small motor's rated
    current for the experiment's 0.5 s; ``[learning] exploration`` sets a smaller one.

    Parameters
    ----------
    config : MotorConfig
        The motor file (its drive's ``dc_voltage``, V, noise and ADC; its motor and
        [saturation]).
    h : float, optional
        The sampling period, s (default: the drive's, else the paper's).
    """
    drive = config.drive
    if drive is None or drive.dc_voltage is None:
        return PAPER_EXPLORATION
    motor = config.motor
    if not isinstance(motor, IPMSM) or motor.L_d == motor.L_q or config.saturation is not None:
        return DRIVE_DEFAULTS["exploration_fraction"] * drive.dc_voltage
    exploration = DRIVE_DEFAULTS["interior_exploration_fraction"] * drive.dc_voltage
    h = (config.drive_h or PAPER_SAMPLING) if h is None else h
    wanted = EXPLORED_RESOLUTIONS * drive.current_resolution
    raised = exploration * wanted / float(np.min(explored_current(motor, h, exploration)))
    cap = DRIVE_DEFAULTS["interior_exploration_cap"] * drive.dc_voltage
    return float(min(max(exploration, raised), max(exploration, cap)))


@dataclass(frozen=True)
class _Defaults:
    """The defaults of a motor file's [learning] keys (not validated: the settings are)."""

    h: float
    K0: Array
    exploration: float
    episode_length: float = PAPER_EPISODE_LENGTH
    input_hold: int = 2
    target: str = "continuous"
    dead_time: bool = False
    perturbation: str = "paper"


def _drive_defaults(config: MotorConfig, table: ConfigTable) -> _Defaults:
    """The defaults of this file: the paper's, or a realistic drive's (the paper's are for
    its ideal drive)."""
    h = table.ranged("h", PAPER_SAMPLING)
    drive = config.drive
    if drive is None:
        return _Defaults(h, paper_K0(), PAPER_EXPLORATION)
    if config.drive_h is not None:
        if "h" in table and abs(h - config.drive_h) > 1e-9 * h:
            raise table.error(
                "h",
                f"{h:g} s disagrees with the [drive] switching_frequency "
                f"({1.0 / config.drive_h:g} Hz: one PWM period per sample)",
            )
        h = config.drive_h
    return _Defaults(
        h=h,
        K0=DRIVE_DEFAULTS["K0_fraction"] * np.diag([config.motor.L_d, config.motor.L_q]) / h,
        exploration=default_exploration(config, h),
        episode_length=DRIVE_DEFAULTS["episode_length"],
        input_hold=1,
        target="digital",
        dead_time=True,
        perturbation="steps",
    )


def tuning_settings(
    config: MotorConfig, seed: int = 0, target: str | None = None, algorithm: str | None = None
) -> TuningSettings:
    """The self-tuning settings of a motor file: its operating point, cost and [learning].

    ``[learning]`` may set ``h`` (the sampling period, s; formerly ``sampling``),
    ``episode_length`` (s), ``K0`` (2x2, V/A), ``exploration`` (V), ``input_hold``
    (samples per controller update), ``interval`` (samples), ``max_iterations``,
    ``policy_iterations``, ``target``, ``integral_action``, ``dead_time``,
    ``perturbation`` and ``flux_length`` (s). Absent keys take the defaults of
    :class:`TuningSettings` (the paper's values, but ``input_hold = 2``: the controller at
    half the sampling rate, which lets the learner integrate the data to fourth order).
    With a ``[drive]`` table (a realistic drive) the defaults are a drive's instead: the
    sampling period of its switching frequency, ``input_hold = 1``, the digital target,
    the dead time modelled, the ``"steps"`` perturbation, a 0.1 s batch, K0 at 1.25% of
    the nameplate's deadbeat gain ``L_s / h`` and exploration at 2% of the DC-bus voltage,
    3% for an interior motor without [saturation] (:func:`default_exploration`).

    Parameters
    ----------
    config : MotorConfig
        The motor file's content.
    seed : int
        Seed of the exploration.
    target : {"continuous", "digital"}, optional
        Overrides the file's ``target`` (the command line's ``--target``); the digital
        target's controller updates every sample, so ``input_hold`` then defaults to 1.
    algorithm : {"1", "2", "3", "offpolicy"}, optional
        The session's algorithm (``selftune tune --algorithm``), where it runs one.

    Returns
    -------
    TuningSettings

    Raises
    ------
    DataFileError
        Naming the file and the key, for an unknown key or a bad value; or naming
        ``[operating_point] torque`` or ``speed`` where the commissioning has nothing to
        learn a part of the law from there (:func:`_check_learnable_point`).
    InputError
        If ``target`` is not one of the two.
    """
    table = ConfigTable(
        config.source, "learning", config.learning, TUNING_KEYS, RENAMED_KEYS["learning"]
    )
    defaults = _drive_defaults(config, table)
    if target is not None:
        if target not in ("continuous", "digital"):
            raise InputError(f"target: must be 'continuous' or 'digital', got {target!r}")
        hold = 1 if target == "digital" else defaults.input_hold
        defaults = replace(defaults, target=target, input_hold=hold)
    elif table.choice("target", ("continuous", "digital"), defaults.target) == "digital":
        defaults = replace(defaults, input_hold=1)
    try:
        settings = TuningSettings(
            speed=config.speed,
            torque=config.torque,
            Q=config.Q,
            R=config.R,
            h=defaults.h,
            episode_length=table.ranged("episode_length", defaults.episode_length),
            K0=table.matrix("K0", (2, 2), defaults.K0),
            exploration=table.ranged("exploration", defaults.exploration),
            input_hold=table.positive_integer("input_hold", defaults.input_hold),
            interval=table.positive_integer("interval", TuningSettings.interval),
            max_iterations=table.positive_integer("max_iterations", TuningSettings.max_iterations),
            policy_iterations=table.positive_integer(
                "policy_iterations", TuningSettings.policy_iterations
            ),
            seed=seed,
            target=_target(
                defaults.target
                if target is not None
                else table.choice("target", ("continuous", "digital"), defaults.target)
            ),
            integral_action=table.flag("integral_action", False),
            dead_time=table.flag("dead_time", defaults.dead_time),
            perturbation=_perturbation(
                table.choice("perturbation", ("paper", "torque", "steps"), defaults.perturbation)
            ),
            flux_length=table.ranged("flux_length", TuningSettings.flux_length, "episode_length"),
            Q_i=config.Q_i,
        )
    except DataFileError:
        raise
    except InputError as exc:  # a rule across keys: name the key it is about
        key, _, reason = str(exc).partition(": ")
        if key in TUNING_KEYS:
            raise table.error(key, reason) from None
        raise table.error(None, str(exc)) from None
    _check_learnable_point(config, settings.perturbation, algorithm)
    return settings


def _check_learnable_point(
    config: MotorConfig, perturbation: Perturbation, algorithm: str | None
) -> None:
    """Refuse an operating point whose commissioning has nothing to learn a part of the
    law from, naming the ``[operating_point]`` key (the learner's rank check refused it
    before, in the regression's own names, ``w1`` and ``w2``, which the file has not).

    - T* = 0 where the torque reference walks through
      :data:`~._knowledge.STEP_LEVELS` times T* (the ``"steps"`` perturbation, a
      ``[drive]``'s default; the interior, saturating and staircase commissioning; the
      flux step of Algorithm 3): every reference is then zero.
    - Standstill where the back-EMF reference ``p speed phi_pm`` is not perturbed (a
      ``[drive]``'s law learned at the operating speed, but a surface motor's staircase
      over its ``[schedule]``; the ``"paper"`` perturbation perturbs it), and for
      Algorithm 3, which reads the flux off the back-EMF: it is zero in every sample.
    """
    drive = config.drive is not None
    session = config.saturation is None and not isinstance(config.motor, IPMSM)
    staircase = session and config.schedule is not None
    single = session and config.schedule is None  # the algorithm's own perturbation
    flux = single and algorithm == "3"
    table = ConfigTable(config.source, "operating_point", {}, ("speed", "torque"))
    steps = drive and (not single or perturbation == "steps")
    if config.torque == 0.0 and (steps or flux):
        raise table.error(
            "torque",
            "0 N m: the commissioning walks the torque reference through +-T* (reversing "
            "the current, so that the inverter's dead time cannot pass for back-EMF), and "
            "T* = 0 leaves every reference at zero, so the controller's feedforward "
            "cannot be learned; give the torque the drive runs at (its rated torque, say)",
        )
    unperturbed = drive and not staircase and (not single or perturbation != "paper")
    if config.speed == 0.0 and (unperturbed or flux):
        raise table.error(
            "speed",
            "0 rad/s: the law is learned at this speed, and at standstill the back-EMF "
            "reference p speed phi_pm is zero in every sample, so its feedforward (and "
            "Algorithm 3's flux) cannot be learned; tune at a speed the drive runs at (a "
            "[schedule] table designs the law over a range of speeds down to standstill)",
        )


def _target(value: str) -> Target:
    return "digital" if value == "digital" else "continuous"


def _perturbation(value: str) -> Perturbation:
    return "steps" if value == "steps" else ("torque" if value == "torque" else "paper")
