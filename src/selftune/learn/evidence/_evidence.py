"""What the data say before any controller is learned: alignment, noise, consistency.

Every learner starts here (:func:`gather_evidence`):

1. the alignment of the logged inputs, checked against the data (:mod:`._alignment`);
2. the exact discrete model refined by output error (:mod:`._output_error`), which
   estimates the measurement noise and gives noise-free states for the ADP learners;
3. consistency tests: at the true model the output errors are the measurement noise,
   white and independent of the inputs before them. Their correlation with the past
   inputs (lags 1 to :data:`TEST_LAGS`), each scaled by its variance under independence
   (Bartlett's formula, so that errors merely correlated in time do not count), is a
   chi-square statistic with ``n m L`` degrees of freedom (counting at most
   :data:`TEST_SAMPLES` samples of a log); far in its tail (p below
   :data:`TEST_LEVEL`) the model does not explain the data and no controller is
   returned: a misaligned log, an input error the log does not show (inverter dead
   time), a nonlinearity (saturation), or too coarse a resolution.
   The same errors, correlated in time, inflate the parameters' robust variances beyond
   what white noise gives (:attr:`OutputErrorFit.correlation_inflation`): the standard
   errors include it; far beyond 1 (:data:`INFLATION_LIMIT`) the model misses an effect,
   which refuses the data unless the dead time is modelled (then it is the dead-time
   model's own approximation near zero current, and the verdict notes it).

With the dead time modelled, the channels hold the measured currents' signs, which the
noise decides where a phase current is within it of zero; each wrong sign is a voltage
error of ``2 v`` on that phase for a sample, which the model's simulation carries for a
time constant of the plant. Output errors correlated so, and with the inputs the
controller computed from the currents they moved, are not an effect the model misses:
before refusing, the tests judge the model refitted on the signs of its own noise-free
currents, then on those the next sample shows (:func:`~._model_signs.sign_refits`), where
those explain the data better, and refuse only if both fail them. The parameters reported
are the measured signs' fit's, with their bias removed (:mod:`._sign_bias`), except a
structured fit's on the next sample's signs where the tests accept that one and it
explains the data better, the measured signs' fit having failed the tests, its own
simulation departing from the data, the DC bus given so that the reported bars hold the
carrier's pulses, or the two fits apart beyond the measured one's bars
(:func:`~._model_signs.on_other_signs`, :func:`~._model_signs.reported_next_signs`); a
refit on the model's own signs would have too small standard errors (its signs follow
its parameters).

A structured fit (``structure = "spmsm"``: three or four physical parameters instead of
every entry of ``[Ad, Bd, Ed]``) is also compared with the unstructured fit of the same
logs (:func:`structure_statistic`, a likelihood ratio): far in the chi-square tail the
structure does not hold, or its search stopped in a wrong minimum, which short noisy logs
do (the inputs' gain fitted near zero, say) while every other test passes.

An inverter's dead time is such an unlogged input error: ``-v sign(i_x)`` on each phase.
With ``dead_time = True`` the model carries it (the dq vector of the phase currents'
signs becomes an extra exogenous input whose gain ``-v Bd`` is fitted, :mod:`._dead_time`),
so it is neither refused nor mistaken for back-EMF or feedforward; ``v`` is reported.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.special

from ...core import Array
from ...errors import (
    ConfigurationMismatch,
    InputError,
    ModelMissesEffect,
    NotExciting,
)
from .._problem import LearningOptions, LearningProblem
from ..data._trajectory import Trajectory
from ._alignment import Alignment, applied_inputs, check_alignment, stated_shift
from ._dead_time import (
    DeadTimeChannels,
    DeadTimeModel,
    Switching,
    against_back_emf,
    with_dead_time,
)
from ._discrete_model import DiscreteModel, lack_of_rank, regressor_names
from ._incremental_structure import IncrementalStructure
from ._model_signs import changed_signs, on_other_signs, reported_next_signs
from ._output_error import (
    IpmsmStructure,
    MotorStructure,
    OutputErrorFit,
    SpmsmStructure,
    fit_output_error,
)
from ._pulses import check_bus, holds_pulses, pulse_shift
from ._rounding import resolution_floor
from ._sign_bias import OwnSimulation, without_sign_bias
from ._structure_check import check_structure, structure_statistic

__all__ = [
    "INFLATION_LIMIT",
    "TEST_LAGS",
    "TEST_LEVEL",
    "TEST_SAMPLES",
    "ConsistencyTest",
    "Evidence",
    "autocorrelation",
    "gather_evidence",
    "log_precision",
    "reduced_problem",
    "structure_statistic",
]

#: Lags of the input-residual cross-correlation test, samples.
TEST_LAGS = 10

#: Significance level of the consistency test: the data are refused only far in the tail.
TEST_LEVEL = 1e-6

#: The most samples of one log the consistency test counts (2 s at 10 kHz). Its power
#: grows with the samples, so on a long enough log it finds any model's approximation:
#: 100 s of the README's drive (1,000,000 rows) gave a statistic of 2,973 against a
#: threshold of 98, for a misfit of correlation 0.009 (counted over 20,000 samples, 59).
#: Counting at most this many samples keeps a log accepted when it grows longer: a
#: misfit is refused when it would be in 2 s of data.
TEST_SAMPLES = 20_000

#: The ratio of the parameters' robust variances to what white output errors would give
#: above which the model is said to miss an effect: about 1 (0.7-1.3 measured) when the
#: model explains the data up to white noise; 20-45 with an inverter's dead time left
#: out of the model (whose feedforward then absorbed the dead-time voltage: U 4-5% off
#: with standard errors of 0.5-0.8%, so such data are refused); but also 14-24 with the
#: dead time modelled on logs whose currents reverse (the signs near zero current),
#: where the results stayed within their inflated standard errors (a note, not a
#: refusal).
INFLATION_LIMIT = 10.0


@dataclass(frozen=True)
class ConsistencyTest:
    """The cross-correlation test of the output errors against the past inputs.

    Attributes
    ----------
    statistic : float
        ``T sum r^2`` over lags, inputs and states (r the normalized cross-correlations).
    threshold : float
        The chi-square quantile at ``1 - TEST_LEVEL``.
    degrees_of_freedom : int
        ``n m L``.
    exact : bool
        True when the model explains the data to rounding (noise-free data): the test is
        then not meaningful and passes.
    """

    statistic: float
    threshold: float
    degrees_of_freedom: int
    exact: bool

    @property
    def passed(self) -> bool:
        """Whether the data are consistent with the model."""
        return self.exact or self.statistic <= self.threshold


@dataclass(frozen=True)
class Evidence:
    """Alignment, model, noise and consistency of the logs.

    Attributes
    ----------
    episodes : list of Trajectory
        The logs as fitted: with ``dead_time``, ``w`` carries the dq vector of the phase
        currents' signs as extra channels after the reference's.
    alignment : Alignment
        The alignment of the logged inputs (and its least-squares model).
    fit : OutputErrorFit or None
        The output-error model (None for an unstable plant).
    consistency : ConsistencyTest
        The cross-correlation test of the output errors.
    extra : int
        Number of extra exogenous channels (n with ``dead_time``, else 0).
    precision : str
        The precision the states were logged with (:func:`log_precision`).
    dead_time_model : str or None
        How the phase signs were computed (:func:`~._dead_time.with_dead_time`); None
        without ``dead_time``.
    sign_correction : ndarray or None
        The correction of the fit's parameters for the bias of the measured signs
        (:mod:`._sign_bias`); None where none was made.
    switching : {"sample", "path"} or None
        When the dead time's error switches, as the data preferred
        (:data:`~._dead_time.Switching`); None without phase signs.
    adc_step : float or None
        The ADC's step the correction's simulations rounded the phase currents to, A (read
        from the logged currents, :mod:`._adc`); None where they found none (Gaussian
        noise simulated) or no correction was made.
    adc_noise : float or None
        The noise before that ADC on each phase, A (standard deviation; with
        ``adc_step``).
    pulse_shift : ndarray or None
        The shift of the structured fit's parameters that the dead time's short and
        late pulses leave (:func:`~._pulses.pulse_shift`), with the options' DC bus;
        None without it.
    next_sample_signs : int
        The samples whose phase signs the fit took from the next sample instead of the
        measured currents (:func:`~._model_signs.next_sample_signs`): nonzero where the
        measured signs' fit did not explain the data and this one did.
    """

    episodes: list[Trajectory] = field(repr=False)
    alignment: Alignment = field(repr=False)
    fit: OutputErrorFit | None = field(repr=False)
    consistency: ConsistencyTest
    extra: int
    precision: str = "float64"
    dead_time_model: DeadTimeModel | None = None
    sign_correction: Array | None = field(default=None, repr=False)
    switching: Switching | None = None
    adc_step: float | None = None
    adc_noise: float | None = None
    pulse_shift: Array | None = field(default=None, repr=False)
    next_sample_signs: int = 0

    @property
    def model(self) -> DiscreteModel:
        """The model the verdict and identify-then-design use: the output-error fit's, or
        the least-squares one of the alignment without a fit."""
        return self.alignment.model if self.fit is None else self.fit.model

    @property
    def model_noise(self) -> Array | None:
        """Estimated measurement-noise standard deviation of each state (None without an
        output-error fit)."""
        if self.fit is None:
            return None
        return np.asarray(np.sqrt(np.diag(self.fit.noise_covariance)))


def log_precision(episodes: Sequence[Trajectory]) -> tuple[str, float]:
    """The precision the states were logged with: float32, a number of significant
    digits, or full float64 precision; and its relative rounding.

    Parameters
    ----------
    episodes : sequence of Trajectory
        The logs.

    Returns
    -------
    text : str
        ``"float32"``, ``"7 significant digits"`` or ``"float64"``.
    relative : float
        Half a unit in the last place, relative.
    """
    x = np.concatenate([episode.x for episode in episodes])
    if np.array_equal(x.astype(np.float32).astype(np.float64), x):
        return "float32", float(np.finfo(np.float32).eps) / 2
    finite = x[x != 0.0]
    for digits in range(3, 16):
        exponent = np.floor(np.log10(np.abs(finite)))
        scale = 10.0 ** (digits - 1 - exponent)
        if np.allclose(np.round(finite * scale) / scale, finite, rtol=1e-15, atol=0.0):
            return f"{digits} significant digits", 0.5 * 10.0 ** (1 - digits)
    return "float64", float(np.finfo(np.float64).eps) / 2


def autocorrelation(series: Array, lags: int) -> Array:
    """Sample autocorrelations of each column at lags 1..``lags``, shape (lags, columns).

    Parameters
    ----------
    series : ndarray, shape (T, columns)
        The series (with its mean removed by the caller where it has one).
    lags : int
        The largest lag, samples.
    """
    energy = np.maximum(np.sum(series**2, axis=0), 1e-300)
    return np.array([np.sum(series[k:] * series[:-k], axis=0) / energy for k in range(1, lags + 1)])


def _bartlett(e: Array, u: Array) -> Array:
    """``T var(r)`` of the cross-correlation of each output error with each input when the
    two are independent (Bartlett's formula, ``1 + 2 sum_k w_k rho_e(k) rho_u(k)`` with
    Bartlett weights), at least 1: white-noise errors give 1; errors that the model leaves
    correlated in time (an approximate dead-time model near zero current) are not taken
    for a dependence on the inputs. Shape (n, m)."""
    count = e.shape[0]
    lags = int(min(max(count // 10, 1), 4 * count ** (1 / 3)))
    weights = 1.0 - np.arange(1, lags + 1) / (lags + 1)
    rho_e, rho_u = autocorrelation(e, lags), autocorrelation(u, lags)
    factor = 1.0 + 2.0 * np.einsum("k,ki,kj->ij", weights, rho_e, rho_u)
    return np.asarray(np.maximum(factor, 1.0))


def _consistency(
    episodes: Sequence[Trajectory], shift: int, fit: OutputErrorFit
) -> ConsistencyTest:
    """Correlation of the output errors with the applied inputs 1 to TEST_LAGS samples
    before them (see the module docstring)."""
    n, m = fit.model.n, fit.model.Bd.shape[1]
    statistic, exact = 0.0, True
    for episode, residual in zip(episodes, fit.residuals, strict=True):
        a, _ = applied_inputs(episode, shift)
        count = min(a.shape[0], residual.shape[0] - 1)
        scale = float(np.sqrt(np.mean(episode.x**2)))
        if float(np.sqrt(np.mean(residual**2))) > 1e-9 * max(scale, 1e-300):
            exact = False
        # residual[j + 1] is the error at the sample after a[j] was applied
        e = residual[1 : count + 1] - residual[1 : count + 1].mean(axis=0)
        u = a[:count] - a[:count].mean(axis=0)
        variance = _bartlett(e, u)
        for lag in range(1, min(TEST_LAGS, count - 1) + 1):
            later, earlier = e[lag - 1 :], u[: count - lag + 1]  # e_k against a_(k - lag)
            norms = np.outer(np.linalg.norm(later, axis=0), np.linalg.norm(earlier, axis=0))
            r = (later.T @ earlier) / np.maximum(norms, 1e-300)
            statistic += min(later.shape[0], TEST_SAMPLES) * float(np.sum(r**2 / variance))
    freedom = n * m * TEST_LAGS * len(episodes)
    threshold = float(scipy.special.chdtri(freedom, TEST_LEVEL))  # chi-square quantile
    return ConsistencyTest(statistic, threshold, freedom, exact)


def gather_evidence(
    episodes: Sequence[Trajectory],
    problem: LearningProblem,
    options: LearningOptions,
) -> Evidence:
    """Alignment, output-error model and consistency of the logs (see the module).

    Parameters
    ----------
    episodes : sequence of Trajectory
        The logs.
    problem : LearningProblem
        What the learner knows.
    options : LearningOptions
        How to learn (alignment, dead time, structure).

    Returns
    -------
    Evidence

    Raises
    ------
    MisalignedLog
        If the data contradict the stated alignment (a ConsistencyError).
    ModelMissesEffect
        If the model cannot explain the data (a ConsistencyError).
    ConfigurationMismatch
        If the structure the options state explains the data worse than none, or the
        DC bus they state cannot have applied the logged voltages (a ConsistencyError).
    InputError
        If the options' electrical speed has the other sign than the logs' back-EMF
        reference ``w_1``.
    """
    if options.dc_voltage is not None:
        check_bus([episode.u for episode in episodes], options.dc_voltage)
    channels = _fitted(episodes, options)
    fitted = channels.episodes
    try:
        alignment = check_alignment(fitted, options.logged_input, options.input_delay)
    except NotExciting as error:
        raise _untied_dead_time(error, episodes[0], options) from None
    structure = None
    if options.structure != "none":
        assert options.electrical_speed is not None
        _check_stated_sense(episodes, options.electrical_speed)
        kinds: dict[str, type[MotorStructure]] = {
            "spmsm": SpmsmStructure, "ipmsm": IpmsmStructure, "incremental": IncrementalStructure,
        }  # fmt: skip
        structure = kinds[options.structure](
            options.electrical_speed, alignment.model.h, options.dead_time, options.voltage_hold
        )
    precision, relative = log_precision(episodes)
    fit = fit_output_error(fitted, alignment.shift, alignment.model, structure, resolution=relative)
    test = (
        ConsistencyTest(0.0, float("inf"), 0, True)
        if fit is None
        else _consistency(fitted, alignment.shift, fit)
    )
    judge = _Judge(alignment, structure, relative, options.dead_time)
    measured = channels
    try:
        judge.check(fitted, fit, test)
    except (ModelMissesEffect, ConfigurationMismatch) as error:
        if not isinstance(channels, DeadTimeChannels) or channels.angles is None:
            raise
        assert fit is not None
        rescued = on_other_signs(channels, alignment.shift, fit, relative, judge)
        if rescued is None:
            raise error from None
        channels, fit, test = rescued
    correction = None
    adc: tuple[float | None, float | None] = (None, None)  # the ADC's step, noise (A)
    if (
        isinstance(channels, DeadTimeChannels) and channels.angles is not None
        and fit is not None and not test.exact
    ):  # fmt: skip
        own = None
        if channels is measured:
            own = OwnSimulation.of(fit, channels, alignment.shift)
            pulses = (own.departure, holds_pulses(fit.structure, options.dc_voltage))
            adopted = reported_next_signs(channels, alignment.shift, fit, relative, judge, pulses)
            if adopted is not None:
                (channels, fit, test), own = adopted, None
        floor = resolution_floor(np.concatenate([e.x for e in episodes]), relative)
        corrected = without_sign_bias(
            fit, channels, alignment.shift, floor, own, next_sample=channels is not measured
        )
        if corrected is not None:
            fit, correction, adc = corrected
    fitted = channels.episodes
    extra = problem.n if options.dead_time else 0
    moved, bus = None, options.dc_voltage
    if bus is not None and isinstance(channels, DeadTimeChannels) and fit is not None:
        moved = pulse_shift(fit, channels, alignment.shift, bus)
    return Evidence(
        fitted, alignment, fit, test, extra, precision, channels.model, correction,
        channels.switching, *adc, pulse_shift=moved,
        next_sample_signs=changed_signs(measured, channels),
    )  # fmt: skip


@dataclass(frozen=True)
class _Judge:
    """The tests a fit of the logs must pass (:func:`_check_fit`), with what they need."""

    alignment: Alignment
    structure: MotorStructure | None
    resolution: float
    dead_time: bool

    def check(
        self, episodes: list[Trajectory], fit: OutputErrorFit | None, test: ConsistencyTest
    ) -> None:
        """Raise unless ``fit`` with its consistency ``test`` explains ``episodes``."""
        _check_fit(
            episodes, self.alignment, (fit, test), self.structure, self.resolution,
            self.dead_time,
        )  # fmt: skip

    def __call__(self, episodes: list[Trajectory], fit: OutputErrorFit) -> ConsistencyTest:
        """The consistency of ``fit`` on ``episodes``, which the tests accept (else a
        :class:`~selftune.errors.ConsistencyError`)."""
        test = _consistency(episodes, self.alignment.shift, fit)
        self.check(episodes, fit, test)
        return test


def _check_fit(
    episodes: list[Trajectory],
    alignment: Alignment,
    tested: tuple[OutputErrorFit | None, ConsistencyTest],
    structure: MotorStructure | None,
    resolution: float,
    dead_time: bool,
) -> None:
    """Raise unless the fit explains the logs: the consistency test, the structure's
    comparison with the unstructured model, and (without the dead-time model) the output
    errors' correlation in time (see the module)."""
    fit, test = tested
    if not test.passed:
        causes: tuple[str, ...] = (
            _DEAD_TIME_CAUSE[dead_time],
            "a misaligned or late voltage log",
            "a nonlinearity (saturation, the voltage limit)",
            "a measurement resolution too coarse for the signal",
            _CARRIER_CAUSE,
        )
        raise ModelMissesEffect(
            f"the model cannot explain the data: its output errors correlate with the "
            f"inputs before them (statistic {test.statistic:.4g}, threshold {test.threshold:.4g} "
            f"for {test.degrees_of_freedom} degrees of freedom), which the measurement "
            f"noise alone does not do; likely causes: {_listed(causes)}",
            statistic=test.statistic,
            threshold=test.threshold,
            causes=causes,
        )
    if structure is not None and (fit is None or not test.exact):  # exact: nothing to miss
        check_structure(episodes, alignment, fit, (resolution, TEST_LEVEL), dead_time)
    inflated = fit is not None and fit.correlation_inflation > INFLATION_LIMIT
    if inflated and not test.exact and not dead_time:  # exact: rounding only
        assert fit is not None
        causes = (
            "an input error the log does not show (inverter dead time: set dead_time = true)",
            "a nonlinearity (a saturated sensor or ADC, the voltage limit)",
            "an ADC whose steps are coarse against the noise",
            "a misaligned voltage log",
        )
        raise ModelMissesEffect(
            f"the model misses an effect in the data: its output errors are correlated in "
            f"time, {fit.correlation_inflation:.3g} times the variance white noise gives (at "
            f"most {INFLATION_LIMIT:g} without a dead-time model); likely causes: "
            f"{_listed(causes)}",
            statistic=fit.correlation_inflation,
            threshold=INFLATION_LIMIT,
            causes=causes,
        )


