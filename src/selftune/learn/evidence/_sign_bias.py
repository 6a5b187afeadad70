"""The dead-time model's bias from the currents' signs near zero, measured and removed.

The dead-time channels are the phase currents' signs as measured (:mod:`._dead_time`).
Where a phase current is within the noise of zero, the noise decides its sign: the
channel is then wrong where the true current is small, which correlates the error with
the current itself, so the fit is biased (errors in variables that no number of samples
removes). The fitted resistance takes the part of the dead-time voltage the wrong signs
hide, and the feedforward U follows it: on the README's drive (2 V of dead time, 10 mA
of noise, 0.3 A rms currents) U was 5-9% off under standard errors of 1.4-2.2%; with the
true signs, 0.07% off.

The bias is measured on the fitted model itself (a parametric bootstrap): the model's
own currents are simulated from the logged inputs with the dead time switching on their
true signs, measurement noise of the estimated covariance is added, the signs are taken
from those noisy currents as from the log, and the model is refitted
(:data:`BIAS_DRAWS` times). The refits' mean departure from the model is the bias at
the model; the parameters are corrected by it and their variances are at least the
refits'. The bias is measured where the model is, not where the truth is: a second
round measures it again at the corrected model and corrects again, and the covariance
gains the second correction's outer product (the correction is known no better than its
last round) and the draws' noise in the rounds' means.

The refits' world replays the logged voltages open loop where the data fix the replayed
currents: their standard deviation under the fit's covariance is at most
:data:`REPLAY_UNCERTAINTY` of their spread. Where the resistance barely damps the plant
(``R_s h / L`` of 1e-4), the replay's slow currents are the voltages over an ``R_s`` the
data fix to several percent, and the bias, an effect of where the currents cross zero,
moved with every small change of the model (L_q's, in four rounds on a 4.5/11.3 mH motor
of 0.32 ohm rated 0.28 A: -0.08%, +0.47%, +0.18%, -0.35%; reported 0.52% off). There the
experiment is re-run instead: the drive's current control law, read off the log
(:class:`~._drive_law.DriveLaw`), closes the loop on the model with the logged
exploration and the world's own noise, as the drive held its currents (that motor: 0.06%
off). A law that is not one (a residual that is not white) or that does not close a
stable loop on the model leaves the replay.

The simulation must describe the data. Where the fitted model's noise-free currents,
its dead time switched on their own signs, are off the measured ones by more than
:data:`WORLD_FIDELITY` of their spread, the refits would measure the bias of another
drive: a structured fit is then refitted on the signs the next sample shows, and that
fit is reported where it explains the data better, passes the tests and its own
simulation describes them (:func:`~._model_signs.adopted_next_signs`); else the fit is
left as it was. Where they are off by more than the spread itself
(:data:`OWN_SIGNS_LIMIT`) and the next sample's signs do not help, the fit explains the
data only through the measured signs, which near zero current are the noise's, and the
data are refused
(:class:`~selftune.errors.ModelMissesEffect`): a 25 uH, 0.02 ohm motor on 48 V with 2 V of
dead time, 1.1-1.2 times the spread, was returned with R_s 61-71% high and L_d 3-5% low at
4-6 standard errors before this check. Where the corrected model's currents leave the
data in a later round, the correction is not made.

The simulation switches the dead time as the data preferred (:data:`~._dead_time.Switching`):
on each sample's own signs, or along the current's path within it.

The measurement noise is estimated from the one-step residuals of the fitted model on
the log (their lag-one covariance is ``-Ad R``: each measured state enters two
consecutive residuals), not from the output errors, which the signs' errors inflate.
Where the logged currents are whole steps of an ADC coarse against the noise
(:mod:`._adc`), the simulation rounds its phase currents to those steps after noise of
the variance the rounding does not explain: rounding finer than the noise is noise,
coarser is a fixed function of the current, which the bias and the refits' spread must
include (the corpus's 48 V motor,
48.8 mA steps and 2 mA of noise: the norm of K's error from up to 4.5 stated standard
errors, with Gaussian noise simulated, to at most 2.9).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ...core import Array
from ...errors import InputError, ModelMissesEffect
from ._adc import current_lattice
from ._alignment import applied_inputs
from ._bootstrap import refits, with_spread
from ._dead_time import SWITCHING_SIGNS, DeadTimeChannels, Switching, path_vector, sign_vector
from ._drive_law import DriveLaw
from ._next_signs import next_signs
from ._output_error import OutputErrorFit, _finish, _Log, _logs, simulation_spread

__all__ = [
    "BIAS_DRAWS",
    "OWN_SIGNS_LIMIT",
    "REPLAY_UNCERTAINTY",
    "WORLD_FIDELITY",
    "OwnSimulation",
    "measurement_noise",
    "model_currents",
    "without_sign_bias",
]

#: Refits that measure the bias, per round.
BIAS_DRAWS = 6

#: The most transitions the refits see (the first of the logs): the bias, an effect of
#: the signs near zero current, is the same on a longer log; the refits' cost is not
#: (a 1,000,000-row log would take hours).
BIAS_SAMPLES = 20_000

#: Rounds: each measures the bias where the previous one's correction put the model.
BIAS_ROUNDS = 2

#: The largest rms of the simulated currents' departure from the measured ones, as a
#: fraction of the measured currents' spread, at which the simulation describes the data
#: (measured: 0.05-0.1 on the README's drive; 1.0 on a 48 V motor whose fitted plant
#: did not follow its 0.07 A currents, where the correction made the flux's standard
#: error 40 times larger).
WORLD_FIDELITY = 1.0 / 3.0

#: The departure (as :data:`WORLD_FIDELITY`) beyond which the fit explains the data only
#: through the measured signs and is refused: its own simulation is then further from the
#: measured currents than their spread, worse than their mean. Measured: 1.1-1.2 on the
#: 25 uH motor on 48 V with 2 V of dead time (R_s 62-71% high, L_d 3-5% low at 4-6
#: standard errors); 0.37-0.51 on logs whose results were within their errors (the flux
#: step of a low-inductance motor, a two-speed ramp), where the bias is left unmeasured.
OWN_SIGNS_LIMIT = 1.0

#: The largest standard deviation of the fit's simulated currents under its parameter
#: covariance, as a fraction of the measured currents' spread (:func:`_replay_uncertainty`),
#: at which the logged voltages replayed open loop are the refits' world; beyond it the
#: data do not fix the replayed currents and the experiment is re-run under the drive's
#: law read off the log (:mod:`._drive_law`). Measured: 0.00005-0.0005 on the interior
#: study's seed 14 at rated speed, 0.0013 on the honesty study's log 87 (whose error, 2.8
#: standard errors on the replay, was 2.9 on the re-run experiment); 0.007-0.013 on that
#: seed's three 540 V motors of 0.25-0.31 A whose resistance barely damps them.
REPLAY_UNCERTAINTY = 0.003

#: Gauss-Newton iterations of each refit: on the README's drive (1-2 s logs, four seeds)
#: 4 left K and U as close to the truth as 12 did (their errors' norms within 0.7 of a
#: standard error of each other, neither always smaller), in half the time.
BIAS_REFIT_ITERATIONS = 4


def measurement_noise(logs: Sequence[_Log], matrices: tuple[Array, Array, Array]) -> Array | None:
    """The covariance ``R`` of the measurement noise on the states, unit^2, from the lag-one
    covariance ``-Ad R`` of the model's one-step residuals; None unless it is positive
    definite (the residuals then say nothing of the noise).

    Parameters
    ----------
    logs : sequence of _Log
        The aligned logs.
    matrices : (Ad, Bd, Ed)
        The fitted model.
    """
    Ad = matrices[0]
    lagged, count = np.zeros_like(Ad), 0
    for log in logs:
        e = log.one_step_residuals(matrices)
        lagged += e[1:].T @ e[:-1]
        count += e.shape[0] - 1
    if count < 2:
        return None
    R = -np.linalg.solve(Ad, lagged / count)
    R = 0.5 * (R + R.T)
    return R if bool(np.all(np.linalg.eigvalsh(R) > 0.0)) else None


def _simulated(
    matrices: tuple[Array, Array, Array],
    log: _Log,
    start: tuple[Array, Array],
    switching: Switching,
    loop: tuple[DriveLaw, Array] | None = None,
) -> tuple[Array, Array]:
    """The model's currents (T + 1, 2) from ``start = (x0, angles)`` with the dead time
    switching on their own signs (the last two columns of ``Ed`` are the signs' gain),
    and the inputs (T, m) it ran on: the logged ones; or with ``loop = (law, noise)``
    those of the drive's law (:class:`~._drive_law.DriveLaw`) on the currents plus
    ``noise`` (draws, T + 1, 2), the logged exploration kept, for each of the draws side
    by side: currents (draws, T + 1, 2) and inputs (draws, T, m).

    On the path (:func:`~._dead_time.path_vector`) a sample's signs need its end: taken
    from the step with the signs at its start, then from the step with the path's
    (twice)."""
    Ad, Bd, Ed = matrices
    x0, angle = start
    q = Ed.shape[1] - 2
    forcing = (log.a @ Bd.T + log.w[:, :q] @ Ed[:, :q].T).tolist()
    cos, sin = np.cos(angle).tolist(), np.sin(angle).tolist()
    (a00, a01), (a10, a11) = Ad.tolist()
    (g00, g01), (g10, g11) = Ed[:, q:].tolist()
    d: Any = float(x0[0])  # a float, or the draws' array where the law closes the loop
    q_: Any = float(x0[1])
    if loop is not None:  # the law's answer to the departure from the logged currents
        law, noise = loop
        draws = noise.shape[0]
        history = law.start(draws)
        departures = noise[:, :-1] - log.x[:-1]
        answers = np.empty((draws, *log.a.shape))
        d, q_ = np.full(draws, d), np.full(draws, q_)
    states = [(d, q_)]
    for k, (f_d, f_q) in enumerate(forcing):
        if loop is not None:
            answer = law.answer(history, np.column_stack([d, q_]) + departures[:, k])
            answers[:, k] = answer
            move = answer @ Bd.T
            f_d, f_q = f_d + move[:, 0], f_q + move[:, 1]
        free_d, free_q = a00 * d + a01 * q_ + f_d, a10 * d + a11 * q_ + f_q
        s_d, s_q = sign_vector(d, q_, cos[k], sin[k])
        next_d, next_q = free_d + g00 * s_d + g01 * s_q, free_q + g10 * s_d + g11 * s_q
        for _ in range(2 if switching == "path" else 0):
            s_d, s_q = path_vector(
                (d, q_, cos[k], sin[k]), (next_d, next_q, cos[k + 1], sin[k + 1])
            )
            next_d, next_q = free_d + g00 * s_d + g01 * s_q, free_q + g10 * s_d + g11 * s_q
        d, q_ = next_d, next_q
        states.append((d, q_))
    x = np.array(states)  # (T + 1, 2), or (T + 1, 2, draws)
    if loop is None:
        return x, log.a
    return x.transpose(2, 0, 1), log.a + answers


def model_currents(fit: OutputErrorFit, channels: DeadTimeChannels, shift: int) -> list[Array]:
    """The fitted model's noise-free currents at each log's rows, the dead time switching
    on their own signs (as the data preferred), from the fit's initial states and the
    logged inputs; the rows before the first the fit used are the measured ones.

    Parameters
    ----------
    fit : OutputErrorFit
        The output-error fit on the channels.
    channels : DeadTimeChannels
        The logs as fitted, with their angles and way of switching.
    shift : int
        The alignment of the logged inputs.

    Returns
    -------
    list of ndarray, shape (T, 2)
        ``[i_d, i_q]`` of each log, A.
    """
    assert channels.angles is not None and channels.switching is not None
    matrices = fit.matrices(fit.parameters)
    currents = []
    for episode, log, angle, simulated in zip(
        channels.episodes, _logs(channels.episodes, shift), channels.angles, fit.simulated,
        strict=True,
    ):  # fmt: skip
        _, first = applied_inputs(episode, shift)
        rows = angle[first : first + log.x.shape[0]]
        x = episode.x.copy()
        x[first : first + log.x.shape[0]] = _simulated(
            matrices, log, (simulated[0], rows), channels.switching
        )[0]
        currents.append(x)
    return currents


def _first_samples(
    logs: Sequence[_Log], rows: Sequence[Array], x0s: Sequence[Array]
) -> tuple[list[_Log], list[Array], list[Array]]:
    """The logs' first :data:`BIAS_SAMPLES` transitions in all (with their angles and
    initial states): the bias does not shrink with the length, the refits' cost grows."""
    kept: tuple[list[_Log], list[Array], list[Array]] = ([], [], [])
    left = BIAS_SAMPLES
    for log, angle, x0 in zip(logs, rows, x0s, strict=True):
        count = min(log.a.shape[0], left)
        if count < 1:
            break
        kept[0].append(_Log(x=log.x[: count + 1], a=log.a[:count], w=log.w[:count]))
        kept[1].append(angle[: count + 1])
        kept[2].append(x0)
        left -= count
    return kept


