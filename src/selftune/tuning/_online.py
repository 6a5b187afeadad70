"""A drive that heats, run with the online tuner in the loop (``selftune tune --online``).

:func:`run_online` commissions the drive as ``selftune tune`` does (one batch of data,
the off-policy learner: the law *tuned cold*), then runs the motor's operating point
through a :class:`~selftune.sim.ParameterProfile` of R_s, L_s and phi_pm on the realistic
drive of the motor file, with an :class:`~selftune.learn.online.OnlineTuner` fed every
chunk of the drive's log:

- the torque reference steps every :data:`SEGMENT_CHUNKS` chunks through
  :data:`TORQUE_LEVELS` (fractions of the operating point's torque), as a servo's does;
- while the tuner asks for it, a probing voltage, uniform within
  :data:`PROBING_SHARE` of the DC bus (or of the operating point's voltage without a
  bus), is added to the commands;
- a law the tuner hands over (certified, rescaled for the flux, or the watchdog's
  return) is switched in at the next chunk's first sample, bumplessly
  (:meth:`~selftune.core.ControlLaw.bumpless_integrator`).

The run records what a drive's logger would, and the truth beside it: the switches with
their reasons, the estimates and the true parameters, the law in force over time, the
steady torque error of every reference step, when the probing was on, and the tuner's
own CPU time (:attr:`OnlineRun.real_time_factor`). The comparison with the optimum of
each instant is the report's (:mod:`selftune.report`), computed from this record.
"""

from __future__ import annotations

import time as clock
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from typing import Literal

import numpy as np

from ..core import Array, ControlLaw
from ..errors import ConfigurationMismatch, DataFileError, InputError
from ..learn import CsvHeader, LearningProblem
from ..learn.evidence._alignment import SAMPLING_JITTER
from ..learn.evidence._dead_time import check_angle
from ..learn.online import OnlineSettings, OnlineTuner, TunerEvent
from ..model import SPMSM
from ..sim import DriveSettings, ParameterProfile, RealisticDrive
from ._knowledge import known_flux_form
from ._results import TuningResult
from ._session import run_algorithm
from ._settings import TuningSettings

__all__ = [
    "CHUNK_SECONDS",
    "LOG_COLUMNS",
    "PROBING_SHARE",
    "SEGMENT_CHUNKS",
    "TORQUE_LEVELS",
    "OnlineRun",
    "OnlineSwitch",
    "follow",
    "online_settings",
    "replay",
    "run_online",
]

#: The torque reference's levels, fractions of the operating point's torque, stepped
#: through in turn (both signs and two sizes: every direction of the plant is excited).
TORQUE_LEVELS = (1.0, 1.0 / 3.0, -1.0 / 3.0, -1.0)
#: The chunks the drive hands the tuner, s of drive time.
CHUNK_SECONDS = 0.01
#: Chunks per torque step (0.1 s): the steady torque error is the mean over its second
#: half (the integrator's travel after a step from rest is over by then).
SEGMENT_CHUNKS = 10
#: The probing voltage's bound, a fraction of the DC-bus voltage.
PROBING_SHARE = 0.005
#: The columns of a recorded log (:attr:`OnlineRun.log`): time (s), the measured
#: currents (A), the commanded voltages (V), the reference and the electrical angle (rad).
LOG_COLUMNS = ("t", "x1", "x2", "u1", "u2", "w1", "w2", "theta")


@dataclass(frozen=True)
class OnlineSwitch:
    """A law switched in while the drive ran.

    Attributes
    ----------
    time : float
        Drive time of the switch (the law acts from the next chunk), s.
    kind : {"switch", "rescale", "revert"}
        A certified law; the law in force with its torque reference's current rescaled
        for the flux (the same feedback); or the watchdog's return to the law certified
        before.
    reason : str
        The tuner's evidence, in words.
    law : ControlLaw
        The law switched to.
    """

    time: float
    kind: Literal["switch", "rescale", "revert"]
    reason: str
    law: ControlLaw


