"""The corpus of the refusals study (bench study 10): its motors, its two plants, its logs.

Five motors (:data:`MOTORS`: the README's, the paper's, a 48 V low-inductance one, one
above 1,000 rad/s electrical, a large slow one), each logged by two plants
(:data:`PLANTS`):

- ``"realistic drive"``: the library's :class:`~selftune.sim.RealisticDrive` with its
  hardware-like settings (carrier PWM, stationary-frame hold with the usual angle
  compensation, one-sample computation delay, the commanded voltages logged);
- ``"exact dq"``: an independent simulator written here (:func:`exact_dq_log`), not the
  library's: the surface-PMSM dq model at constant electrical speed, discretized exactly
  (scipy's matrix exponential) for a dq zero-order hold of the applied voltage, the
  voltage applied one sample after it was commanded, the inverter's dead time as
  ``-v sign(i_x)`` on each phase, held in the stationary frame over the sample (the
  signs of the true phase currents at the sample's start, turned into dq with the true
  angle, exactly), white noise on the three measured phase currents, and a 12-bit ADC.

Both run the README's experiment: a gentle ``K0`` (:attr:`~._experiment.Experiment.K0`)
with the back-EMF fed forward, the torque reference stepping through ``+-T*`` and
``+-T*/3`` every 10 ms (:func:`~selftune.tuning.reference_perturbation`, ``"steps"``),
uniform exploration of :data:`~._experiment.EXPLORATION_FRACTION` of the motor's bus on
each voltage; 1-50 mA of noise and 0.5-2 V of dead time (drawn per motor and plant,
seeded; the seeds of one motor and plant are siblings: another exploration and noise).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.linalg

from ..core import PAPER_MOTOR, PAPER_SPEED, PAPER_TORQUE, Array, ControlLaw
from ..learn import Trajectory
from ..model import SPMSM
from ..sim import DriveSettings, RealisticDrive, held, uniform
from ..tuning import reference_perturbation
from ._experiment import EXPLORATION_FRACTION, Experiment
from ._motors import Span

__all__ = [
    "ADC_BITS",
    "CORPUS_SEED",
    "MOTORS",
    "PLANTS",
    "CorpusLog",
    "CorpusMotor",
    "RefusalsConfig",
    "corpus_logs",
    "exact_dq_log",
    "recorded",
]

#: Seed of the generator of each log's noise and dead time (no test uses it).
CORPUS_SEED = 16_000_016
#: The plants that log the corpus.
PLANTS = ("realistic drive", "exact dq")
#: ADC resolution of both plants, bits.
ADC_BITS = 12
#: The back-EMF fed forward by the logging law: ``u_q += p speed phi_pm``.
BACK_EMF_FEEDFORWARD = np.array([[0.0, 0.0], [1.0, 0.0]])


@dataclass(frozen=True)
class CorpusMotor:
    """A motor of the corpus, its operating point and its drive.

    Attributes
    ----------
    name_text : str
    R_s_ohm, L_s_henry, phi_pm_weber : float
    pole_pairs_count : int
    speed_rad_per_second : float
        Held mechanical speed.
    torque_newton_meters : float
        T*, the torque reference's amplitude.
    sampling_frequency_hz : float
    dc_voltage_volts : float
        The bus (its fraction is the exploration; the dead time's reference).
    adc_range_amperes : float
        The ADC's full scale ``+-adc_range`` (12 bits).
    """

    name_text: str
    R_s_ohm: float
    L_s_henry: float
    phi_pm_weber: float
    pole_pairs_count: int
    speed_rad_per_second: float
    torque_newton_meters: float
    sampling_frequency_hz: float
    dc_voltage_volts: float
    adc_range_amperes: float

    @property
    def experiment(self) -> Experiment:
        """The motor, speed, torque and sampling period."""
        motor = SPMSM(
            R_s=self.R_s_ohm, L_s=self.L_s_henry, phi_pm=self.phi_pm_weber,
            p=self.pole_pairs_count,
        )  # fmt: skip
        return Experiment(
            motor, self.speed_rad_per_second, self.torque_newton_meters,
            1.0 / self.sampling_frequency_hz,
        )  # fmt: skip

    @property
    def adc_step_amperes(self) -> float:
        """The ADC's step (one least significant bit), A."""
        return 2.0 * self.adc_range_amperes / 2**ADC_BITS

    def text(self) -> str:
        """The motor in one line."""
        electrical = self.pole_pairs_count * self.speed_rad_per_second
        return (
            f"{self.name_text} (R_s = {self.R_s_ohm:g} ohm, L_s = {self.L_s_henry * 1e3:g} mH, "
            f"phi_pm = {self.phi_pm_weber * 1e3:g} mWb, p = {self.pole_pairs_count}, "
            f"{electrical:g} rad/s electrical, T* = {self.torque_newton_meters:g} N m, "
            f"{self.sampling_frequency_hz / 1e3:g} kHz, {self.dc_voltage_volts:g} V bus, "
            f"ADC +-{self.adc_range_amperes:g} A: {self.adc_step_amperes * 1e3:.3g} mA steps)"
        )


#: The motors of the corpus: the README's; the paper's at its operating point, sampled at
#: 10 kHz; a 48 V low-inductance one at 20 kHz; one at 1,600 rad/s electrical at 10 kHz;
#: a large slow one at 5 kHz.
MOTORS = (
    CorpusMotor("README", 0.6, 8e-3, 0.35, 3, 50.0, 5.0, 1e4, 540.0, 50.0),
    CorpusMotor(
        "paper",
        PAPER_MOTOR["R_s"],
        PAPER_MOTOR["L_s"],
        PAPER_MOTOR["phi_pm"],
        int(PAPER_MOTOR["p"]),
        PAPER_SPEED,
        PAPER_TORQUE,
        1e4,
        540.0,
        50.0,
    ),
    CorpusMotor("48 V", 0.08, 0.9e-3, 0.01, 4, 300.0, 1.2, 2e4, 48.0, 100.0),
    CorpusMotor("fast", 0.3, 2e-3, 0.05, 4, 400.0, 2.0, 1e4, 540.0, 50.0),
    CorpusMotor("large slow", 0.05, 2e-3, 1.2, 8, 10.0, 500.0, 5e3, 540.0, 200.0),
)


@dataclass(frozen=True)
class RefusalsConfig:
    """Sizes of the corpus: :meth:`full` or :meth:`quick`.

    Attributes
    ----------
    motor_names_text : tuple of str
        The motors (:data:`MOTORS`' names).
    plants_text : tuple of str
        The plants (:data:`PLANTS`).
    seeds : tuple of int
        The logs' seeds (exploration, noise; sibling seeds of one motor and plant).
    durations_seconds : tuple of float
        The lengths learned, increasing: prefixes of one log.
    method_text : str
        ``"adp"`` or ``"identify"``.
    """

    motor_names_text: tuple[str, ...]
    plants_text: tuple[str, ...]
    seeds: tuple[int, ...]
    durations_seconds: tuple[float, ...]
    method_text: str

    @classmethod
    def full(cls) -> RefusalsConfig:
        """Five motors, both plants, 3 seeds, 0.1, 0.5 and 2 s: 90 runs, about 11 minutes."""
        names = tuple(motor.name_text for motor in MOTORS)
        return cls(names, PLANTS, (160_001, 160_002, 160_003), (0.1, 0.5, 2.0), "adp")

    @classmethod
    def quick(cls) -> RefusalsConfig:
        """CI-sized: the README's motor on both plants, one seed, 0.1 s."""
        return cls(("README",), PLANTS, (160_001,), (0.1,), "adp")


@dataclass(frozen=True)
class CorpusLog:
    """One log of the corpus (every length learned is a prefix of it).

    Attributes
    ----------
    motor : CorpusMotor
    plant_text : str
        ``"realistic drive"`` or ``"exact dq"``.
    seed : int
    current_noise_amperes : float
        Noise on each measured phase current, A rms.
    dead_time_volts : float
        ``v = t_d f_sw V_dc`` per phase, V.
    """

    motor: CorpusMotor
    plant_text: str
    seed: int
    current_noise_amperes: float
    dead_time_volts: float

    def text(self, seconds: float) -> str:
        """The log and length in one line: enough to rebuild it.

        Parameters
        ----------
        seconds : float
            The length learned (a prefix of the log), s.
        """
        return (
            f"{self.motor.name_text}, {self.plant_text}, seed {self.seed}, "
            f"{seconds:g} s, noise {self.current_noise_amperes * 1e3:.3g} mA, dead time "
            f"{self.dead_time_volts:.3g} V"
        )


def corpus_logs(config: RefusalsConfig) -> list[CorpusLog]:
    """The logs of the sizes. Each motor and plant has its noise (1-50 mA, log-uniform)
    and dead time (0.5-2 V), drawn from a generator seeded by :data:`CORPUS_SEED` and
    their places (a draw does not depend on which others are run); its seeds are
    siblings: the same conditions, another exploration and noise.

    Parameters
    ----------
    config : RefusalsConfig
        The sizes.
    """
    logs = []
    for index, motor in enumerate(MOTORS):
        if motor.name_text not in config.motor_names_text:
            continue
        for plant in config.plants_text:
            rng = np.random.default_rng([CORPUS_SEED, index, PLANTS.index(plant)])
            noise, volts = Span(1e-3, 5e-2, log=True).draw(rng), Span(0.5, 2.0).draw(rng)
            logs += [CorpusLog(motor, plant, seed, noise, volts) for seed in config.seeds]
    return logs


# -- the plants ----------------------------------------------------------------------------


def _w(motor: CorpusMotor, t: Array) -> Array:
    """``w = [p speed phi_pm, T*(t)]`` at the times t: the torque steps through
    ``+-T*``, ``+-T*/3``."""
    experiment = motor.experiment
    base = experiment.motor.exogenous(experiment.speed, experiment.torque)
    return base + reference_perturbation(t, "steps", experiment.torque)


def _logging_law(experiment: Experiment) -> ControlLaw:
    """The drive's law while it logs: ``K0``, the current reference, the back-EMF fed
    forward."""
    return ControlLaw.regulator(experiment.K0, -experiment.problem().F, BACK_EMF_FEEDFORWARD)


def _turn(vectors: Array, angles: Array) -> Array:
    """Each row of ``vectors`` (alpha-beta) in the frame at ``angles`` (dq): ``Rot(-angle)``."""
    c, s = np.cos(angles), np.sin(angles)
    return np.column_stack([c * vectors[:, 0] + s * vectors[:, 1],
                            -s * vectors[:, 0] + c * vectors[:, 1]])  # fmt: skip


def _phases(dq: Array, angle: float) -> Array:
    """The three phase values of a dq vector at the electrical angle (amplitude-invariant)."""
    c, s = np.cos(angle), np.sin(angle)
    alpha, beta = c * dq[0] - s * dq[1], s * dq[0] + c * dq[1]
    root = np.sqrt(3.0) / 2.0
    return np.array([alpha, -0.5 * alpha + root * beta, -0.5 * alpha - root * beta])


def _alpha_beta(phases: Array) -> Array:
    """The amplitude-invariant Clarke transform of three phase values (common mode dropped)."""
    a, b, c = phases
    return np.array([(2.0 * a - b - c) / 3.0, (b - c) / np.sqrt(3.0)])


def _transition(motor: CorpusMotor) -> Array:
    """``expm(M h)`` of the augmented state ``[i_d, i_q, u_d, u_q, v_d, v_q, 1]``: the
    currents, the dq-held command, the dead-time vector held in the stationary frame (it
    turns backwards in dq: ``v' = w_e [[0, 1], [-1, 0]] v``) and the constant that
    carries the back-EMF."""
    R, L, flux = motor.R_s_ohm, motor.L_s_henry, motor.phi_pm_weber
    w_e = motor.pole_pairs_count * motor.speed_rad_per_second
    M = np.zeros((7, 7))
    M[:2, :2] = [[-R / L, w_e], [-w_e, -R / L]]
    M[:2, 2:4] = np.eye(2) / L
    M[:2, 4:6] = np.eye(2) / L
    M[1, 6] = -w_e * flux / L
    M[4:6, 4:6] = [[0.0, w_e], [-w_e, 0.0]]
    return np.asarray(scipy.linalg.expm(M / motor.sampling_frequency_hz))


def exact_dq_log(
    motor: CorpusMotor,
    samples: int,
    seed: int,
    noise: float,
    dead_time: float,
    adc: bool = True,
) -> Trajectory:
    """A log of the independent exact dq plant (see the module docstring), from rest.

    Parameters
    ----------
    motor : CorpusMotor
        The motor and its drive.
    samples : int
        N, samples.
    seed : int
        Seed of the exploration and the noise.
    noise : float
        Noise on each measured phase current, A rms.
    dead_time : float
        ``v`` per phase, V.
    adc : bool
        Quantize the measured phase currents (12 bits over ``+-adc_range``).

    Returns
    -------
    Trajectory
        t, the measured currents, the commanded voltages (applied one sample later), w and
        the true electrical angle.
    """
    experiment = motor.experiment
    h = experiment.h
    Phi = _transition(motor)
    t = np.asarray(np.arange(samples + 1) * h, dtype=float)
    angle = np.asarray(experiment.electrical_speed * t, dtype=float)
    w = _w(motor, t)
    # one generator each: a shorter log is a prefix of a longer one of the same seed
    exploring, sensing = (np.random.default_rng([seed, stream]) for stream in (0, 1))
    amplitude = EXPLORATION_FRACTION * motor.dc_voltage_volts
    exploration = exploring.uniform(-amplitude, amplitude, (samples, 2))
    measurement_noise = noise * sensing.standard_normal((samples + 1, 3))
    lsb = motor.adc_step_amperes
    law = _logging_law(experiment)
    no_past = np.zeros((0, 2))
    s = np.zeros(7)
    s[6] = 1.0
    measured = np.zeros((samples + 1, 2))
    commanded = np.zeros((samples, 2))
    for k in range(samples + 1):
        phases = _phases(s[:2], angle[k])
        sensed = phases + measurement_noise[k]
        if adc:
            sensed = np.clip(np.round(sensed / lsb), -(2 ** (ADC_BITS - 1)),
                             2 ** (ADC_BITS - 1) - 1) * lsb  # fmt: skip
        measured[k] = _turn(_alpha_beta(sensed)[None, :], angle[k : k + 1])[0]
        if k == samples:
            break
        commanded[k] = law.command(measured[k], w[k], no_past) + exploration[k]
        error = _alpha_beta(-dead_time * np.sign(phases))
        s[4:6] = _turn(error[None, :], angle[k : k + 1])[0]
        s = Phi @ s
        s[2:4] = commanded[k]  # applied over the next sample
    wrapped = np.angle(np.exp(1j * angle))
    return Trajectory(t=t, x=measured, u=commanded, w=w, angle=wrapped)


def _realistic_log(log: CorpusLog, samples: int) -> Trajectory:
    """A log of the library's realistic drive, hardware-like with the log's noise, dead
    time and the motor's bus and ADC range, the commanded voltages logged."""
    motor = log.motor
    experiment = motor.experiment
    bus = motor.dc_voltage_volts
    settings = replace(
        DriveSettings.hardware_like(bus, experiment.h), logged_input="commanded",
        current_noise=log.current_noise_amperes,
        dead_time=log.dead_time_volts * experiment.h / bus,
        adc_bits=ADC_BITS, adc_range=motor.adc_range_amperes,
    )  # fmt: skip
    drive = RealisticDrive(experiment.motor, experiment.speed, experiment.h, settings)
    return drive.run(
        _logging_law(experiment), held(lambda t: _w(motor, t)), num_samples=samples,
        exploration=uniform(EXPLORATION_FRACTION * bus), seed=log.seed,
    )  # fmt: skip


def recorded(log: CorpusLog, samples: int) -> Trajectory:
    """The log of its plant, ``samples`` long.

    Parameters
    ----------
    log : CorpusLog
        The motor, plant, seed, noise and dead time.
    samples : int
        N, samples.
    """
    if log.plant_text == "exact dq":
        return exact_dq_log(
            log.motor, samples, log.seed, log.current_noise_amperes, log.dead_time_volts
        )
    return _realistic_log(log, samples)
