"""TOML configuration files: the one home of reading them and of their error messages.

Every command that reads a configuration file goes through this module, so every bad
input gives the same kind of message: one line naming the file, the table and the key,
and what is wrong, raised as a :class:`~selftune.errors.DataFileError`::

    motor.toml: [cost] Q: must be symmetric positive definite (smallest eigenvalue -1)
    motor.toml: [motor] L_s: missing
    motor.toml: [motor] Ls: unknown key (known: R_s, L_s, phi_pm, p, J; did you mean L_s?)

The generic part is :func:`read_toml`, :class:`ConfigFile` (the top-level tables) and
:class:`ConfigTable` (typed values of one table). The motor file, MOTOR.toml, is read by
:func:`load_motor_config`::

    [motor]            # R_s (ohm), L_s (H), phi_pm (Wb), p (pole pairs), optional J (kg m^2)
    R_s = 0.439
    L_s = 0.0601
    phi_pm = 0.46
    p = 2
    [operating_point]  # optional: mechanical speed (rad/s), torque reference (N m)
    speed = 10.0
    torque = 10.0
    [cost]             # optional: weights of the cost, both symmetric positive definite
    Q = [[1000.0, 0.0], [0.0, 1000.0]]
    R = [[1.0, 0.0], [0.0, 1.0]]

A ``[learning]`` table is also allowed; it is kept unvalidated in
:attr:`MotorConfig.learning` for the command that learns.
"""

from __future__ import annotations

import difflib
import math
import os
import tomllib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ._validation import as_matrix, check_positive_definite, finite_float, symmetric_tolerance
from .errors import DataFileError, InputError
from .motor import SPMSM
from .regulation import RegulationProblem

if TYPE_CHECKING:
    from .torque import TuningSettings

__all__ = [
    "LEARN_TABLES",
    "MOTOR_TABLES",
    "TUNING_KEYS",
    "ConfigFile",
    "ConfigTable",
    "LearnConfig",
    "MotorConfig",
    "load_learn_config",
    "load_motor_config",
    "read_toml",
    "tuning_settings",
]

Array = NDArray[np.float64]

#: The tables of MOTOR.toml and the keys each may hold (``learning`` is checked later).
MOTOR_TABLES: Mapping[str, tuple[str, ...]] = MappingProxyType(
    {
        "motor": ("R_s", "L_s", "phi_pm", "p", "J"),
        "operating_point": ("speed", "torque"),
        "cost": ("Q", "R"),
        "learning": (),
    }
)

#: The paper's operating point (Sec. V): mechanical speed, rad/s, and torque reference, N m.
PAPER_SPEED = 10.0
PAPER_TORQUE = 10.0


def _paper_Q() -> Array:
    return 1e3 * np.eye(2)


def _paper_R() -> Array:
    return np.eye(2)


def _one_line(text: str) -> str:
    return " ".join(text.split())


def _suggestion(word: str, known: Iterable[str]) -> str:
    close = difflib.get_close_matches(word, list(known), n=1, cutoff=0.6)
    if not close:
        lowered = {name.lower().replace("_", ""): name for name in known}
        match = lowered.get(word.lower().replace("_", ""))
        close = [match] if match else []
    return f"; did you mean {close[0]}?" if close else ""


def _type_name(value: object) -> str:
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, int | float):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, list):
        return "an array"
    if isinstance(value, dict):
        return "a table"
    return f"a {type(value).__name__}"


