"""Configuration files: reading TOML with one-line errors, MOTOR.toml and CONFIG.toml.

- :func:`read_toml`, :class:`ConfigFile`, :class:`ConfigTable`: the generic reader whose
  every error names the file, the table and the key (:mod:`._toml`);
- :func:`load_motor_config` -> :class:`MotorConfig`: the motor, its operating point and
  the cost weights (:mod:`._motor_file`);
- :func:`load_learn_config` -> :class:`LearnConfig`: what ``selftune learn`` needs
  besides the data (:mod:`._learn_file`).
"""

from __future__ import annotations

from ._learn_file import LEARN_TABLES, LearnConfig, load_learn_config
from ._motor_file import MOTOR_TABLES, MotorConfig, load_motor_config
from ._toml import RENAMED_KEYS, ConfigFile, ConfigTable, read_toml

__all__ = [
    "LEARN_TABLES",
    "MOTOR_TABLES",
    "RENAMED_KEYS",
    "ConfigFile",
    "ConfigTable",
    "LearnConfig",
    "MotorConfig",
    "load_learn_config",
    "load_motor_config",
    "read_toml",
]
