"""Study 11: the online tuner on drives that heat (issue 17).

Three motors no test uses (one above 1,000 rad/s electrical), each on a hardware-like
drive at 10 kHz (one-sample delay, carrier PWM, dead time, 10 mA of noise, a 12-bit ADC),
commissioned by the off-policy learner and then run by :func:`~selftune.tuning.run_online`
through two profiles of 120 s: a warm-up (R_s +40%, the flux -8%) and the same warm-up
with a loose connection (+20% R_s in a step at 60 s). Each run is scored against the
truth by :func:`~selftune.report.evaluate_online`: the time-averaged excess cost over the
optimum of each instant (and the cold law's, kept), the largest steady torque error,
switches that raised the true cost or destabilized, the step's detection delay and every
other change reported (a false alarm), the probing's share of the time after the first
certification, and the tuner's speed (drive time over its CPU time; the simulated
drive's not counted).

A recorded log replayed: a run's log (every row the tuner was fed) written as CSV,
read back and fed to a fresh tuner gives the same events; the full run's log (the servo
on the hardware-like drive, 20 s with a resistance step) is replayed five times, and the
tuner's speed (the target's) and each chunk's latency are read off those replays: the
tuner alone, on the same data every time.
"""

from __future__ import annotations

import io
import time
from dataclasses import dataclass, replace

import numpy as np

from ..config import MotorConfig
from ..model import SPMSM
from ..report import evaluate_online, online_summary
from ..sim import DriveSettings, ParameterProfile
from ..tuning import LOG_COLUMNS, online_settings, replay, run_online, tuning_settings
from ._common import table, with_progress
from ._targets import TargetOutcome

__all__ = [
    "ONLINE_MOTORS",
    "ONLINE_PROFILES",
    "OnlineCase",
    "OnlineReplay",
    "OnlineStudy",
    "markdown_online",
    "measure_online",
    "online_targets",
]


def _drive(dc_voltage: float, adc_range: float) -> DriveSettings:
    return DriveSettings(
        input_delay=1, pwm="carrier", dead_time=0.5e-6, dc_voltage=dc_voltage,
        current_noise=0.01, adc_bits=12, adc_range=adc_range,
    )  # fmt: skip


#: The study's motors (name, motor, speed rad/s, torque N m, DC bus V, ADC range A).
ONLINE_MOTORS: tuple[tuple[str, SPMSM, float, float, float, float], ...] = (
    ("servo 1,200 rad/s", SPMSM(R_s=1.2, L_s=3e-3, phi_pm=0.08, p=4), 300.0, 1.0, 300.0, 20.0),
    ("medium 500 rad/s", SPMSM(R_s=0.25, L_s=2.5e-3, phi_pm=0.12, p=5), 100.0, 8.0, 540.0, 50.0),
    ("large 160 rad/s", SPMSM(R_s=0.05, L_s=8e-4, phi_pm=0.25, p=8), 20.0, 50.0, 540.0, 100.0),
)

#: The profiles (name, profile): 120 s warm-ups, one with a +20% R_s step at 60 s.
ONLINE_PROFILES = (
    ("warm-up", ParameterProfile([0.0, 120.0], R_s=[1.0, 1.4], phi_pm=[1.0, 0.92])),
    (
        "warm-up, R_s +20% at 60 s",
        ParameterProfile(
            [0.0, 60.0, 60.0, 120.0], R_s=[1.0, 1.2, 1.44, 1.68], phi_pm=[1.0, 0.96, 0.96, 0.92]
        ),
    ),
)

#: The quick run: the second motor, 3 s at the warm-up's rates with the step at 2 s, on
#: average PWM (the carrier's sample-by-sample simulation is what takes the time).
QUICK_PROFILE = (
    "3 s at the warm-up's rates, R_s +20% at 2 s",
    ParameterProfile(
        [0.0, 2.0, 2.0, 3.0], R_s=[1.0, 1.00667, 1.208, 1.21133],
        phi_pm=[1.0, 0.99867, 0.99867, 0.998],
    ),
)  # fmt: skip

