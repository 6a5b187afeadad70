"""The motor file, MOTOR.toml, read by :func:`load_motor_config`::

    [motor]            # R_s (ohm), L_s (H), phi_pm (Wb), p (pole pairs), optional J (kg m^2)
    R_s = 0.439        # an interior PM motor: L_d and L_q (H) instead of L_s
    L_s = 0.0601
    phi_pm = 0.46
    p = 2
    [operating_point]  # optional: mechanical speed (rad/s), torque reference (N m)
    speed = 10.0
    torque = 10.0
    [cost]             # optional: weights of the cost, both symmetric positive definite
    Q = [[1000.0, 0.0], [0.0, 1000.0]]
    R = [[1.0, 0.0], [0.0, 1.0]]
    Q_i = [[4e7, 0.0], [0.0, 4e7]]  # optional, with integral_action: the integral weight
    [learning]         # optional: selftune tune's settings (selftune.tuning.TuningSettings)
    target = "digital" # or "continuous"; integral_action, dead_time (true/false),
                       # perturbation, flux_length (s), h, K0, exploration, ...
    [drive]            # optional: tune on a realistic drive (see ._drive_table)
    input_delay = 1
    [schedule]         # optional: speeds = [...] or speed_range = [min, max] (._schedule_file)
    [saturation]       # optional: the simulated motor saturates (._saturation_table)

A ``[learning]`` table (``selftune tune``'s settings) is also allowed; its keys and each
value's type and range are checked here, and the table is kept in
:attr:`MotorConfig.learning` for the command that learns (which checks how the values
fit together). A ``[drive]`` table makes ``selftune tune`` run on a realistic drive
(:mod:`._drive_table`): :attr:`MotorConfig.drive`.

Every number has a plausible range (``PLAUSIBLE_RANGES`` of :mod:`selftune.core`), and
the motor's resistance and speed must suit its inductance (``R_s^2 / L_s`` and
``(p speed)^2 L_s`` at most 5e6); a value outside is named by its key, before it can
overflow the model.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import numpy as np

from ..core import (
    PAPER_SPEED,
    PAPER_TORQUE,
    Array,
    as_matrix,
    check_positive_definite,
    finite_float,
    paper_Q,
    paper_R,
)
from ..core._validation import (
    LIMITS,
    PLAUSIBLE_RANGES,
    check_electrical_speed,
    check_electrical_time_constant,
    check_entries,
    check_range,
    check_weight_ratio,
)
from ..errors import DataFileError, InputError
from ..model import IPMSM, SPMSM, Motor, RegulationProblem
from ._saturation_table import SATURATION_KEYS, saturation_model
from ._schedule_file import SCHEDULE_KEYS, ScheduleConfig, schedule_config
from ._toml import ConfigFile, ConfigTable

if TYPE_CHECKING:
    from ..sim import DriveSettings, Saturation

__all__ = [
    "LEARNING_KEYS",
    "MOTOR_TABLES",
    "VOLTAGE_HEADROOM",
    "MotorConfig",
    "load_motor_config",
]

#: Keys of MOTOR.toml's optional [learning] table (``selftune tune``'s settings).
LEARNING_KEYS = (
    "h",
    "episode_length",
    "K0",
    "exploration",
    "input_hold",
    "interval",
    "max_iterations",
    "policy_iterations",
    "target",
    "integral_action",
    "dead_time",
    "flux_length",
    "perturbation",
)

#: The values of the [learning] keys that are words.
LEARNING_CHOICES: Mapping[str, tuple[str, ...]] = MappingProxyType(
    {"target": ("continuous", "digital"), "perturbation": ("paper", "torque", "steps")}
)

#: The share of the linear voltage range ``V_dc / sqrt(3)`` an operating point may need:
#: the rest is the controller's and the exploration's.
VOLTAGE_HEADROOM = 0.9

#: The tables of MOTOR.toml and the keys each may hold.
MOTOR_TABLES: Mapping[str, tuple[str, ...]] = MappingProxyType(
    {
        "motor": ("R_s", "L_s", "L_d", "L_q", "phi_pm", "p", "J"),
        "operating_point": ("speed", "torque"),
        "cost": ("Q", "R", "Q_i"),
        "learning": LEARNING_KEYS,
        "drive": (
            "input_delay",
            "switching_frequency",
            "pwm",
            "dead_time",
            "dead_time_compensation",
            "dc_voltage",
            "current_noise",
            "adc_bits",
            "adc_range",
            "temperature_rise",
            "logged_input",
            "voltage_hold",
            "encoder_counts",
        ),
        "schedule": SCHEDULE_KEYS,
        "saturation": SATURATION_KEYS,
    }
)


@dataclass(frozen=True, eq=False)
class MotorConfig:
    """A motor, its operating point and the cost weights: the content of MOTOR.toml.

    Parameters
    ----------
    motor : SPMSM or IPMSM
        The motor's parameters.
    speed : float
        Mechanical speed held by the load machine, rad/s.
    torque : float
        Torque reference ``T*``, N m.
    Q : ndarray, shape (2, 2)
        State weight of the cost (eq. 5), symmetric positive definite.
    R : ndarray, shape (2, 2)
        Input weight of the cost, symmetric positive definite.
    learning : mapping
        The raw ``[learning]`` table (empty if absent); validated by the learning command.
    drive : DriveSettings or None
        The realistic drive of the ``[drive]`` table; None without one (the ideal drive).
    drive_h : float or None
        ``1 / switching_frequency`` of the ``[drive]`` table, s, if it gives one.
    Q_i : ndarray, shape (2, 2), or None
        The weight of the integrated current error (``[cost] Q_i``), symmetric positive
        definite; None: the learner's default (:class:`selftune.learn.LearningProblem`).
    source : str
        Where the configuration came from (a file name, or ``"paper preset"``), for
        messages.
    schedule : ScheduleConfig or None
        The speeds of the ``[schedule]`` table; None without one.
    saturation : SaturationModel or FluxMap or None
        The simulated motor's saturation (the ``[saturation]`` table: the analytic model on
        ``motor``'s inductances and flux, or a flux map); None without one.

    Raises
    ------
    InputError
        Naming the field, if a value is not finite or outside its plausible range, the
        speed is too fast for the motor (``(p speed)^2 L_s`` above 1e7), Q, R are not
        2x2 symmetric positive definite with entries at most 1e12, or (with a DC bus) the
        operating point needs more than :data:`VOLTAGE_HEADROOM` of the linear voltage
        range.
    """

    motor: Motor
    speed: float = PAPER_SPEED
    torque: float = PAPER_TORQUE
    Q: Array = field(default_factory=paper_Q)
    R: Array = field(default_factory=paper_R)
    learning: Mapping[str, Any] = field(default_factory=dict)
    source: str = "paper preset"
    drive: DriveSettings | None = None
    drive_h: float | None = None
    Q_i: Array | None = None
    schedule: ScheduleConfig | None = None  # [schedule]: the speeds (._schedule_file)
    saturation: Saturation | None = None  # [saturation] (._saturation_table)

    def __post_init__(self) -> None:
        for name in ("speed", "torque"):
            object.__setattr__(
                self, name, check_range(finite_float(getattr(self, name), name), name)
            )
        check_electrical_time_constant(self.motor.R_s, min(self.motor.L_d, self.motor.L_q))
        check_electrical_speed(self.speed, self.motor.p, max(self.motor.L_d, self.motor.L_q))
        for name in ("Q", "R", "Q_i"):
            if getattr(self, name) is None:
                continue
            matrix = check_entries(as_matrix(getattr(self, name), name, (2, 2)), name)
            matrix = check_positive_definite(matrix, name)
            matrix.setflags(write=False)
            object.__setattr__(self, name, matrix)
        check_weight_ratio(self.Q, self.R)
        object.__setattr__(self, "learning", MappingProxyType(dict(self.learning)))
        self._check_voltage()

    def _check_voltage(self) -> None:
        """With a DC bus, the operating point must lie within the drive's linear voltage
        range (reversed torque included: the self-tuning session reverses it)."""
        if self.drive is None or self.drive.dc_voltage is None:
            return
        limit = VOLTAGE_HEADROOM * self.drive.dc_voltage / np.sqrt(3.0)
        needed = max(
            float(np.linalg.norm(self.motor.equilibrium(self.speed, torque)[1]))
            for torque in (self.torque, -self.torque)
        )
        if needed > limit:
            raise InputError(
                f"speed: the operating point needs a voltage of {needed:.4g} V (back-EMF "
                f"{self.motor.p * self.speed * self.motor.phi_pm:.4g} V), beyond "
                f"{VOLTAGE_HEADROOM:.0%} of the drive's linear range V_dc / sqrt(3) = "
                f"{self.drive.dc_voltage / np.sqrt(3.0):.4g} V; lower the speed or the "
                "torque, or raise [drive] dc_voltage (field weakening is not modelled)"
            )

    @classmethod
    def default(cls) -> MotorConfig:
        """The paper's setting: :meth:`SPMSM.paper`, 10 rad/s, 10 N m, ``Q = 1e3 I``, ``R = I``."""
        return cls(motor=SPMSM.paper())

    def surface_motor(self) -> SPMSM:
        """The motor, if it is a surface motor (``L_d = L_q``): what the paper's algorithms
        and the online tuner model (an interior motor is commissioned by
        :func:`selftune.tuning.commission_interior`).

        Raises
        ------
        InputError
            Naming the file and the keys, for an interior motor.
        """
        if isinstance(self.motor, SPMSM):
            return self.motor
        raise InputError(
            f"{self.source}: [motor] L_d, L_q: an interior PM motor (L_q / L_d ="
            f" {self.motor.saliency:.3g}) has no online tuner yet (it follows a surface"
            " motor's R_s, L_s and flux); selftune tune without --online commissions it"
        )

    def regulation_problem(self) -> RegulationProblem:
        """The known-flux output-regulation problem at this operating point's speed."""
        return self.motor.regulation_problem(self.speed)

    def exogenous(self) -> Array:
        """``w`` at this operating point: ``[p speed phi_pm, T*]`` (a surface motor) or
        ``[p speed phi_pm, i_d*, i_q*]`` (an interior one, MTPA)."""
        return self.motor.exogenous(self.speed, self.torque)