@dataclass(frozen=True, eq=False)
class OnlineRun:
    """What an online run did, and the truth beside it (SI units).

    The per-chunk arrays have one entry per chunk of :data:`CHUNK_SECONDS` (at its end);
    the per-look arrays one per look of the tuner.

    Attributes
    ----------
    motor : SPMSM
        The true motor at the start (the profile's factors multiply it).
    speed, torque : float
        The operating point: mechanical speed (rad/s) and torque reference (N m).
    Q, R : ndarray
        The cost's weights.
    drive : DriveSettings
        The drive.
    h : float
        Sampling period, s.
    profile : ParameterProfile
        The factors over time.
    duration : float
        Drive time run, s.
    seed : int
        The noise's and probing's seed.
    cold : TuningResult
        The commissioning's result (the law tuned cold).
    problem : LearningProblem
        What the tuner optimizes (Q, R, C, F of the nameplate flux, integral weight).
    switches : tuple of OnlineSwitch
        Every law switched in, in order.
    events : tuple of TunerEvent
        Everything the tuner decided, with the drive time of each at ``events_time``.
    events_time : ndarray
        The drive time of each event, s.
    chunk_time : ndarray
        The end of every chunk, s.
    law_index : ndarray of int
        The law in force over each chunk: -1 the cold law, i the ``switches[i]``'s.
    probing : ndarray of bool
        Whether the probing was on over each chunk.
    torque_reference : ndarray
        The torque reference over each chunk, N m.
    torque_error : ndarray
        At each chunk that ends a reference step, the steady torque error: the mean true
        torque's error over the step's second half, a fraction of ``|torque|`` (nan
        elsewhere).
    R_s, L_s, phi_pm : ndarray
        The true values at each chunk's end, ohm, H, Wb.
    look_time : ndarray
        The drive time of each look whose estimate the tuner acted on, s (not those it
        waited on: too young, or doubted; their standard errors do not hold).
    estimates : ndarray, shape (looks, p)
        Its ``[R_s, L_s, kappa(, v)]`` (kappa: the flux over the nameplate's).
    standard_errors : ndarray, shape (looks, p)
        Their reported standard errors (the error bars:
        :data:`~selftune.learn.online._tuner.REPORTED_DOUBT`; the tuner decided with
        wider ones).
    tuner_seconds : float
        CPU time the tuner took, s.
    drive_seconds : float
        CPU time the simulated drive took, s.
    log : ndarray or None
        With ``keep_log``: every row the tuner was fed, columns :data:`LOG_COLUMNS`.
    """

    motor: SPMSM
    speed: float
    torque: float
    Q: Array
    R: Array
    drive: DriveSettings
    h: float
    profile: ParameterProfile
    duration: float
    seed: int
    cold: TuningResult
    problem: LearningProblem
    switches: tuple[OnlineSwitch, ...]
    events: tuple[TunerEvent, ...]
    events_time: Array
    chunk_time: Array
    law_index: Array
    probing: Array
    torque_reference: Array
    torque_error: Array
    R_s: Array
    L_s: Array
    phi_pm: Array
    look_time: Array
    estimates: Array
    standard_errors: Array
    tuner_seconds: float
    drive_seconds: float
    log: Array | None = None

    @property
    def real_time_factor(self) -> float:
        """Drive time over the tuner's CPU time (the tuner's speed; the simulated
        drive's time not counted)."""
        return self.duration / max(self.tuner_seconds, 1e-12)

    def law_at(self, index: int) -> ControlLaw:
        """The law of a ``law_index`` entry (-1: the cold law).

        Parameters
        ----------
        index : int
            -1, or an index into :attr:`switches`.
        """
        return self.cold.law if index < 0 else self.switches[index].law

    @property
    def detections(self) -> Array:
        """The drive times of the changes the tuner detected, s."""
        kinds = np.array([event.kind == "change" for event in self.events], dtype=bool)
        return self.events_time[kinds] if kinds.size else np.zeros(0)

    @property
    def first_certified(self) -> float:
        """The end of the first chunk without probing after the start (nan if none), s:
        when the tuner first certified the law in force or a new one."""
        off = np.flatnonzero(np.logical_not(self.probing))
        return float(self.chunk_time[off[0]]) if off.size else float("nan")


def _last(commands: Array, count: int) -> Array:
    """The last ``count`` rows of ``commands`` (none for 0)."""
    return commands[commands.shape[0] - count :]