#: The full run's replayed log: the servo's 20 s at the warm-up's rates, R_s +20% at
#: 10 s, on the hardware-like drive (so the replay's speed includes re-learning).
SPEED_PROFILE = (
    "20 s at the warm-up's rates, R_s +20% at 10 s",
    ParameterProfile(
        [0.0, 10.0, 10.0, 20.0], R_s=[1.0, 1.03333, 1.24, 1.28],
        phi_pm=[1.0, 0.99333, 0.99333, 0.98667],
    ),
)  # fmt: skip

#: Replays of the full run's log whose speeds are reported (a range, not the best).
SPEED_REPEATS = 5


@dataclass(frozen=True)
class OnlineCase:
    """One online run, scored against the truth.

    Attributes
    ----------
    motor_text, profile_text : str
        The motor and the profile.
    seed : int
        The commissioning's, noise's and probing's seed.
    duration_seconds : float
        Drive time run, s.
    excess_cost_percent, cold_excess_cost_percent : float
        The law in force's and the cold law's cost over the optimum of each instant,
        averaged over time, %.
    steady_torque_error_max_percent : float
        The largest steady torque error of a reference step, % of the operating point's.
    bad_switches_count : int
        Switches that raised the true cost or destabilized.
    switches_count, rescales_count, reverts_count : int
        New laws, rescaled torque references and the watchdog's returns.
    step_seconds : float or None
        The profile's step (None without one), s.
    step_delay_seconds : float or None
        Its detection's delay (None if not detected or no step), s.
    false_changes_count : int
        Changes reported that no step explains.
    probing_share_percent : float
        The probing's share of the time after the first certification, %.
    real_time_factor : float
        Drive time over the tuner's CPU time.
    tuner_seconds, drive_seconds : float
        The tuner's and the simulated drive's CPU time, s.
    error_bars : dict
        Per parameter (``R_s``, ``L_s``, ``phi_pm``), the share of the looks' true errors
        within one standard error and their rms in standard errors
        (:func:`~selftune.report.error_bars`).
    """

    motor_text: str
    profile_text: str
    seed: int
    duration_seconds: float
    excess_cost_percent: float
    cold_excess_cost_percent: float
    steady_torque_error_max_percent: float
    bad_switches_count: int
    switches_count: int
    rescales_count: int
    reverts_count: int
    step_seconds: float | None
    step_delay_seconds: float | None
    false_changes_count: int
    probing_share_percent: float
    real_time_factor: float
    tuner_seconds: float
    drive_seconds: float
    error_bars: dict[str, dict[str, float]]


@dataclass(frozen=True)
class OnlineReplay:
    """A recorded log written as CSV, read back and replayed through a fresh tuner.

    Attributes
    ----------
    rows_count : int
        The log's rows.
    differing_events_count : int
        Events that differ from the live run's (0: the same decisions at the same times).
    events_count : int
        The replay's events.
    replay_seconds : float
        The first replay's CPU time, s.
    real_time_factor : float
        The log's duration over that time.
    real_time_factors : tuple of float
        The same over every repeat of the replay (the tuner alone, the same data).
    chunk_latency_max_seconds, chunk_latency_p99_seconds : float
        The largest and the 99th percentile of a 10 ms chunk's CPU time in the tuner,
        looks and re-learning included, over every repeat, s.
    """

    rows_count: int
    differing_events_count: int
    events_count: int
    replay_seconds: float
    real_time_factor: float
    real_time_factors: tuple[float, ...]
    chunk_latency_max_seconds: float
    chunk_latency_p99_seconds: float


@dataclass(frozen=True)
class OnlineStudy:
    """Study 11's results.

    Attributes
    ----------
    cases : tuple of OnlineCase
        Every run.
    replay : OnlineReplay
        The recorded log replayed.
    wall_seconds : float
        The study's time, s.
    encoder_counts : int or None
        The drive's angle in an encoder's counts a turn (None: exact).
    """

    cases: tuple[OnlineCase, ...]
    replay: OnlineReplay
    wall_seconds: float
    encoder_counts: int | None = None


