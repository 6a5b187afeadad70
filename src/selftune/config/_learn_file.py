"""The learning configuration of ``selftune learn``, CONFIG.toml (:func:`load_learn_config`)."""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

from ..core import Array
from ..core._validation import LIMITS, PLAUSIBLE_RANGES, check_weight_ratio
from ..errors import InputError
from ._log_table import LOG_KEYS
from ._schedule_file import SCHEDULE_KEYS, ScheduleConfig, schedule_config
from ._toml import ConfigFile, ConfigTable

__all__ = ["LEARN_TABLES", "LearnConfig", "load_learn_config"]


#: The tables of a learning configuration (``selftune learn``) and their keys.
LEARN_TABLES: Mapping[str, tuple[str, ...]] = MappingProxyType(
    {
        "cost": ("Q", "R", "Q_i"),
        "policy": ("K0",),
        "regulation": ("C", "E", "F"),
        "learning": (
            "interval",
            "max_iterations",
            "tolerance",
            "target",
            "method",
            "input_delay",
            "logged_input",
            "integral_action",
            "dead_time",
            "noise",
            "structure",
            "electrical_speed",
            "voltage_hold",
            "max_relative_error",
            "dc_voltage",
            "nameplate_resistance",
        ),
        "log": LOG_KEYS,
        "schedule": (*SCHEDULE_KEYS, "pole_pairs"),
    }
)


@dataclass(frozen=True, eq=False)
class LearnConfig:
    """The content of a learning configuration file (``selftune learn --config``).

    Attributes
    ----------
    Q, R : ndarray
        Cost weights, symmetric positive definite.
    K0 : ndarray, shape (m, n)
        Stabilizing initial feedback.
    C, E, F : ndarray or None
        The known output and exosystem matrices; None for plain optimal state feedback.
    interval : int
        Samples per regression interval.
    max_iterations : int
        Upper bound on policy-iteration steps.
    tolerance : float
        Relative change of P at which iteration stops.
    source : str
        The file name, for messages.
    options : mapping
        The other ``[learning]`` keys as given (validated), the keyword arguments of
        :class:`selftune.learn.LearningOptions`: target, method, input_delay,
        logged_input, dead_time, noise, structure (``"incremental"``: a saturating
        motor's :class:`selftune.learn.IncrementalStructure`), electrical_speed,
        voltage_hold, max_relative_error, dc_voltage, nameplate_resistance.
    integral_action : bool
        Learn the optimal servo controller (integral action on ``e = C x + F w``).
    Q_i : ndarray, shape (r, r), or None
        The integral weight ``[cost] Q_i`` (symmetric positive definite); None: the
        learner's default (:class:`selftune.learn.LearningProblem`), or no integral action.
    schedule : ScheduleConfig or None
        ``[schedule] speeds`` or ``speed_range`` (mechanical rad/s): the log is learned
        speed by speed (:func:`selftune.learn.learn_over_speeds`) and a speed schedule is
        designed on the motor learned; None: one controller.
    pole_pairs : int or None
        ``[schedule] pole_pairs``: the electrical speed is ``pole_pairs`` times the
        mechanical.
    """

    Q: Array
    R: Array
    K0: Array
    C: Array | None
    E: Array | None
    F: Array | None
    interval: int = 10
    max_iterations: int = 50
    tolerance: float = 1e-9
    source: str = ""
    options: Mapping[str, object] = field(default_factory=dict)
    integral_action: bool = False
    Q_i: Array | None = None
    schedule: ScheduleConfig | None = None
    pole_pairs: int | None = None

    @property
    def regulation(self) -> bool:
        """Whether the file asks for output regulation (has a [regulation] table)."""
        return self.C is not None


