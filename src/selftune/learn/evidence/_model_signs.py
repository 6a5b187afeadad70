"""The dead-time model judged on other signs than the measured ones.

With the dead time modelled, the channels hold the measured phase currents' signs, which
the noise decides where a phase current is within it of zero. Each wrong sign is a
voltage error of ``2 v`` on that phase for a sample, which the model's simulation
carries for a time constant of the plant: output errors correlated in time, which the
consistency and structure tests read as an effect the model misses. Before refusing,
:func:`~._evidence.gather_evidence` judges the model refitted on other signs where those
explain the data better (:func:`sign_refits`): first those of its own noise-free
currents (:func:`on_model_signs`), then those the next sample shows
(:func:`next_sample_signs`).

The parameters a structured fit reports are those of the signs the tests accepted: the
next sample's where the measured ones fail them (:func:`on_other_signs`), or where the
measured signs' fit passes them but its own simulation does not describe the data, the
reported bars hold the carrier's pulses, or it lies beyond its own bars from the next
sample's (:func:`reported_next_signs`); the verdict notes it. The next sample's signs' bias is
measured and removed as the measured ones' is (:mod:`._sign_bias`, its simulations
taking their signs the same way).

The model's own currents drift from the true ones where the plant is nearly an
integrator: a small-inductance motor at low speed (``R_s h / L`` about 0.01, so a wrong
sign's 1.4 A lasts 100 samples) whose phase currents linger near zero. On the ramp's 30-34
uH motors at 5% of rated speed on 48 V (0.24 V of dead time, ADC steps of 0.05-0.2 A) the
measured signs were wrong in 62-133 of 15,000 phase samples, the output errors 0.2-0.6 A
rms and correlated 0.97-0.99 from sample to sample (the robust variances 50-68 times
white noise's), and the consistency test refused (statistic 123-181 against 97.65); the
own currents' signs did not help. The next sample's signs were wrong in 3, and the
errors as white as with the true signs (inflation 1.1-1.5, statistic 24-38).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING, Protocol

import numpy as np

from ...core import Array
from ...errors import ConsistencyError
from ..data._trajectory import Trajectory
from ._alignment import applied_inputs
from ._dead_time import DeadTimeChannels, with_signs_of
from ._next_signs import next_signs
from ._output_error import OutputErrorFit, _Log, _logs, fit_output_error
from ._sign_bias import (
    OWN_SIGNS_LIMIT,
    WORLD_FIDELITY,
    OwnSimulation,
    measurement_noise,
    model_currents,
)

if TYPE_CHECKING:
    from ._evidence import ConsistencyTest

__all__ = [
    "DISAGREEMENT",
    "MODEL_SIGN_ROUNDS",
    "Judge",
    "adopted_next_signs",
    "changed_signs",
    "log_det",
    "next_sample_signs",
    "on_model_signs",
    "on_next_signs",
    "on_other_signs",
    "reported_next_signs",
    "sign_refits",
]


#: The most refits on the signs of the model's own currents (:func:`on_model_signs`):
#: each moves the signs of the few samples whose simulated phase current changed its
#: sign; on 0.2 s logs of the hardware-like drive the second changed none.
MODEL_SIGN_ROUNDS = 3


def sign_refits(
    channels: DeadTimeChannels, shift: int, fit: OutputErrorFit, resolution: float
) -> Iterator[tuple[bool, DeadTimeChannels, OutputErrorFit]]:
    """The refits on other signs to judge the model by, in turn: :func:`on_model_signs`,
    then :func:`on_next_signs` (each where it explains the data better than ``fit``),
    each with whether its signs are the next sample's (its parameters are then the ones
    to report: those signs are the data's, read with the model, not its simulation's)."""
    for next_sample, refitted in ((False, on_model_signs), (True, on_next_signs)):
        refit = refitted(channels, shift, fit, resolution)
        if refit is not None:
            yield (next_sample, *refit)


class Judge(Protocol):
    """The tests a fit of the logs must pass: the consistency of ``fit`` on ``episodes``
    where they accept it, else a :class:`~selftune.errors.ConsistencyError`."""

    def __call__(self, episodes: list[Trajectory], fit: OutputErrorFit) -> ConsistencyTest: ...


#: The channels a fit used, the fit, and its consistency the tests accepted.
Accepted = tuple[DeadTimeChannels, OutputErrorFit, "ConsistencyTest"]


def on_other_signs(
    channels: DeadTimeChannels, shift: int, fit: OutputErrorFit, resolution: float, judge: Judge
) -> Accepted | None:
    """The channels and fit to report, and the consistency the tests accepted, where the
    measured signs' ``fit`` failed them; None where they accept no refit of
    :func:`sign_refits`.

    Accepted on the next sample's signs, a structured fit is that refit. Otherwise the
    measured signs' ``fit`` is reported, its bias removed later (:mod:`._sign_bias`): the
    model's own signs follow its parameters, so a refit on them has too small standard
    errors; and an unstructured fit's many parameters and correlation-robust variances
    hold the wrong signs' effect, where the carrier PWM's late pulses, which the bars of
    a structured fit hold (:mod:`._pulses`), are in no unstructured bar. Measured on the
    flux step of a 0.9 mH motor at 5,000 rad/s on 150 V (carrier PWM): the flux 0.085%
    low at 1.0 standard error on the measured signs, 0.011% low at 3.4 on the next
    sample's.
    """
    for next_sample, judged, judged_fit in sign_refits(channels, shift, fit, resolution):
        try:
            test = judge(judged.episodes, judged_fit)
        except ConsistencyError:
            continue
        reported = next_sample and fit.structure is not None
        return (judged, judged_fit, test) if reported else (channels, fit, test)
    return None


#: How many of the measured signs' fit's standard errors the next sample's signs' fit
#: may be from it before those bars are taken not to hold the measured signs' bias
#: (:func:`reported_next_signs`).
DISAGREEMENT = 3.0


def reported_next_signs(
    channels: DeadTimeChannels,
    shift: int,
    fit: OutputErrorFit,
    resolution: float,
    judge: Judge,
    pulses: tuple[float, bool],
) -> Accepted | None:
    """The next sample's signs' fit to report instead of a measured signs' ``fit`` that
    passed the tests (:func:`adopted_next_signs`), or None.

    It is reported where it explains the data better, passes the tests and its own
    simulation describes them, and one of: the measured signs' own simulation departs
    from the data (its bias cannot be measured); the reported bars hold the carrier's
    pulses (the DC bus given), which the next sample's signs' narrower bars would miss
    otherwise; or it is beyond :data:`DISAGREEMENT` of the measured signs' fit's standard
    errors from it, so that those bars do not hold that fit's error. The last: a 91/136
    uH motor of 3.2 mOhm on 48 V with 2 V of dead time, on the measured signs L_d and L_q
    16% and 18% high at 3.8-4.0 standard errors and R_s 10 times the truth, every
    parameter within 0.005% on the next sample's.

    Parameters
    ----------
    channels, shift, fit, resolution, judge
        As :func:`adopted_next_signs`.
    pulses : (float, bool)
        The measured signs' own simulation's departure
        (:attr:`~._sign_bias.OwnSimulation.departure`), and whether the reported bars
        hold the carrier's pulses (:func:`~._pulses.holds_pulses`).
    """
    departure, held = pulses
    departs = departure > WORLD_FIDELITY
    limit = OWN_SIGNS_LIMIT if departs else WORLD_FIDELITY
    adopted = adopted_next_signs(channels, shift, fit, resolution, judge, limit)
    if adopted is None or departs or held:
        return adopted
    scale = np.sqrt(np.diag(fit.parameter_covariance))
    moved = np.abs(adopted[1].parameters - fit.parameters)
    return adopted if bool(np.any(moved > DISAGREEMENT * scale)) else None


def adopted_next_signs(
    channels: DeadTimeChannels,
    shift: int,
    fit: OutputErrorFit,
    resolution: float,
    judge: Judge,
    departure: float,
) -> Accepted | None:
    """The fit on the signs the next sample shows (:func:`on_next_signs`), its channels
    and its consistency, for a measured signs' structured ``fit`` that passed the tests
    (:func:`reported_next_signs` says when it is reported): where the refit explains the
    data better, passes the tests and its own simulation describes them; else None.

    ``departure`` is the most the refit's own simulation may depart from the data
    (:class:`~._sign_bias.OwnSimulation`): :data:`~._sign_bias.WORLD_FIDELITY`, or
    where the measured signs' own simulation departs beyond it already (neither fit's
    bias can then be measured) :data:`~._sign_bias.OWN_SIGNS_LIMIT`, the departure at
    which the data are refused. With 2 us of dead time on 540 V (10.8 V) two drawn
    0.9/1.4 and 0.7/1.1 mH motors passed every test on the measured signs with R_s 17
    and 3.7 times the truth and L_d 2.8% and 4.0% low at 5.4 and 7.8 standard errors,
    their own simulations departing 0.54 and 0.55; on the next sample's signs (departing
    0.59 and 0.35, the output errors' covariance's determinant e^12.6 smaller) every
    parameter came out within 0.05%.

    That bias can be large: a 0.6/1.2 mH interior motor on 300 V with 2 us of dead time
    (6 V), whose phase currents change sign in 37% of the samples, passed every test with
    R_s 0.52-0.53 ohm against 0.1 at 7.6-10.6 standard errors; on the next sample's signs
    0.0995-0.1000 ohm, the output errors' covariance's determinant e^11 times smaller,
    the simulation's departure 0.009-0.017 against 0.44-0.49.

    :func:`~._evidence.gather_evidence` also tries it where the measured signs' own
    simulation describes the data but the reported bars can hold the carrier's pulses
    (:func:`~._pulses.holds_pulses`: the DC bus given). The refit then explains the data
    better where the measured signs' wrong ones only correlate the output errors: at 5%
    of rated speed a 0.11/0.28 mH motor on 48 V had L_d 1.31% off at 1.5 standard
    errors on the measured signs, 0.018% (1.7) on the next sample's, and with the true
    signs 0.01%. The next sample's signs' bars are the noise's, and on carrier PWM they
    missed the pulses' bias of L_q (0.03-0.06% low at 3.0-3.6 standard errors on 4 of 30
    drawn interior motors at rated speed), which :func:`~._pulses.pulse_shift` now puts
    in them; without the bus the measured signs' wider bars hold it.
    """
    if fit.structure is None:  # an unstructured fit keeps the measured signs (on_other_signs)
        return None
    refit = on_next_signs(channels, shift, fit, resolution)
    if refit is None:
        return None
    judged, judged_fit = refit
    try:
        test = judge(judged.episodes, judged_fit)
    except ConsistencyError:
        return None
    if OwnSimulation.of(judged_fit, judged, shift).departure > departure:
        return None
    return judged, judged_fit, test


def changed_signs(measured: object, used: object) -> int:
    """How many samples' sign channels of ``used`` differ from the ``measured`` ones'
    (both :class:`~._dead_time.DeadTimeChannels`; 0 for anything else or the same)."""
    if measured is used or not isinstance(used, DeadTimeChannels):
        return 0
    assert isinstance(measured, DeadTimeChannels)
    return sum(
        int(np.sum(np.any(np.asarray(a.w) != np.asarray(b.w), axis=1)))
        for a, b in zip(measured.episodes, used.episodes, strict=True)
    )


def on_model_signs(
    channels: DeadTimeChannels, shift: int, fit: OutputErrorFit, resolution: float
) -> tuple[DeadTimeChannels, OutputErrorFit] | None:
    """The logs with the dead-time channels on the signs of the fitted model's own
    noise-free currents (:func:`~._dead_time.with_signs_of`,
    :func:`~._sign_bias.model_currents`) and the fit on them, refitted from ``fit``
    on the signs of each refit's currents while that explains the data better (a
    smaller determinant of the output errors' covariance: a larger likelihood, with as
    many parameters), at most :data:`MODEL_SIGN_ROUNDS` times; None when the first
    does not."""
    best: tuple[DeadTimeChannels, OutputErrorFit] | None = None
    for _ in range(MODEL_SIGN_ROUNDS):
        current = (channels, fit) if best is None else best
        trial = with_signs_of(channels, model_currents(current[1], current[0], shift))
        pairs = zip(trial.episodes, current[0].episodes, strict=True)
        if best is not None and all(
            np.array_equal(np.asarray(a.w), np.asarray(b.w)) for a, b in pairs
        ):
            break  # the refit's currents have the signs it was fitted on
        refit = fit_output_error(
            trial.episodes, shift, current[1].model, fit.structure, resolution=resolution
        )
        if refit is None or log_det(refit) >= log_det(current[1]):
            break
        best = (trial, refit)
    return best


def on_next_signs(
    channels: DeadTimeChannels, shift: int, fit: OutputErrorFit, resolution: float
) -> tuple[DeadTimeChannels, OutputErrorFit] | None:
    """The logs with the dead-time channels on the signs the next sample shows
    (:func:`next_sample_signs`) and the fit on them, refitted from ``fit``; None where
    that does not explain the data better (as :func:`on_model_signs`)."""
    trial = next_sample_signs(channels, shift, fit)
    if trial is None:
        return None
    refit = fit_output_error(trial.episodes, shift, fit.model, fit.structure, resolution=resolution)
    if refit is None or log_det(refit) >= log_det(fit):
        return None
    return trial, refit


def next_sample_signs(
    channels: DeadTimeChannels, shift: int, fit: OutputErrorFit
) -> DeadTimeChannels | None:
    """The channels with each undecided phase sign taken as the next sample shows it
    (:func:`~._next_signs.next_signs`, by the fitted model), held over each sample
    (``"sample"`` switching). The noise is the model's one-step residuals' measurement
    noise (:func:`~._sign_bias.measurement_noise`), or where they give none a robust
    spread of them.

    Parameters
    ----------
    channels : DeadTimeChannels
        The logs as fitted, with their angles.
    shift : int
        The alignment of the logged inputs.
    fit : OutputErrorFit
        The structured fit on the channels.

    Returns
    -------
    DeadTimeChannels or None
        None where the residuals give no measurement noise.
    """
    assert channels.angles is not None
    Ad, Bd, Ed = fit.matrices(fit.parameters)
    logs = _logs(channels.episodes, shift)
    noise = measurement_noise(logs, (Ad, Bd, Ed))
    if noise is None:
        noise = _robust_noise(logs, (Ad, Bd, Ed))
    if noise is None:
        return None
    episodes = []
    for episode, log, angle in zip(channels.episodes, logs, channels.angles, strict=True):
        _, first = applied_inputs(episode, shift)
        q = log.w.shape[1] - 2
        rows = angle[first : first + log.a.shape[0]]
        chosen = next_signs(log.x, log.a, log.w[:, :q], rows, (Ad, Bd, Ed), noise)
        w = np.array(episode.w, dtype=float, copy=True)
        w[first : first + chosen.shape[0], q:] = chosen
        episodes.append(Trajectory(t=episode.t, x=episode.x, u=episode.u, w=w, angle=episode.angle))
    return DeadTimeChannels(episodes, channels.model, channels.angles, "sample")


def _robust_noise(logs: list[_Log], matrices: tuple[Array, Array, Array]) -> Array | None:
    """A diagonal covariance of the measurement noise on the states, unit^2, where the
    one-step residuals' lag-one covariance gives none (:func:`~._sign_bias.measurement_noise`):
    a model far off, its residuals then correlated by its own error. Half the robust
    variance of each state's one-step residuals (each holds two samples' noise; the
    median's spread ignores the few samples a wrong sign moves far); None where it is
    zero. It is larger than the noise by the model's error, which leaves more signs
    undecided, each then taken by the larger effect of the dead time."""
    e = np.concatenate([log.one_step_residuals(matrices) for log in logs])
    spread = 1.4826 * np.median(np.abs(e - np.median(e, axis=0)), axis=0)
    if not np.all(spread > 0.0):
        return None
    return np.diag(0.5 * spread**2)


def log_det(fit: OutputErrorFit) -> float:
    """``log det`` of the fit's output errors' covariance."""
    return float(np.linalg.slogdet(fit.noise_covariance)[1])