def load_motor_config(path: str | os.PathLike[str]) -> MotorConfig:
    """Read a MOTOR.toml file (format in the module docstring).

    ``[motor]`` is required; ``[operating_point]`` and ``[cost]`` and each of their keys
    default to the paper's setting (10 rad/s, 10 N m, ``Q = 1e3 I``, ``R = I``).
    ``[learning]`` is kept as a raw table.

    Parameters
    ----------
    path : str or path-like
        The file to read.

    Returns
    -------
    MotorConfig

    Raises
    ------
    DataFileError
        With a one-line message naming the file, the table and the key: the file cannot be
        read or is not TOML, a table or key is unknown, a required key is missing, a value
        has the wrong type or shape, a motor parameter is not positive and finite, ``p`` is
        not a whole number, or Q or R is not symmetric positive definite.

    Examples
    --------
    >>> config = load_motor_config("motor.toml")  # doctest: +SKIP
    >>> config.motor.L_s, config.speed  # doctest: +SKIP
    (0.0601, 10.0)
    """
    config = ConfigFile(path, MOTOR_TABLES)
    motor = _motor(config.table("motor", required=True))
    operating_point = config.table("operating_point")
    cost = config.table("cost")
    learning = config.table("learning")
    _check_learning(learning)
    speed = operating_point.ranged("speed", PAPER_SPEED)
    torque = operating_point.ranged("torque", PAPER_TORQUE)
    Q = cost.positive_definite("Q", 2, paper_Q())
    R = cost.positive_definite("R", 2, paper_R())
    Q_i = _integral_weight(cost, learning)
    drive, drive_h = None, None
    if "drive" in config:
        from ._drive_table import drive_settings  # here: solve loads no simulator

        drive, drive_h = drive_settings(config.table("drive"))
    schedule = schedule_config(config.table("schedule"), motor) if "schedule" in config else None
    saturation = None
    if "saturation" in config:
        saturation = saturation_model(config.table("saturation"), motor, drive)
    try:
        raw = config.data.get("learning", {})  # as written: read with its names by the tuner
        return MotorConfig(
            motor,
            speed,
            torque,
            Q,
            R,
            raw,
            config.file,
            drive,
            drive_h,
            Q_i,
            schedule=schedule,
            saturation=saturation,
        )
    except InputError as exc:  # a rule across tables (the speed for the motor)
        key, _, reason = str(exc).partition(": ")
        table = operating_point if key in ("speed", "torque") else cost
        raise table.error(key, reason) from None


