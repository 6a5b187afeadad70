"""The ADP learner's sliding window: the last stretch of the log a look learns from."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ...core import Array, ControlLaw
from .._problem import LearningProblem

if TYPE_CHECKING:
    from ._settings import OnlineSettings

__all__ = ["LogWindow"]


class LogWindow:
    """The last ``rows`` rows of the log (:attr:`~._settings.OnlineSettings.adp_window`),
    kept as ``[x, u commanded, w, angle]`` chunks: memory independent of the run's length.

    Parameters
    ----------
    rows : int
        The rows kept (at least; whole chunks are dropped).
    """

    def __init__(self, rows: int) -> None:
        self.rows = rows
        self._chunks: list[Array] = []

    def add(self, x: Array, u: Array, w: Array, angle: Array | None) -> None:
        """Add a chunk's rows, dropping the chunks that fall out."""
        angles = np.zeros(x.shape[0]) if angle is None else angle
        self._chunks.append(np.column_stack([x, u, w, angles]))
        while sum(part.shape[0] for part in self._chunks[1:]) >= self.rows:
            self._chunks.pop(0)

    def learned(self, settings: OnlineSettings, problem: LearningProblem, K_x: Array) -> ControlLaw:
        """The paper's ADP (the digital target) on the window, from the feedback ``K_x``
        (the law in force's): model-free; ``problem`` holds the torque reference's
        current for the estimated flux."""
        from .._pipeline import learn_controller  # the pipeline imports this package
        from .._problem import LearningOptions
        from ..data._trajectory import Trajectory

        rows = np.concatenate(self._chunks)
        n, m, q = problem.n, problem.m, problem.q
        x, u, w = rows[:, :n], rows[:, n : n + m], rows[:, n + m : n + m + q]
        log = Trajectory(
            settings.h * np.arange(rows.shape[0]), x, u[:-1], w,
            angle=rows[:, -1] if settings.dead_time else None,
        )  # fmt: skip
        options = LearningOptions(
            target="digital", method="adp", input_delay=settings.input_delay,
            logged_input="commanded", dead_time=settings.dead_time,
            electrical_speed=settings.electrical_speed, voltage_hold=settings.hold,
        )  # fmt: skip
        return learn_controller(log, problem, K_x, options).law