def _own_currents(
    matrices: tuple[Array, Array, Array],
    logs: Sequence[_Log],
    rows: Sequence[Array],
    x0s: Sequence[Array],
    switching: Switching,
) -> list[Array]:
    """Each log's currents simulated by the model from its inputs, the dead time switched
    on the simulated currents' own signs."""
    return [
        _simulated(matrices, log, (x0, angle), switching)[0]
        for log, x0, angle in zip(logs, x0s, rows, strict=True)
    ]


def _replay_uncertainty(fit: OutputErrorFit, logs: list[_Log], x0s: list[Array]) -> float:
    """The fit's simulated currents' standard deviation under its parameter covariance
    (:func:`~._output_error.simulation_spread`) as a fraction of the measured currents'
    spread, the larger state's (:data:`REPLAY_UNCERTAINTY`)."""
    return float(np.max(simulation_spread(fit, logs, x0s) / _spread(logs)))


def _spread(logs: Sequence[_Log]) -> Array:
    """The measured currents' standard deviation per state (never zero), A."""
    measured = np.concatenate([log.x for log in logs])
    return np.maximum(np.std(measured, axis=0), np.finfo(float).tiny)


def _departure(truths: Sequence[Array], logs: Sequence[_Log]) -> Array:
    """The rms of the simulated currents' departure from the measured ones, per state, as
    a fraction of the measured currents' spread."""
    departure = np.concatenate([truth - log.x for truth, log in zip(truths, logs, strict=True)])
    return np.sqrt(np.mean(departure**2, axis=0)) / _spread(logs)