def _integral_weight(cost: ConfigTable, learning: ConfigTable) -> Array | None:
    """``[cost] Q_i``, 2x2 symmetric positive definite, only with integral action."""
    if "Q_i" not in cost:
        return None
    if not learning.flag("integral_action", False):
        raise cost.error(
            "Q_i",
            "weighs the integrated current error, but integral action is off: set "
            "[learning] integral_action = true, or remove Q_i",
        )
    return cost.positive_definite("Q_i", 2)


def _inductances(table: ConfigTable) -> dict[str, float]:
    """``{"L_s": ...}`` or ``{"L_d": ..., "L_q": ...}``: the [motor] table's inductance(s),
    H; equal L_d and L_q are a surface motor's L_s."""
    given = [key for key in ("L_s", "L_d", "L_q") if key in table]
    if "L_s" in given and len(given) > 1:
        raise table.error(
            given[1], "give either L_s (a surface motor) or L_d and L_q (an interior one)"
        )
    if given in (["L_d"], ["L_q"]):
        missing = "L_q" if given == ["L_d"] else "L_d"
        raise table.error(missing, "missing: an interior motor needs L_d and L_q (or L_s alone)")
    keys = given or ["L_s"]  # none: the required L_s is reported missing
    values = {}
    for key in keys:
        table.positive(key)
        values[key] = table.ranged(key, limits="L_s")
    if len(values) == 2 and values["L_d"] == values["L_q"]:
        return {"L_s": values["L_d"]}
    return values


