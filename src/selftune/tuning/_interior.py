"""Commissioning an interior PM motor on a drive: identify R_s, L_d, L_q and the flux,
design the digital optimum, put the torque reference on the identified motor's MTPA
curve, and measure the torque it gives.

The drive engineer knows the pole pairs, the operating point, the nameplate flux (what
the controller assumes in ``w_1 = p speed phi_assumed``), inductances (roughly: K0's
default and the experiment's decoupling use them) and resistance; the fit
re-estimates every parameter, and an R_s far from the nameplate's is refused
(:func:`~._resistance.check_against_nameplate`: where the dead time dwarfs the resistive
drop, a fit can take part of it for resistance, and the inductances move with it). The
experiment runs the current-reference form ``w = [w_1, i_d*, i_q*]`` under the gentle K0
with the back-EMF and the references' cross-coupling fed forward
(:func:`decoupling_feedforward`): the q current walks through the ``"steps"`` levels
(:data:`~._knowledge.STEP_LEVELS`, reversing the current for the dead-time model) of the
q current ``2 T* / (3 p phi_assumed)``, and the d current through ``0`` and ``-D_SHARE``
of it with a different dwell, so that the three channels vary independently.
Identify-then-design with the interior structure
(:class:`~selftune.learn.IpmsmStructure`) gives the law with its verdict; the MTPA
references of ``T*`` come from the identified motor
(:meth:`~selftune.model.IPMSM.current_reference`), and a run of the learned law at them
measures the true torque (noise-free, after the transient).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..core import Array, ControlLaw
from ..errors import CurrentOverrange
from ..learn import LearnedController, LearningProblem, MotorEstimate, learn_controller
from ..model import IPMSM, SPMSM, Motor
from ..sim import DriveRecord, DriveSettings, RealisticDrive, constant, held, uniform
from ._knowledge import STEP_DWELL, STEP_LEVELS
from ._learning import learned_at_length, learning_options, pulse_bus
from ._resistance import check_against_nameplate
from ._settings import TuningSettings

__all__ = [
    "CHECK_LIMIT",
    "CHECK_SECONDS",
    "CHECK_TURNS",
    "CLIP_TOLERANCE",
    "D_SHARE",
    "K0_REMEDY",
    "InteriorCommissioning",
    "check_current_range",
    "check_samples",
    "commission_interior",
    "current_steps",
    "decoupling_feedforward",
    "motor_of",
]

#: The d-current reference's lowest level in the experiment, a share of the q scale.
D_SHARE = 0.5

#: The d-current reference's dwell at each level, in units of the q steps' (not a
#: multiple of it, so that the two references do not move together).
D_DWELL = 2.5

#: ``F`` of the current-reference form: ``e = [i_d - i_d*, i_q - i_q*]``.
CURRENT_REFERENCE_F = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])


@dataclass(frozen=True)
class InteriorCommissioning:
    """An interior motor commissioned on a drive (SI units).

    Attributes
    ----------
    learned : LearnedController
        The law designed on the identified plant, with its verdict.
    motor : IPMSM
        The identified motor (R_s, L_d, L_q, phi_pm; the nameplate's p).
    standard_errors : dict of str to float
        The identified parameters' standard errors (ohm, H, H, Wb).
    torque : float
        The torque reference T*, N m.
    references : ndarray, shape (2,)
        ``[i_d*, i_q*]``, A: MTPA of the identified motor at T*.
    true_torque : float
        The true torque the learned law gives at those references, N m (mean over the
        second half of the check run).
    data_seconds : float
        Length of the experiment learned from, s.
    integral_weight : ndarray, shape (2, 2), or None
        The integral weight the learner used (None without integral action).
    notes : tuple of str
        A line for each longer experiment run because the learner found one too short
        for its noise (:func:`~._learning.learned_at_length`).
    """

    learned: LearnedController
    motor: IPMSM
    standard_errors: dict[str, float]
    torque: float
    references: Array
    true_torque: float
    data_seconds: float
    integral_weight: Array | None
    notes: tuple[str, ...] = ()

    @property
    def torque_error(self) -> float:
        """``|true torque - T*| / |T*|``."""
        return abs(self.true_torque - self.torque) / abs(self.torque)


def motor_of(estimate: MotorEstimate, p: int) -> tuple[Motor, dict[str, float]]:
    """The motor a structured fit identified, of its kind (an interior one with ``L_d``
    and ``L_q``, else a surface one), and the parameters' standard errors (``R_s``,
    ``L_d`` and ``L_q`` or ``L_s``, ``phi_pm``: ohm, H, Wb).

    Parameters
    ----------
    estimate : MotorEstimate
        The fit's parameters (``quality.motor`` of a law learned with a structure).
    p : int
        Pole pairs.
    """
    if estimate.L_d is not None and estimate.L_q is not None:
        motor: Motor = IPMSM(
            R_s=estimate.R_s, L_d=estimate.L_d, L_q=estimate.L_q, phi_pm=estimate.phi_pm, p=p
        )
        errors = {
            "R_s": estimate.R_s_se, "L_d": float(estimate.L_d_se or 0.0),
            "L_q": float(estimate.L_q_se or 0.0), "phi_pm": estimate.phi_pm_se,
        }  # fmt: skip
        return motor, errors
    assert estimate.L_s is not None
    surface = SPMSM(R_s=estimate.R_s, L_s=estimate.L_s, phi_pm=estimate.phi_pm, p=p)
    return surface, {
        "R_s": estimate.R_s_se, "L_s": float(estimate.L_s_se or 0.0),
        "phi_pm": estimate.phi_pm_se,
    }  # fmt: skip


def current_steps(t: Array, scale: float) -> tuple[Array, Array]:
    """The experiment's current references at the times ``t`` (s): ``i_q*`` walks through
    :data:`~._knowledge.STEP_LEVELS` times ``scale`` (A), each held
    :data:`~._knowledge.STEP_DWELL`; ``i_d*`` through 0 and ``-D_SHARE |scale|``, each
    held :data:`D_DWELL` times as long (see the module docstring).

    Returns
    -------
    i_d*, i_q* : ndarray, shape like ``t``
    """
    levels = np.asarray(STEP_LEVELS)
    q = levels[np.floor(t / STEP_DWELL).astype(int) % levels.size] * scale
    d = -D_SHARE * abs(scale) * (np.floor(t / (D_DWELL * STEP_DWELL)).astype(int) % 2)
    return d, q


#: How far the current may go beyond the ADC's full scale, a share of it, before an
#: experiment is refused: its readings are then clipped by at most that share, near the
#: phases' peaks. On the 2/5 mH interior motor at 1-1.7 times its speed (average PWM, no
#: dead time, seeds 0-2), peaks up to 3.2% over the +-50 A scale left L_d, L_q and the
#: flux within 0.02% (as unclipped); 3.6-5% over, within 0.13% (at most 2.3 standard
#: errors); 5.6-8% over, 0.11-0.42%; 8-20% over, 0.3-1.4% (torque errors up to 1.1%).
CLIP_TOLERANCE = 0.05

#: What to do when an experiment under the gentle K0 (with the feedforward) goes beyond
#: the ADC's range: its steps, its exploration (large on a small inductance: 10.8 V on
#: 25 uH at 10 kHz is 43 A a sample) and what the nameplate's feedforward misses of the
#: back-EMF drive the current.
K0_REMEDY = (
    "the experiment's steps, exploration and back-EMF under the gentle K0 drive the "
    "current: lower the exploration (its [learning] exploration, V), commission at a lower "
    "speed, use a larger K0 (its [learning] K0), or a drive whose ADC range covers the current"
)


def decoupling_feedforward(motor: Motor, electrical_speed: float) -> Array:
    """``U`` of the experiment's law on the motor's ``w`` (``[w_1, i_d*, i_q*]`` for an
    interior motor, ``[w_1, T*]`` for a surface one): the back-EMF ``w_1`` and the
    cross-coupling of the current references ``[i_d*, i_q*] = -F w`` through the nameplate
    inductances, ``u_d = -w_e L_q i_q*``, ``u_q = w_1 + w_e L_d i_d*``, so that the
    currents follow their references (about the rated current) under the gentle K0.

    Under K0 alone the back-EMF drove the currents: 4-5 times the rated current at the
    interior bench's speeds on three of its six motors (a median of 39-40 A against
    8.3-9.5 A rated), beyond the ADC's +-50 A at twice the speed (clipped readings learned
    1-2% off). With the back-EMF alone fed forward, the cross-coupling kept the currents at
    0.5-3 A, and two of 24 logs gave inductances over 0.5% off. With both, the currents'
    median is 0.6-7 A, the 24 logs' inductances and flux within 0.37%, and at twice the
    speed (``w_e h`` = 0.08) within 0.04%.

    Parameters
    ----------
    motor : SPMSM or IPMSM
        The nameplate motor (its L_d and L_q, H, as K0's default uses them; its ``F``).
    electrical_speed : float
        ``p`` times the mechanical speed, rad/s.
    """
    references = -motor.regulation_problem(electrical_speed / motor.p).F  # w -> [i_d*, i_q*]
    coupling = electrical_speed * np.array([[0.0, -motor.L_q], [motor.L_d, 0.0]])
    U = coupling @ references
    U[1, 0] += 1.0  # w_1, the back-EMF
    return U


def check_current_range(
    record: DriveRecord, drive: DriveSettings, rated: float, what: str, remedy: str = K0_REMEDY
) -> None:
    """Refuse an experiment whose current went beyond the drive's ADC full scale (by more
    than :data:`CLIP_TOLERANCE` of it).

    A phase current beyond ``adc_range`` reads as the ADC's extreme code: the clipped
    readings are no noise a model allows for. At twice the interior bench's speed
    (``w_e h`` = 0.08) the 2/5 mH motor's experiment, under K0 alone against the back-EMF,
    reached the +-50 A scale and was learned, not refused, with L_d 1.6-2.3% and the flux
    1.4-2.1% high (torque errors 1.3-1.8%); with the range at 500 A, within 0.13%.

    Parameters
    ----------
    record : DriveRecord
        The experiment's run (its true currents, A).
    drive : DriveSettings
        The drive (``adc_range``, A; None: no ADC, nothing to check).
    rated : float
        The rated current the experiment's references scale with, A (for the message).
    what : str
        The experiment, for the message (``"the commissioning at 200 rad/s"``).
    remedy : str
        What to do, for the message (default :data:`K0_REMEDY`).

    Raises
    ------
    CurrentOverrange
        When the largest true current magnitude exceeds ``adc_range`` by more than
        :data:`CLIP_TOLERANCE` of it.
    """
    if drive.adc_range is None:
        return
    peak = float(np.max(np.hypot(record.true_currents[:, 0], record.true_currents[:, 1])))
    if peak <= (1.0 + CLIP_TOLERANCE) * drive.adc_range:
        return
    raise CurrentOverrange(
        f"{what} drove the current to {peak:.3g} A ({peak / rated:.2g} times the rated "
        f"{rated:.3g} A), beyond the ADC's full scale adc_range = {drive.adc_range:g} A: its "
        f"readings are clipped and no model explains them; {remedy}",
        peak=peak, full_scale=float(drive.adc_range),
    )  # fmt: skip


#: The torque check's least length, s: its second half's mean is the steady torque's
#: estimate, which the loop's noise and the dead time move over a short one. On a 65/164
#: uH motor rated 2.8 A (2 V of dead time on 48 V, its parameters within 0.11%) the mean
#: over the last 50 ms of a 0.1 s check was 0.60% off the reference, over the whole turns
#: of the last 0.2 s of a 0.4 s check 0.009% (see also :func:`check_samples`).
CHECK_SECONDS = 0.4

#: The torque check holds at least this many electrical turns in its second half, whose
#: whole turns its mean is taken over (:meth:`~selftune.sim.DriveRecord.steady_torque`)...
CHECK_TURNS = 2
#: ... unless that is longer than this, s.
CHECK_LIMIT = 2.0


def check_samples(seconds: float, electrical_speed: float, h: float) -> int:
    """The torque check's samples: ``seconds`` (s), or longer where its second half would
    hold fewer than :data:`CHECK_TURNS` turns at ``electrical_speed`` (rad/s), up to
    :data:`CHECK_LIMIT`.

    The mean torque over a part of a turn holds part of the dead time's six-step ripple:
    at 5 % of the rated speed of a 0.74/1.11 mH motor rated 0.45 A (28 rad/s electrical,
    2 V of dead time on 540 V) the mean over the last 50 ms of a 0.1 s check was 1.2 %
    off the reference, over the whole turns of the second half of a 0.88 s one 0.026 %.

    Parameters
    ----------
    seconds : float
        The check's least length, s.
    electrical_speed : float
        ``p`` times the mechanical speed, rad/s.
    h : float
        Sampling period, s.
    """
    turns_seconds = 2.0 * CHECK_TURNS * 2.0 * np.pi / max(abs(electrical_speed), 1e-12)
    return round(max(seconds, min(turns_seconds, CHECK_LIMIT)) / h)


def commission_interior(
    motor: IPMSM,
    settings: TuningSettings,
    drive: DriveSettings,
    *,
    seconds: float = 0.5,
    check_seconds: float = CHECK_SECONDS,
    seed: int = 0,
) -> InteriorCommissioning:
    """Identify, design, apply MTPA and check the torque (see the module docstring).

    Parameters
    ----------
    motor : IPMSM
        The true motor of the simulated drive (its nameplate flux, inductances and pole
        pairs are what the engineer knows).
    settings : TuningSettings
        Operating point (speed, rad/s; T*, N m), cost, K0, exploration, integral action.
    drive : DriveSettings
        The drive.
    seconds : float
        Length of the experiment, s.
    check_seconds : float
        Least length of the torque check, s (:func:`check_samples`).
    seed : int
        Seed of the experiment's exploration and noise (the check's is ``seed + 1``).

    Raises
    ------
    SelftuneError
        The learner's refusal, if the data do not support a controller (an experiment
        refused as too short for its noise is first run again as long as the learner
        asks, :func:`~._learning.learned_at_length`).
    ModelMissesEffect
        When the identified R_s is far from the nameplate's
        (:func:`~._resistance.check_against_nameplate`).
    """
    plant = RealisticDrive(motor, settings.speed, settings.h, drive)
    back_emf = motor.p * settings.speed * motor.phi_pm  # w_1 with the nameplate flux
    scale = 2.0 * settings.torque / (3.0 * motor.p * motor.phi_pm)

    def reference(t: Array) -> Array:
        d, q = current_steps(t, scale)
        return np.column_stack([np.full_like(t, back_emf), d, q])

    law = ControlLaw.regulator(
        settings.K0, -CURRENT_REFERENCE_F, decoupling_feedforward(motor, motor.p * settings.speed)
    )
    problem = LearningProblem(
        settings.Q, settings.R, C=np.eye(2), F=CURRENT_REFERENCE_F,
        integral_action=settings.integral_action, integral_weight=settings.Q_i,
    )  # fmt: skip
    options = replace(
        learning_options(plant, settings), method="identify", structure="ipmsm",
        dc_voltage=pulse_bus(drive),
    )  # fmt: skip

    def learned_from(samples: int) -> LearnedController:
        experiment = plant.record(
            law, held(reference), num_samples=samples,
            exploration=uniform(settings.exploration), seed=seed,
        )  # fmt: skip
        check_current_range(
            experiment, drive, abs(scale), f"the commissioning at {settings.speed:g} rad/s"
        )
        return learn_controller(experiment.trajectory, problem, settings.K0, options)

    learned, samples, notes = learned_at_length(
        learned_from, round(seconds / settings.h), settings.h
    )
    assert learned.quality is not None and learned.quality.motor is not None  # the verdict
    found, errors = motor_of(learned.quality.motor, motor.p)
    assert isinstance(found, IPMSM)  # structure = "ipmsm"
    identified = found
    check_against_nameplate(
        identified.R_s, identified.L_d, identified.L_q, motor.R_s, settings.h,
        (drive.dead_time_voltage(settings.h), motor.R_s * abs(scale)),
    )  # fmt: skip
    references = identified.current_reference(settings.torque)
    w = np.concatenate([[back_emf], references])
    count = check_samples(check_seconds, motor.p * settings.speed, settings.h)
    record = plant.record(
        learned.law, constant(w), num_samples=count, exploration=None, seed=seed + 1
    )
    true_torque = record.steady_torque()
    return InteriorCommissioning(
        learned=learned, motor=identified, standard_errors=errors, torque=settings.torque,
        references=references, true_torque=true_torque, data_seconds=samples * settings.h,
        integral_weight=problem.integral_weight if settings.integral_action else None,
        notes=notes,
    )  # fmt: skip