def _describes(truths: Sequence[Array], logs: Sequence[_Log]) -> bool:
    """Whether the simulated currents follow the measured ones (:data:`WORLD_FIDELITY`)."""
    return bool(np.all(_departure(truths, logs) <= WORLD_FIDELITY))


def _own_signs_refusal(ratio: float) -> ModelMissesEffect:
    """The refusal of a fit that explains the data only through the measured signs."""
    causes = (
        "the noise decides the measured currents' signs near zero current, and a dead-time "
        "voltage large against the resistive drop (a low-voltage drive with microseconds "
        "of dead time) makes their errors decide R_s and the inductances",
        "an effect the dead-time model misses",
    )
    return ModelMissesEffect(
        "the model explains the data only through the measured currents' signs: with its "
        "dead time switched on its own currents' signs, its simulation departs from the "
        f"measured currents by {ratio:.3g} times their spread (at most {OWN_SIGNS_LIMIT:.3g}); "
        f"likely causes: {causes[0]}, or {causes[1]}; larger currents, the drive's "
        "dead-time compensation or a shorter dead time help",
        statistic=ratio, threshold=OWN_SIGNS_LIMIT, causes=causes,
    )  # fmt: skip


def _stable(fit: OutputErrorFit, parameters: Array) -> bool:
    """Whether the parameters give a finite, stable model (the fit's kind)."""
    if not np.all(np.isfinite(parameters)):
        return False
    try:
        Ad = fit.matrices(parameters)[0]
    except (InputError, np.linalg.LinAlgError):
        return False
    return bool(np.all(np.isfinite(Ad))) and float(np.max(np.abs(np.linalg.eigvals(Ad)))) < 1.0