def _motor(table: ConfigTable) -> Motor:
    """The [motor] table's motor, each parameter positive and in its range."""
    values: dict[str, float] = {}
    table.positive("R_s")
    values["R_s"] = table.ranged("R_s")
    inductances = _inductances(table)
    for key in ("phi_pm", "J"):
        if key != "J" or key in table:
            table.positive(key)
            values[key] = table.ranged(key)
    pole_pairs = table.positive_integer("p", maximum=int(PLAUSIBLE_RANGES["p"][1]))
    try:
        check_electrical_time_constant(values["R_s"], min(inductances.values()))
        if "L_s" in inductances:
            return SPMSM(p=pole_pairs, L_s=inductances["L_s"], **values)
        return IPMSM(p=pole_pairs, **inductances, **values)
    except DataFileError:
        raise
    except InputError as exc:  # a rule across keys: name the first key
        key, _, reason = str(exc).partition(": ")
        raise table.error(key, reason) from None


def _check_learning(table: ConfigTable) -> None:
    """Each [learning] value of the right type and in its range (``selftune tune`` checks
    how they fit together)."""
    for key in ("h", "episode_length", "exploration"):
        if key in table:
            table.positive(key)
            table.ranged(key)
    if "K0" in table:
        table.matrix("K0", (2, 2))
    for key, limit in (
        ("input_hold", LIMITS["episode_samples"]),
        ("interval", LIMITS["episode_samples"]),
        ("max_iterations", LIMITS["iterations"]),
        ("policy_iterations", LIMITS["iterations"]),
    ):
        if key in table:
            table.positive_integer(key, maximum=limit)
    for key, allowed in LEARNING_CHOICES.items():
        if key in table:
            table.choice(key, allowed, allowed[0])
    for key in ("integral_action", "dead_time"):
        if key in table:
            table.flag(key, False)
    if "flux_length" in table:
        table.positive("flux_length")
        table.ranged("flux_length", limits="episode_length")