def _config(index: int, quick: bool, encoder_counts: int | None = None) -> MotorConfig:
    name, motor, speed, torque, bus, adc = ONLINE_MOTORS[index]
    drive = replace(_drive(bus, adc), encoder_counts=encoder_counts)
    if quick:
        drive = replace(drive, pwm="average")
    return MotorConfig(
        motor=motor, speed=speed, torque=torque, learning={"integral_action": True},
        source=name, drive=drive, drive_h=1e-4,
    )  # fmt: skip


def _case(
    index: int, profile: tuple[str, ParameterProfile], seed: int, quick: bool,
    encoder_counts: int | None = None,
) -> OnlineCase:  # fmt: skip
    config = _config(index, quick, encoder_counts)
    assert config.drive is not None
    name, shape = profile
    duration = float(shape.time[-1])
    run = run_online(
        config.surface_motor(), tuning_settings(config, seed, "digital"), config.drive, shape,
        duration, seed=seed,
    )  # fmt: skip
    evaluation = evaluate_online(run, points=200 if quick else 600)
    summary = online_summary(run, evaluation)
    steps = summary["steps_detected"]
    delay = steps[0]["delay"] if steps else None
    torque = summary["steady_torque_error_max"]
    return OnlineCase(
        motor_text=config.source, profile_text=name, seed=seed, duration_seconds=run.duration,
        excess_cost_percent=100 * evaluation.excess_cost,
        cold_excess_cost_percent=100 * evaluation.cold_excess_cost,
        steady_torque_error_max_percent=float("nan") if torque is None else 100 * torque,
        bad_switches_count=evaluation.bad_switches, switches_count=summary["switches"],
        rescales_count=summary["rescales"], reverts_count=summary["reverts"],
        step_seconds=steps[0]["time"] if steps else None,
        step_delay_seconds=None if delay is None or not np.isfinite(delay) else delay,
        false_changes_count=len(summary["changes_unexplained"]),
        probing_share_percent=100 * summary["probing_share_after_first_certified"],
        real_time_factor=run.real_time_factor, tuner_seconds=run.tuner_seconds,
        drive_seconds=run.drive_seconds, error_bars=summary["error_bars"],
    )  # fmt: skip


def _replay(quick: bool, encoder_counts: int | None = None) -> OnlineReplay:
    """A run's log through CSV and a fresh tuner: the same events, and how fast (the
    full run: the servo's hardware-like drive, 20 s with a step, replayed
    :data:`SPEED_REPEATS` times)."""
    config = _config(1, True, encoder_counts) if quick else _config(0, False, encoder_counts)
    assert config.drive is not None
    settings = tuning_settings(config, 0, "digital")
    profile = QUICK_PROFILE[1] if quick else SPEED_PROFILE[1]
    run = run_online(
        config.surface_motor(), settings, config.drive, profile, float(profile.time[-1]), seed=0,
        keep_log=True,
    )  # fmt: skip
    assert run.log is not None
    text = io.StringIO()
    np.savetxt(text, run.log, fmt="%.17g", delimiter=",", header=",".join(LOG_COLUMNS),
               comments="")  # fmt: skip
    log = np.loadtxt(io.StringIO(text.getvalue()), delimiter=",", skiprows=1)
    chunk = round(0.01 / settings.h)
    tuner = online_settings(config.surface_motor(), settings, config.drive)
    latencies: list[float] = []
    events, seconds = replay(log, tuner, run.cold.law, chunk, latencies)
    duration = log.shape[0] * settings.h
    factors = [duration / max(seconds, 1e-12)]
    for _ in range(1 if quick else SPEED_REPEATS - 1):
        factors.append(duration / max(replay(log, tuner, run.cold.law, chunk, latencies)[1],
                                      1e-12))  # fmt: skip
    live = [
        (round(t, 9), e.kind, e.reason) for t, e in zip(run.events_time, run.events, strict=True)
    ]
    again = [(round(t, 9), e.kind, e.reason) for t, e in events]
    return OnlineReplay(
        rows_count=log.shape[0],
        differing_events_count=sum(a != b for a, b in zip(live, again, strict=False))
        + abs(len(live) - len(again)),
        events_count=len(again),
        replay_seconds=seconds, real_time_factor=factors[0], real_time_factors=tuple(factors),
        chunk_latency_max_seconds=max(latencies),
        chunk_latency_p99_seconds=float(np.percentile(latencies, 99)),
    )  # fmt: skip