def read_toml(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read a TOML file into a dictionary.

    Parameters
    ----------
    path : str or path-like
        The file to read.

    Returns
    -------
    dict
        The parsed document (tables are dicts).

    Raises
    ------
    DataFileError
        If the file cannot be read, is not UTF-8 text, or is not valid TOML; the message
        names the file.
    """
    name = os.fspath(path)
    try:
        raw = Path(path).read_bytes()
    except OSError as exc:
        reason = exc.strerror or str(exc)
        raise DataFileError(_one_line(f"{name}: cannot read the file ({reason})")) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise DataFileError(
            f"{name}: not a TOML file (not UTF-8 text at byte {exc.start})"
        ) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise DataFileError(_one_line(f"{name}: not a valid TOML file ({exc})")) from None


class ConfigTable:
    """One table of a configuration file, with typed getters whose errors name the key.

    Every getter raises :class:`DataFileError` with a one-line message
    ``"<file>: [<table>] <key>: <what is wrong>"``.

    Parameters
    ----------
    file : str
        The file name used in messages.
    name : str
        The table's key path, e.g. ``"motor"`` (shown as ``[motor]``).
    data : mapping
        The table's content as parsed by :func:`read_toml`.
    known_keys : iterable of str, optional
        If given, any other key is an error (catches typos such as ``Ls`` for ``L_s``).

    Examples
    --------
    >>> table = ConfigTable("motor.toml", "motor", {"L_s": 0.06}, known_keys=["L_s", "J"])
    >>> table.positive("L_s")
    0.06
    >>> "J" in table
    False
    """

    def __init__(
        self,
        file: str,
        name: str,
        data: Mapping[str, Any],
        known_keys: Iterable[str] | None = None,
    ) -> None:
        self.file = file
        self.name = name
        self.data: Mapping[str, Any] = MappingProxyType(dict(data))
        if known_keys is not None:
            self.check_keys(known_keys)

    def __contains__(self, key: object) -> bool:
        return key in self.data

    def error(self, key: str | None, message: str) -> DataFileError:
        """A :class:`DataFileError` about ``key`` (or the whole table if None)."""
        where = f"[{self.name}]" if key is None else f"[{self.name}] {key}"
        return DataFileError(_one_line(f"{self.file}: {where}: {message}"))

    def check_keys(self, known_keys: Iterable[str]) -> None:
        """Raise :class:`DataFileError` for the first key not in ``known_keys``."""
        known = list(known_keys)
        for key in self.data:
            if key not in known:
                listing = ", ".join(known) if known else "none"
                raise self.error(key, f"unknown key (known: {listing}{_suggestion(key, known)})")

    def _get(self, key: str, default: object) -> object:
        if key in self.data:
            return self.data[key]
        if default is None:
            raise self.error(key, "missing")
        return default

    def number(self, key: str, default: float | None = None) -> float:
        """A finite number; required unless ``default`` is given."""
        value = self._get(key, default)
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.error(key, f"must be a number, got {_type_name(value)}")
        number = float(value)
        if not math.isfinite(number):
            raise self.error(key, f"must be finite, got {value!r}")
        return number

    def positive(self, key: str, default: float | None = None) -> float:
        """A finite, strictly positive number; required unless ``default`` is given."""
        number = self.number(key, default)
        if number <= 0.0:
            raise self.error(key, f"must be positive, got {self.data.get(key, default)!r}")
        return number

    def positive_integer(self, key: str, default: int | None = None) -> int:
        """A whole number >= 1 (``2`` or ``2.0``); required unless ``default`` is given."""
        number = self.positive(key, None if default is None else float(default))
        if not number.is_integer():
            raise self.error(key, f"must be a whole number, got {self.data.get(key)!r}")
        return int(number)

    def matrix(
        self,
        key: str,
        shape: tuple[int | None, int | None],
        default: Array | None = None,
    ) -> Array:
        """A finite matrix written as an array of rows, e.g. ``[[1.0, 0.0], [0.0, 1.0]]``.

        Parameters
        ----------
        key : str
            The key in this table.
        shape : (rows, columns)
            The expected shape; None for a free dimension.
        default : ndarray, optional
            Returned (copied) if the key is absent; without it the key is required.
        """
        if key not in self.data and default is not None:
            return np.array(default, dtype=float)
        value = self._get(key, None)
        expected = "x".join("n" if size is None else str(size) for size in shape)
        if not isinstance(value, list) or not all(isinstance(row, list) for row in value):
            raise self.error(
                key, f"must be a {expected} matrix (an array of rows), got {_type_name(value)}"
            )
        for row in value:
            for entry in row:
                if isinstance(entry, bool) or not isinstance(entry, int | float):
                    raise self.error(key, f"entries must be numbers, found {_type_name(entry)}")
        lengths = {len(row) for row in value}
        if len(lengths) > 1:
            raise self.error(key, "rows have different lengths")
        columns = lengths.pop() if lengths else 0
        if any(
            size is not None and size != actual
            for size, actual in zip(shape, (len(value), columns), strict=True)
        ):
            raise self.error(key, f"must be a {expected} matrix, got {len(value)}x{columns}")
        matrix = np.array(value, dtype=float).reshape(len(value), columns)
        if not np.all(np.isfinite(matrix)):
            raise self.error(key, "contains NaN or infinite values")
        return matrix

    def positive_definite(self, key: str, size: int, default: Array | None = None) -> Array:
        """A ``size x size`` symmetric positive definite matrix (a weight of the cost)."""
        matrix = self.matrix(key, (size, size), default)
        tolerance = symmetric_tolerance(matrix)
        if np.max(np.abs(matrix - matrix.T), initial=0.0) > tolerance:
            raise self.error(key, "must be symmetric positive definite (it is not symmetric)")
        matrix = 0.5 * matrix + 0.5 * matrix.T  # halves first: no overflow near 1e308
        eigenvalues = np.linalg.eigvalsh(matrix) if size else np.ones(1)
        smallest, largest = float(np.min(eigenvalues)), float(np.max(eigenvalues))
        if not math.isfinite(smallest) or smallest <= 0.0:
            raise self.error(
                key, f"must be symmetric positive definite (smallest eigenvalue {smallest:.3g})"
            )
        if smallest <= tolerance:
            raise self.error(
                key,
                "must be symmetric positive definite; it is nearly singular"
                f" (eigenvalues from {smallest:.3g} to {largest:.3g})",
            )
        return matrix


class ConfigFile:
    """A parsed configuration file whose top level holds only known tables.

    Parameters
    ----------
    path : str or path-like
        The file to read (see :func:`read_toml`).
    tables : mapping of str to tuple of str
        The allowed tables and, for each, its allowed keys; an empty tuple means the
        table's keys are checked later, by whoever reads it.

    Raises
    ------
    DataFileError
        If the file cannot be read or parsed, or holds an unknown table or a top-level
        value that is not a table.
    """

    def __init__(self, path: str | os.PathLike[str], tables: Mapping[str, tuple[str, ...]]) -> None:
        self.path = Path(path)
        self.file = os.fspath(path)
        self.tables = dict(tables)
        self.data = read_toml(path)
        for key, value in self.data.items():
            known = ", ".join(f"[{name}]" for name in self.tables)
            if key not in self.tables and not isinstance(value, dict):
                raise DataFileError(
                    f"{self.file}: {key}: a key outside any table (tables: {known})"
                )
            if key not in self.tables:
                hint = _suggestion(key, self.tables)
                if hint:
                    hint = hint.replace("mean ", "mean [").replace("?", "]?")
                raise DataFileError(
                    _one_line(f"{self.file}: {key}: unknown table (known: {known}{hint})")
                )
            if not isinstance(value, dict):
                raise DataFileError(
                    f"{self.file}: {key}: must be a table [{key}], got {_type_name(value)}"
                )

    def __contains__(self, name: object) -> bool:
        return name in self.data

    def table(self, name: str, required: bool = False) -> ConfigTable:
        """The table ``name`` with its keys checked; an absent optional table is empty.

        Raises
        ------
        DataFileError
            If the table is required and absent, or holds an unknown key.
        """
        if name not in self.data and required:
            raise DataFileError(f"{self.file}: [{name}]: missing table")
        known = self.tables[name]
        return ConfigTable(self.file, name, self.data.get(name, {}), known or None)


@dataclass(frozen=True, eq=False)
class MotorConfig:
    """A motor, its operating point and the cost weights: the content of MOTOR.toml.

    Parameters
    ----------
    motor : SPMSM
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
    source : str
        Where the configuration came from (a file name, or ``"paper preset"``), for
        messages.

    Raises
    ------
    InputError
        Naming the field, if a value is not finite or Q, R are not 2x2 symmetric positive
        definite.
    """

    motor: SPMSM
    speed: float = PAPER_SPEED
    torque: float = PAPER_TORQUE
    Q: Array = field(default_factory=_paper_Q)
    R: Array = field(default_factory=_paper_R)
    learning: Mapping[str, Any] = field(default_factory=dict)
    source: str = "paper preset"

    def __post_init__(self) -> None:
        object.__setattr__(self, "speed", finite_float(self.speed, "speed"))
        object.__setattr__(self, "torque", finite_float(self.torque, "torque"))
        for name in ("Q", "R"):
            matrix = check_positive_definite(as_matrix(getattr(self, name), name, (2, 2)), name)
            matrix.setflags(write=False)
            object.__setattr__(self, name, matrix)
        object.__setattr__(self, "learning", MappingProxyType(dict(self.learning)))

    @classmethod
    def default(cls) -> MotorConfig:
        """The paper's setting: :meth:`SPMSM.paper`, 10 rad/s, 10 N m, ``Q = 1e3 I``, ``R = I``."""
        return cls(motor=SPMSM.paper())

    def regulation_problem(self) -> RegulationProblem:
        """The known-flux output-regulation problem at this operating point's speed."""
        return self.motor.regulation_problem(self.speed)

    def exogenous(self) -> Array:
        """``w = [p speed phi_pm, T*]`` at this operating point."""
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
    motor_table = config.table("motor", required=True)
    try:
        motor = SPMSM(
            R_s=motor_table.positive("R_s"),
            L_s=motor_table.positive("L_s"),
            phi_pm=motor_table.positive("phi_pm"),
            p=motor_table.positive_integer("p"),
            J=motor_table.positive("J") if "J" in motor_table else None,
        )
    except DataFileError:
        raise
    except InputError as exc:  # a rule of SPMSM not checked above: still name the file
        raise motor_table.error(None, str(exc)) from None
    operating_point = config.table("operating_point")
    cost = config.table("cost")
    learning = config.data.get("learning", {})
    return MotorConfig(
        motor=motor,
        speed=operating_point.number("speed", PAPER_SPEED),
        torque=operating_point.number("torque", PAPER_TORQUE),
        Q=cost.positive_definite("Q", 2, _paper_Q()),
        R=cost.positive_definite("R", 2, _paper_R()),
        learning=learning,
        source=config.file,
    )


#: The tables of a learning configuration (``selftune learn``) and their keys.
LEARN_TABLES: Mapping[str, tuple[str, ...]] = MappingProxyType(
    {
        "cost": ("Q", "R"),
        "policy": ("K0",),
        "regulation": ("C", "E", "F"),
        "learning": ("interval", "max_iterations", "tolerance"),
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

    @property
    def regulation(self) -> bool:
        """Whether the file asks for output regulation (has a [regulation] table)."""
        return self.C is not None


def load_learn_config(path: str | os.PathLike[str], n: int, m: int, q: int) -> LearnConfig:
    """Read a learning configuration for data with n states, m inputs and q exogenous signals.

    The format::

        [cost]
        Q = [[...]]           # n x n, symmetric positive definite
        R = [[...]]           # m x m, symmetric positive definite
        [policy]
        K0 = [[...]]          # m x n stabilizing gain that policy iteration starts from
        [regulation]          # optional: omit it to learn plain optimal state feedback
        C = [[...]]           # r x n
        E = [[...]]           # q x q (all zeros: w held over each sample)
        F = [[...]]           # r x q
        [learning]            # optional
        interval = 10         # samples per regression interval
        max_iterations = 50
        tolerance = 1e-9

    Raises
    ------
    DataFileError
        One line naming the file, the table and the key, for anything missing, unknown,
        of the wrong shape (the shapes follow from the data), or out of range.
    """
    config = ConfigFile(path, LEARN_TABLES)
    cost = config.table("cost", required=True)
    policy = config.table("policy", required=True)
    learning = config.table("learning")
    C = E = F = None
    if "regulation" in config:
        regulation = config.table("regulation")
        if q == 0:
            raise regulation.error(
                None, "the data have no exogenous signal w (no w columns) to regulate against"
            )
        C = regulation.matrix("C", (None, n))
        E = regulation.matrix("E", (q, q))
        F = regulation.matrix("F", (C.shape[0], q))
    tolerance = learning.positive("tolerance", 1e-9)
    return LearnConfig(
        Q=cost.positive_definite("Q", n),
        R=cost.positive_definite("R", m),
        K0=policy.matrix("K0", (m, n)),
        C=C,
        E=E,
        F=F,
        interval=learning.positive_integer("interval", 10),
        max_iterations=learning.positive_integer("max_iterations", 50),
        tolerance=tolerance,
        source=config.file,
    )


#: Keys of MOTOR.toml's optional [learning] table (``selftune tune``).
TUNING_KEYS = (
    "sampling",
    "episode_length",
    "K0",
    "exploration",
    "input_hold",
    "interval",
    "max_iterations",
)


def tuning_settings(config: MotorConfig, seed: int = 0) -> TuningSettings:
    """The self-tuning settings of a motor file: its operating point, cost and [learning].

    ``[learning]`` may set ``sampling`` (s), ``episode_length`` (s), ``K0`` (2x2, V/A),
    ``exploration`` (V), ``input_hold`` (samples per controller update), ``interval``
    (samples) and ``max_iterations``; absent keys take the paper's values
    (:class:`~selftune.torque.TuningSettings`), except ``input_hold``, 2: the controller
    at half the sampling rate, which lets the learner integrate the data to fourth order.

    Raises
    ------
    DataFileError
        Naming the file and the key, for an unknown key or a bad value.
    """
    from .torque import TuningSettings

    defaults = TuningSettings()
    table = ConfigTable(config.source, "learning", config.learning, TUNING_KEYS)
    try:
        return TuningSettings(
            speed=config.speed,
            torque=config.torque,
            Q=config.Q,
            R=config.R,
            sampling=table.positive("sampling", defaults.sampling),
            episode_length=table.positive("episode_length", defaults.episode_length),
            K0=table.matrix("K0", (2, 2), defaults.K0),
            exploration=table.positive("exploration", defaults.exploration),
            input_hold=table.positive_integer("input_hold", defaults.input_hold),
            interval=table.positive_integer("interval", defaults.interval),
            max_iterations=table.positive_integer("max_iterations", defaults.max_iterations),
            seed=seed,
        )
    except DataFileError:
        raise
    except InputError as exc:
        raise table.error(None, str(exc)) from None