def online_settings(
    motor: SPMSM,
    settings: TuningSettings,
    drive: DriveSettings,
    learner: Literal["identify", "adp"] = "identify",
) -> OnlineSettings:
    """What the tuner of an online run knows: the drive's sampling period, delay, hold
    and dead time, the pole pairs and speed, and the servo problem the commissioning
    learned (Q, R, the nameplate flux's F, the default integral weight); on carrier PWM
    with dead time, the DC bus (the pulses too short to carry the dead time: its error
    bars; average PWM does not shorten them, :mod:`selftune.sim._inverter`).

    Parameters
    ----------
    motor : SPMSM
        The motor (its pole pairs and nameplate flux).
    settings : TuningSettings
        The commissioning's settings.
    drive : DriveSettings
        The drive.
    learner : {"identify", "adp"}
        How the tuner re-learns (:attr:`~selftune.learn.online.OnlineSettings.learner`).
    """
    C, _, F, _ = known_flux_form(motor.p, settings.speed, settings.torque, motor.phi_pm)
    problem = LearningProblem(
        settings.Q, settings.R, C=C, F=F, integral_action=True, integral_weight=settings.Q_i
    )
    dead_time = drive.dead_time > 0.0
    return OnlineSettings(
        settings.h, drive.input_delay, problem, motor.p * settings.speed, drive.voltage_hold,
        dead_time=dead_time, learner=learner,
        dc_voltage=drive.dc_voltage if dead_time and drive.pwm == "carrier" else None,
    )  # fmt: skip


def _events(
    tuner: OnlineTuner, tables: Iterable[Array], h: float
) -> Iterator[tuple[float, TunerEvent]]:
    """Feed ``tables`` (rows of :data:`LOG_COLUMNS`) to ``tuner``, chunk by chunk; each
    event with the time of the sample after its chunk's last row, s."""
    for rows in tables:
        angle = rows[:, 7] if rows.shape[1] > 7 else None
        for event in tuner.feed(rows[:, 1:3], rows[:, 3:5], rows[:, 5:7], angle):
            yield float(rows[-1, 0] + h), event


def replay(
    log: Array,
    settings: OnlineSettings,
    law: ControlLaw,
    chunk: int,
    chunk_seconds: list[float] | None = None,
) -> tuple[list[tuple[float, TunerEvent]], float]:
    """A recorded log fed to a fresh tuner in chunks, as the drive fed the live one.

    Parameters
    ----------
    log : ndarray, shape (rows, 8)
        The columns of :data:`LOG_COLUMNS` (an online run's :attr:`OnlineRun.log`, or
        a drive's own record of the same quantities).
    settings : OnlineSettings
        What the tuner knows.
    law : ControlLaw
        The law in force at the log's first row.
    chunk : int
        Rows per chunk.
    chunk_seconds : list of float, optional
        Given, each chunk's CPU time in the tuner is appended to it, s (its latency).

    Returns
    -------
    events : list of (float, TunerEvent)
        Each event with the time of the sample after its chunk, s.
    seconds : float
        The tuner's CPU time, s.
    """
    if log.ndim != 2 or log.shape[1] != len(LOG_COLUMNS):
        raise InputError(f"log: needs the {len(LOG_COLUMNS)} columns {', '.join(LOG_COLUMNS)}")
    tuner = OnlineTuner(settings, law)
    started = clock.process_time()
    tables = (log[first : first + chunk] for first in range(0, log.shape[0], chunk))
    if chunk_seconds is None:
        events = list(_events(tuner, tables, settings.h))
        return events, clock.process_time() - started
    events, before = [], started
    for rows in tables:
        events += _events(tuner, [rows], settings.h)
        now = clock.process_time()
        chunk_seconds.append(now - before)
        before = now
    return events, clock.process_time() - started


def follow(
    settings: OnlineSettings,
    law: ControlLaw,
    chunks: Iterable[tuple[CsvHeader, Array]],
    source: str,
) -> Iterator[tuple[float, TunerEvent]]:
    """The tuner's events as a drive's log arrives (``selftune follow``).

    Parameters
    ----------
    settings : OnlineSettings
        What the tuner knows.
    law : ControlLaw
        The law in force at the log's first row.
    chunks : iterable of (CsvHeader, ndarray)
        The log's rows as they arrive (:func:`selftune.learn.read_csv_chunks`): columns
        ``t,x1,x2,u1,u2,w1,w2`` and, with dead time, ``theta``; ``u`` the voltage
        commanded at each row (applied ``settings.input_delay`` rows later).
    source : str
        The log's name, for messages.

    Yields
    ------
    (float, TunerEvent)
        Each event, with the time of the sample after the chunk that raised it, s.

    Raises
    ------
    DataFileError
        Naming the log, if its columns are not those; naming the line, where the time
        steps by other than the sampling period or the angle is not the electrical one
        in rad at the motor file's speed (:func:`_check_rows`).
    """
    tuner = OnlineTuner(settings, law)
    wanted = ",".join(LOG_COLUMNS if settings.dead_time else LOG_COLUMNS[:-1])

    def tables() -> Iterator[Array]:
        line, before = 2, None  # the chunk's first line; the row before it
        for header, table in chunks:
            if (header.n, header.m, header.q) != (2, 2, 2) or (
                settings.dead_time and not header.angle
            ):
                got = ",".join(header.names)
                reason = "; the dead-time model needs theta" if settings.dead_time else ""
                raise DataFileError(f"{source}: line 1: the columns must be {wanted}, got {got}"
                                    f"{reason}")  # fmt: skip
            rows = table if before is None else np.vstack([before, table])
            _check_rows(rows, settings, source, line - (0 if before is None else 1))
            line, before = line + table.shape[0], table[-1]
            yield table

    yield from _events(tuner, tables(), settings.h)