def load_learn_config(
    path: str | os.PathLike[str],
    n: int,
    m: int,
    q: int,
    overrides: Mapping[str, Mapping[str, object]] | None = None,
    overridden_by: str = "",
) -> LearnConfig:
    """Read a learning configuration for data with n states, m inputs and q exogenous signals.

    The format::

        [cost]
        Q = [[...]]           # n x n, symmetric positive definite
        R = [[...]]           # m x m, symmetric positive definite
        Q_i = [[...]]         # optional, r x r, symmetric positive definite: the weight
                              # of the integrated error (needs integral_action = true)
        [policy]
        K0 = [[...]]          # m x n stabilizing gain that policy iteration starts from
        [regulation]          # optional: omit it to learn plain optimal state feedback
        C = [[...]]           # r x n
        E = [[...]]           # q x q (all zeros: w held over each sample)
        F = [[...]]           # r x q
        [learning]            # optional
        interval = 10         # samples per regression interval (at most 1,000,000)
        max_iterations = 50   # at most 1000
        tolerance = 1e-9      # in (0, 1e-3], as the learners require
        target = "digital"    # or "continuous" (the paper's, the default)
        method = "adp"        # or "identify" (identify-then-design)
        input_delay = 1       # the drive's computation delay, samples (0, 1, 2)
        logged_input = "applied"  # or "commanded", or "auto" (read off the data)
        integral_action = false   # true: the optimal servo controller
        dead_time = false     # true: model the inverter's dead time (n = m = 2)
        noise = "smoothed"    # or "instruments", "none"
        structure = "none"    # or "spmsm", "ipmsm", "incremental" (a saturating motor's
                              # incremental L_d, L_q, L_dq and flux offset phi_pm, phi_q
                              # about the log's operating current; identify only, needs
                              # electrical_speed; not with [schedule])
        electrical_speed = 150.0  # p speed, rad/s (structure, unless [schedule]: each
                              # held speed's own; dead time without angle)
        voltage_hold = "stationary"  # or "rotor": what the drive holds over a sample
        max_relative_error = 0.05    # refuse results with larger standard errors
        dc_voltage = 540.0    # optional, V: a carrier PWM inverter's DC bus; with
                              # dead_time and a surface or interior structure, the
                              # reported motor's standard errors hold its pulses' shift
                              # and the next sample's signs' fit may be reported
        nameplate_resistance = 0.6  # optional, ohm: the nameplate's R_s; a motor
                              # structure's fit whose R_s is beyond 2 times it either
                              # way (moving the sampled plant) is refused
        [log]                 # optional: the log's own columns, units and frame
                              # (selftune.config._log_table); then n = m = 2 and q is
                              # the number of references w1..wq it names
        [schedule]            # optional: a log over several held speeds (its angle
                              # column's), each learned at its own speed with the
                              # structure; the schedule designed on the motor learned
        pole_pairs = 4        # p: electrical speed = p times mechanical
        speeds = [5.0, 100.0] # mechanical rad/s (or speed_range = [min, max]), within
                              # the speeds the log covers

    Parameters
    ----------
    path : str or os.PathLike
        The TOML file.
    n : int
        Number of states of the data.
    m : int
        Number of inputs of the data.
    q : int
        Number of exogenous signals of the data (0: none).
    overrides : mapping of str to mapping, optional
        ``{table: {key: value}}`` over the file's values (a fleet's per-drive settings),
        checked as the file's are.
    overridden_by : str, optional
        Where the overrides come from, for messages (e.g. ``"manifest.csv row 3"``).

    Raises
    ------
    DataFileError
        One line naming the file, the table and the key, for anything missing, unknown,
        of the wrong shape (the shapes follow from the data), or out of range.
    """
    from ..learn import check_iteration_settings  # here: selftune solve loads no learner

    config = ConfigFile(path, LEARN_TABLES, overrides, overridden_by)
    cost = config.table("cost", required=True)
    policy = config.table("policy", required=True)
    learning = config.table("learning")
    C = E = F = None
    if q and "regulation" not in config:
        raise config.table("regulation").error(
            None,
            f"missing table, but the data have {q} exogenous column(s) w (the reference and "
            "back-EMF channels): give C, E, F of the error to regulate (E = 0 for a held "
            "reference), or leave the w columns out of the data for plain state feedback",
        )
    if "regulation" in config:
        regulation = config.table("regulation")
        if q == 0:
            raise regulation.error(
                None, "the data have no exogenous signal w (no w columns) to regulate against"
            )
        C = regulation.matrix("C", (None, n))
        E = regulation.matrix("E", (q, q))
        F = regulation.matrix("F", (C.shape[0], q))
    Q, R = cost.positive_definite("Q", n), cost.positive_definite("R", m)
    try:
        check_weight_ratio(Q, R)
    except InputError as exc:
        raise cost.error("Q", str(exc).removeprefix("Q: ")) from None
    K0 = policy.matrix("K0", (m, n))
    interval = learning.positive_integer("interval", 10, maximum=LIMITS["samples"])
    iterations = learning.positive_integer("max_iterations", 50, maximum=LIMITS["iterations"])
    tolerance = learning.positive("tolerance", 1e-9)
    try:  # the learners' own rule
        iterations, tolerance = check_iteration_settings(iterations, tolerance)
    except InputError as exc:
        key, _, reason = str(exc).partition(": ")
        raise learning.error(key, reason) from None
    options = _options(learning, (interval, iterations, tolerance), "schedule" in config)
    integral = learning.flag("integral_action", False)
    if integral and C is None:
        raise learning.error("integral_action", "needs a [regulation] table (C, E, F)")
    schedule, pole_pairs = _schedule(config, options)
    return LearnConfig(
        Q, R, K0, C, E, F, interval, iterations, tolerance, config.file, options, integral,
        _integral_weight(cost, integral, None if C is None else C.shape[0]), schedule,
        pole_pairs,
    )  # fmt: skip