#: A carrier PWM inverter among a refusal's likely causes: the model holds the voltage
#: over the sample, the inverter applies each leg's pulse at its place in the period. On
#: the hardware-like drive without its ADC (10 mA of noise alone) three 48 V motors of
#: 43-79 uH were refused so, with the dead time and without it; on average PWM they were
#: learned (docs/interior.md, "Not yet").
_CARRIER_CAUSE = (
    "a carrier PWM inverter's pulses, which the model takes as the voltage held over the "
    "sample (on a small inductance its measured currents can show them)"
)

#: The dead time among a refusal's likely causes: without the model, the remedy; with it,
#: what the model approximates.
_DEAD_TIME_CAUSE = {
    False: "an input error the log does not show (inverter dead time: set dead_time = true)",
    True: (
        "the dead-time model's approximation (dead_time = true: each phase's error taken "
        "as -v sign(i) at or along the sample; an inverter whose error fades near zero "
        "current or depends on the voltage)"
    ),
}


def _check_stated_sense(episodes: Sequence[Trajectory], electrical_speed: float) -> None:
    """Refuse a stated speed (rad/s) of the other sign than the logs' back-EMF reference
    ``w_1 = p speed phi_assumed`` (:func:`~._dead_time.against_back_emf`)."""
    given = [episode.w for episode in episodes if episode.w is not None]
    reference = against_back_emf(np.concatenate(given) if given else None, electrical_speed)
    if reference is not None:
        raise InputError(
            f"electrical_speed: says {electrical_speed:.6g} rad/s, where the logs' back-EMF "
            f"reference w1 (p speed phi) averages {reference:.4g}: they count the rotation in "
            "opposite senses; give electrical_speed the sign of w1 (or negate w1)"
        )