def measure_online(
    quick: bool, progress: bool = True, seeds: int = 2, encoder_counts: int | None = None
) -> OnlineStudy:
    """Study 11 (see the module).

    Parameters
    ----------
    quick : bool
        One motor, 3 s on average PWM (under a minute); else every motor and profile
        over ``seeds`` seeds on the hardware-like drive (about 3.5 minutes a run).
    progress : bool
        Show a progress bar.
    seeds : int
        Seeds per motor and profile in the full run.
    encoder_counts : int, optional
        The drive's angle as an encoder of that many counts a mechanical turn logs it, in
        the commissioning's logs and the tuner's chunks
        (:class:`~selftune.sim.DriveSettings`); None: the exact angle.
    """
    if quick:
        cases = [(1, QUICK_PROFILE, 0)]
    else:
        cases = [
            (index, profile, seed)
            for index in range(len(ONLINE_MOTORS))
            for profile in ONLINE_PROFILES
            for seed in range(seeds)
        ]
    started = time.perf_counter()
    results = with_progress(
        cases, lambda case: _case(*case, quick, encoder_counts), "online", progress
    )
    return OnlineStudy(
        tuple(results), _replay(quick, encoder_counts), time.perf_counter() - started,
        encoder_counts,
    )  # fmt: skip


#: The parameters whose error bars are judged (:func:`~selftune.report.error_bars`).
_BARS = ("R_s", "L_s", "phi_pm")


def _range(values: list[float], form: str) -> str:
    finite = [v for v in values if np.isfinite(v)]
    if not finite:
        return "-"
    low, high = min(finite), max(finite)
    return f"{low:{form}}" if low == high else f"{low:{form}}-{high:{form}}"


def online_targets(study: OnlineStudy, quick: bool = False) -> list[TargetOutcome]:
    """The issue's targets, over every run of the study.

    Parameters
    ----------
    study : OnlineStudy
        The results.
    quick : bool
        The quick run (3 s with the step at 2 s, average PWM): the probing's share and
        the speed are not judged (a change a second before the end is a third of the
        time after it; the target's runs are 120 s on carrier PWM).
    """
    judged = None if quick else True
    cases = study.cases
    excess = [case.excess_cost_percent for case in cases]
    torque = [case.steady_torque_error_max_percent for case in cases]
    delays = [case.step_delay_seconds for case in cases if case.step_seconds is not None]
    probing = [case.probing_share_percent for case in cases]
    speed = [case.real_time_factor for case in cases]
    bad = sum(case.bad_switches_count for case in cases)
    false = sum(case.false_changes_count for case in cases)
    worst_delay = max((d if d is not None else float("inf")) for d in delays) if delays else None
    shares = {name: [c.error_bars[name]["within_one_ratio"] for c in cases] for name in _BARS}
    rms = {name: [c.error_bars[name]["rms_ratio"] for c in cases] for name in _BARS}
    return [
        TargetOutcome("online excess cost", "<= 0.5% over the optimum of each instant",
                      f"{_range(excess, '.3f')}%", max(excess) <= 0.5,
                      "cold law kept: " + _range([c.cold_excess_cost_percent for c in cases],
                                                  ".3f") + "%"),
        TargetOutcome("online steady torque", "<= 0.1% throughout",
                      f"largest {_range(torque, '.3f')}%", max(torque) <= 0.1,
                      "the torque reference's current follows the estimated flux"),
        TargetOutcome("online switches", "0 that raise the true cost or destabilize",
                      f"{bad}", bad == 0, "certified on every plant the data allow"),
        TargetOutcome("online step detection", "<= 50 ms, no false alarm",
                      "-" if worst_delay is None else
                      f"{1e3 * worst_delay:.0f} ms at worst; {false} other changes reported",
                      None if worst_delay is None else worst_delay <= 0.05 and false == 0,
                      "the change watch, against the structured model"),
        TargetOutcome("online probing", "<= 20% of the time after the first certification",
                      f"{_range(probing, '.1f')}%", judged and max(probing) <= 20.0,
                      "on while the model is young or doubted"),
        TargetOutcome("online speed", ">= 20x real time",
                      f"{_range(list(study.replay.real_time_factors), '.1f')}x",
                      judged and min(study.replay.real_time_factors) >= 20.0,
                      f"the tuner alone on a recorded log, {len(study.replay.real_time_factors)}"
                      f" replays; a 10 ms chunk's latency at most "
                      f"{1e3 * study.replay.chunk_latency_max_seconds:.1f} ms (99%: "
                      f"{1e3 * study.replay.chunk_latency_p99_seconds:.1f} ms); in the loop "
                      f"beside the simulated drive {_range(speed, '.1f')}x"),
        TargetOutcome("online error bars", "about 68% of true errors within one standard "
                      "error (rms 0.5-2 standard errors in every run)",
                      "; ".join(f"{name} {_range(shares[name], '.0%')}" for name in shares),
                      bool(all(0.5 <= value <= 2.0 for values in rms.values() for value in values)),
                      "the looks' estimates against the truth of their data's last sample, per "
                      "run; rms in standard errors " + "; ".join(
                          f"{name} {_range(rms[name], '.2f')}" for name in rms)),
        TargetOutcome("online replay", "a recorded log replayed gives the same events",
                      f"{study.replay.events_count} events, "
                      + (f"{study.replay.differing_events_count} differ"),
                      study.replay.differing_events_count == 0,
                      "the tuner is deterministic in its data"),
    ]  # fmt: skip


