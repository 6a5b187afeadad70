"""``selftune tune`` (offline and ``--online``) and ``selftune follow``: the tuner on
the simulated drive, and the online tuner on a drive's log."""

from __future__ import annotations

import json
import sys
from typing import TYPE_CHECKING, Any

import numpy as np

from ..config import MotorConfig
from ..core import finite_or_null, to_jsonable
from ..core._atomic import check_output_directory
from ..errors import DataFileError, InputError
from ..model import IPMSM, SPMSM
from ._output import (
    STANDARD_OUTPUT,
    _check_json_target,
    _check_numerics,
    _check_report_target,
    _numerics,
    _print_report,
    _say_report_written,
    _write_json,
    _write_report,
)
from ._schedule import schedule_document, schedule_lines, scheduled

if TYPE_CHECKING:  # matplotlib is loaded only to draw
    from matplotlib.figure import Figure

    from ..core import Array
    from ..learn import LearnedController


def _tune_interior(
    config: MotorConfig,
    motor: IPMSM,
    seed: int,
    json_path: str | None,
    algorithm: str,
    target: str | None,
    report_dir: str | None,
) -> int:
    """``selftune tune`` of an interior motor: identify, design, MTPA, check the torque
    (:func:`selftune.tuning.commission_interior`), on the file's realistic drive."""
    from ..report import evaluate_interior, interior_document, interior_lines
    from ..tuning import commission_interior, tuning_settings

    _identify_only(config, algorithm, target, "an interior PM motor is", "a surface motor")
    assert config.drive is not None
    settings = tuning_settings(config, seed, "digital")
    with _numerics(config.source) as caught:
        result = commission_interior(motor, settings, config.drive, seed=seed)
        evaluation = evaluate_interior(result, motor, settings, config.drive)
        run = scheduled(config, result.motor)  # on the identified motor, never the file's
    _check_numerics(config.source, caught, result.learned.law.K)
    lines = interior_lines(config.source, result, evaluation, config.drive)
    if run is not None:
        _check_numerics(config.source, caught, run.design.schedule.table("K"))
        lines = [*lines, *schedule_lines(run, config.speed)]
    if json_path is not None:
        document = interior_document(motor, settings, result, evaluation, config.drive)
        if run is not None:  # the learned law at the operating speed stays the control_law
            document.update(
                {k: v for k, v in schedule_document(run, config).items() if k != "control_law"}
            )
        _write_json(json_path, document)
    # the step response's step: the MTPA currents from 0 at the operating point's speed
    back_emf = motor.p * settings.speed * motor.phi_pm
    step = (np.array([back_emf, 0.0, 0.0]), np.concatenate([[back_emf], result.references]))
    figure = run.figure(config.speed) if run is not None and report_dir is not None else None
    return _reported(config, result.learned, lines, (report_dir, json_path), step, figure)


def _reported(
    config: MotorConfig,
    learned: LearnedController | None,
    lines: list[str],
    targets: tuple[str | None, str | None],
    step: tuple[Array, Array] | None = None,
    schedule: Figure | None = None,
) -> int:
    """The end of every ``tune``: the report of ``learned`` (its step response's ``step``
    and a schedule's figure) into the report directory, the lines printed, and where
    each went said; ``targets`` is ``(report_dir, json_path)``. Returns the exit code 0."""
    report_dir, json_path = targets
    title = f"selftune tune: {config.source}"
    _write_report(learned, title, lines, report_dir, step, schedule=schedule)
    _print_report(lines, json_path)
    _say_report_written(report_dir, json_path, scheduled=schedule is not None)
    return 0


def _identify_only(
    config: MotorConfig, algorithm: str, target: str | None, subject: str, other: str
) -> None:
    """Refuse what an identify-then-design commissioning cannot take: another algorithm or
    target than the default (they are ``other``'s), or no realistic drive."""
    for given, wanted, what in (
        (algorithm, "offpolicy", "--algorithm"),
        (target, "digital", "--target"),
    ):
        if given not in (None, wanted):
            raise InputError(
                f"{what}: {subject} commissioned by identify-then-design of the digital"
                f" target; {given} is for {other} (leave {what} out)"
            )
    if config.drive is None:
        raise InputError(
            f"{config.source}: {subject} commissioned on a realistic drive: add a [drive]"
            " table (e.g. switching_frequency = 10000.0, input_delay = 1)"
        )


