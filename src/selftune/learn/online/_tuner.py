"""The online tuner: a surface PMSM's current controller re-tuned while the drive runs.

The drive feeds its log in chunks (:meth:`OnlineTuner.feed`). Every
:attr:`OnlineSettings.look_every` samples the tuner looks:

1. the slow model (:class:`~._model.OnlineModel`) gives the motor's parameters
   (:func:`~._physical.physical_estimate`) and becomes the change watch's reference;
2. the digital optimum of the estimated motor is designed (identify-then-design on the
   structured model, the torque reference's current scaled by the estimated flux) and
   certified against the law in force (:func:`~._certify.certify`); a certified law
   replaces it, and the event carries it for the drive to switch to.

Between looks every chunk is scored against the reference (:class:`~._physical.ChangeWatch`):
on an alarm the slow memory restarts from a share of the fast one's (the old plant's
samples would mislead it), and the next look comes two fast memories later, on the new
plant's data.

Probing (a small exploration) is wanted while the estimates do not certify any law: at
the start, after a change, and while the candidate is not stable with margin on every
plausible plant.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Literal

import numpy as np

from ...core import Array, ControlLaw
from ...errors import InputError
from .._problem import LearningProblem
from ..evidence._discrete_model import DiscreteModel
from ..evidence._spmsm_structure import SpmsmStructure
from ..learners._identify import design_digital
from ._certify import Certificate, certify
from ._model import OnlineModel
from ._physical import ChangeTest, ChangeWatch, PhysicalEstimate, physical_estimate

__all__ = ["RESTART_SHARE", "OnlineSettings", "OnlineTuner", "TunerEvent"]

#: The share of the fast memory's weight the slow one restarts from after a change: the
#: fast memory still holds the old plant (an alarm comes within its memory), and a
#: restart from all of it was reported as a second and third change while the slow
#: model re-learned (README drive, R_s +20%: at 1.08 and 1.28 s after 1.01 s).
RESTART_SHARE = 0.1


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
    memories : (float, float)
        The fast and the slow model's memories, s.
    look_every : int
        Samples between looks.
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
    """

    h: float
    input_delay: int
    problem: LearningProblem
    electrical_speed: float
    hold: Literal["stationary", "rotor"] = "stationary"
    dead_time: bool = True
    memories: tuple[float, float] = (0.05, 2.0)
    look_every: int = 1000
    false_alarm: float = 1e-4
    window: int = 500
    torque_channel: int | None = 1
    least_saving: float = 1e-3

    @property
    def structure(self) -> SpmsmStructure:
        """The motor's structure at the speed and sampling period."""
        return SpmsmStructure(self.electrical_speed, self.h, self.dead_time, self.hold)


@dataclass(frozen=True)
class TunerEvent:
    """What a look decided.

    Attributes
    ----------
    sample : int
        The samples fed before the look.
    kind : {"change", "switch", "kept", "waiting"}
        A change detected; a certified law to switch to; the law in force kept; no
        estimate yet (too little data, or data that do not excite the plant).
    reason : str
        Why, in words.
    estimate : PhysicalEstimate or None
        The parameters the look used.
    law : ControlLaw or None
        With ``"switch"``: the law to switch to at the next sample.
    certificate : Certificate or None
        The candidate's certificate.
    change : ChangeTest or None
        The change test.
    """

    sample: int
    kind: Literal["change", "switch", "kept", "waiting"]
    reason: str
    estimate: PhysicalEstimate | None = None
    law: ControlLaw | None = None
    certificate: Certificate | None = None
    change: ChangeTest | None = None