def _check_rows(rows: Array, settings: OnlineSettings, source: str, line: int) -> None:
    """Refuse rows (the first at ``line`` of the log) the tuner would take for what they
    are not: a time step that is not the drive's sampling period (rows lost, or a log of
    every few samples: the tuner's model steps one period a row), within the rule of
    :func:`~selftune.learn.evidence._alignment.sampling_period`; and, with dead time, an
    angle that is not the electrical one in rad at the motor file's speed
    (:func:`~selftune.learn.evidence._dead_time.check_angle`)."""
    h = settings.h
    steps = np.diff(rows[:, 0])
    off = np.flatnonzero(np.abs(steps - h) > SAMPLING_JITTER * h)
    if off.size:
        k = int(off[0])
        raise DataFileError(
            f"{source}: line {line + k + 1}, column 1 (t): the step from the row before is "
            f"{steps[k]:.6g} s, not the sampling period {h:.6g} s the motor file states "
            "([drive] switching_frequency, or [learning] h): the online tuner needs every "
            "sample at that period, so a log with rows lost or of every few samples cannot "
            "be followed from there"
        )
    if settings.dead_time and rows.shape[0] > 2:
        speed = "[operating_point] speed (times [motor] p)"
        try:
            check_angle(rows[:, 7], rows[:, 0], settings.electrical_speed, speed)
        except (InputError, ConfigurationMismatch) as error:
            last = line + rows.shape[0] - 1
            raise DataFileError(f"{source}: lines {line}-{last}: {error}") from None