def _tune_ramp(
    config: MotorConfig,
    motor: SPMSM,
    seed: int,
    json_path: str | None,
    algorithm: str,
    target: str | None,
    report_dir: str | None,
) -> int:
    """``selftune tune`` of a surface motor with a ``[schedule]``: the staircase of speeds
    over the schedule's range on the file's realistic drive, the motor identified held
    speed by held speed (:func:`selftune.tuning.commission_ramp`), and the schedule
    designed on it within the speeds the data cover."""
    from ..report import evaluate_ramp, ramp_document, ramp_lines
    from ..tuning import commission_ramp, tuning_settings

    _identify_only(
        config, algorithm, target, "a surface motor with a [schedule] table is",
        "a surface motor's single-speed law, without [schedule]",
    )  # fmt: skip
    assert config.schedule is not None and config.drive is not None
    settings = tuning_settings(config, seed, "digital")
    speeds = config.schedule.speeds
    with _numerics(config.source) as caught:
        result = commission_ramp(
            motor, settings, config.drive, (min(speeds), max(speeds)), seed=seed
        )
        run = scheduled(config, result.motor, result.covered)
        assert run is not None
        evaluation = evaluate_ramp(
            result, motor, settings, config.drive, speeds, run.design, run.single_law
        )
    _check_numerics(config.source, caught, run.design.schedule.table("K"))
    lines = [
        *ramp_lines(config.source, result, evaluation, config.drive),
        *schedule_lines(run, config.speed),
    ]
    if json_path is not None:
        document = ramp_document(motor, settings, result, evaluation, config.drive)
        _write_json(json_path, {**document, **schedule_document(run, config)})
    # the report's law: the one learned at the highest held speed, with its evidence
    figure = run.figure(config.speed) if report_dir is not None else None
    return _reported(config, result.top[1], lines, (report_dir, json_path), schedule=figure)


def _tune_saturating(
    config: MotorConfig,
    seed: int,
    json_path: str | None,
    algorithm: str,
    target: str | None,
    report_dir: str | None,
) -> int:
    """``selftune tune`` of a saturating motor (a ``[saturation]`` table): its incremental
    model learned at several current levels on the file's realistic drive, the law
    scheduled over ``i_q*`` (:func:`selftune.tuning.commission_over_current`) and, with a
    ``[schedule]``, over speed and ``i_q*`` together, judged against the true motor's
    pointwise optimum."""
    from tqdm import tqdm

    from ..report import current_document, current_lines, evaluate_current_schedule
    from ..tuning import commission_over_current, tuning_settings
    from ..tuning._saturation import MAX_LEVELS

    _identify_only(
        config, algorithm, target, "a saturating motor is", "a surface motor's unsaturated law"
    )
    assert config.drive is not None and config.saturation is not None
    motor = IPMSM.of(config.motor)
    settings = tuning_settings(config, seed, "digital")
    with (
        tqdm(
            total=MAX_LEVELS, desc="current levels", file=sys.stderr, disable=None, leave=False,
            bar_format="{desc}: {n} learned (at most {total}) {elapsed}",
        ) as bar,
        _numerics(config.source) as caught,
    ):  # fmt: skip
        result = commission_over_current(
            motor, config.saturation, settings, config.drive, seed=seed,
            progress=lambda count: bar.update(count - bar.n),
            speeds=None if config.schedule is None else config.schedule.speeds,
        )  # fmt: skip
        evaluation = evaluate_current_schedule(result, motor, config.saturation, settings)
    _check_numerics(config.source, caught, result.design.schedule.table("K"))
    lines = current_lines(config.source, result, evaluation, config.drive)
    if json_path is not None:
        document = current_document(
            motor, config.saturation, settings, result, evaluation, config.drive
        )
        _write_json(json_path, document)
    rated, figure = result.levels[-1], None  # the report: the law learned at rated current
    if report_dir is not None and result.speed_design is not None:  # and the schedule
        from ..report._schedule_figure import figure_speed_current

        figure = figure_speed_current(
            result.speed_design, evaluation.electrical_speeds, evaluation.speed_excess,
            evaluation.current_only_excess,
        )  # fmt: skip
    elif report_dir is not None:  # beside that one law
        from ..report._saturation_report import current_schedule_figure

        figure = current_schedule_figure(
            result.design, rated.learned.law, float(rated.reference[1])
        )
    return _reported(config, rated.learned, lines, (report_dir, json_path), schedule=figure)