def markdown_online(study: OnlineStudy) -> list[str]:
    """Section 11 of bench.md.

    Parameters
    ----------
    study : OnlineStudy
        The results.
    """
    lines = [
        "## 11. The online tuner on drives that heat"
        + (
            ""
            if study.encoder_counts is None
            else f" (the angle a {study.encoder_counts}-count encoder's)"
        ),
        "",
        "Each motor commissioned by the off-policy learner, then run with the online tuner "
        "in the loop; scored against the truth (`selftune tune --online`). Excess cost: "
        "over the optimum of each instant, averaged over time (the cold law kept beside "
        "it). Torque: the largest steady error of any reference step. Changes: the step's "
        "detection delay, and every other change reported. Speed: drive time over the "
        "tuner's CPU time.",
        "",
    ]
    lines += table(
        ["motor", "profile", "seed", "excess cost (cold kept)", "torque", "switches / "
         "rescales / reverts", "bad", "step found", "other changes", "probing",
         "within 1 se: R_s / L_s / flux", "speed"],
        [
            [case.motor_text, case.profile_text, str(case.seed),
             f"{case.excess_cost_percent:.3f}% ({case.cold_excess_cost_percent:.3f}%)",
             f"{case.steady_torque_error_max_percent:.3f}%",
             f"{case.switches_count} / {case.rescales_count} / {case.reverts_count}",
             str(case.bad_switches_count),
             "-" if case.step_delay_seconds is None else f"{1e3 * case.step_delay_seconds:.0f} ms",
             str(case.false_changes_count), f"{case.probing_share_percent:.1f}%",
             " / ".join(f"{case.error_bars[name]['within_one_ratio']:.0%}" for name in _BARS),
             f"{case.real_time_factor:.1f}x"]
            for case in study.cases
        ],
    )  # fmt: skip
    replayed = study.replay
    lines += [
        "",
        f"A recorded log replayed: {replayed.rows_count} rows written as CSV, read back and "
        f"fed to a fresh tuner: {replayed.events_count} events, "
        + (
            "the same as live"
            if replayed.differing_events_count == 0
            else f"{replayed.differing_events_count} NOT the same as live"
        )
        + f"; {replayed.replay_seconds:.2f} s of CPU ({replayed.real_time_factor:.1f}x real "
        f"time). Replayed {len(replayed.real_time_factors)} times: "
        + ", ".join(f"{factor:.1f}x" for factor in replayed.real_time_factors)
        + f" real time; a 10 ms chunk took at most {1e3 * replayed.chunk_latency_max_seconds:.1f}"
        f" ms of CPU (99th percentile {1e3 * replayed.chunk_latency_p99_seconds:.2f} ms), a "
        "look's design and certification included.",
    ]
    return lines