def _untied_dead_time(
    error: NotExciting, episode: Trajectory, options: LearningOptions
) -> NotExciting:
    """A lack of rank with the dead-time model, told in the log's own channels: with the
    dead-time channels among the tied ones, the currents keep their signs, so the
    dead-time voltage is a constant the data cannot tell from the reference."""
    if not options.dead_time:
        return error
    n, m, q = episode.n, episode.m, episode.q
    names = regressor_names(n, m, q) + tuple(f"sign(x{i + 1})" for i in range(n))
    if not any(column >= n + m + q for column in error.columns):
        return error.retold(lack_of_rank(error.rank, error.rank_needed, names, error.columns))
    tied = ", ".join(names[column] for column in error.columns)
    return error.retold(
        f"dead_time = true, but the currents' signs do not change against the rest of the "
        f"data ({tied} do not vary independently; rank {error.rank} of "
        f"{error.rank_needed}): the dead-time voltage is then a constant offset the data "
        "cannot tell apart; log a reference that reverses the current (perturbation = "
        "'steps'), or set dead_time = false"
    )


def _listed(causes: tuple[str, ...]) -> str:
    """The likely causes as a message lists them: "a, b, or c"."""
    return ", or ".join([", ".join(causes[:-1]), causes[-1]]) if len(causes) > 1 else causes[0]


