"""A log learned with a learning configuration: what ``selftune learn`` computes, and
what a fleet computes for each of its logs (:func:`learn_log`)."""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from ..core._numerics import check_numerics, numerics
from ..errors import DataFileError, InputError, Refusal
from ._learn_file import LEARN_TABLES, LearnConfig, load_learn_config
from ._log_table import load_log_format

if TYPE_CHECKING:
    from ..learn import LearnedController, LearningProblem, SpeedsLearned, Trajectory

__all__ = [
    "LearnedLog",
    "learn_log",
    "learn_over_speeds_with_config",
    "learn_with_config",
    "learning_problem",
    "load_learn_input",
]


@dataclass(frozen=True)
class LearnedLog:
    """A log, its configuration and the controller learned from it.

    Attributes
    ----------
    data : Trajectory
        The log as loaded.
    config : LearnConfig
        The configuration, checked against the log's dimensions.
    result : LearnedController
        The learned controller, with its quality (with a ``[schedule]``: the one learned
        at the log's highest speed).
    speeds : SpeedsLearned or None
        With a ``[schedule]``: the log learned speed by speed, the motor combined.
    """

    data: Trajectory
    config: LearnConfig
    result: LearnedController
    speeds: SpeedsLearned | None = None


def load_learn_input(
    data_path: str | os.PathLike[str],
    config_path: str | os.PathLike[str],
    overrides: Mapping[str, Mapping[str, object]] | None = None,
    overridden_by: str = "",
) -> tuple[Trajectory, LearnConfig]:
    """A log and its learning configuration, loaded as :func:`learn_log` loads them: the
    log's header (or the configuration's ``[log]`` table) gives n, m, q; the
    configuration is read and checked against them completely before the rows are
    loaded.

    Parameters
    ----------
    data_path, config_path, overrides, overridden_by
        As :func:`learn_log` takes them.

    Raises
    ------
    SelftuneError
        One line: the file or configuration that stopped it.
    """
    from pathlib import Path

    from ..learn import load_log, load_trajectory
    from ..learn.data._io import file_format_of, trajectory_dimensions

    name = os.fspath(data_path)
    file_format_of(Path(name))  # a file of no known type is said first, as the first argument
    log = load_log_format(config_path, LEARN_TABLES)  # None: selftune's own columns
    dimensions = trajectory_dimensions(name) if log is None else log.dimensions
    n, m, q = dimensions
    config = load_learn_config(config_path, n, m, q, overrides, overridden_by)
    data = load_trajectory(name) if log is None else load_log(name, log)
    return data, config


def learn_with_config(data: Trajectory, config: LearnConfig, source: str) -> LearnedController:
    """The learned controller for ``config`` on ``data``; any failure names ``source``.

    Parameters
    ----------
    data : Trajectory
        The log.
    config : LearnConfig
        What the learner knows and how it learns.
    source : str
        The log's name, for messages.

    Raises
    ------
    SelftuneError
        A refusal or a failure, its message naming ``source``; a value of the
        configuration the learner objects to names the configuration file, its table
        and key instead.
    """
    from ..learn import learn_controller

    return _learned(data, config, source, learn_controller)


def learn_over_speeds_with_config(
    data: Trajectory, config: LearnConfig, source: str
) -> SpeedsLearned:
    """:func:`selftune.learn.learn_over_speeds` of ``data`` for ``config`` (with a
    ``[schedule]``); failures said as :func:`learn_with_config` says them.

    Parameters
    ----------
    data : Trajectory
        The log, over several held speeds.
    config : LearnConfig
        What the learner knows and how it learns.
    source : str
        The log's name, for messages.
    """
    from ..learn import learn_over_speeds

    # each part is learned at its own speed: a stated electrical_speed is not needed
    own = {} if "electrical_speed" in config.options else {"electrical_speed": 1.0}
    return _learned(data, config, source, learn_over_speeds, own)


def _learned(
    data: Trajectory,
    config: LearnConfig,
    source: str,
    learner: Any,
    own: Mapping[str, object] | None = None,
) -> Any:
    """``learner(data, problem, K0, options)`` of ``config`` (``own``: options over the
    file's), a value of the configuration it objects to said against the file, its
    numbers checked."""
    from ..learn import LearningOptions

    problem = learning_problem(config)
    options = LearningOptions(
        interval=config.interval, max_iterations=config.max_iterations,
        tolerance=config.tolerance, **{**config.options, **(own or {})},  # type: ignore[arg-type]
    )  # fmt: skip
    mistake: DataFileError | None = None
    with numerics(source) as caught:
        try:
            result = learner(data, problem, config.K0, options)
        except InputError as exc:
            mistake = _against_config(exc, config.source)
            if mistake is None:
                raise
    if mistake is not None:
        raise mistake
    laws = [result] if hasattr(result, "P") else [law for _, law in result.parts]
    for law in laws:
        check_numerics(source, caught, law.P, law.K, law.U)
    return result


def learning_problem(config: LearnConfig) -> LearningProblem:
    """The learner's problem of ``config``: the regulation and the whole cost (Q, R and,
    with integral action, Q_i).

    Parameters
    ----------
    config : LearnConfig
        The configuration.
    """
    from ..learn import LearningProblem

    return LearningProblem(
        config.Q, config.R, C=config.C, E=config.E, F=config.F,
        integral_action=config.integral_action, integral_weight=config.Q_i,
    )  # fmt: skip


def _against_config(error: InputError, config_file: str) -> DataFileError | None:
    """The learner's objection to a configuration value (a key of CONFIG.toml, not a
    refusal of the data), said against the configuration file and its table; None for
    any other error."""
    key, _, reason = str(error).partition(": ")
    tables = [name for name, keys in LEARN_TABLES.items() if key in keys]
    if isinstance(error, Refusal) or not tables or not reason:
        return None
    return DataFileError(f"{config_file}: [{tables[0]}] {key}: {reason}")


def learn_log(
    data_path: str | os.PathLike[str],
    config_path: str | os.PathLike[str],
    overrides: Mapping[str, Mapping[str, object]] | None = None,
    overridden_by: str = "",
) -> LearnedLog:
    """``selftune learn``'s computation: the log's header (or the configuration's
    ``[log]`` table) gives n, m, q; the configuration is read and checked against them
    completely before the rows are loaded; then the controller is learned
    (:func:`learn_with_config`).

    Parameters
    ----------
    data_path : str or os.PathLike
        The CSV, NPZ or MAT log (in selftune's columns, or the ``[log]`` table's).
    config_path : str or os.PathLike
        CONFIG.toml.
    overrides : mapping of str to mapping, optional
        ``{table: {key: value}}`` over the configuration's values.
    overridden_by : str, optional
        Where the overrides come from, for messages.

    Raises
    ------
    SelftuneError
        One line: the file, configuration or refusal that stopped it.
    """
    name = os.fspath(data_path)
    data, config = load_learn_input(name, config_path, overrides, overridden_by)
    if config.schedule is None:
        return LearnedLog(data, config, learn_with_config(data, config, name))
    speeds = learn_over_speeds_with_config(data, config, name)
    return LearnedLog(data, config, speeds.top[1], speeds)
