"""The experiment of the noise, honesty and calibration studies (issue 11), their truth, and
the one learning run of every seeded study (:func:`attempt`).

A motor held at a speed by a load machine, on the library's realistic drive
(:func:`~selftune.sim.run_drive_batch`), under a gentle initial controller ``K0`` (1.25% of
the deadbeat gain ``L_s / h``: stable with a computation delay of one or two samples):

- exploration uniform within ``EXPLORATION_FRACTION`` (2%) of a ``DC_VOLTAGE`` (540 V)
  bus on each axis, a new value every sample;
- a torque reference with a +-30% square ripple (20 Hz) and a +-10% sine ripple (130 Hz)
  about ``T*``, so that the feedforward is identifiable;
- the drive's effects as :class:`~selftune.sim.DriveSettings` says (computation delay,
  white noise on the measured phase currents inside the loop, ADC, dead time, PWM).

The reference experiment of the issue is :data:`REFERENCE` (0.6 ohm, 8 mH, 0.35 Wb, p = 3,
50 rad/s, T* = 5 N m). What the learner knows is :meth:`Experiment.known`: the cost
``Q = 1e3 I``, ``R = I``, K0 and the regulated output (C = I and F, which follows from the
flux the drive's torque reference assumes). The truth (:meth:`Experiment.digital_optimum`,
:meth:`Experiment.continuous_optimum`) is the model-based optimum of the true motor,
computed here and only to score the learners.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from ..core import Array, ControlLaw
from ..errors import SelftuneError
from ..learn import (
    LearnedController,
    LearningOptions,
    LearningProblem,
    Trajectory,
    learn_controller,
)
from ..model import (
    SPMSM,
    ModelBasedSolution,
    RegulationProblem,
    solve_digital_regulation,
    solve_optimal_regulation,
)
from ..sim import DriveRecord, DriveSettings, held, run_drive_batch, uniform
from ._causes import refusal_cause
from ._common import relative
from ._motors import Choice, MotorRanges, Span, draw_motor

__all__ = [
    "DC_VOLTAGE",
    "EXPERIMENT_RANGES",
    "EXPLORATION_FRACTION",
    "MOTOR_RANGES_TEXT",
    "REFERENCE",
    "Attempt",
    "Experiment",
    "Learned",
    "Refused",
    "attempt",
    "delayed_drive",
    "random_experiment",
    "truncated",
]

#: The DC-bus voltage whose fraction is the exploration amplitude, V.
DC_VOLTAGE = 540.0
#: Exploration amplitude as a fraction of the DC-bus voltage.
EXPLORATION_FRACTION = 0.02
#: The torque reference's square ripple (fraction of T*) and its frequency, Hz.
SQUARE_RIPPLE, SQUARE_HZ = 0.3, 20.0
#: The torque reference's sine ripple (fraction of T*) and its frequency, Hz.
SINE_RIPPLE, SINE_HZ = 0.1, 130.0
#: The cost weights of every study: ``Q = 1e3 I``, ``R = I``.
STATE_WEIGHT, INPUT_WEIGHT = 1e3, 1.0


@dataclass(frozen=True)
class Experiment:
    """A motor at a speed and torque reference, sampled at h (see the module docstring).

    Attributes
    ----------
    motor : SPMSM
        The true motor.
    speed : float
        Held mechanical speed, rad/s.
    torque : float
        Torque reference T*, N m (before the ripples).
    h : float
        Sampling period, s.
    """

    motor: SPMSM
    speed: float
    torque: float
    h: float

    @property
    def electrical_speed(self) -> float:
        """``p speed``, rad/s."""
        return self.motor.p * self.speed

    @property
    def K0(self) -> Array:
        """The initial controller: 1.25% of the deadbeat gain ``L_s / h``, V/A."""
        return 0.0125 * self.motor.L_s / self.h * np.eye(2)

    def problem(self) -> RegulationProblem:
        """The true known-flux regulation problem."""
        return self.motor.regulation_problem(self.speed)

    def known(self) -> tuple[LearningProblem, Array]:
        """What the learner knows: cost, C and F (no A, B or D), and the K0 of the log."""
        weights = (STATE_WEIGHT * np.eye(2), INPUT_WEIGHT * np.eye(2))
        return LearningProblem(*weights, C=np.eye(2), F=self.problem().F), self.K0

    def digital_optimum(self, delay: int, hold: str) -> ModelBasedSolution:
        """The optimum of the digital cost on the true sampled loop with a delay of d
        samples; ``hold`` is what the inverter holds over a sample (``"rotor"``: the dq
        zero-order hold; ``"stationary"``: a PWM inverter's stationary-frame vector)."""
        plant = None if hold == "rotor" else self.motor.sampled_plant(self.speed, self.h, hold)
        return solve_digital_regulation(
            self.problem(), STATE_WEIGHT * np.eye(2), INPUT_WEIGHT * np.eye(2), self.h,
            input_delay=delay, plant=plant,
        )  # fmt: skip

    def continuous_optimum(self) -> ModelBasedSolution:
        """The paper's continuous-time optimum K*, U*."""
        return solve_optimal_regulation(
            self.problem(), STATE_WEIGHT * np.eye(2), INPUT_WEIGHT * np.eye(2)
        )

    def truths(self) -> dict[str, tuple[Array, Array]]:
        """``(K*, U*)`` of each target on the drive of :func:`delayed_drive`: ``"digital"``
        (:meth:`digital_optimum` with one sample of delay, dq hold) and ``"continuous"``
        (:meth:`continuous_optimum`)."""
        digital, continuous = self.digital_optimum(1, "rotor"), self.continuous_optimum()
        return {"digital": (digital.K, digital.U), "continuous": (continuous.K, continuous.U)}

    def records(
        self, settings: DriveSettings, seconds: float, seeds: Sequence[int]
    ) -> list[DriveRecord]:
        """One log per seed (independent exploration and noise), in one vectorized run.

        Parameters
        ----------
        settings : DriveSettings
            The drive's effects.
        seconds : float
            Length of each log, s.
        seeds : sequence of int
            The seed of each log.
        """
        base = self.motor.exogenous(self.speed, self.torque)
        torque = self.torque

        def reference(t: Array) -> Array:
            ripple = SQUARE_RIPPLE * torque * np.sign(np.sin(2 * np.pi * SQUARE_HZ * t))
            ripple = ripple + SINE_RIPPLE * torque * np.sin(2 * np.pi * SINE_HZ * t)
            return base + np.column_stack([0.0 * t, ripple])

        law = ControlLaw.regulator(self.K0, -self.problem().F, np.zeros((2, 2)))
        return run_drive_batch(
            [self.motor] * len(seeds), self.speed, self.h, settings, law, held(reference),
            num_samples=max(round(seconds / self.h), 1),
            exploration=uniform(EXPLORATION_FRACTION * DC_VOLTAGE), seed=list(seeds),
        )  # fmt: skip

    def logs(
        self, settings: DriveSettings, seconds: float, seeds: Sequence[int]
    ) -> list[Trajectory]:
        """What the drive logs, one per seed (:meth:`records`)."""
        return [record.trajectory for record in self.records(settings, seconds, seeds)]


def delayed_drive(noise: float) -> DriveSettings:
    """The library's drive with a one-sample computation delay, the dq zero-order hold and
    white noise on the measured phase currents (the noise and calibration studies').

    Parameters
    ----------
    noise : float
        Noise on each measured phase current, A rms.
    """
    return replace(DriveSettings.ideal(), input_delay=1, current_noise=noise)


#: The reference experiment of issue 11 at 10 kHz.
REFERENCE = Experiment(SPMSM(R_s=0.6, L_s=8e-3, phi_pm=0.35, p=3), speed=50.0, torque=5.0, h=1e-4)


#: The ranges of :func:`random_experiment`, in the order drawn.
EXPERIMENT_RANGES = MotorRanges(
    draws=(
        ("R_s_ohm", Span(0.05, 2.0, log=True)),
        ("L_s_henry", Span(5e-4, 3e-2, log=True)),
        ("phi_pm_weber", Span(0.02, 0.5, log=True)),
        ("pole_pairs", Choice((2, 3, 4, 5, 6, 7, 8))),
        ("current_amperes", Span(2.0, 15.0, log=True)),
        ("electrical_speed_rad_per_second", Span(100.0, 2000.0, log=True)),
        ("sampling_frequency_hz", Choice((1e4, 2e4))),
    ),
    speed_cap_volts=150.0,
)
#: The ranges of :func:`random_experiment`, in words.
MOTOR_RANGES_TEXT = (
    "R_s 0.05-2 ohm, L_s 0.5-30 mH, phi_pm 0.02-0.5 Wb (log-uniform), p 2-8, i_q* 2-15 A, "
    "100-2,000 rad/s electrical (capped so that the back-EMF and w_e L_s i_q* stay under "
    "150 V), 10 or 20 kHz"
)


def random_experiment(rng: np.random.Generator) -> Experiment:
    """A plausible motor, operating point and sampling rate (:data:`EXPERIMENT_RANGES`).

    Parameters
    ----------
    rng : numpy.random.Generator
        The generator (the studies seed their own: their motors are not the tests').
    """
    drawn = draw_motor(rng, EXPERIMENT_RANGES)
    assert drawn.sampling_frequency is not None
    nameplate, _ = drawn.surface()
    return Experiment(nameplate, drawn.speed, drawn.torque, h=1.0 / drawn.sampling_frequency)


def truncated(log: Trajectory, samples: int) -> Trajectory:
    """The first ``samples`` samples of a log (its first ``samples * h`` seconds)."""
    w = None if log.w is None else log.w[: samples + 1]
    angle = None if log.angle is None else log.angle[: samples + 1]
    return Trajectory(
        t=log.t[: samples + 1], x=log.x[: samples + 1], u=log.u[:samples], w=w, angle=angle
    )


@dataclass(frozen=True)
class Learned:
    """A learning run that returned a controller.

    Attributes
    ----------
    controller : LearnedController
    seconds : float
        Wall time of :func:`~selftune.learn.learn_controller`, s.
    """

    controller: LearnedController
    seconds: float

    def errors(self, truth: tuple[Array, Array]) -> tuple[float, float]:
        """``||K - K*|| / ||K*||`` and ``||U - U*|| / ||U*||`` against the truth ``(K*, U*)``.

        Parameters
        ----------
        truth : (ndarray, ndarray)
            K* and U* of the target learned for.
        """
        learned = self.controller
        return relative(learned.K, truth[0]), relative(learned.U, truth[1])


@dataclass(frozen=True)
class Refused:
    """A learning run that refused (or whose log was refused as read).

    Attributes
    ----------
    error : SelftuneError
    seconds : float
        Wall time of the run until it refused, s.
    """

    error: SelftuneError
    seconds: float

    @property
    def cause(self) -> str:
        """The cause the message names (:func:`~._causes.refusal_cause`)."""
        return refusal_cause(self.error)

    @property
    def message(self) -> str:
        """The exception's class and message."""
        return f"{type(self.error).__name__}: {self.error}"


#: What became of a learning run.
Attempt = Learned | Refused


def attempt(
    log: Trajectory | Callable[[], Trajectory],
    known: tuple[LearningProblem, Array],
    options: LearningOptions,
) -> Attempt:
    """One seeded trial's learning run: the learned controller or the refusal, timed.

    Parameters
    ----------
    log : Trajectory or callable
        The log, or what makes it as read (a refusal there is the run's refusal).
    known : (LearningProblem, ndarray)
        What the learner knows: the problem, and the K0 the log was taken under.
    options : LearningOptions
        How it learns.

    Returns
    -------
    Learned or Refused
        The outcome is recorded; the learner's floating-point warnings are not shown.
    """
    started = time.perf_counter()
    try:
        if callable(log):
            log = log()
            started = time.perf_counter()
        with np.errstate(all="ignore"):
            learned = learn_controller(log, *known, options)
    except SelftuneError as error:
        return Refused(error, time.perf_counter() - started)
    return Learned(learned, time.perf_counter() - started)
