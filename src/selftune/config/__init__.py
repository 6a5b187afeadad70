"""Configuration files: reading TOML with one-line errors, MOTOR.toml and CONFIG.toml.

- :func:`read_toml`, :class:`ConfigFile`, :class:`ConfigTable`: the generic reader whose
  every error names the file, the table and the key (:mod:`._toml`);
- :func:`load_motor_config` -> :class:`MotorConfig`: the motor, its operating point and
  the cost weights (:mod:`._motor_file`);
- :func:`load_learn_config` -> :class:`LearnConfig`: what ``selftune learn`` needs
  besides the data (:mod:`._learn_file`), and :func:`load_log_format` -> the
  :class:`~selftune.learn.LogFormat` of its optional ``[log]`` table: a log in the
  drive's own columns, units and frame (:mod:`._log_table`);
  :func:`learn_log` -> :class:`LearnedLog`: a
  log learned with it, as ``selftune learn`` and ``selftune fleet`` do, and
  :func:`load_learn_input`: the log and the configuration checked against it, before
  learning (:mod:`._learn_run`);
- :class:`ScheduleConfig`: MOTOR.toml's ``[schedule]`` speeds (:mod:`._schedule_file`);
- :func:`load_online_config` -> :class:`OnlineConfig`: an online run's duration and the
  profile of the motor's R_s, L_s and phi_pm over time (:mod:`._online_file`);
- :func:`load_control_law` -> :class:`~selftune.core.ControlLaw`: the controller a JSON
  result names; :func:`load_law_result` -> :class:`LawResult`: with what the file says of
  its drive (:mod:`._law_file`).
"""

from __future__ import annotations

from ._law_file import LawResult, load_control_law, load_law_result
from ._learn_file import LEARN_TABLES, LearnConfig, load_learn_config
from ._learn_run import (
    LearnedLog,
    learn_log,
    learn_with_config,
    learning_problem,
    load_learn_input,
)
from ._log_table import LOG_KEYS, load_log_format
from ._motor_file import MOTOR_TABLES, MotorConfig, load_motor_config
from ._online_file import ONLINE_TABLES, PROFILE_KEYS, OnlineConfig, load_online_config
from ._schedule_file import SCHEDULE_KEYS, ScheduleConfig
from ._toml import RENAMED_KEYS, ConfigFile, ConfigTable, read_toml

__all__ = [
    "LEARN_TABLES",
    "LOG_KEYS",
    "MOTOR_TABLES",
    "ONLINE_TABLES",
    "PROFILE_KEYS",
    "RENAMED_KEYS",
    "SCHEDULE_KEYS",
    "ConfigFile",
    "ConfigTable",
    "LawResult",
    "LearnConfig",
    "LearnedLog",
    "MotorConfig",
    "OnlineConfig",
    "ScheduleConfig",
    "learn_log",
    "learn_with_config",
    "learning_problem",
    "load_control_law",
    "load_law_result",
    "load_learn_config",
    "load_learn_input",
    "load_log_format",
    "load_motor_config",
    "load_online_config",
    "read_toml",
]
