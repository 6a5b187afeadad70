"""``selftune learn`` of several logs: a saturating motor's current levels, its law
scheduled over the q-axis current reference.

Each log holds the drive at one load: the current references ``w = [w_1, i_d*, i_q*]``
about a level (with steps or exploration about it, as ``selftune tune``'s levels do,
:func:`selftune.tuning._saturation.level_log`), at the configuration's
``electrical_speed``. Each is learned as ``selftune learn`` learns one log, with
``[learning] structure = "incremental"`` (R_s, the incremental inductances and the flux
offset at the log's operating current; a log refused stops the command, naming it). A
level is the log's mean ``i_q*`` (A, the variable the firmware looks up); the law is
designed on each level's identified model and scheduled over ``i_q*`` with the check of
``selftune tune``'s saturating motor
(:func:`~selftune.tuning._saturation.schedule_over_levels`). Where two neighbouring
levels' inductances differ by more than
:data:`~selftune.tuning._saturation.INDUCTANCE_MOVE` of the larger one, ``tune`` would
learn a level between them; from logs it cannot, and it says so, naming the currents
between which a log would help.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from itertools import pairwise
from typing import TYPE_CHECKING, Any

import numpy as np

from ..config import (
    LEARN_TABLES,
    LearnConfig,
    learn_with_config,
    learning_problem,
    load_learn_input,
    load_log_format,
    read_toml,
)
from ..core import Array, cost_document
from ..core._numerics import check_numerics, numerics
from ..errors import DataFileError
from ..learn import IncrementalStructure, LearnedController, LogFormat, Trajectory
from ..learn.evidence._alignment import SAMPLING_JITTER
from ..model import CurrentScheduleDesign
from ..report._saturation_report import (
    check_entry,
    current_schedule_figure,
    level_document,
    level_table,
    schedule_check_lines,
)
from ..tuning._curvature import precise_levels, with_curvature
from ..tuning._interior import CURRENT_REFERENCE_F
from ..tuning._resistance import kept_levels
from ..tuning._saturation import (
    INDUCTANCE_MOVE,
    incremental_parameters,
    inductances_move,
    schedule_over_levels,
)

if TYPE_CHECKING:  # matplotlib is loaded only to draw
    from matplotlib.figure import Figure

__all__ = ["LearnedLevel", "LearnedLevels", "learn_levels"]

#: Two logs whose mean ``i_q*`` differ by at most this share of the larger are at one
#: level: a schedule's grid needs its currents apart (two laws 1 % apart in current
#: would make its interpolation between them as steep as their models' noise).
SAME_LEVEL = 0.01

#: Two logs whose mean ``w_1`` differ by more than this share disagree on the flux the
#: reference channel assumes (``w_1 / w_e``), or were logged at other speeds: the
#: schedule feeds ``w_1`` forward for one. 0.1 %: the back-EMF's feedforward is then off
#: by at most that much, which the integral action removes; a ``w_1`` computed from a
#: measured speed varies by less over a log's mean.
SAME_FLUX = 1e-3


@dataclass(frozen=True)
class LearnedLevel:
    """One log learned at its current level.

    Attributes
    ----------
    source : str
        The log's file name.
    reference : ndarray, shape (2,)
        The log's mean ``[i_d*, i_q*]``, A (``i_q*``: the level).
    mean_current : ndarray, shape (2,)
        The log's mean measured ``[i_d, i_q]``, A (the operating current).
    theta, standard_errors : ndarray, shape (6,)
        ``[R_s, L_dd, L_qq, L_dq, kappa, kappa_q]`` identified and their standard errors
        (:func:`~selftune.tuning._saturation.incremental_parameters`).
    learned : LearnedController
        The law learned on the log, with its verdict.
    current_spread : ndarray, shape (2,)
        The log's standard deviation of ``[i_d, i_q]``, A.
    curvature_errors : ndarray, shape (3,)
        The part of the inductances' standard errors that is their curvature over the
        log's currents, H (:func:`~selftune.tuning._curvature.curvature_errors`).
    """

    source: str
    reference: Array
    mean_current: Array
    theta: Array
    standard_errors: Array
    learned: LearnedController
    current_spread: Array
    curvature_errors: Array = field(default_factory=lambda: np.zeros(3))


@dataclass(frozen=True, eq=False)
class LearnedLevels:
    """Several logs learned as a saturating motor's current levels, and the schedule.

    Attributes
    ----------
    config : LearnConfig
        The learning configuration.
    levels : tuple of LearnedLevel
        By rising ``|i_q*|`` (the last, the highest load, is the law reported; a negative
        torque's levels are scheduled in rising ``i_q*``).
    top_data : Trajectory
        The highest level's log (whose law ``selftune learn`` reports in full).
    design : CurrentScheduleDesign
        The schedule over ``i_q*`` and its check.
    integral_weight : ndarray or None
        ``Q_i`` of the learner and the design (None without integral action).
    flux : float
        The flux the first log's ``w_1`` assumes, ``w_1 / w_e``, Wb (the others' within
        :data:`SAME_FLUX`; each level's ``kappa`` is over its own).
    left_out : tuple of LearnedLevel
        Logs learned but left out of the schedule: their R_s disagrees with the highest
        level's (:func:`~selftune.tuning._resistance.misled_levels`), or their inductances
        are too imprecise (:func:`~selftune.tuning._curvature.precise_levels`).
    left_out_text : str
        Why ("" when none were).
    """

    config: LearnConfig
    levels: tuple[LearnedLevel, ...]
    top_data: Trajectory
    design: CurrentScheduleDesign
    integral_weight: Array | None
    flux: float
    left_out: tuple[LearnedLevel, ...] = ()
    left_out_text: str = ""

    @property
    def top(self) -> LearnedLevel:
        """The highest level."""
        return self.levels[-1]

    @property
    def gaps(self) -> list[tuple[float, float]]:
        """The neighbouring levels' ``i_q*`` (A) between which the identified inductances
        move by more than :data:`~selftune.tuning._saturation.INDUCTANCE_MOVE`."""
        return [
            (float(low.reference[1]), float(high.reference[1]))
            for low, high in pairwise(self.levels)
            if inductances_move(low.theta, high.theta)
        ]

    def lines(self) -> list[str]:
        """What ``selftune learn`` prints of the levels and the schedule."""
        speed = self.config.options["electrical_speed"]
        lines = [
            "",
            f"Saturating PM motor learned at {len(self.levels)} current levels with the "
            f"incremental structure at omega_e = {speed:g} rad/s; the law above is the one "
            "at the highest",
            *level_table("log", [level.source for level in self.levels], self.levels),
            *schedule_check_lines(self.design),
            *([f"  note: logs {self.left_out_text}"] if self.left_out else []),
        ]
        for low, high in self.gaps:
            lines.append(
                f"  the inductances move by more than {INDUCTANCE_MOVE:.0%} between i_q* = "
                f"{low:.4g} and {high:.4g} A: the schedule interpolates the motor there; a "
                f"log at a level between them (about {0.5 * (low + high):.4g} A) would "
                "learn it"
            )
        return lines

    def figure(self) -> Figure:
        """The schedule's figure (:func:`selftune.report.figure_schedule`) beside the law
        learned at the highest level."""
        return current_schedule_figure(
            self.design, self.top.learned.law, float(self.top.reference[1]),
            "one law (the highest level)",
        )  # fmt: skip

    @property
    def document(self) -> dict[str, Any]:
        """The JSON keys ``current_schedule`` (the tables,
        :meth:`~selftune.model.CurrentSchedule.document`) and ``current_schedule_design``:
        each level's identified model with its log and verdict, and everything the design
        needs to be recomputed from the file (speed, period, delay, hold, cost, flux)."""
        top = self.top.learned
        assert top.h is not None  # identify-then-design reads h off the log
        return {
            "current_schedule": self.design.schedule.document(),
            "current_schedule_design": {
                "levels": [_entry(level) for level in self.levels],
                "left_out": [_entry(level) for level in self.left_out],
                "left_out_reason": self.left_out_text,
                "electrical_speed": self.config.options["electrical_speed"],
                "h": top.h,
                "input_delay": top.law.history,
                "hold": self.config.options["voltage_hold"],
                "cost": cost_document(self.config.Q, self.config.R, self.integral_weight),
                "flux": self.flux,
                "inductance_move": INDUCTANCE_MOVE,
                "gaps": [list(gap) for gap in self.gaps],
                "check": check_entry(self.design),
            },
        }


def _entry(level: LearnedLevel) -> dict[str, Any]:
    """A level's entry in ``current_schedule_design``: its log and
    :func:`~selftune.report._saturation_report.level_document`'s."""
    return {
        "source": level.source,
        **level_document(
            level.reference,
            level.mean_current,
            level.theta,
            level.standard_errors,
            level.learned,
            level.current_spread,
            level.curvature_errors,
        ),
    }


def _checked_config(config: LearnConfig) -> None:
    """Refuse a configuration that cannot learn a current schedule from several logs: the
    incremental structure, the digital target, the current-reference form and a turning
    speed are needed."""
    options = config.options
    structure = options.get("structure", "none")
    if structure != "incremental":
        raise DataFileError(
            f"{config.source}: [learning] structure: several logs are learned as a "
            'saturating motor\'s current levels, which needs structure = "incremental" '
            f'(got "{structure}"); or give one log'
        )
    if options.get("target") != "digital":
        raise DataFileError(
            f"{config.source}: [learning] target: the current schedule is the digital "
            'optimum of the sampled loop with its delay; set target = "digital"'
        )
    form = {"C": (config.C, np.eye(2)), "E": (config.E, np.zeros((3, 3))),
            "F": (config.F, CURRENT_REFERENCE_F)}  # fmt: skip
    for key, (given, expected) in form.items():
        if given is None or given.shape != expected.shape or not np.allclose(given, expected):
            raise DataFileError(
                f"{config.source}: [regulation] {key}: the current schedule is for the "
                "current-reference form (w = [p speed phi, i_d*, i_q*], C = I, E = 0, F = "
                "[[0, -1, 0], [0, 0, -1]]), the form the firmware's i_q* = w3 is looked up in"
            )
    if not options.get("electrical_speed"):
        raise DataFileError(
            f"{config.source}: [learning] electrical_speed: the levels are learned at a "
            "turning speed (the flux offset is read off the back-EMF); 0 gives none"
        )


@dataclass(frozen=True)
class _Columns:
    """The user's names of the time and reference columns (selftune's ``t``, ``w1``,
    ``w3``, or the ``[log]`` table's)."""

    time: str = "t"
    w1: str = "w1"
    w3: str = "w3"

    @classmethod
    def of(cls, log: LogFormat | None) -> _Columns:
        """The names a log format gives (None: selftune's own columns)."""
        if log is None:
            return cls()
        names = {column.key: column.column or column.key for column in log.references}
        time = log.time.column or log.time.key
        return cls(time, names.get("w1", "w1"), names.get("w3", "w3"))


def _level_of(data: Trajectory, speed: float, source: str) -> tuple[Array, float]:
    """A log's mean ``[i_d*, i_q*]`` (A) and mean ``w_1`` (V)."""
    if data.w is None or data.w.shape[1] != 3:
        raise DataFileError(
            f"{source}: a current level's log has the current-reference form's three "
            "reference columns, w1 (p speed phi), w2 (i_d*) and w3 (i_q*)"
        )
    return np.mean(data.w[:, 1:3], axis=0), float(np.mean(data.w[:, 0]))


def _checked_logs(
    loaded: Sequence[tuple[str, Trajectory]], speed: float, columns: _Columns
) -> float:
    """Refuse logs that are not one drive's levels: other sampling periods, other
    ``w_1``, one level twice; the flux ``w_1`` assumes (Wb)."""
    first_path, first = loaded[0]
    period = float(np.mean(np.diff(first.t)))
    _, first_w1 = _level_of(first, speed, first_path)
    seen: list[tuple[str, float]] = []
    for path, data in loaded:
        own = float(np.mean(np.diff(data.t)))
        if abs(own - period) > SAMPLING_JITTER * period:
            raise DataFileError(
                f"{path}: {columns.time}: sampled every {own:.6g} s, {first_path} every "
                f"{period:.6g} s: one schedule is for one sampling period"
            )
        reference, w1 = _level_of(data, speed, path)
        if abs(w1 - first_w1) > SAME_FLUX * abs(first_w1):
            raise DataFileError(
                f"{path}: {columns.w1}: its mean is {w1:.6g}, {first_path}'s {first_w1:.6g} "
                f"({abs(w1 / first_w1 - 1.0):.2%} apart): the logs assume other fluxes or run "
                "at other speeds, and the schedule feeds w1 forward for one; log every level "
                "at the configuration's speed with one assumed flux"
            )
        for other, current in seen:
            if abs(reference[1] - current) <= SAME_LEVEL * max(abs(current), abs(reference[1])):
                raise DataFileError(
                    f"{path}: {columns.w3}: its mean i_q* reference ({reference[1]:.6g} A) is "
                    f"within {SAME_LEVEL:.0%} of {other}'s ({current:.6g} A): each log is a "
                    "level of its own current"
                )
        seen.append((path, float(reference[1])))
    return first_w1 / speed


def _loaded(
    data_paths: Sequence[str], config_path: str
) -> tuple[list[tuple[str, Trajectory]], LearnConfig, _Columns]:
    """Every log and the configuration, read and checked before any is learned."""
    from pathlib import Path

    from ..learn.data._io import file_format_of, trajectory_dimensions

    if "schedule" in read_toml(config_path):
        raise DataFileError(
            f"{config_path}: [schedule]: a speed schedule is learned from one log over "
            "several held speeds, several logs are a current schedule's levels; give one "
            "log, or leave out [schedule]"
        )
    for index, path in enumerate(data_paths):
        for other in data_paths[:index]:
            if Path(path).exists() and Path(other).exists() and Path(path).samefile(other):
                raise DataFileError(f"{path}: given twice (as {other}): each log is a level")
    log = load_log_format(config_path, LEARN_TABLES)
    if log is None:  # each file's own header gives its columns
        dimensions = []
        for path in data_paths:
            file_format_of(Path(path))
            dimensions.append(trajectory_dimensions(path))
        for path, found in zip(data_paths, dimensions, strict=True):
            if found != dimensions[0]:
                raise DataFileError(
                    f"{path}: its columns are n, m, q = {found} (x, u, w), {data_paths[0]}'s "
                    f"{dimensions[0]}: the levels are logs of one drive in one form"
                )
    loaded = [(path, *load_learn_input(path, config_path)) for path in data_paths]
    config = loaded[0][2]
    _checked_config(config)
    return [(path, data) for path, data, _ in loaded], config, _Columns.of(log)


def learn_levels(
    data_paths: Sequence[str], config_path: str, progress: bool = True
) -> LearnedLevels:
    """Several logs learned as a saturating motor's current levels and its law scheduled
    over ``i_q*`` (see the module docstring).

    Every log and the configuration are read and checked before any is learned.

    Parameters
    ----------
    data_paths : sequence of str
        The logs (CSV, NPZ or MAT, as ``selftune learn`` reads one), two or more.
    config_path : str
        CONFIG.toml, with ``[learning] method = "identify"``, ``structure =
        "incremental"`` and ``electrical_speed``.
    progress : bool
        Show a progress bar over the logs on standard error (when it is a terminal).

    Raises
    ------
    SelftuneError
        One line naming the file and its key or column: a configuration that cannot learn
        levels (not the incremental structure, the digital target, the current-reference
        form and a turning speed; a ``[schedule]``), a log given twice, logs of other
        columns, sampling periods or ``w_1``, two logs at one level, a log refused.
    """
    from tqdm import tqdm

    loaded, config, columns = _loaded(data_paths, config_path)
    speed = float(config.options["electrical_speed"])  # type: ignore[arg-type]
    flux = _checked_logs(loaded, speed, columns)
    # a level whose R_s is far from the nameplate's is left out, not the whole schedule
    nameplate = config.options.get("nameplate_resistance")
    each = replace(config, options={
        key: value for key, value in config.options.items() if key != "nameplate_resistance"
    })  # fmt: skip
    levels = []
    for path, data in tqdm(
        loaded, desc="current levels", unit=" log", file=sys.stderr,
        disable=None if progress else True, leave=False,
    ):  # fmt: skip
        learned = learn_with_config(data, each, path)
        reference, w1 = _level_of(data, speed, path)
        theta, errors = incremental_parameters(learned, w1 / speed)  # the fit's own kappa
        mean, spread = np.mean(data.x, axis=0), np.std(data.x, axis=0)
        levels.append(LearnedLevel(path, reference, mean, theta, errors, learned, spread))
    order = np.argsort([abs(level.reference[1]) for level in levels])
    learned_levels = [levels[index] for index in order]
    names = [level.source for level in learned_levels]
    thetas = np.array([level.theta for level in learned_levels])
    errors = np.array([level.standard_errors for level in learned_levels])
    h = learned_levels[0].learned.h
    assert h is not None  # identify-then-design reads h off the log
    stated = float(nameplate) if isinstance(nameplate, int | float) else None
    kept, left_out = kept_levels(names, thetas, errors, stated, h)
    found, imprecise, loose = precise_levels(
        with_curvature([learned_levels[k] for k in kept]), [names[k] for k in kept]
    )
    left_out = "; ".join(text for text in (left_out, loose) if text)
    problem = learning_problem(config)
    integral_weight = problem.integral_weight if config.integral_action else None
    top = found[-1].learned
    assert top.h is not None  # identify-then-design reads h off the log
    structure = IncrementalStructure(speed, top.h, False, config.options["voltage_hold"])  # type: ignore[arg-type]
    with numerics(config.source) as caught:
        design = schedule_over_levels(
            np.array([level.reference[1] for level in found]),
            np.array([level.theta for level in found]),
            structure, config.Q, config.R,
            input_delay=top.law.history, integral_weight=integral_weight,
        )  # fmt: skip
    check_numerics(config.source, caught, design.schedule.table("K"))
    top_data = next(data for path, data in loaded if path == found[-1].source)
    return LearnedLevels(
        config, found, top_data, design, integral_weight, flux,
        tuple(level for k, level in enumerate(learned_levels) if k not in kept) + imprecise,
        left_out,
    )  # fmt: skip
