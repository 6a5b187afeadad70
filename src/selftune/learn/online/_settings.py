"""What the online tuner knows and how it looks (:class:`OnlineSettings`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from .._problem import LearningProblem
from ..evidence._spmsm_structure import SpmsmStructure

__all__ = ["OnlineSettings"]


@dataclass(frozen=True)
class OnlineSettings:
    """What the online tuner knows and how it looks.

    Attributes
    ----------
    h : float
        Sampling period, s.
    input_delay : int
        d, the drive's computation delay, samples (the log's ``u`` is the command
        computed at each row, applied d rows later).
    problem : LearningProblem
        Q, R, C, F (for the flux the reference assumes) and integral action.
    electrical_speed : float
        ``p`` times the mechanical speed, rad/s.
    hold : {"stationary", "rotor"}
        What the drive holds over a sample (:class:`~selftune.learn.SpmsmStructure`).
    dead_time : bool
        Model the inverter's dead time (the rows need the electrical angle).
    memories : (float, float, float)
        The fast model's memory and the two slow ones', s: the slow models' difference
        removes the lag a steady drift leaves in them (:meth:`~._model.OnlineModel.drift_free`).
    look_every : int
        Samples between looks (a look costs as much as 30 chunks of 100 samples; at
        10 kHz, 0.2 s between them follows heating, 0.4%/s at most, to 0.1%, and a
        change is watched for at every chunk between them).
    false_alarm : float
        The change watch's false-alarm probability per window of ``window`` samples.
    window : int
        The transitions the change watch sums over.
    torque_channel : int or None
        The channel of ``w`` that is the torque reference: its current, ``F``'s column,
        is scaled by the estimated flux ratio (None: F is kept).
    least_saving : float
        The least saving of a reference step's cost worth a switch, a fraction (a switch
        adds a transient; below 0.1% it is not seen in the torque).
    flux_tolerance : float
        The least change of the flux ratio, a fraction, for which the torque reference's
        current is rescaled (the steady torque error it leaves: a quarter of 0.1%, the
        rest for the estimate's error and the current's noise; at half of it a 120 s
        warm-up's largest steady error was 0.101%).
    probation : int
        Samples after a switch during which a detected change reverts it (the watchdog).
    drift_rates : (float, float, float, float)
        The fastest drift heating gives ``R_s``, ``L_s``, the flux ratio and the
        dead-time voltage, fractions per second (copper 0.39%/K heating at up to 2 K/s;
        the magnets' 0.1%/K at up to 1 K/s): drift this fast over the slow memory is not
        a change (:class:`~._physical.ChangeWatch`'s allowance, over the time a
        reference is used: until the next look, and the window).
    learner : {"identify", "adp"}
        How a look learns its candidate: identify-then-design (the digital optimum of
        the estimated motor), or the paper's ADP, model-free (the digital learner of
        :func:`~selftune.learn.learn_controller` on the last ``adp_window`` of the log,
        from the law in force's feedback). Either candidate is certified the same way.
    adp_window : float
        The log the ADP learner takes, s (a sliding window: memory independent of the
        run's length).
    dc_voltage : float or None
        The inverter's DC bus, V, if known (with ``dead_time`` and the ``"stationary"``
        hold of a PWM inverter): the reported error bars then hold the shift that the
        dead time's pulses leave in the estimates, the part short pulses do not carry
        (:func:`~..evidence._pulses.lost_signs`; :meth:`~._model.OnlineModel.omitted_shift`)
        and every pulse's delay by half of it (:func:`~..evidence._pulses.pulse_delay_gain`).
        It does not enter any decision.
    least_change : (float, float, float, float)
        The least change of ``R_s``, ``L_s``, the flux ratio and the dead-time voltage
        alone, fractions of each, that the change watch reports: what the model leaves
        out is not a change. The carrier's ripple, which the average model leaves out,
        grows as ``V_dc h / L_s`` and shows as an inductance change: on a 0.8 mH motor
        at 540 V windows scored like a 4.7% change of L_s (false alarms every few
        seconds at a 1% floor). The faults watched for are a loose connection (+20% on
        R_s) and a demagnetized magnet; the inductance and the dead-time voltage move
        with the operating point, not in steps.
    """

    h: float
    input_delay: int
    problem: LearningProblem
    electrical_speed: float
    hold: Literal["stationary", "rotor"] = "stationary"
    dead_time: bool = True
    memories: tuple[float, float, float] = (0.05, 1.0, 2.0)
    look_every: int = 2000
    false_alarm: float = 1e-4
    window: int = 500
    torque_channel: int | None = 1
    least_saving: float = 1e-3
    flux_tolerance: float = 2.5e-4
    probation: int = 1000
    drift_rates: tuple[float, float, float, float] = (0.008, 0.001, 0.001, 0.01)
    least_change: tuple[float, float, float, float] = (0.02, 0.1, 0.01, 0.2)
    learner: Literal["identify", "adp"] = "identify"
    adp_window: float = 1.0
    dc_voltage: float | None = None

    @property
    def structure(self) -> SpmsmStructure:
        """The motor's structure at the speed and sampling period."""
        return SpmsmStructure(self.electrical_speed, self.h, self.dead_time, self.hold)