@dataclass(frozen=True)
class _Fitted:
    """The logs without dead-time channels (the fields :class:`DeadTimeChannels` has)."""

    episodes: list[Trajectory]
    model: None = None
    angles: None = None
    switching: None = None


def _fitted(episodes: Sequence[Trajectory], options: LearningOptions) -> _Fitted | DeadTimeChannels:
    """The logs as the model sees them: with the dead time's channels if asked for."""
    if not options.dead_time:
        return _Fitted(list(episodes))
    if episodes[0].n != 2 or episodes[0].m != 2:
        raise InputError(
            f"dead_time: the dead-time model is for a three-phase machine's dq currents "
            f"(n = m = 2); the data have n = {episodes[0].n}, m = {episodes[0].m}"
        )
    shift = stated_shift(options.logged_input, options.input_delay)
    if shift is None:  # "auto": the alignment of the simpler model decides the offset's fit
        rough = with_dead_time(episodes, None, 0).episodes
        shift = check_alignment(rough, "auto", options.input_delay).shift
    return with_dead_time(episodes, options.electrical_speed, shift)


def reduced_problem(problem: LearningProblem, extra: int) -> LearningProblem:
    """The problem with ``extra`` zero columns in F (and E): the appended channels of the
    current's direction are regulated against nothing.

    Parameters
    ----------
    problem : LearningProblem
        The user's problem.
    extra : int
        Number of appended exogenous channels.
    """
    if not extra:
        return problem
    assert problem.F is not None
    return problem.with_F(np.hstack([problem.F, np.zeros((problem.r, extra))]))