@dataclass(frozen=True)
class OwnSimulation:
    """A fit's own currents, its dead time switched on their own signs, beside the logs'
    first :data:`BIAS_SAMPLES` transitions they simulate (:meth:`of`); their
    :attr:`departure` from the measured currents says whether the simulation describes
    the data (see the module)."""

    switching: Switching
    whole: list[_Log]  # every log, in the fit's alignment
    starts: list[Array]  # the fit's initial state of each log
    logs: list[_Log]
    rows: list[Array]  # the logs' angles
    x0s: list[Array]
    truths: list[Array]  # the simulated currents

    @classmethod
    def of(cls, fit: OutputErrorFit, channels: DeadTimeChannels, shift: int) -> OwnSimulation:
        """The simulation of ``fit`` on the logs of ``channels`` aligned by ``shift``.

        Parameters
        ----------
        fit : OutputErrorFit
            The output-error fit with sign channels as the last two exogenous channels.
        channels : DeadTimeChannels
            The logs as fitted, their angles and the way of switching.
        shift : int
            The alignment of the logged inputs.
        """
        episodes, angles, switching = channels.episodes, channels.angles, channels.switching
        assert angles is not None and switching is not None
        whole = _logs(episodes, shift)  # the fit's own alignment of the logs
        rows = [
            angle[first : first + log.x.shape[0]]
            for angle, log, (_, first) in zip(
                angles, whole, (applied_inputs(e, shift) for e in episodes), strict=True
            )
        ]
        starts = [simulated[0] for simulated in fit.simulated]
        logs, rows, x0s = _first_samples(whole, rows, starts)
        truths = _own_currents(fit.matrices(fit.parameters), logs, rows, x0s, switching)
        return cls(switching, whole, starts, logs, rows, x0s, truths)

    @property
    def departure(self) -> float:
        """The rms of the simulated currents' departure from the measured ones as a
        fraction of their spread, the larger state's: up to :data:`WORLD_FIDELITY` the
        simulation describes the data, beyond :data:`OWN_SIGNS_LIMIT` the fit explains
        them only through the measured signs."""
        return float(np.max(_departure(self.truths, self.logs)))


