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
from dataclasses import dataclass
from itertools import pairwise
from typing import TYPE_CHECKING, Any

import numpy as np

from ..config import LearnConfig, learn_with_config, learning_problem, load_learn_input
from ..core import Array, cost_document
from ..errors import DataFileError
from ..learn import IncrementalStructure, LearnedController, Trajectory
from ..model import CurrentScheduleDesign
from ..report._saturation_report import level_document, level_table, schedule_check_lines
from ..tuning._saturation import (
    INDUCTANCE_MOVE,
    incremental_parameters,
    inductances_move,
    schedule_over_levels,
)

if TYPE_CHECKING:  # matplotlib is loaded only to draw
    from matplotlib.figure import Figure

__all__ = ["LearnedLevel", "LearnedLevels", "learn_levels"]

#: Two logs whose mean ``i_q*`` differ by less than this share of the largest are at one
#: level (a schedule needs its currents apart).
SAME_LEVEL = 1e-6

#: Two logs' assumed fluxes (``w_1 / w_e``) that differ by more than this share disagree:
#: the schedule's feedforward of ``w_1`` is for one.
SAME_FLUX = 1e-6


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
    """

    source: str
    reference: Array
    mean_current: Array
    theta: Array
    standard_errors: Array
    learned: LearnedController


@dataclass(frozen=True, eq=False)
class LearnedLevels:
    """Several logs learned as a saturating motor's current levels, and the schedule.

    Attributes
    ----------
    config : LearnConfig
        The learning configuration.
    levels : tuple of LearnedLevel
        By rising ``i_q*``.
    top_data : Trajectory
        The highest level's log (whose law ``selftune learn`` reports in full).
    design : CurrentScheduleDesign
        The schedule over ``i_q*`` and its check.
    integral_weight : ndarray or None
        ``Q_i`` of the learner and the design (None without integral action).
    flux : float
        The flux the logs' ``w_1`` assumes, ``w_1 / w_e``, Wb.
    """

    config: LearnConfig
    levels: tuple[LearnedLevel, ...]
    top_data: Trajectory
    design: CurrentScheduleDesign
    integral_weight: Array | None
    flux: float

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
            *level_table(
                "log",
                [
                    (level.source, level.reference, level.theta, level.standard_errors)
                    for level in self.levels
                ],
            ),
            *schedule_check_lines(self.design),
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
        from ..model import excess_over
        from ..report import figure_schedule

        single = excess_over(self.design.check.optima, self.top.learned.law)
        return figure_schedule(self.design, single, float(self.top.reference[1]))

    @property
    def document(self) -> dict[str, Any]:
        """The JSON keys ``current_schedule`` (the tables,
        :meth:`~selftune.model.CurrentSchedule.document`) and ``current_schedule_design``:
        each level's identified model with its log and verdict, and everything the design
        needs to be recomputed from the file (speed, period, delay, hold, cost, flux)."""
        check = self.design.check
        top = self.top.learned
        assert top.h is not None  # identify-then-design reads h off the log
        return {
            "current_schedule": self.design.schedule.document(),
            "current_schedule_design": {
                "levels": [
                    {
                        "source": level.source,
                        **level_document(
                            level.reference,
                            level.mean_current,
                            level.theta,
                            level.standard_errors,
                            level.learned,
                        ),
                    }
                    for level in self.levels
                ],
                "electrical_speed": self.config.options["electrical_speed"],
                "h": top.h,
                "input_delay": top.law.history,
                "hold": self.config.options["voltage_hold"],
                "cost": cost_document(self.config.Q, self.config.R, self.integral_weight),
                "flux": self.flux,
                "inductance_move": INDUCTANCE_MOVE,
                "gaps": [list(gap) for gap in self.gaps],
                "check": {"i_q": check.points, "excess": check.excess, "limit": check.limit},
            },
        }


def _checked_config(config: LearnConfig) -> None:
    """Refuse a configuration that cannot learn a current schedule from several logs."""
    structure = config.options.get("structure", "none")
    if structure != "incremental":
        raise DataFileError(
            f"{config.source}: [learning] structure: several logs are learned as a saturating "
            f'motor\'s current levels, which needs structure = "incremental" (got '
            f'"{structure}"); or give one log'
        )
    if config.schedule is not None:
        raise DataFileError(
            f"{config.source}: [schedule]: a speed schedule is learned from one log over "
            "several held speeds, several logs are a current schedule's levels; give one "
            "log, or leave out [schedule]"
        )


def _level_of(data: Trajectory, speed: float, source: str) -> tuple[Array, float]:
    """A log's mean ``[i_d*, i_q*]`` (A) and the flux its ``w_1`` assumes (Wb)."""
    if data.w is None or data.w.shape[1] < 3:
        raise DataFileError(
            f"{source}: a current level's log has the current-reference form's columns "
            "w1 (p speed phi), w2 (i_d*) and w3 (i_q*)"
        )
    return np.mean(data.w[:, 1:3], axis=0), float(np.mean(data.w[:, 0])) / speed


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
        One line naming the file: a configuration that cannot learn levels, two logs at
        one level, logs of different sampling periods or assumed fluxes, a log refused.
    """
    from tqdm import tqdm

    loaded = [(path, *load_learn_input(path, config_path)) for path in data_paths]
    config = loaded[0][2]
    _checked_config(config)
    speed = float(config.options["electrical_speed"])  # type: ignore[arg-type]
    first_path, first_data, _ = loaded[0]
    period = float(np.median(np.diff(first_data.t)))
    seen: list[tuple[str, float]] = []
    _, flux = _level_of(first_data, speed, first_path)
    for path, data, _ in loaded:
        own = float(np.median(np.diff(data.t)))
        if abs(own - period) > 1e-9 * period:
            raise DataFileError(
                f"{path}: t: sampled every {own:.6g} s, {first_path} every {period:.6g} s: "
                "one schedule is for one sampling period"
            )
        reference, assumed = _level_of(data, speed, path)
        if abs(assumed - flux) > SAME_FLUX * abs(flux):
            raise DataFileError(
                f"{path}: w1: assumes a flux of {assumed:.6g} Wb (w1 / electrical_speed), "
                f"{first_path} {flux:.6g} Wb: the schedule feeds w1 forward for one flux; "
                "log every level with the same w1"
            )
        for other, current in seen:
            if abs(reference[1] - current) <= SAME_LEVEL * max(abs(current), 1.0):
                raise DataFileError(
                    f"{path}: w3: its mean i_q* reference ({current:.6g} A) is that of "
                    f"{other}: each log is a level of its own current"
                )
        seen.append((path, float(reference[1])))
    levels = []
    for path, data, _ in tqdm(
        loaded, desc="current levels", unit=" log", file=sys.stderr,
        disable=None if progress else True, leave=False,
    ):  # fmt: skip
        learned = learn_with_config(data, config, path)
        theta, errors = incremental_parameters(learned, flux)
        reference, _ = _level_of(data, speed, path)
        levels.append(
            LearnedLevel(path, reference, np.mean(data.x, axis=0), theta, errors, learned)
        )
    order = np.argsort([level.reference[1] for level in levels])
    found = tuple(levels[index] for index in order)
    problem = learning_problem(config)
    integral_weight = problem.integral_weight if config.integral_action else None
    top = found[-1].learned
    assert top.h is not None  # identify-then-design reads h off the log
    structure = IncrementalStructure(speed, top.h, False, config.options["voltage_hold"])  # type: ignore[arg-type]
    design = schedule_over_levels(
        np.array([level.reference[1] for level in found]),
        np.array([level.theta for level in found]),
        structure, config.Q, config.R,
        input_delay=top.law.history, integral_weight=integral_weight,
    )  # fmt: skip
    top_data = next(data for path, data, _ in loaded if path == found[-1].source)
    return LearnedLevels(config, found, top_data, design, integral_weight, flux)
