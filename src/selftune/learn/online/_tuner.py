"""The online tuner: a surface PMSM's current controller re-tuned while the drive runs.

The drive feeds its log in chunks (:meth:`OnlineTuner.feed`). Every
:attr:`OnlineSettings.look_every` samples the tuner looks:

1. the two slow memories' lag-free model (:meth:`~._model.OnlineModel.drift_free`)
   gives the motor's parameters (:func:`~._physical.physical_estimate`, weighed by the
   instruments, with the drift correction's doubt in their covariance: wide in the
   guard estimate every decision below uses, :data:`GUARD_DOUBT`; calibrated against
   the truth in the estimate the events report, :data:`REPORTED_DOUBT`);
2. the estimate is not acted on while the slow memory is young (:data:`YOUNG_SHARE`), or
   if it is not a motor or jumped (:meth:`OnlineTuner._doubt`); else the structured
   model becomes the change watch's reference;
3. where R_s, L_s or the dead-time voltage moved (:data:`DESIGN_MOVE`), a candidate is
   learned (:attr:`OnlineSettings.learner`: the digital optimum of the estimated motor,
   or the paper's ADP on a window of the log) and certified against the law in force
   (:func:`~._certify.certify`); a certified law replaces it, and the event carries it
   for the drive to switch to.

Between looks every chunk is scored against the reference (:class:`~._physical.ChangeWatch`):
on an alarm the slow memory restarts from a share of the fast one's (the old plant's
samples would mislead it), and the next look comes two fast memories later, on the new
plant's data.

**The torque reference's current** follows the magnet flux: where a look's flux ratio
differs from the one the law in force assumes by more than its guard standard error and
:attr:`OnlineSettings.flux_tolerance`, the law in force is switched to itself with its
torque channel rescaled (:meth:`~selftune.core.ControlLaw.scaled_reference`: the same
feedback, so the same loop and cost; the steady torque right again).

**The watchdog**: a change detected within :attr:`OnlineSettings.probation` samples of a
switch to a new feedback (the measured currents left the band the model in force
predicts, just after the new law came in) reverts to the last law certified before it (a
``"revert"`` event), and the tuner learns the plant afresh. A rescaled torque reference
keeps the feedback: it is not on probation.

Probing (a small exploration) is wanted while the estimates do not certify any law: at
the start, after a change, and while the candidate is not stable with margin on every
plausible plant.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from ...core import Array, ControlLaw
from ...errors import InputError, Refusal, UnsolvableError
from .._problem import LearningProblem
from ..evidence._discrete_model import DiscreteModel
from ..evidence._pulses import pulse_delay_gain
from ..learners._identify import design_digital
from ._certify import Certificate, certify
from ._model import OnlineModel
from ._moments import transposed_covariance
from ._physical import ChangeTest, ChangeWatch, PhysicalEstimate, physical_estimate
from ._settings import OnlineSettings
from ._window import LogWindow

__all__ = [
    "DESIGN_MOVE",
    "GUARD_DOUBT",
    "JUMP",
    "REPORTED_DOUBT",
    "RESTART_SHARE",
    "YOUNG_SHARE",
    "OnlineTuner",
    "TunerEvent",
]

#: The share of the fast memory's weight the slow one restarts from after a change: the
#: fast memory still holds the old plant (an alarm comes within its memory), and a
#: restart from all of it was reported as a second and third change while the slow
#: model re-learned (README drive, R_s +20%: at 1.08 and 1.28 s after 1.01 s).
RESTART_SHARE = 0.1

#: The drift correction's doubt in the guard covariance, the one the tuner decides with
#: (the change watch's reference, the flux rescale's bound, a design's nearness, the
#: certificate's plausible plants): a share of the correction (the slow memory's lag,
#: read off the difference of the two estimates) taken as a standard error of ``R_s``,
#: ``L_s``, the flux ratio and the dead-time voltage. The correction is exact for a
#: steady drift over steady excitation; under a warming ramp it left about 8% of the lag
#: in R_s. 30% is wider than the errors (bench section 11: the flux's within one of its
#: standard errors at every look) and stays so: at 10% the change watch raised a false
#: alarm on a constant motor (the medium motor's warm-up, seed 1); at 5% the torque
#: reference was rescaled about 295 times a run instead of 165, a steady torque error
#: reached 0.103%, and two changes were reported on that constant motor.
GUARD_DOUBT = (0.3, 0.3, 0.3, 0.3)

#: The drift correction's doubt in the reported covariance (the events' estimates and
#: :attr:`OnlineTuner.estimate`: the error bars), a share of the correction as in
#: :data:`GUARD_DOUBT`, calibrated on bench section 11's twelve runs (each look acted on
#: against the true motor of its data's last sample, :func:`selftune.report.error_bars`;
#: docs/online.md). R_s: none; its true errors were within one standard error at 49-76%
#: of the looks, rms 0.83-1.48 (the lower after the resistance step, when the estimates
#: stayed 0.15-0.19% low: the looks then fall later in the reference's cycle of torque
#: steps, and the split of the voltage between R_s and the dead-time voltage follows the
#: current levels the last second holds; the servo's warm-up with its looks 0.11 s into
#: the cycle, rms 1.56: 30% of the correction as R_s's doubt made that 1.25 and the
#: unshifted run's 0.93 into 0.68; all of it, 0.59 and 0.30). L_s: the guard's. Its bars
#: were too narrow on carrier PWM with dead time (rms 2.7-3.9 on the medium and large
#: motors) for a reason
#: the share cannot carry: a large torque step's first samples are at the voltage limit,
#: where a leg's pulse is shorter than the dead time and loses only its own length, which
#: the model's full dead-time voltage leaves out (:func:`~..evidence._pulses.lost_signs`;
#: the medium motor, 30 s: rms 0.9-1.1 without dead time, on average PWM, or with the
#: simulator's pulses unclipped; 4.1 with them, the same bias under 3-30 mA of noise or a
#: 12-bit ADC alone). The flux: 5%. It was the servo's (rms 3.4-4.3 without), and it
#: covered a bias that is not the drift's: on a constant servo the flux was 0.0088% low,
#: 23 standard errors (on average PWM 0.0001%; with the dead time centred in the pulse,
#: 0.0012% high): the dead time delays every pulse by half of it, so the voltage moves
#: the current ``R_s t_d / (2 L_s)`` more than the held model says
#: (:func:`~..evidence._pulses.pulse_delay_gain`; 0.010% on the servo, 0.0025% and
#: 0.0016% on the medium and large motors, whose constant runs were 0.0023% and 0.0015%
#: low). Where the DC bus is known (:attr:`OnlineSettings.dc_voltage`) the reported
#: covariance holds the shift both leave in each parameter
#: (:meth:`~._model.OnlineModel.omitted_shift` for the short pulses, read off the data's
#: own moments): on the twelve runs L_s's rms 0.82-1.21 (52-75% within one), the flux's
#: 0.12-0.64 (0.12-0.43 on the slower motors: too wide, as before). Without the 5% the
#: flux's would be 0.27-0.85, but the looks of a young memory need it: at 1.2-2.0 s of
#: tests/test_online_run.py's average-PWM drive the flux was 2-5e-5 off with standard
#: errors of 4-8e-6 without it (z up to 7). The large motor's flux bars are too wide
#: either way: its warm-up's drift correction leaves a residual that cancels most of the
#: delay's bias, and its instruments' standard errors were 3.7 times its errors' spread.
#: The dead-time voltage: the guard's (no truth to measure it against).
REPORTED_DOUBT = (0.0, 0.3, 0.05, 0.3)

#: The least move of a parameter, a fraction of it, for which a look designs a new law
#: (a 1% change of R_s or L_s moves the digital optimum's cost by far less than the 0.1%
#: a switch must save).
DESIGN_MOVE = 0.01

#: The most R_s, L_s or the flux ratio may move between consecutive looks, a fraction
#: of itself, for the estimate to be acted on (:meth:`OnlineTuner._doubt`). In standard
#: errors the test misfired: the instruments' standard errors of R_s swing tenfold
#: from look to look (the reference steps bring its information in lumps), and a bound
#: of 2 of them kept the probing on a third of the time on an ideal drive.
JUMP = 0.2

#: The share of the slow memory's full weight its model needs before it is acted on and
#: the change watch takes it as the reference: younger, it holds a few reference steps
#: (one current level cannot tell R_s from the flux, and a restart's share still holds
#: the old plant), and its noise moments misjudge the errors. Acted on at 0.1 s after a
#: resistance step, the flux was 0.2-0.4% off with a standard error of 0.05%; watched
#: from 0.1 s on the realistic drive, a constant motor raised an alarm at 0.2 s.
YOUNG_SHARE = 0.25


@dataclass(frozen=True)
class TunerEvent:
    """What a look decided.

    Attributes
    ----------
    sample : int
        The samples fed before the look.
    kind : {"change", "switch", "rescale", "revert", "kept", "waiting"}
        A change detected; a certified law to switch to; the law in force with its
        torque reference rescaled for the flux (the same feedback); the watchdog's
        return to the law certified before the last switch; the law in force kept; no
        estimate acted on (too little data, or data that do not excite the plant).
    reason : str
        Why, in words.
    estimate : PhysicalEstimate or None
        The parameters the look used, with the reported covariance (the error bars,
        :data:`REPORTED_DOUBT`); the look decided on the same parameters with the guard
        covariance (:data:`GUARD_DOUBT`), which the certificate's plants are drawn from.
    law : ControlLaw or None
        With ``"switch"``, ``"rescale"`` and ``"revert"``: the law to switch to at the
        next sample (an event with a law is one to switch to).
    certificate : Certificate or None
        The candidate's certificate.
    change : ChangeTest or None
        The change test.
    """

    sample: int
    kind: Literal["change", "switch", "rescale", "revert", "kept", "waiting"]
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
    start : ndarray, optional
        The parameters to start the estimates from (the nameplate's ``[R_s, L_s, 1]``,
        and a dead-time voltage guess, V); by default read off the first model
        (:meth:`~selftune.learn.SpmsmStructure.initial`).
    law_flux : float
        The flux ratio (to the flux of ``settings.problem``'s F) the law in force assumes.

    Raises
    ------
    InputError
        If the law does not fit the drive: its dimensions, its past inputs against the
        delay, or no integrator at the drive's sampling period.
    """

    def __init__(
        self,
        settings: OnlineSettings,
        law: ControlLaw,
        start: Array | None = None,
        law_flux: float = 1.0,
    ) -> None:
        problem = settings.problem
        if (law.n, law.m, law.q) != (problem.n, problem.m, problem.q):
            raise InputError(
                f"law: it maps {law.n} states, {law.q} references to {law.m} inputs; the "
                f"tuner's problem has {problem.n}, {problem.q} and {problem.m}"
            )
        if law.history != settings.input_delay:
            raise InputError(
                f"law: it feeds back {law.history} past inputs; the drive's delay is "
                f"{settings.input_delay} samples"
            )
        if law.K_i is None or law.h is None or not math.isclose(law.h, settings.h, rel_tol=1e-9):
            raise InputError(
                f"law: the tuner switches servo laws with an integrator at the drive's "
                f"period h = {settings.h:g} s; this one has "
                + ("none" if law.K_i is None else f"h = {law.h:g} s")
            )
        self.settings = settings
        self.law = law
        self.law_flux = float(law_flux)
        self._previous: tuple[ControlLaw, float] | None = None
        self._probation_end = -1
        bus, advance = settings.dc_voltage, 0.5 * settings.electrical_speed * settings.h
        self._model = OnlineModel(
            settings.h, settings.memories, problem.n, problem.m, problem.q, settings.dead_time,
            (advance, bus) if bus is not None and settings.hold == "stationary" else None,
        )  # fmt: skip
        self._theta = None if start is None else np.asarray(start, dtype=float)
        self._pending = np.zeros((settings.input_delay, problem.m))
        self._window = LogWindow(round(settings.adp_window / settings.h))  # the ADP's data
        self._sample = 0
        self._next_look = settings.look_every
        self._watch = ChangeWatch(settings.window, settings.false_alarm)
        #: the last estimate acted on, with the reported covariance (the error bars)
        self.estimate: PhysicalEstimate | None = None
        self._designed: PhysicalEstimate | None = None
        self._last_estimate: PhysicalEstimate | None = None
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
        if self.settings.learner == "adp":
            self._window.add(x, u, w, angle)
        commands = np.concatenate([self._pending, u])  # row k is applied d rows later
        applied, self._pending = commands[: u.shape[0]], commands[u.shape[0] :]
        rows = self._model.add(x, applied, w, angle)
        self._sample += x.shape[0]
        events = []
        test = self._watch.add(*rows)
        if test is not None and test.changed:
            events.append(self._changed(test))
            if self._previous is not None and self._sample <= self._probation_end:
                events.append(self._revert())
        if self._sample >= self._next_look:
            self._next_look = self._sample + self.settings.look_every
            events += self._look(w[-1])
        return events

    def _changed(self, test: ChangeTest) -> TunerEvent:
        """The slow memory restarts from a tenth of the fast one's (enough to be solved,
        little of the old plant); the next look two fast memories on."""
        moments = self._model.moments
        for slow in (1, 2):
            restarted = copy.deepcopy(moments[0])
            restarted.forgetting = moments[slow].forgetting
            restarted.forget(RESTART_SHARE)
            moments[slow] = restarted
        self._watch.reference_off()
        self.probing = True
        self._designed = None
        self._last_estimate = None
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

    def _revert(self) -> TunerEvent:
        """The watchdog: back to the law certified before the last switch."""
        assert self._previous is not None
        self.law, self.law_flux = self._previous
        self._previous = None
        return TunerEvent(
            self._sample, "revert",
            "a change was detected within the probation after the last switch: back to "
            "the law certified before it",
            law=self.law,
        )  # fmt: skip

    def _switch(self, law: ControlLaw, flux: float) -> None:
        """Put ``law`` (assuming the flux ratio ``flux``) in force, on probation."""
        self._previous = (self.law, self.law_flux)
        self._probation_end = self._sample + self.settings.probation
        self.law, self.law_flux = law, flux

    def _flux_update(self, guard: PhysicalEstimate, reported: PhysicalEstimate) -> list[TunerEvent]:
        """The law in force with its torque reference rescaled, if the flux moved beyond
        the guard estimate's standard error (the event carries the reported one)."""
        channel = self.settings.torque_channel
        kappa, se = float(guard.theta[2]), float(guard.standard_errors[2])
        moved = kappa / self.law_flux - 1.0
        bound = max(se / self.law_flux, self.settings.flux_tolerance)
        if channel is None or self.settings.problem.F is None or not abs(moved) > bound:
            return []
        scales = np.ones(self.law.q)
        scales[channel] = self.law_flux / kappa
        reason = (
            f"the flux ratio is {kappa:.5f}, {moved:+.3%} from the {self.law_flux:.5f} the "
            f"law in force assumes (beyond its guard standard error, {se:.5f}, and "
            f"{self.settings.flux_tolerance:.3%}): its torque reference's current rescaled, "
            "the feedback kept"
        )
        law = self.law.scaled_reference(scales)
        self.law, self.law_flux = law, kappa  # the same feedback: no probation
        if self._previous is not None:  # a return keeps the rescaled reference
            before, flux = self._previous
            scales[channel] = flux / kappa
            self._previous = (before.scaled_reference(scales), kappa)
        return [TunerEvent(self._sample, "rescale", reason, reported, law)]

    def _look(self, w: Array) -> list[TunerEvent]:
        """A look: every decision on the guard estimate; the events carry the reported
        one (the same parameters, the error bars calibrated: :data:`REPORTED_DOUBT`)."""
        try:
            model, Theta, _, lag = self._model.drift_free(1, 2)
            if self._theta is None:
                self._theta = self.settings.structure.initial(model)
            guard, reported = self._estimate(model, Theta, lag)
        except (np.linalg.LinAlgError, InputError) as failure:
            self.probing = True
            return [TunerEvent(self._sample, "waiting", f"no estimate yet: {failure}")]
        previous, self._last_estimate = self._last_estimate, guard
        if np.all(guard.theta[:3] > 0.0):  # the next fit starts here
            self._theta = guard.theta
        doubt = self._doubt(guard, previous)
        if doubt:
            self.probing = True
            self._watch.reference_off()  # the last reference would age beyond its allowance
            return [TunerEvent(self._sample, "waiting", doubt, reported)]
        settings = self.settings
        slow = self._model.moments[2]
        held, needed = slow.weight * settings.h, YOUNG_SHARE * settings.memories[2]
        if held < needed:
            self.probing = True
            self._watch.reference_off()
            reason = (
                f"the model holds {held:.2f} s of data since the start or the last change; "
                f"it is acted on from {needed:.2f} s (a few reference steps), probing until then"
            )
            return [TunerEvent(self._sample, "waiting", reason, reported)]
        # the reference ages until the next look and over the watch's window (its lag
        # behind a drift is in its covariance: the drift correction's doubt)
        rates = np.array(settings.drift_rates[: guard.theta.size])
        ageing = (settings.look_every + settings.window) * settings.h
        allowance = rates * np.abs(guard.theta) * ageing
        # the structured model: its errors are the few parameters', J C J'
        structured = np.concatenate(settings.structure(guard.theta), axis=1).T  # (p, n)
        J = guard.sensitivities  # d vec(Theta') / d theta
        # vec(Theta')'s covariance as vec(Theta)'s
        entries = transposed_covariance(J @ guard.covariance @ J.T, *structured.shape[::-1])
        least = np.array(settings.least_change[: guard.theta.size]) * np.abs(guard.theta)
        self._watch.reference(structured, slow.noise(structured), J, entries, allowance, least)
        self.estimate = reported
        if self._designed_near(guard):
            self.probing = False
            return self._flux_update(guard, reported) or [
                TunerEvent(self._sample, "kept", "R_s, L_s and the dead-time voltage have "
                           f"not moved by half a guard standard error or {DESIGN_MOVE:.0%} "
                           "since the last design", reported)
            ]  # fmt: skip
        self._designed = guard
        try:
            candidate = self._design(guard)
        except (UnsolvableError, Refusal) as failure:
            self.probing = True
            return [TunerEvent(self._sample, "kept", f"no law designed: {failure}", reported)]
        problem = self._scaled_problem(guard)
        certificate = certify(
            candidate, self.law, guard, settings.structure,
            problem.loop(settings.h, settings.input_delay), (problem.Q, problem.R), w,
            settings.least_saving,
        )  # fmt: skip
        self.probing = not bool(np.all(certificate.radii <= certificate.limit))
        if certificate.certified:
            self._switch(candidate, float(guard.theta[2]))
            return [TunerEvent(self._sample, "switch", certificate.reason, reported,
                               candidate, certificate)]  # fmt: skip
        return self._flux_update(guard, reported) or [
            TunerEvent(self._sample, "kept", certificate.reason, reported, None, certificate)
        ]

    def _estimate(
        self, model: DiscreteModel, Theta: Array, lag: float
    ) -> tuple[PhysicalEstimate, PhysicalEstimate]:
        """The parameters of the drift-free model, weighed by the instruments, with the
        drift correction's own doubt in their covariance: a share of the correction (the
        slow memory's lag, read off the difference of its estimate and this one) as a
        standard error in each, :data:`GUARD_DOUBT` in the guard estimate the decisions
        use, :data:`REPORTED_DOUBT` in the one reported; where the model is ``lag``
        seconds late (no correction), the fastest drift
        (:attr:`OnlineSettings.drift_rates`) over that lag in both. The reported one also
        holds the shift the dead time's pulses leave in the parameters (with
        :attr:`OnlineSettings.dc_voltage`: the short ones' lost part,
        :meth:`~._model.OnlineModel.omitted_shift`, and every pulse's delay,
        :func:`~..evidence._pulses.pulse_delay_gain`)."""
        settings, slow = self.settings, self._model.moments[2]
        assert self._theta is not None
        weight = slow.instrument_weight(Theta)
        estimate = physical_estimate(model, settings.structure, self._theta, weight=weight)
        theta, gain, shift = estimate.theta, estimate.gain, np.zeros(estimate.theta.size)
        assert gain is not None
        if self._model.pulses is not None:  # what the dead time's pulses leave out: the
            # short ones' lost part (-Ed's dead-time block: v times the held vector), and
            # every pulse t_d / 2 late (Bd too small by the delay's gain)
            _, Bd, Ed = settings.structure(theta)
            v = max(float(theta[3]), 0.0)
            moved = self._model.omitted_shift(1, 2, -Ed[:, -2:]).T.ravel(order="F")
            t_d = v * settings.h / self._model.pulses[1]
            delayed = pulse_delay_gain(float(theta[0]), float(theta[1]), t_d)
            moved[Bd.size : 2 * Bd.size] += (delayed - 1.0) * Bd.ravel(order="F")
            shift = gain @ moved
            self._model.dead_time_voltage = v  # judges pulses short from now
        if lag > 0.0:
            late = np.array(settings.drift_rates[: theta.size]) * np.abs(theta) * lag
            return estimate.doubted(late), estimate.doubted(np.hypot(late, shift))
        # the lagging memory's parameters, to first order: the fit's gain on its model
        lagging = slow.coefficients().T.ravel(order="F")  # vec([Ad, Bd, Ed])
        correction = gain @ (lagging - model.parameters)
        guard = estimate.doubted(np.array(GUARD_DOUBT[: theta.size]) * correction)
        reported = np.array(REPORTED_DOUBT[: theta.size]) * correction
        return guard, estimate.doubted(np.hypot(reported, shift))

    def _doubt(self, estimate: PhysicalEstimate, previous: PhysicalEstimate | None) -> str:
        """Why the estimate is not to be acted on ("" if it is): ``R_s``, ``L_s`` or the
        flux ratio not positive, or moved since the last look by more than
        :data:`JUMP` of itself. Heating moves them by less than 0.1% between looks; a
        larger jump is the instruments failing (the currents hold still between
        reference steps, and only their noise is left to excite the plant), where the
        estimate is far off and its standard errors do not say so (on an ideal drive,
        weighing the entries by their variances alone, R_s went from 0.66 to -0.52 ohm in
        0.1 s with a standard error of 0.1 ohm, then to 669 ohm, and laws designed on
        them were certified); or its covariance not positive definite (the model's
        instrument moment singular in a direction, whose entries' huge variances leave
        round-off of their size in the parameters': on the online bench's medium motor with
        an encoder's angle and the flux rescaled only beyond two standard errors, R_s and
        the flux had negative variances, read as standard errors of 0, and the change
        watch's scores against that reference reached 1e149)."""
        names = self.settings.structure.names(self.settings.dead_time)
        theta = estimate.theta[:3]
        if not np.all(theta > 0.0):
            values = ", ".join(
                f"{name} {value:.4g}" for name, value in zip(names, theta, strict=False)
            )
            return f"the estimate is not a motor ({values}): the data do not excite it; probing"
        covariance = estimate.covariance
        if not np.all(np.isfinite(covariance)) or np.linalg.eigvalsh(covariance)[0] <= 0.0:
            return (
                "the estimate's covariance is not positive definite: the instruments leave "
                "a direction of the model unexcited, and its error bars would be zero or "
                "negative; probing"
            )
        if previous is None:
            return ""
        moved = np.abs(theta / previous.theta[:3] - 1.0)
        if np.all(moved <= JUMP):
            return ""
        worst = int(np.argmax(moved))
        return (
            f"{names[worst]} moved from {previous.theta[worst]:.5g} to {theta[worst]:.5g} "
            f"since the last look, by more than {JUMP:.0%} (heating moves it by less than "
            "0.1%): the data do not excite the plant enough to trust it; probing"
        )

    def _designed_near(self, estimate: PhysicalEstimate) -> bool:
        """Whether the last design's estimate (certified stable) is near this guard
        estimate: every parameter within half its guard standard error or
        :data:`DESIGN_MOVE` of itself (the flux's moves are the rescale's, not a
        design's). A new design would give the same law: with the instruments' weight the
        standard errors are so small that a bound in them alone redesigned at nearly every
        look, to no switch."""
        last = self._designed
        if last is None or self.probing:
            return False
        bound = np.maximum(0.5 * estimate.standard_errors, DESIGN_MOVE * np.abs(last.theta))
        moved = np.abs(estimate.theta - last.theta)
        moved[2] = 0.0  # the flux ratio: rescaled, not redesigned
        return bool(np.all(moved <= bound))

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
        """The candidate: the digital optimum of the estimated motor, or the ADP's."""
        if self.settings.learner == "adp":
            problem = self._scaled_problem(estimate)
            return self._window.learned(self.settings, problem, self.law.K_x)
        settings = self.settings
        Ad, Bd, Ed = settings.structure(estimate.theta)
        Ed = Ed[:, : settings.problem.q]  # the reference's channels, not the signs'
        model = DiscreteModel.given(Ad, Bd, Ed, settings.h)
        return design_digital(model, self._scaled_problem(estimate), settings.input_delay).law