class OnlineTuner:
    """The tuner (see the module).

    Parameters
    ----------
    settings : OnlineSettings
        What it knows and how it looks.
    law : ControlLaw
        The law in force (the loop's delay and integral action).
    start : ndarray
        The parameters to start the estimates from (the nameplate's ``[R_s, L_s, 1]``,
        and a dead-time voltage guess, V).
    """

    def __init__(self, settings: OnlineSettings, law: ControlLaw, start: Array) -> None:
        self.settings = settings
        self.law = law
        problem = settings.problem
        self._model = OnlineModel(
            settings.h, settings.memories, problem.n, problem.m, problem.q, settings.dead_time
        )
        self._theta = np.asarray(start, dtype=float)
        self._pending = np.zeros((settings.input_delay, problem.m))
        self._sample = 0
        self._next_look = settings.look_every
        self._watch = ChangeWatch(settings.window, settings.false_alarm)
        self.estimate: PhysicalEstimate | None = None
        self._designed: PhysicalEstimate | None = None
        self.probing = True

    @property
    def sample(self) -> int:
        """Samples fed so far."""
        return self._sample

    def feed(self, x: Array, u: Array, w: Array, angle: Array | None = None) -> list[TunerEvent]:
        """Add a chunk of the log and look where a look falls due.

        Parameters
        ----------
        x : ndarray, shape (T, n)
            Measured states.
        u : ndarray, shape (T, m)
            The command computed at each row (applied ``input_delay`` rows later), V.
        w : ndarray, shape (T, q)
            The reference held at each row.
        angle : ndarray, shape (T,), optional
            Electrical angle, rad (with dead time).
        """
        commands = np.vstack([self._pending, u])  # row k is applied d rows later
        applied, self._pending = commands[: u.shape[0]], commands[u.shape[0] :]
        rows = self._model.add(x, applied, w, angle)
        self._sample += x.shape[0]
        events = []
        test = self._watch.add(*rows)
        if test is not None and test.changed:
            events.append(self._changed(test))
        if self._sample >= self._next_look:
            self._next_look = self._sample + self.settings.look_every
            events += self._look(w[-1])
        return events

    def _changed(self, test: ChangeTest) -> TunerEvent:
        """The slow memory restarts from a tenth of the fast one's (enough to be solved,
        little of the old plant); the next look two fast memories on."""
        moments = self._model.moments
        restarted = copy.deepcopy(moments[0])
        restarted.forgetting = moments[1].forgetting
        restarted.forget(RESTART_SHARE)
        moments[1] = restarted
        self._watch.reference_off()
        self.probing = True
        self._designed = None
        fast_samples = round(self.settings.memories[0] / self.settings.h)
        self._next_look = self._sample + 2 * fast_samples
        names = self.settings.structure.names(self.settings.dead_time)
        scores = ", ".join(
            f"{name} {score:+.2f}" for name, score in zip(names, test.scores, strict=True)
        )
        return TunerEvent(
            self._sample, "change",
            f"the parameters changed: scores {scores} (threshold {test.threshold:.2f})",
            change=test,
        )  # fmt: skip

    def _look(self, w: Array) -> list[TunerEvent]:
        moments = self._model.moments[1]
        try:
            estimate = physical_estimate(self._model.model(1), self.settings.structure, self._theta)
            Theta, _, covariance = moments.estimate()
        except (np.linalg.LinAlgError, InputError) as failure:
            self.probing = True
            return [TunerEvent(self._sample, "waiting", f"no estimate yet: {failure}")]
        self._watch.reference(Theta, moments.noise(Theta), estimate.sensitivities, covariance)
        self._theta = estimate.theta
        self.estimate = estimate
        if self._designed_near(estimate):
            self.probing = False
            return [TunerEvent(self._sample, "kept", "the estimate has not moved by half a "
                               "standard error since the last design", estimate)]  # fmt: skip
        self._designed = estimate
        candidate = self._design(estimate)
        settings = self.settings
        problem = self._scaled_problem(estimate)
        certificate = certify(
            candidate, self.law, estimate, settings.structure,
            problem.loop(settings.h, settings.input_delay), (problem.Q, problem.R), w,
            settings.least_saving,
        )  # fmt: skip
        self.probing = not bool(np.all(certificate.radii <= certificate.limit))
        if certificate.certified:
            self.law = candidate
            return [TunerEvent(self._sample, "switch", certificate.reason, estimate,
                               candidate, certificate)]  # fmt: skip
        return [TunerEvent(self._sample, "kept", certificate.reason, estimate, None,
                           certificate)]  # fmt: skip

    def _designed_near(self, estimate: PhysicalEstimate) -> bool:
        """Whether the last design's estimate is within half a standard error of this
        one in every parameter and was certified stable (a new design would give the
        same law)."""
        last = self._designed
        if last is None or self.probing:
            return False
        return bool(np.all(np.abs(estimate.theta - last.theta) <= 0.5 * estimate.standard_errors))

    def _scaled_problem(self, estimate: PhysicalEstimate) -> LearningProblem:
        """The problem with the torque reference's current for the estimated flux."""
        problem, channel = self.settings.problem, self.settings.torque_channel
        if channel is None or problem.F is None:
            return problem
        F = problem.F.copy()
        F[:, channel] = F[:, channel] / float(estimate.theta[2])
        weight = problem.integral_weight
        return LearningProblem(
            problem.Q, problem.R, problem.C, problem.E, F,
            integral_action=weight is not None, integral_weight=weight,
        )  # fmt: skip

    def _design(self, estimate: PhysicalEstimate) -> ControlLaw:
        """The digital optimum of the estimated motor."""
        settings = self.settings
        Ad, Bd, Ed = settings.structure(estimate.theta)
        Ed = Ed[:, : settings.problem.q]  # the reference's channels, not the signs'
        model = DiscreteModel.given(Ad, Bd, Ed, settings.h)
        return design_digital(model, self._scaled_problem(estimate), settings.input_delay).law