def tune_command(
    config: MotorConfig,
    algorithm: str,
    seed: int,
    json_path: str | None,
    target: str | None = None,
    report_dir: str | None = None,
) -> int:
    """``selftune tune``: a self-tuning session on the simulated drive of ``config``.

    The drive is the ideal one, or the realistic one of the file's ``[drive]`` table; the
    report gives the controller a drive can run, its quality, and what it does on the
    simulated drive (steady torque, also after R_s rose 40%). An interior motor is
    commissioned by identify-then-design (:func:`_tune_interior`); with a ``[schedule]``
    table its identified motor's optimum is scheduled over speed too (:mod:`._schedule`: a
    table in the report, ``schedule`` and ``schedule_design`` in the JSON). A surface
    motor with a ``[schedule]`` table is commissioned over a staircase of the schedule's
    speeds and identified there, and the schedule designed on it (:func:`_tune_ramp`);
    without one, the session runs ``algorithm``. With a ``[saturation]`` table the motor
    is learned at several current levels and its law scheduled over ``i_q*``, and with a
    ``[schedule]`` too over speed and ``i_q*`` together (:func:`_tune_saturating`).

    Parameters
    ----------
    config : MotorConfig
        The motor file's content (its [learning] table gives the settings).
    algorithm : str
        ``"1"``, ``"2"``, ``"3"`` or ``"offpolicy"``.
    seed : int
        Exploration seed.
    json_path : str or None
        Where to write the JSON (``-``: standard output, without the report).
    target : {"continuous", "digital"}, optional
        Overrides the motor file's target.
    report_dir : str or None
        Where to write the report of the learned controller: one HTML page and its
        figures (:func:`selftune.report.write_learn_report`).
    """
    from ..report import evaluate, torque_check, tune_document, tune_lines, tuned_pi
    from ..tuning import run_algorithm, tuning_settings

    _check_json_target(json_path)
    _check_report_target(report_dir)
    if config.saturation is not None:
        return _tune_saturating(config, seed, json_path, algorithm, target, report_dir)
    if isinstance(config.motor, IPMSM):
        return _tune_interior(config, config.motor, seed, json_path, algorithm, target, report_dir)
    motor = config.surface_motor()
    if config.schedule is not None:
        return _tune_ramp(config, motor, seed, json_path, algorithm, target, report_dir)
    settings = tuning_settings(config, seed, target, algorithm)
    with _numerics(config.source) as caught:
        result = run_algorithm(algorithm, motor, settings, drive=config.drive)  # type: ignore[arg-type]
        evaluation = evaluate(result, motor, settings, config.drive)
        torque = torque_check(motor, settings, result, config.drive)
    _check_numerics(config.source, caught, result.P, result.K)
    pi = tuned_pi(motor, settings, result)
    lines = tune_lines(config.source, result, evaluation, torque, config.drive, pi)
    if json_path is not None:
        _write_json(json_path, tune_document(motor, settings, result, evaluation, torque, pi[0]))
    # the step response's step: the torque reference from 0 at the operating point's speed
    step = (result.w * np.array([1.0, 0.0]), result.w)
    return _reported(config, result.learned, lines, (report_dir, json_path), step)


def _online_drive(config: MotorConfig, seed: int) -> tuple[Any, Any]:
    """The digital servo settings and the drive an online tuner works with (the motor
    file's ``[drive]``, or the ideal drive at the ``[learning]`` sampling period)."""
    from ..sim import DriveSettings
    from ..tuning import tuning_settings

    drive = config.drive if config.drive is not None else DriveSettings()
    return tuning_settings(config, seed, "digital"), drive


