"""An online run against the optimum of each instant (evaluation only): what
``selftune tune --online`` prints, writes as JSON and draws.

At :data:`TIMELINE_POINTS` instants spread evenly over the run, the true motor of that
instant (the profile's factors on the drive's motor) gives the optimum of its sampled
loop (:func:`selftune.model.solve_digital_regulation`, the tuner's cost and integral
weight). Three laws' costs of a reference step on it (:func:`step_cost`: the feedback's
digital cost from rest to the optimum's equilibrium) make the timeline's cost rates, each
divided by the step period (the reference steps every
:data:`~selftune.tuning.SEGMENT_CHUNKS` chunks): the law in force, the law tuned cold and
kept, and the optimum itself. The excess cost is their ratio minus one, averaged over
the instants (a time average). The feedforward's errors are not in that cost (as in
``selftune tune``): they show in the steady torque error, measured on the simulated
drive over the second half of every reference step.

Every switch is checked on the true plant of its moment: the law switched to must
stabilize it with a cost no higher than the law it replaced (a rescaled torque reference
keeps the feedback, so its cost is the same).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..core import Array, ControlLaw, write_json
from ..core._atomic import output_directory, write_text
from ..learn.evidence._spmsm_structure import SpmsmStructure
from ..model import SPMSM, ModelBasedSolution, solve_digital_regulation
from ..tuning import CHUNK_SECONDS, SEGMENT_CHUNKS, OnlineRun
from ._digital_evaluation import step_cost, true_motor

__all__ = [
    "ONLINE_REPORT_FILES",
    "TIMELINE_POINTS",
    "OnlineEvaluation",
    "error_bars",
    "evaluate_online",
    "online_document",
    "online_lines",
    "online_summary",
    "steps_detected",
    "unexplained_changes",
    "write_online_report",
]

#: The instants the timeline holds (evenly spread over the run, the last at its end).
TIMELINE_POINTS = 600

#: The files ``--report DIR`` writes.
ONLINE_REPORT_FILES = ("online.png", "online.svg", "online.json", "report.txt")

#: A switch raises the cost if the new law's exceeds the old one's by more than this
#: fraction (rounding: a rescaled reference keeps the feedback, so its cost is the same).
_SAME_COST = 1e-9


@dataclass(frozen=True, eq=False)
class OnlineEvaluation:
    """An online run against the optimum of each instant (see the module).

    Attributes
    ----------
    time : ndarray
        The timeline's instants, s.
    chunks : ndarray of int
        The chunk ending at each instant.
    cost_rate, cold_cost_rate, optimal_cost_rate : ndarray
        The cost per second of the stepping reference under the law in force, the law
        tuned cold and kept, and the optimum of the instant (the cost's unit per s).
    switch_costs : ndarray, shape (switches, 2)
        At each switch, the step cost on the true plant of the law before and after.
    """

    time: Array
    chunks: Array
    cost_rate: Array
    cold_cost_rate: Array
    optimal_cost_rate: Array
    switch_costs: Array

    @property
    def excess_cost(self) -> float:
        """The law in force's cost over the optimum's, minus 1, averaged over time."""
        return float(np.mean(self.cost_rate / self.optimal_cost_rate - 1.0))

    @property
    def cold_excess_cost(self) -> float:
        """The same for the law tuned cold and kept."""
        return float(np.mean(self.cold_cost_rate / self.optimal_cost_rate - 1.0))

    @property
    def bad_switches(self) -> int:
        """Switches to a law that does not stabilize the true plant or costs more on it."""
        before, after = self.switch_costs.T if self.switch_costs.size else (np.zeros(0),) * 2
        return int(np.sum(~(after <= before * (1.0 + _SAME_COST))))


def _true_motor(run: OnlineRun, chunk: int) -> SPMSM:
    """The true motor over chunk ``chunk``."""
    return SPMSM(
        R_s=float(run.R_s[chunk]), L_s=float(run.L_s[chunk]),
        phi_pm=float(run.phi_pm[chunk]), p=run.motor.p,
    )  # fmt: skip


def _optimum(run: OnlineRun, motor: SPMSM) -> ModelBasedSolution:
    """The optimum of the sampled loop of ``motor`` with the run's cost and delay."""
    return solve_digital_regulation(
        motor.regulation_problem(run.speed), run.Q, run.R, run.h,
        input_delay=run.drive.input_delay, integral_weight=run.problem.integral_weight,
        plant=motor.sampled_plant(run.speed, run.h, run.drive.voltage_hold),
    )  # fmt: skip


def _costs(run: OnlineRun, chunk: int, laws: list[ControlLaw]) -> list[float]:
    """The step costs of ``laws`` and of the optimum on the true plant of ``chunk``."""
    motor = _true_motor(run, chunk)
    optimum = _optimum(run, motor)
    w = motor.exogenous(run.speed, run.torque)
    return [step_cost(optimum, law, w) for law in [*laws, optimum.law]]


def evaluate_online(run: OnlineRun, points: int = TIMELINE_POINTS) -> OnlineEvaluation:
    """The run's costs against the optimum of each instant, and its switches checked.

    Parameters
    ----------
    run : OnlineRun
        What :func:`selftune.tuning.run_online` recorded.
    points : int
        The timeline's instants.
    """
    count = run.chunk_time.size
    chunks = np.unique(np.round(np.linspace(0, count - 1, min(points, count))).astype(int))
    period = SEGMENT_CHUNKS * CHUNK_SECONDS
    rates = np.array(
        [_costs(run, int(chunk), [run.law_at(int(run.law_index[chunk])), run.cold.law])
         for chunk in chunks]
    ) / period  # fmt: skip
    switch_costs = []
    laws = [run.cold.law]
    for switch in run.switches:
        chunk = min(int(np.searchsorted(run.chunk_time, switch.time - 1e-12)), count - 1)
        before, after, _ = _costs(run, chunk, [laws[-1], switch.law])
        switch_costs.append((before, after))
        laws.append(switch.law)
    return OnlineEvaluation(
        time=run.chunk_time[chunks], chunks=chunks, cost_rate=rates[:, 0],
        cold_cost_rate=rates[:, 1], optimal_cost_rate=rates[:, 2],
        switch_costs=np.array(switch_costs).reshape(-1, 2),
    )  # fmt: skip


def _estimates_at(run: OnlineRun, time: Array) -> tuple[Array, Array]:
    """The last look's estimates and standard errors at each of ``time`` (nan before)."""
    last = np.searchsorted(run.look_time, time, side="right") - 1
    width = run.estimates.shape[1]
    values = np.full((time.size, width), np.nan)
    errors = np.full((time.size, width), np.nan)
    seen = last >= 0
    values[seen], errors[seen] = run.estimates[last[seen]], run.standard_errors[last[seen]]
    return values, errors


def _worst_torque_errors(run: OnlineRun, chunks: Array) -> Array:
    """At each timeline chunk, the largest steady torque error since the one before."""
    worst = np.full(chunks.size, np.nan)
    start = 0
    for index, chunk in enumerate(chunks):
        errors = run.torque_error[start : chunk + 1]
        errors = errors[np.isfinite(errors)]
        if errors.size:
            worst[index] = errors[np.argmax(np.abs(errors))]
        start = chunk + 1
    return worst


def steps_detected(run: OnlineRun) -> list[tuple[float, float]]:
    """Each step of the profile (two points at one time) and the delay to the first
    change the tuner detected at or after it (nan if none), s.

    Parameters
    ----------
    run : OnlineRun
        The run.
    """
    times = run.profile.time
    steps = [float(t) for t, after in itertools.pairwise(times) if t == after]
    found = []
    for step in steps:
        later = run.detections[run.detections >= step]
        found.append((step, float(later[0] - step) if later.size else float("nan")))
    return found


def unexplained_changes(run: OnlineRun) -> Array:
    """The changes the tuner reported that no step of the profile explains (a change
    explained is the first detection at or after a step): false alarms, s.

    Parameters
    ----------
    run : OnlineRun
        The run.
    """
    explained = [
        int(np.searchsorted(run.detections, step)) for step, delay in steps_detected(run)
        if np.isfinite(delay)
    ]  # fmt: skip
    return np.delete(run.detections, explained)


def error_bars(run: OnlineRun) -> dict[str, dict[str, float]]:
    """Whether the estimates' standard errors mean what they say: at every look the
    tuner acted on, the true ``R_s``, ``L_s`` and magnet flux of that instant against the
    estimate; per parameter, the share of the errors within one standard error (about
    68% for errors that are normal with that deviation) and their root mean square in
    standard errors (about 1).

    The truth of a look is the drive's true motor at the last sample its data hold (the
    profile at one period before the look): a look at a step's instant was fitted to data
    all from before it, while the true values recorded at its chunk's end are the next
    sample's, after it (bench section 11's resistance step at 60 s: the look at 60 s
    was within 0.3% of R_s before the step, 16.4-16.7% below the stepped value; that
    one look made the runs' rms 2.8-3.6 standard errors, 0.8-1.1 without it).

    Parameters
    ----------
    run : OnlineRun
        The run.

    Returns
    -------
    dict
        ``{"R_s" | "L_s" | "phi_pm": {"within_one_ratio": share, "rms_ratio": rms}}``
        (nan without a look).
    """
    true = true_motor(run.motor, run.drive)
    factors = run.profile.factors(run.look_time - run.h)
    flux = true.phi_pm * factors.phi_pm / run.motor.phi_pm  # the estimate's: over the nameplate's
    truths = (true.R_s * factors.R_s, true.L_s * factors.L_s, flux)
    found = {}
    for column, (name, truth) in enumerate(zip(("R_s", "L_s", "phi_pm"), truths, strict=True)):
        with np.errstate(divide="ignore", invalid="ignore"):  # a zero error bar: z infinite
            z = (run.estimates[:, column] - truth) / run.standard_errors[:, column]
        empty = z.size == 0
        found[name] = {
            "within_one_ratio": float("nan") if empty else float(np.mean(np.abs(z) <= 1.0)),
            "rms_ratio": float("nan") if empty else float(np.sqrt(np.mean(z**2))),
        }
    return found


def _steady_errors(run: OnlineRun) -> Array:
    errors = run.torque_error
    return errors[np.isfinite(errors)]


def _probing_share(run: OnlineRun) -> float:
    """The share of the time the probing was on after the first certification."""
    after = run.chunk_time > run.first_certified
    return float(np.mean(run.probing[after])) if np.any(after) else float("nan")


def online_summary(run: OnlineRun, evaluation: OnlineEvaluation) -> dict[str, Any]:
    """The run's figures of merit (the JSON's ``online.summary``).

    Parameters
    ----------
    run : OnlineRun
        The run.
    evaluation : OnlineEvaluation
        Its evaluation.
    """
    errors = _steady_errors(run)
    kinds = [switch.kind for switch in run.switches]
    return {
        "excess_cost": evaluation.excess_cost,
        "cold_excess_cost": evaluation.cold_excess_cost,
        "steady_torque_error_max": float(np.max(np.abs(errors))) if errors.size else None,
        "switches": kinds.count("switch"),
        "rescales": kinds.count("rescale"),
        "reverts": kinds.count("revert"),
        "bad_switches": evaluation.bad_switches,
        "changes_detected": [float(t) for t in run.detections],
        "changes_unexplained": [float(t) for t in unexplained_changes(run)],
        "steps_detected": [{"time": step, "delay": delay} for step, delay in steps_detected(run)],
        "first_certified": run.first_certified,
        "probing_share_after_first_certified": _probing_share(run),
        "error_bars": error_bars(run),
        "tuner_seconds": run.tuner_seconds,
        "drive_seconds": run.drive_seconds,
    }


def online_document(run: OnlineRun, evaluation: OnlineEvaluation) -> dict[str, Any]:
    """The JSON of ``selftune tune --online`` (the whole problem, the run, the truth).

    Parameters
    ----------
    run : OnlineRun
        The run.
    evaluation : OnlineEvaluation
        Its evaluation.
    """
    values, errors = _estimates_at(run, evaluation.time)
    nameplate = run.motor.phi_pm
    chunks = evaluation.chunks
    return {
        "motor": run.motor,
        "operating_point": {"speed": run.speed, "torque": run.torque},
        "Q": run.Q,
        "R": run.R,
        "h": run.h,
        "drive": run.drive,
        "problem": {
            "C": run.problem.C,
            "F": run.problem.F,
            "integral_weight": run.problem.integral_weight,
        },
        "profile": {
            "time": run.profile.time,
            "R_s": run.profile.R_s,
            "L_s": run.profile.L_s,
            "phi_pm": run.profile.phi_pm,
        },
        "duration": run.duration,
        "seed": run.seed,
        "cold": {"control_law": run.cold.law.document(), "quality": run.cold.quality},
        "online": {
            "switches": [
                {
                    "time": switch.time,
                    "kind": switch.kind,
                    "reason": switch.reason,
                    "control_law": switch.law.document(),
                }
                for switch in run.switches
            ],
            "timeline": {
                "time": evaluation.time,
                "R_s_true": run.R_s[chunks],
                "R_s_estimated": values[:, 0],
                "R_s_standard_error": errors[:, 0],
                "phi_pm_true": run.phi_pm[chunks],
                "phi_pm_estimated": values[:, 2] * nameplate,
                "phi_pm_standard_error": errors[:, 2] * nameplate,
                "cost_rate": evaluation.cost_rate,
                "cost_rate_cold": evaluation.cold_cost_rate,
                "cost_rate_optimal": evaluation.optimal_cost_rate,
                "torque_error": _worst_torque_errors(run, chunks),
                "probing": run.probing[chunks],
            },
            "changes": [
                {"time": float(t), "reason": event.reason}
                for t, event in zip(run.events_time, run.events, strict=True)
                if event.kind == "change"
            ],
            "real_time_factor": run.real_time_factor,
            "summary": online_summary(run, evaluation),
        },
    }


def online_lines(source: str, run: OnlineRun, evaluation: OnlineEvaluation) -> list[str]:
    """The printed report of an online run.

    Parameters
    ----------
    source : str
        The motor file's name.
    run : OnlineRun
        The run.
    evaluation : OnlineEvaluation
        Its evaluation.
    """
    summary = online_summary(run, evaluation)
    names = SpmsmStructure.names(run.estimates.shape[1] == 4)
    lines = [
        f"Online tuning on {source}: {run.duration:g} s of drive time at {run.speed:g} rad/s, "
        f"the torque reference stepping through +-{abs(run.torque):g} and "
        f"+-{abs(run.torque) / 3:.3g} N m every {SEGMENT_CHUNKS * CHUNK_SECONDS:g} s",
        "",
        f"switches to a new law: {summary['switches']}; returns by the watchdog: "
        f"{summary['reverts']}; the torque reference's current rescaled for the flux: "
        f"{summary['rescales']} times",
    ]
    shown = [switch for switch in run.switches if switch.kind != "rescale"]
    lines += [f"  {switch.time:8.3f} s {switch.kind}: {switch.reason}" for switch in shown]
    rescales = [switch for switch in run.switches if switch.kind == "rescale"]
    if rescales:
        lines.append(f"  last rescale, {rescales[-1].time:.3f} s: {rescales[-1].reason}")
    changes = [(t, e) for t, e in zip(run.events_time, run.events, strict=True)
               if e.kind == "change"]  # fmt: skip
    lines.append(f"changes detected: {len(changes)}")
    lines += [f"  {t:8.3f} s: {event.reason}" for t, event in changes]
    for step, delay in steps_detected(run):
        found = f"detected {delay * 1e3:.0f} ms later" if np.isfinite(delay) else "not detected"
        lines.append(f"  the profile's step at {step:g} s: {found}")
    if run.estimates.size:
        last = ", ".join(
            f"{name} {value:.5g} +- {error:.2g}"
            for name, value, error in zip(
                names, run.estimates[-1], run.standard_errors[-1], strict=False
            )
        )
        truth = (
            f"R_s {run.R_s[-1]:.5g}, L_s {run.L_s[-1]:.5g}, "
            f"kappa {run.phi_pm[-1] / run.motor.phi_pm:.5g}"
        )
        lines.append(f"last estimate: {last} (true: {truth})")
    torque = summary["steady_torque_error_max"]
    lines += [
        "",
        f"excess cost over the optimum of each instant, averaged over time: "
        f"{evaluation.excess_cost:.3%} (the law tuned cold and kept: "
        f"{evaluation.cold_excess_cost:.3%})",
        "largest steady torque error: "
        + ("-" if torque is None else f"{torque:.3%}")
        + f"; switches that raised the true cost or destabilized: {evaluation.bad_switches}",
        (
            f"probing on {_probing_share(run):.1%} of the time after the first certification "
            f"({run.first_certified:.2f} s)"
            if np.isfinite(run.first_certified)
            else f"the tuner acted on no estimate in {run.duration:g} s (it waits for a few "
            "reference steps of data): the probing was on all along"
        ),
        f"tuner: {run.tuner_seconds:.2f} s of CPU for {run.duration:g} s of drive time "
        f"({run.real_time_factor:.1f}x real time); the simulated drive took "
        f"{run.drive_seconds:.1f} s",
    ]
    return lines


def _figure(run: OnlineRun, evaluation: OnlineEvaluation) -> Any:
    """Estimates against the truth, the costs and the torque error over time."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(7.0, 9.0), layout="constrained")
    FigureCanvasAgg(figure)
    axes = list(figure.subplots(4, 1, sharex=True)[:])
    t = evaluation.time
    values, errors = _estimates_at(run, t)
    chunks = evaluation.chunks
    for panel, (index, truth, unit, scale) in zip(
        axes[:2],
        ((0, run.R_s[chunks], "$R_s$ (ohm)", 1.0),
         (2, run.phi_pm[chunks], r"$\phi_{pm}$ (Wb)", run.motor.phi_pm)),
        strict=True,
    ):  # fmt: skip
        estimate, error = values[:, index] * scale, errors[:, index] * scale
        panel.plot(t, truth, color="black", linewidth=1.2, label="true")
        panel.plot(t, estimate, color="#ff7f0e", linewidth=1.0, label="estimated")
        panel.fill_between(t, estimate - error, estimate + error, color="#ff7f0e", alpha=0.25,
                           linewidth=0, label="one standard error")  # fmt: skip
        panel.set_ylabel(unit)
        low, high = float(np.min(truth)), float(np.max(truth))
        margin = max(high - low, 0.05 * high)  # early estimates may be far off: clipped
        panel.set_ylim(low - margin, high + margin)
    excess = evaluation.cost_rate / evaluation.optimal_cost_rate - 1.0
    cold = evaluation.cold_cost_rate / evaluation.optimal_cost_rate - 1.0
    axes[2].plot(t, 100 * cold, color="#1f3fd0", linestyle="--", label="tuned cold, kept")
    axes[2].plot(t, 100 * excess, color="#ff7f0e", label="online")
    axes[2].set_ylabel("excess cost (%)")
    torque = 100 * _worst_torque_errors(run, chunks)
    axes[3].plot(t, torque, color="#ff7f0e", marker=".", linestyle="none", markersize=3,
                 label="steady torque error")  # fmt: skip
    axes[3].axhline(0.1, color="grey", linewidth=0.8)
    axes[3].axhline(-0.1, color="grey", linewidth=0.8)
    axes[3].set_ylabel("torque error (%)")
    axes[3].set_xlabel("drive time $t$ (s)")
    for panel in axes:
        panel.grid(True, alpha=0.3)
        for switch in run.switches:
            if switch.kind != "rescale":
                panel.axvline(switch.time, color="#2ca02c" if switch.kind == "switch" else "red",
                              linewidth=0.5, alpha=0.6)  # fmt: skip
        panel.legend(loc="best", fontsize=8, frameon=False)
    figure.suptitle(
        "Online tuning: estimates, excess cost over the optimum of each instant, steady "
        "torque error\n(vertical lines: switches to a new law; red: the watchdog's returns)",
        fontsize=9,
    )
    return figure


def write_online_report(
    run: OnlineRun, evaluation: OnlineEvaluation, lines: list[str], out: str
) -> list[Path]:
    """Write :data:`ONLINE_REPORT_FILES` into ``out`` as one set.

    Parameters
    ----------
    run : OnlineRun
        The run.
    evaluation : OnlineEvaluation
        Its evaluation.
    lines : list of str
        The printed report.
    out : str
        The directory: absent, empty or a previous report.
    """
    from ._figures import save_figure

    with output_directory(out, ONLINE_REPORT_FILES, "online report") as temporary:
        save_figure(_figure(run, evaluation), temporary / "online")
        write_json(temporary / "online.json", online_document(run, evaluation))
        write_text(temporary / "report.txt", "\n".join(lines) + "\n")
    return [Path(out) / name for name in ONLINE_REPORT_FILES]
