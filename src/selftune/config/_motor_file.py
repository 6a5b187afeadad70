"""The motor file, MOTOR.toml, read by :func:`load_motor_config`::

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

import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

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
from ..errors import DataFileError, InputError
from ..model import SPMSM, RegulationProblem
from ._toml import ConfigFile

__all__ = ["MOTOR_TABLES", "MotorConfig", "load_motor_config"]

#: The tables of MOTOR.toml and the keys each may hold (``learning`` is checked later).
MOTOR_TABLES: Mapping[str, tuple[str, ...]] = MappingProxyType(
    {
        "motor": ("R_s", "L_s", "phi_pm", "p", "J"),
        "operating_point": ("speed", "torque"),
        "cost": ("Q", "R"),
        "learning": (),
    }
)


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
    Q: Array = field(default_factory=paper_Q)
    R: Array = field(default_factory=paper_R)
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
        Q=cost.positive_definite("Q", 2, paper_Q()),
        R=cost.positive_definite("R", 2, paper_R()),
        learning=learning,
        source=config.file,
    )