def online_command(
    config: MotorConfig,
    profile_path: str,
    seed: int,
    json_path: str | None,
    report_dir: str | None,
    learner: str = "identify",
) -> int:
    """``selftune tune --online``: commission the drive of ``config``, then run it
    through the profile with the online tuner in the loop; print, and write the JSON and
    the report's figures.

    Parameters
    ----------
    config : MotorConfig
        The motor file's content (its ``[drive]`` table: the drive; without one, the
        ideal drive at the ``[learning]`` sampling period).
    profile_path : str
        PROFILE.toml (:func:`selftune.config.load_online_config`).
    seed : int
        The seed of the commissioning, the noise and the probing.
    json_path : str or None
        Where to write the JSON (``-``: standard output, without the report).
    report_dir : str or None
        Where to write the figures, the JSON and the printed report as one set.
    learner : {"identify", "adp"}
        How the tuner re-learns.
    """
    from tqdm import tqdm

    from ..config import load_online_config
    from ..report import (
        ONLINE_REPORT_FILES,
        evaluate_online,
        online_document,
        online_lines,
        write_online_report,
    )
    from ..tuning import run_online

    _check_json_target(json_path)
    if report_dir is not None:
        check_output_directory(report_dir, ONLINE_REPORT_FILES, "online report")
    if config.saturation is not None:
        raise InputError(
            f"{config.source}: [saturation]: the online tuner follows a surface motor's R_s, "
            "L_s and flux, not a saturating motor's current-dependent inductances; leave out "
            "--online (tune schedules it over the current) or the [saturation] table"
        )
    online = load_online_config(profile_path)
    settings, drive = _online_drive(config, seed)
    with (
        tqdm(
            total=round(online.duration, 3), desc="online", unit=" s", file=sys.stderr,
            disable=None, leave=False, bar_format="{desc}: {n:.1f}/{total} s {bar} {elapsed}",
        ) as bar,
        _numerics(config.source) as caught,
    ):  # fmt: skip

        def progress(now: float) -> None:
            bar.update(now - bar.n)

        run = run_online(
            config.surface_motor(), settings, drive, online.profile, online.duration, seed=seed,
            progress=progress, learner=learner,  # type: ignore[arg-type]
        )  # fmt: skip
        evaluation = evaluate_online(run)
    _check_numerics(config.source, caught, run.cold.P, run.cold.K)
    lines = online_lines(config.source, run, evaluation)
    if json_path is not None:
        _write_json(json_path, online_document(run, evaluation))
    if report_dir is not None:
        write_online_report(run, evaluation, lines, report_dir)
    _print_report(lines, json_path)
    if report_dir is not None and json_path != STANDARD_OUTPUT:
        print(f"wrote {report_dir}/ ({', '.join(ONLINE_REPORT_FILES)})")
    return 0


def follow_command(
    config: MotorConfig, law_path: str, log_path: str, learner: str = "identify"
) -> int:
    """``selftune follow``: the online tuner's events on a drive's log as it arrives,
    one JSON line each on standard output.

    Parameters
    ----------
    config : MotorConfig
        What the tuner knows (the motor file; without a ``[drive]`` table, the ideal
        drive at the ``[learning]`` sampling period).
    law_path : str
        The JSON result whose controller is in force at the log's first row.
    log_path : str
        The CSV log, or ``-`` for standard input.
    learner : {"identify", "adp"}
        How the tuner re-learns.
    """
    import io

    from ..config import load_control_law
    from ..core._atomic import open_regular_file
    from ..learn import read_csv_chunks
    from ..learn.online import OnlineTuner
    from ..tuning import CHUNK_SECONDS, follow, online_settings

    settings, drive = _online_drive(config, 0)
    tuner = online_settings(config.surface_motor(), settings, drive, learner)  # type: ignore[arg-type]
    law = load_control_law(law_path)
    try:  # the law must fit the drive: said of the file that gave it
        OnlineTuner(tuner, law)
    except InputError as exc:
        raise DataFileError(f"{law_path}: {exc}") from None
    rows = max(1, round(CHUNK_SECONDS / settings.h))
    if log_path == STANDARD_OUTPUT:
        stream, source = sys.stdin, "standard input"
    else:
        stream = io.TextIOWrapper(open_regular_file(log_path), encoding="utf-8", newline="")
        source = log_path
    names = tuner.structure.names(tuner.dead_time)
    with stream:
        for time, event in follow(tuner, law, read_csv_chunks(stream, source, rows), source):
            line: dict[str, Any] = {"time": time, "kind": event.kind, "reason": event.reason}
            if event.law is not None:
                line["control_law"] = event.law.document()
            if event.estimate is not None:
                line["estimate"] = dict(zip(names, event.estimate.theta, strict=True))
                line["standard_errors"] = dict(
                    zip(names, event.estimate.standard_errors, strict=True)
                )
            print(json.dumps(finite_or_null(to_jsonable(line))), flush=True)
    return 0