def _schedule(
    config: ConfigFile, options: Mapping[str, object]
) -> tuple[ScheduleConfig | None, int | None]:
    """``[schedule]``: its speeds and pole pairs; it needs identify-then-design with a
    motor's structure whose parameters hold at every speed (a surface or interior motor:
    the incremental structure's hold at one operating current, and the schedule's motor
    has no cross-saturation or q flux offset), or ADP (the law learned at each held
    speed)."""
    if "schedule" not in config:
        return None, None
    table = config.table("schedule")
    if options["method"] == "identify" and options["structure"] == "none":
        raise table.error(
            None,
            "identify-then-design schedules the motor learned: set [learning] structure = "
            '"spmsm" or "ipmsm" (or method = "adp": the law learned at each held speed)',
        )
    if options["structure"] == "incremental":
        raise table.error(
            None,
            "a speed schedule is designed on a surface or interior motor, not on [learning] "
            'structure = "incremental" (its L_dq and phi_q hold at one operating current): '
            'remove [schedule], or set structure = "ipmsm"',
        )
    pole_pairs = table.positive_integer("pole_pairs", maximum=int(PLAUSIBLE_RANGES["p"][1]))
    return schedule_config(table, None), pole_pairs


def _integral_weight(cost: ConfigTable, integral: bool, r: int | None) -> Array | None:
    """``[cost] Q_i``, r x r symmetric positive definite, only with integral action."""
    if "Q_i" not in cost:
        return None
    if not integral or r is None:
        raise cost.error(
            "Q_i",
            "weighs the integrated error, but integral action is off: set [learning] "
            "integral_action = true (with a [regulation] table), or remove Q_i",
        )
    return cost.positive_definite("Q_i", r)


def _options(
    learning: ConfigTable, iteration: tuple[int, int, float], over_speeds: bool = False
) -> Mapping[str, object]:
    """The [learning] keys of :class:`selftune.learn.LearningOptions`, checked by it
    (``over_speeds``: a log over several speeds, each part learned at its own, so that
    ``electrical_speed`` is not needed)."""
    from ..learn import LearningOptions  # here: selftune solve loads no learner

    values: dict[str, object] = {
        "target": learning.choice("target", ("continuous", "digital"), "continuous"),
        "method": learning.choice("method", ("adp", "identify"), "adp"),
        "logged_input": learning.choice(
            "logged_input", ("applied", "commanded", "auto"), "applied"
        ),
        "dead_time": learning.flag("dead_time", False),
        "noise": learning.choice("noise", ("smoothed", "instruments", "none"), "smoothed"),
        "structure": learning.choice(
            "structure", ("none", "spmsm", "ipmsm", "incremental"), "none"
        ),
        "voltage_hold": learning.choice("voltage_hold", ("stationary", "rotor"), "stationary"),
        "max_relative_error": learning.positive("max_relative_error", 0.05),
    }
    if values["target"] == "digital" and "input_delay" not in learning:
        raise learning.error(
            "input_delay",
            'missing: target = "digital" is the optimum of the loop with the drive\'s '
            "computation delay; state it in samples (usually 1: each voltage is applied one "
            "sample after it is computed; 0 if applied at once)",
        )
    if "input_delay" in learning:
        delay = learning.number("input_delay")
        if not (delay.is_integer() and 0 <= delay <= 2):
            raise learning.error("input_delay", f"must be 0, 1 or 2 samples, got {delay:g}")
        values["input_delay"] = int(delay)
    if "electrical_speed" in learning:
        values["electrical_speed"] = learning.number("electrical_speed")
    if "dc_voltage" in learning:
        values["dc_voltage"] = learning.ranged("dc_voltage")
    if "nameplate_resistance" in learning:
        values["nameplate_resistance"] = learning.ranged("nameplate_resistance", limits="R_s")
    own = {"electrical_speed": 1.0} if over_speeds and "electrical_speed" not in values else {}
    try:
        LearningOptions(
            interval=iteration[0], max_iterations=iteration[1], tolerance=iteration[2],
            **values, **own,  # type: ignore[arg-type]
        )  # fmt: skip
    except InputError as exc:
        key, _, reason = str(exc).partition(": ")
        raise learning.error(key if key in LEARN_TABLES["learning"] else None, reason) from None
    return MappingProxyType(values)