def without_sign_bias(
    fit: OutputErrorFit,
    channels: DeadTimeChannels,
    shift: int,
    floor: Array,
    own: OwnSimulation | None = None,
    next_sample: bool = False,
) -> tuple[OutputErrorFit, Array, tuple[float | None, float | None]] | None:
    """``fit`` corrected for the signs' bias, the correction, and the ADC's step and the
    noise before it that the simulations used, A (None, None: Gaussian noise; see the
    module); None when the bias cannot be measured (no noise estimate, the refits fail,
    or the corrected model leaves the data).

    Parameters
    ----------
    fit : OutputErrorFit
        The output-error fit with the measured signs as the last two exogenous channels.
    channels : DeadTimeChannels
        The logs as fitted (``w`` with the signs' channels), their angles and the way of
        switching.
    shift : int
        The alignment of the logged inputs.
    floor : ndarray, shape (2,)
        The states' rounding floor.
    own : OwnSimulation, optional
        The fit's own simulation on the channels, where it was made already.
    next_sample : bool
        Whether the channels' signs are those the next sample shows
        (:func:`~._next_signs.next_signs`): the simulations' signs are then taken so too,
        by the simulated model and the measured noise.

    Raises
    ------
    ModelMissesEffect
        When the fit's own simulation, its dead time on its own currents' signs, does not
        describe the measured currents (see the module).
    """
    own = OwnSimulation.of(fit, channels, shift) if own is None else own
    switching, whole, starts = own.switching, own.whole, own.starts
    logs, rows, x0s, truths = own.logs, own.rows, own.x0s, own.truths
    signs = SWITCHING_SIGNS[switching]
    departure = own.departure
    if departure > OWN_SIGNS_LIMIT:  # the fit itself: the measured signs carry it
        raise _own_signs_refusal(departure)
    if departure > WORLD_FIDELITY:
        return None
    R = measurement_noise(whole, fit.matrices(fit.parameters))
    if R is None:
        return None
    R = R + np.diag(np.maximum(floor**2 - np.diag(R), 0.0))
    root = np.linalg.cholesky(R)
    lattice = current_lattice(np.concatenate([log.x for log in logs]), np.concatenate(rows))
    analog = 0.0 if lattice is None else lattice.noise_sd(R)
    if lattice is not None and not lattice.coarse(analog):
        lattice = None  # rounding finer than the noise: Gaussian noise describes it
    share = sum(log.a.shape[0] for log in logs) / sum(log.a.shape[0] for log in whole)
    q = logs[0].w.shape[1] - 2
    structured = fit.structure is not None
    law = None  # the logged voltages replayed, unless the data leave the replay open
    if _replay_uncertainty(fit, logs, x0s) > REPLAY_UNCERTAINTY:
        law = DriveLaw.of([(log.x, log.a, log.w[:, :q]) for log in logs], shift)
    corrected, steps = fit.parameters, list[Array]()
    draws = np.zeros((0, fit.parameters.shape[0]))
    for _ in range(BIAS_ROUNDS):
        if steps:  # the corrected model's own currents (the fit's are above)
            truths = _own_currents(fit.matrices(corrected), logs, rows, x0s, switching)
            if not _describes(truths, logs):
                return None

        model = fit.matrices(corrected)
        closed = law is not None and law.closes_stable_loop(model[0], model[1])

        def world(
            rng: np.random.Generator,
            count: int,
            truths: list[Array] = truths,
            model: tuple[Array, Array, Array] = model,  # the next signs' reader
            closed: bool = closed,
        ) -> list[list[_Log]]:
            # the draws' random numbers in turn, as one draw after another takes them: the
            # noise on the currents (which the law answers where it closes the loop; on a
            # coarse ADC the noise before the rounding stands for it), then the ADC's
            noises, analogs = {}, {}
            for draw in range(count):
                for index, truth in enumerate(truths):
                    if closed or lattice is None:
                        noises[draw, index] = rng.standard_normal(truth.shape) @ root.T
                    if lattice is not None:
                        analogs[draw, index] = analog * rng.standard_normal((truth.shape[0], 3))
            currents = [[truth] * count for truth in truths]
            inputs = [[log.a] * count for log in logs]
            if closed:  # the experiment re-run, the draws side by side
                assert law is not None
                for index, (log, angle, x0) in enumerate(zip(logs, rows, x0s, strict=True)):
                    noise = np.array([noises[draw, index] for draw in range(count)])
                    run = _simulated(model, log, (x0, angle), switching, (law, noise))
                    currents[index], inputs[index] = list(run[0]), list(run[1])
            drawn = []
            for draw in range(count):
                logged = []
                for index, (log, angle) in enumerate(zip(logs, rows, strict=True)):
                    truth, applied = currents[index][draw], inputs[index][draw]
                    if lattice is None:
                        x = truth + noises[draw, index]
                    else:
                        x = lattice.measure(truth, angle, analogs[draw, index])
                    samples = log.w.shape[0]
                    if next_sample:  # the signs as the log's fit took them
                        held = next_signs(x, applied, log.w[:, :q], angle[:samples], model, R)
                    else:
                        held = signs(x, angle)[:samples]
                    logged.append(_Log(x=x, a=applied, w=np.hstack([log.w[:, :q], held])))
                drawn.append(logged)
            return drawn

        refitted = refits(
            fit, world, (fit.matrices, structured), floor, BIAS_DRAWS, corrected,
            BIAS_REFIT_ITERATIONS,
        )  # fmt: skip
        if refitted is None:
            return None
        draws = refitted
        steps.append(fit.parameters - np.mean(draws, axis=0))  # the departure, reversed
        corrected = corrected + steps[-1]
        if not _stable(fit, corrected):
            return None
    final = _finish(
        whole, corrected, fit.matrices, structured, starts, fit.model.h, fit.iterations,
        floor,
    )  # fmt: skip
    # the same kind of parameters; the time correlation is the data's, measured at the fit
    final = replace(final, structure=fit.structure, correlation_inflation=fit.correlation_inflation)
    spread = share * np.atleast_2d(np.cov(draws.T))  # the refits saw a share of the log
    extra = np.outer(steps[-1], steps[-1]) + spread / draws.shape[0]
    adc = (None, None) if lattice is None else (lattice.step, analog)
    return with_spread(final, np.diag(spread), extra), corrected - fit.parameters, adc
