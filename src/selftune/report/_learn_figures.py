"""The figures of a learned controller's report (``selftune learn --report``, ``selftune
tune --report``), drawn from what the learner found (:class:`~selftune.learn.LearnedController`
with its evidence); nothing is learned or judged here, every statistic is the library's:

- ``currents``: the measured states against the fitted model's prediction from the logged
  inputs (the output-error fit's simulation; without one, the one-step predictions);
- ``autocorrelation``: the autocorrelation of the model's output errors, with the band
  ``+-1.96 / sqrt(N)`` in which 95% of a white series' values fall;
- ``alignment``: the one-step residual of the exact discrete model for each shift of the
  logged inputs (the alignment scan), the shift used marked;
- ``step``: the learned law's predicted response to a step of the reference on the fitted
  model, and the band (least to largest) of its responses on the plants the data allow;
- ``poles``: the z-plane poles of the learned loop on the fitted model and on those plants,
  with the unit circle and the circle of radius ``1 - margin`` (the verdict's margin);
- ``spectrum``: the power spectral density of the output errors against the flat level
  of white noise of the same variance (peaks are what the model misses: the dead time's
  harmonics, a resonance).

Docs: docs/report.md says how to read each one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.signal
from matplotlib import rc_context
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..core import Array
from ..learn import LearnedController, aligned_transitions, applied_inputs
from ..learn.evidence._evidence import Evidence, autocorrelation
from ..learn.verdict._verdict import plausible_plants
from ..loop import SampledLoop
from ._figures import _PRINT, _TIME, _legend

__all__ = [
    "FIGURE_STEMS",
    "WHITE_BAND",
    "LearnFigureData",
    "learn_figure_data",
    "learn_figures",
    "logged_step",
]

#: The figures' file stems, in the order the page shows them.
FIGURE_STEMS = ("currents", "autocorrelation", "alignment", "step", "poles", "spectrum")

#: The two-sided 95% quantile of the standard normal: a white series' sample
#: autocorrelations at lags >= 1 lie within ``+-WHITE_BAND / sqrt(N)`` 95% of the time.
WHITE_BAND = 1.959963984540054

#: The most samples of the log the ``currents`` figure shows (0.2 s at 10 kHz).
SHOWN_SAMPLES = 2000

#: The most lags of the ``autocorrelation`` figure.
LAGS = 50

#: The step response runs until the fitted loop's slowest mode is down to this fraction.
SETTLED = 1e-3

#: Bounds of the step response's length, samples.
STEP_SAMPLES = (20, 5000)

_ESTIMATE, _BAND, _MEASURED = "#ff7f0e", "#1f3fd0", "black"


@dataclass(frozen=True)
class LearnFigureData:
    """What the report's figures show, computed once.

    Attributes
    ----------
    h : float
        Sampling period, s.
    t : ndarray, shape (T,)
        The times of ``measured`` and ``predicted`` (the first log's), s.
    measured, predicted : ndarray, shape (T, n)
        The logged states and the model's prediction of them.
    one_step : bool
        Whether ``predicted`` is the one-step prediction (no output-error fit).
    residuals : tuple of ndarray
        The model's errors of each log, shape (T_e, n) each, their mean removed.
    shifts : dict of int to float
        The alignment scan: the one-step residual for each shift tried.
    shift, detected_shift : int
        The shift used, and the one the data show.
    step_time : ndarray, shape (S,)
        Time of the step response, s (the step at 0).
    step_reference : ndarray, shape (S, n)
        The steady state the law aims at, ``X w``.
    step_estimate : ndarray, shape (S, n)
        The response on the fitted model.
    step_band : ndarray, shape (2, S, n)
        Least and largest response over the plausible plants.
    step_text : str
        What the step is.
    poles : ndarray, shape (P, nz), complex
        The loop's poles on each plant, the fitted model's first.
    margin : float
        The verdict's stability margin, ``1 - spectral radius`` on the fitted model.
    labels : tuple of str
        The states' names.
    """

    h: float
    t: Array
    measured: Array
    predicted: Array
    one_step: bool
    residuals: tuple[Array, ...]
    shifts: dict[int, float]
    shift: int
    detected_shift: int
    step_time: Array
    step_reference: Array
    step_estimate: Array
    step_band: Array
    step_text: str
    poles: Array
    margin: float
    labels: tuple[str, ...]

    @property
    def plants(self) -> int:
        """The plausible plants beside the fitted model."""
        return int(self.poles.shape[0]) - 1

    @property
    def least_margin(self) -> float:
        """``1 - spectral radius`` of the loop on the worst of the plants (fitted included)."""
        return 1.0 - float(np.max(np.abs(self.poles)))


def learn_figure_data(
    learned: LearnedController, step: tuple[Array, Array] | None = None
) -> LearnFigureData:
    """The figures' numbers of a result of :func:`~selftune.learn.learn_controller`.

    Parameters
    ----------
    learned : LearnedController
        With its verdict and evidence.
    step : (ndarray, ndarray), optional
        The reference ``w`` before and after the step of the step response (default:
        :func:`logged_step`).

    Raises
    ------
    ValueError
        If the result carries no evidence (a learner used alone).
    """
    evidence = learned.evidence
    if evidence is None:
        raise ValueError("this result has no evidence: learn_controller or assess gives one")
    quality = learned.verdict
    shift = evidence.alignment.shift
    t, measured, predicted, residuals = _predictions(evidence)
    plants = plausible_plants(evidence)
    loop = SampledLoop.of_law(learned.law, evidence.model.h, evidence.alignment.input_delay)
    poles = loop.poles([(plant.Ad, plant.Bd) for plant in plants], learned.law)
    before, after = logged_step(learned) if step is None else step
    response = _step_response(learned, evidence, loop, poles, (before, after))
    return LearnFigureData(
        h=evidence.model.h,
        t=t,
        measured=measured,
        predicted=predicted,
        one_step=evidence.fit is None,
        residuals=residuals,
        shifts=dict(evidence.alignment.residuals),
        shift=shift,
        detected_shift=evidence.alignment.detected_shift,
        step_time=response[0],
        step_reference=response[1],
        step_estimate=response[2],
        step_band=response[3],
        step_text=response[4],
        poles=poles,
        margin=quality.stability_margin,
        labels=tuple(learned.law.state[: evidence.model.n]),
    )


def _predictions(evidence: Evidence) -> tuple[Array, Array, Array, tuple[Array, ...]]:
    """The first log's times, measured and predicted states, and every log's errors
    (their mean removed)."""
    shift = evidence.alignment.shift
    episode = evidence.episodes[0]
    first = applied_inputs(episode, shift)[1]
    fit = evidence.fit
    if fit is not None:
        predicted = fit.simulated[0]
        measured = predicted + fit.residuals[0]  # the residuals are x~ - xhat
        errors = fit.residuals
        t = episode.t[first : first + predicted.shape[0]]
    else:
        model = evidence.alignment.model
        errors = tuple(
            transitions.x_next - model.predict(transitions)
            for transitions in (aligned_transitions(log, shift) for log in evidence.episodes)
        )
        measured = aligned_transitions(episode, shift).x_next
        predicted = measured - errors[0]
        t = episode.t[first + 1 : first + 1 + measured.shape[0]]
    shown = slice(0, SHOWN_SAMPLES)
    centred = tuple(error - error.mean(axis=0) for error in errors)
    return t[shown], measured[shown], predicted[shown], centred


def logged_step(learned: LearnedController) -> tuple[Array, Array]:
    """The reference step of the report's step response read off the logs: the channels
    the logs vary step from 0 to their value of largest size (the others keep their
    logged value); before and after equal when none varies.

    Parameters
    ----------
    learned : LearnedController
        With its evidence.
    """
    assert learned.evidence is not None
    q = learned.law.X.shape[1]
    logs = [log.w[:, :q] for log in learned.evidence.episodes if log.w is not None]
    if not q or not logs:
        return np.zeros(q), np.zeros(q)
    w = np.concatenate(logs)
    varying = np.ptp(w, axis=0) > 0.0
    before = w[0].copy()
    before[varying] = 0.0
    after = before.copy()
    largest = np.argmax(np.abs(w), axis=0)
    after[varying] = w[largest, np.arange(q)][varying]
    return before, after


def _step_text(before: Array, after: Array) -> str:
    """What a step of the reference is: ``"Step w2 0 → 5 (w1 = 52.5)"``."""
    moved = before != after
    steps = ", ".join(
        f"w{index + 1} {before[index]:.3g} \u2192 {after[index]:.3g}"
        for index in np.flatnonzero(moved)
    )
    kept = ", ".join(f"w{index + 1} = {before[index]:.3g}" for index in np.flatnonzero(~moved))
    return f"Step {steps}" + (f" ({kept})" if kept else "")


def _step_response(
    learned: LearnedController,
    evidence: Evidence,
    loop: SampledLoop,
    poles: Array,
    step: tuple[Array, Array],
) -> tuple[Array, Array, Array, Array, str]:
    """The step's time, the law's target ``X w``, the response on the fitted model, its
    band over the plausible plants, and what the step is. Without a reference that the
    logs vary, the response from the logged state farthest from the operating point."""
    law = learned.law
    n, q = evidence.model.n, law.X.shape[1]
    radius = float(np.max(np.abs(poles[0])))
    length = int(np.ceil(np.log(SETTLED) / np.log(max(radius, 1e-3))))
    samples = int(np.clip(length, *STEP_SAMPLES))
    before, after = step
    varies = bool(np.any(before != after))
    text = _step_text(before, after) if varies else ""
    responses = []
    for plant in plausible_plants(evidence):
        A_cl, B_w = loop.closed_loop((plant.Ad, plant.Bd), law, plant.Ed[:, :q])
        identity = np.eye(A_cl.shape[0])
        state = np.linalg.solve(identity - A_cl, B_w @ before) if q else np.zeros(len(A_cl))
        if not varies:  # the return of the state farthest from the operating point
            x = np.concatenate([log.x for log in evidence.episodes])
            deviation = x - law.X @ before
            state[:n] += deviation[int(np.argmax(np.linalg.norm(deviation, axis=1)))]
        trajectory = [state]
        for _ in range(samples):
            state = A_cl @ state + B_w @ after
            trajectory.append(state)
        responses.append(np.array(trajectory)[:, :n])
    if not varies:
        text = "Return from the logged state farthest from the operating point"
    stacked = np.array(responses, dtype=float)
    time = np.arange(samples + 1) * evidence.model.h
    reference = np.tile(law.X @ after, (samples + 1, 1))
    band = np.array([stacked.min(axis=0), stacked.max(axis=0)], dtype=float)
    return time.astype(float), reference, stacked[0], band, text


def _figure(rows: int, height: float, share: bool = True) -> tuple[Figure, list[Axes]]:
    figure = Figure(figsize=(7.0, height), layout="constrained")
    FigureCanvasAgg(figure)
    axes = list(figure.subplots(rows, 1, sharex=share, squeeze=False)[:, 0])
    for panel in axes:
        panel.grid(True, alpha=0.3)
    return figure, axes


def figure_currents(data: LearnFigureData) -> Figure:
    """The measured states against the model's prediction from the logged inputs."""
    n = data.measured.shape[1]
    figure, axes = _figure(n, 1.6 + 1.6 * n)
    what = "one-step prediction" if data.one_step else "model's simulation from the inputs"
    for index, panel in enumerate(axes):
        panel.plot(data.t * 1e3, data.measured[:, index], color=_MEASURED, linewidth=0.6,
                   label="measured")  # fmt: skip
        panel.plot(data.t * 1e3, data.predicted[:, index], color=_ESTIMATE, linewidth=1.0,
                   label=f"predicted ({what})")  # fmt: skip
        panel.set_ylabel(f"${data.labels[index]}$ (state's unit)")
    axes[-1].set_xlabel(_TIME)
    _legend(
        figure,
        axes[0],
        "Measured states and the fitted model's prediction from the logged inputs (first "
        f"log, at most {SHOWN_SAMPLES} samples); the difference is the model's error, which "
        "the next figures examine.",
    )
    return figure


def figure_autocorrelation(data: LearnFigureData) -> Figure:
    """The output errors' autocorrelation with the white-noise band."""
    count = sum(error.shape[0] for error in data.residuals)
    lags = int(max(1, min(LAGS, count // 4)))
    weights = [float(np.sum(error**2)) for error in data.residuals]
    # the logs pooled: each log's autocorrelation weighed by its energy
    rho = sum(
        weight * autocorrelation(error, lags)
        for weight, error in zip(weights, data.residuals, strict=True)
    ) / max(sum(weights), 1e-300)
    rho = np.asarray(rho)
    band = WHITE_BAND / np.sqrt(count)
    figure, (panel,) = _figure(1, 3.6)
    lag = np.arange(1, lags + 1)
    for index in range(rho.shape[1]):
        panel.plot(lag, rho[:, index], marker="o", markersize=3, linewidth=0.8,
                   label=f"${data.labels[index]}$")  # fmt: skip
    white = f"white noise, 95%: $\\pm 1.96/\\sqrt{{N}}$ = $\\pm${band:.3g}"
    panel.axhspan(-band, band, color="grey", alpha=0.25, linewidth=0, label=white)
    panel.axhline(0.0, color="black", linewidth=0.6)
    panel.set_xlabel("lag (samples)")
    panel.set_ylabel("autocorrelation (dimensionless)")
    _legend(
        figure,
        panel,
        f"Autocorrelation of the model's errors (N = {count} samples). Within the band they "
        "are white: the model explains the data up to noise; far outside it the model "
        "misses an effect, and the standard errors include its correlation.",
        columns=3,
    )
    return figure


def figure_alignment(data: LearnFigureData) -> Figure:
    """The alignment scan: the one-step residual against the shift of the logged inputs."""
    figure, (panel,) = _figure(1, 3.4)
    shifts = sorted(data.shifts)
    values = [data.shifts[shift] for shift in shifts]
    panel.plot(shifts, values, marker="o", color=_BAND, linewidth=1.0, label="shifts tried")
    panel.plot([data.shift], [data.shifts[data.shift]], "o", color=_ESTIMATE, markersize=11,
               markerfacecolor="none", markeredgewidth=2.0,
               label=f"shift used ({data.shift})")  # fmt: skip
    panel.set_ylim(0.0, 1.1 * max(values))
    panel.set_xticks(shifts)
    panel.set_xlabel("shift: the voltage applied during sample k is in row k - shift")
    panel.set_ylabel("one-step residual (states' unit)")
    _legend(
        figure,
        panel,
        f"The alignment scan: the exact discrete model's one-step residual for each shift "
        f"of the logged inputs. The data show {data.detected_shift}; the lowest point is the "
        "alignment the data prefer, and a clear minimum says the log's timing is known.",
    )
    return figure


def figure_step(data: LearnFigureData) -> Figure:
    """The learned law's predicted step response with the band over the plausible plants."""
    n = data.step_estimate.shape[1]
    figure, axes = _figure(n, 1.6 + 1.6 * n)
    t = data.step_time * 1e3
    for index, panel in enumerate(axes):
        if data.plants:  # none drawn without an output-error model
            panel.fill_between(t, data.step_band[0, :, index], data.step_band[1, :, index],
                               color=_BAND, alpha=0.3, linewidth=0,
                               label=f"the {data.plants} plants the data allow")  # fmt: skip
        panel.plot(t, data.step_estimate[:, index], color=_ESTIMATE, linewidth=1.4,
                   label="fitted model")  # fmt: skip
        panel.plot(t, data.step_reference[:, index], color=_MEASURED, linewidth=0.8,
                   linestyle="--", label="target $X w$")  # fmt: skip
        panel.set_ylabel(f"${data.labels[index]}$ (state's unit)")
    axes[-1].set_xlabel(_TIME)
    _legend(
        figure,
        axes[0],
        f"{data.step_text}: the learned controller's predicted response on the fitted model "
        "(its linear part: a modelled dead time is left out) and its least-to-largest band "
        "on the plants the data allow.",
        columns=3,
    )
    return figure


def figure_poles(data: LearnFigureData) -> Figure:
    """The closed-loop poles in the z-plane, with the unit circle and the margin circle."""
    figure = Figure(figsize=(7.0, 4.6), layout="constrained")
    FigureCanvasAgg(figure)
    whole, near = figure.subplots(1, 2)
    angle = np.linspace(0.0, 2.0 * np.pi, 721)
    radius = 1.0 - data.margin
    for panel in (whole, near):
        panel.plot(np.cos(angle), np.sin(angle), color=_MEASURED, linewidth=0.8,
                   label="unit circle")  # fmt: skip
        panel.plot(radius * np.cos(angle), radius * np.sin(angle), color="red", linewidth=0.8,
                   linestyle="--", label=f"radius 1 - margin = {radius:.4g}")  # fmt: skip
        if data.plants:
            others = data.poles[1:].ravel()
            panel.plot(others.real, others.imag, "o", color=_BAND, markersize=3, alpha=0.5,
                       label=f"the {data.plants} plants the data allow")  # fmt: skip
        panel.plot(data.poles[0].real, data.poles[0].imag, "x", color=_ESTIMATE,
                   markersize=8, markeredgewidth=1.6, label="fitted model")  # fmt: skip
        panel.set_aspect("equal")
        panel.grid(True, alpha=0.3)
        panel.set_xlabel("real part")
    whole.set_ylabel("imaginary part")
    slowest = data.poles[np.arange(len(data.poles)), np.argmax(np.abs(data.poles), axis=1)]
    centre = complex(np.mean(slowest))
    span = max(4.0 * float(np.max(np.abs(slowest - centre))), 1.5 * data.margin, 1e-3)
    near.set_xlim(centre.real - span, centre.real + span)
    near.set_ylim(centre.imag - span, centre.imag + span)
    near.set_title("near the slowest pole", fontsize=9)
    _legend(
        figure,
        whole,
        f"Poles of the learned sampled loop (with the delay and the integrators). Stable "
        f"inside the unit circle; the verdict's margin is {data.margin:.3g} on the fitted "
        f"model and at least {data.least_margin:.3g} on every plant the data allow.",
    )
    return figure


def figure_spectrum(data: LearnFigureData) -> Figure:
    """The power spectral density of the output errors against white noise's level."""
    figure, (panel,) = _figure(1, 3.8)
    fs = 1.0 / data.h
    for index in range(data.residuals[0].shape[1]):
        pieces = [error[:, index] for error in data.residuals]
        longest = max(piece.shape[0] for piece in pieces)
        segment = int(min(256, longest))
        frequency, density = scipy.signal.welch(pieces[0], fs=fs, nperseg=segment)
        if len(pieces) > 1:  # the logs pooled, each weighed by its length
            total = pieces[0].shape[0] * density
            for piece in pieces[1:]:
                total += piece.shape[0] * scipy.signal.welch(piece, fs=fs, nperseg=segment)[1]
            density = total / sum(piece.shape[0] for piece in pieces)
        variance = float(np.mean(np.concatenate(pieces) ** 2))
        line = panel.semilogy(frequency / 1e3, density, linewidth=0.9,
                              label=f"${data.labels[index]}$")  # fmt: skip
        level = f"white noise of ${data.labels[index]}$'s variance"
        panel.axhline(2.0 * variance / fs, color=line[0].get_color(), linewidth=0.8,
                      linestyle="--", label=level)  # fmt: skip
    panel.set_xlabel("frequency (kHz)")
    panel.set_ylabel("power spectral density (unit$^2$/Hz)")
    _legend(
        figure,
        panel,
        "Spectrum of the model's errors (Welch, 256-sample segments) against the flat level "
        "of white noise with their variance: peaks are what the model misses (a dead time's "
        "harmonics of the electrical frequency, a resonance).",
    )
    return figure


def learn_figures(data: LearnFigureData) -> dict[str, Figure]:
    """The report's figures by their file stems (:data:`FIGURE_STEMS`), drawn with the
    printed figures' text sizes.

    Parameters
    ----------
    data : LearnFigureData
        What they show (:func:`learn_figure_data`).
    """
    drawers = (figure_currents, figure_autocorrelation, figure_alignment, figure_step,
               figure_poles, figure_spectrum)  # fmt: skip
    with rc_context(_PRINT):
        return {stem: drawer(data) for stem, drawer in zip(FIGURE_STEMS, drawers, strict=True)}