def run_online(
    motor: SPMSM,
    settings: TuningSettings,
    drive: DriveSettings,
    profile: ParameterProfile,
    duration: float,
    *,
    seed: int = 0,
    progress: Callable[[float], None] | None = None,
    keep_log: bool = False,
    learner: Literal["identify", "adp"] = "identify",
) -> OnlineRun:
    """Commission the drive, then run it through ``profile`` with the tuner in the loop.

    Parameters
    ----------
    motor : SPMSM
        The motor (its nameplate values; the drive's ``temperature_rise`` and the
        profile's factors act on them).
    settings : TuningSettings
        The commissioning's settings (digital target with integral action: the law the
        drive runs).
    drive : DriveSettings
        The realistic drive.
    profile : ParameterProfile
        Factors on R_s, L_s, phi_pm over the run's time.
    duration : float
        Drive time to run, s.
    seed : int
        Seed of the commissioning, the noise and the probing.
    progress : callable, optional
        Called with the drive time reached after every chunk, s.
    keep_log : bool
        Keep every row the tuner was fed (:attr:`OnlineRun.log`: 64 bytes a row).
    learner : {"identify", "adp"}
        How the tuner re-learns: identify-then-design or the paper's ADP.

    Raises
    ------
    InputError
        If the settings do not learn a digital servo law (``target = "digital"`` and
        ``integral_action = true`` in ``[learning]``), or ``duration`` is not positive.
    RefusedError
        If the commissioning's data do not support a controller (its reason).
    """
    if settings.target != "digital" or not settings.integral_action:
        raise InputError(
            '[learning]: the online tuner runs a digital servo law: target = "digital" '
            "and integral_action = true"
        )
    if not (np.isfinite(duration) and duration > 0.0):
        raise InputError(f"duration: must be a positive number of seconds, got {duration!r}")
    h = settings.h
    cold = run_algorithm("offpolicy", motor, settings, drive=drive)
    tuner_settings = online_settings(motor, settings, drive, learner)
    problem = tuner_settings.problem
    plant = RealisticDrive(motor, settings.speed, h, drive)
    tuner = OnlineTuner(tuner_settings, cold.law)
    session = plant.start(cold.law, seed=seed, profile=profile)
    rng = np.random.default_rng([seed, 17])
    chunk = max(1, round(CHUNK_SECONDS / h))
    count = int(np.ceil(duration / (chunk * h) - 1e-9))
    _, _, _, w0 = known_flux_form(motor.p, settings.speed, settings.torque, motor.phi_pm)
    bus = drive.dc_voltage
    probing_bound = PROBING_SHARE * (bus if bus is not None else float(np.linalg.norm(
        cold.law.U @ w0)))  # fmt: skip
    record: dict[str, list[float]] = {
        key: [] for key in ("time", "reference", "error", "R_s", "L_s", "phi_pm")
    }
    law_index, probing_on, switches = [], [], []
    events, events_time, look_time, estimates, errors = [], [], [], [], []
    tuner_seconds = drive_seconds = 0.0
    logged: list[Array] = []
    pending: tuple[OnlineSwitch, int] | None = None
    x_next: Array | None = None
    current = -1
    torque_sum, torque_count = 0.0, 0
    for index in range(count):
        level = TORQUE_LEVELS[(index // SEGMENT_CHUNKS) % len(TORQUE_LEVELS)]
        w = w0 * np.array([1.0, level])
        change: dict[str, object] = {}
        if pending is not None and x_next is not None:  # bumpless: the same command
            switch, current = pending
            old = session.law.command(
                x_next, w, _last(session.past_commands, session.law.history), session.integrator
            )
            past = _last(session.past_commands, switch.law.history)
            change = {
                "law": switch.law,
                "integrator": switch.law.bumpless_integrator(x_next, w, past, old),
            }
            pending = None
        probe = rng.uniform(-probing_bound, probing_bound, (chunk, 2)) if tuner.probing else None
        probing_on.append(tuner.probing)
        law_index.append(current)
        started = clock.process_time()
        part = session.advance(chunk, w, probing=probe, **change)  # type: ignore[arg-type]
        fed = clock.process_time()
        rows = (part.measured[:-1], part.commanded_voltages, np.tile(w, (chunk, 1)))
        new_events = tuner.feed(*rows, part.angle[:-1])
        tuner_seconds += clock.process_time() - fed
        if keep_log:
            times = part.start_time + settings.h * np.arange(chunk)
            logged.append(np.column_stack([times, *rows, part.angle[:-1]]))
        drive_seconds += fed - started
        x_next = part.measured[-1]
        now = session.time
        for event in new_events:
            events.append(event)
            events_time.append(now)
            if event.estimate is not None and event.kind != "waiting":  # acted on
                look_time.append(now)
                estimates.append(event.estimate.theta)
                errors.append(event.estimate.standard_errors)
            if event.kind in ("switch", "rescale", "revert") and event.law is not None:
                switches.append(OnlineSwitch(now, event.kind, event.reason, event.law))
                pending = (switches[-1], len(switches) - 1)
        within = index % SEGMENT_CHUNKS
        if within == SEGMENT_CHUNKS // 2:
            torque_sum, torque_count = 0.0, 0
        if within >= SEGMENT_CHUNKS // 2:
            torque_sum += float(np.sum(part.torque[1:]))
            torque_count += chunk
        error = np.nan
        if within == SEGMENT_CHUNKS - 1:
            error = (torque_sum / torque_count - level * settings.torque) / abs(settings.torque)
        record["time"].append(now)
        record["reference"].append(level * settings.torque)
        record["error"].append(error)
        for name in ("R_s", "L_s", "phi_pm"):
            record[name].append(float(getattr(part, name)[-1]))
        if progress is not None:
            progress(now)
    width = len(estimates[0]) if estimates else 3
    return OnlineRun(
        motor=motor, speed=settings.speed, torque=settings.torque, Q=settings.Q,
        R=settings.R, drive=drive, h=h, profile=profile, duration=count * chunk * h,
        seed=seed, cold=cold, problem=problem, switches=tuple(switches),
        events=tuple(events), events_time=np.array(events_time),
        chunk_time=np.array(record["time"]), law_index=np.array(law_index, dtype=int),
        probing=np.array(probing_on, dtype=bool),
        torque_reference=np.array(record["reference"]),
        torque_error=np.array(record["error"]), R_s=np.array(record["R_s"]),
        L_s=np.array(record["L_s"]), phi_pm=np.array(record["phi_pm"]),
        look_time=np.array(look_time), estimates=np.array(estimates).reshape(-1, width),
        standard_errors=np.array(errors).reshape(-1, width),
        tuner_seconds=tuner_seconds, drive_seconds=drive_seconds,
        log=np.concatenate(logged) if keep_log else None,
    )  # fmt: skip
