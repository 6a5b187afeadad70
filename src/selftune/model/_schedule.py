"""A control law scheduled over speed: the gain tables a drive interpolates.

A firmware stores the law at a grid of electrical speeds ``omega_e = p speed`` and
interpolates ``K``, ``K_i``, ``U`` and ``X`` entrywise, linearly between the two
neighbours of the speed it runs at (:meth:`SpeedSchedule.law_at`); it refuses a speed
outside the grid (a firmware clamps there instead: :mod:`selftune.report._firmware`).
The design of such a schedule is :func:`~selftune.model.design_schedule`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from ..core import Array, ControlLaw, finite_float
from ..errors import InputError

__all__ = ["SpeedSchedule"]


def _same(laws: Sequence[ControlLaw]) -> None:
    """Raise unless the laws share their structure, C, F and h (only gains may vary)."""
    first = laws[0]
    for index, law in enumerate(laws[1:], start=1):
        shape = (law.n, law.m, law.q, law.r, law.history)
        if shape != (first.n, first.m, first.q, first.r, first.history):
            raise InputError(
                f"laws: law {index} has (n, m, q, r, d) = {shape}, law 0 "
                f"{(first.n, first.m, first.q, first.r, first.history)}"
            )
        for name in ("C", "F"):
            mine, theirs = getattr(law, name), getattr(first, name)
            if mine is not None and theirs is not None and not np.array_equal(mine, theirs):
                raise InputError(f"laws: law {index} has another {name} than law 0")
        if law.h != first.h:
            raise InputError(f"laws: law {index} has h = {law.h}, law 0 h = {first.h}")


@dataclass(frozen=True, init=False, eq=False)
class SpeedSchedule:
    """Control laws at a grid of electrical speeds, interpolated linearly between them.

    Parameters
    ----------
    electrical_speed : array_like, shape (g,)
        The grid, rad/s (electrical), strictly increasing, at least two speeds.
    laws : sequence of ControlLaw
        The law at each grid speed: the same structure, ``C``, ``F`` and ``h``.

    Raises
    ------
    InputError
        If the grid is not strictly increasing finite numbers, has fewer than two speeds,
        or the laws do not fit it or each other.
    """

    electrical_speed: Array
    laws: tuple[ControlLaw, ...]
    _tables: dict[str, Array] = field(repr=False, compare=False)

    def __init__(self, electrical_speed: ArrayLike, laws: Sequence[ControlLaw]) -> None:
        grid = np.asarray(electrical_speed, dtype=float)
        if grid.ndim != 1 or grid.size < 2 or not np.all(np.isfinite(grid)):
            raise InputError(
                f"electrical_speed: needs at least two finite speeds, got {electrical_speed!r}"
            )
        if not np.all(np.diff(grid) > 0.0):
            raise InputError(f"electrical_speed: must increase strictly, got {grid.tolist()}")
        if len(laws) != grid.size:
            raise InputError(f"laws: {len(laws)} laws for {grid.size} speeds")
        _same(laws)
        grid.setflags(write=False)
        tables = {
            name: np.array([getattr(law, name) for law in laws])
            for name in ("K", "X", "U", "K_i")
            if getattr(laws[0], name) is not None
        }
        object.__setattr__(self, "electrical_speed", grid)
        object.__setattr__(self, "laws", tuple(laws))
        object.__setattr__(self, "_tables", tables)

    @property
    def covered(self) -> tuple[float, float]:
        """The speeds the schedule covers, rad/s (electrical): its first and last."""
        return float(self.electrical_speed[0]), float(self.electrical_speed[-1])

    def table(self, name: str) -> Array:
        """One matrix over the grid, shape ``(g, rows, columns)``.

        Parameters
        ----------
        name : {"K", "K_i", "U", "X"}
            The matrix.

        Raises
        ------
        InputError
            For another name, or ``K_i`` of a schedule without integral action.
        """
        if name not in self._tables:
            raise InputError(f"name: the schedule has no table {name!r}")
        return self._tables[name]

    def law_at(self, electrical_speed: float) -> ControlLaw:
        """The law the firmware runs at ``electrical_speed``: each matrix interpolated
        linearly between the two neighbouring grid speeds (the grid's own law on a grid
        speed).

        Parameters
        ----------
        electrical_speed : float
            rad/s (electrical), within :attr:`covered`.

        Raises
        ------
        InputError
            If the speed is outside the grid (naming it and the covered range).
        """
        speed = finite_float(electrical_speed, "electrical_speed")
        low, high = self.covered
        if not low <= speed <= high:
            raise InputError(
                f"electrical_speed: {speed:g} rad/s is outside the schedule, which covers "
                f"{low:g} to {high:g} rad/s (electrical); the data do not cover that speed"
            )
        grid = self.electrical_speed
        index = min(int(np.searchsorted(grid, speed, side="right")) - 1, grid.size - 2)
        share = (speed - grid[index]) / (grid[index + 1] - grid[index])
        if share == 0.0:
            return self.laws[index]
        if share == 1.0:
            return self.laws[index + 1]
        values = {
            name: (1.0 - share) * table[index] + share * table[index + 1]
            for name, table in self._tables.items()
        }
        first = self.laws[0]
        return ControlLaw(
            values["K"], values["X"], values["U"], first.history, values.get("K_i"),
            first.C, first.F, first.h,
        )  # fmt: skip

    def document(self) -> dict[str, object]:
        """The schedule for a JSON result: ``electrical_speed`` (rad/s) and, per speed,
        ``K``, ``K_i`` (null without integral action), ``U``, ``X`` in the convention of
        :meth:`~selftune.core.ControlLaw.document`, with what every entry shares:
        ``history``, ``C``, ``F``, ``h``, ``state``, ``equations``."""
        first = self.laws[0]
        return {
            "electrical_speed": self.electrical_speed,
            "K": self._tables["K"],
            "K_i": self._tables.get("K_i"),
            "U": self._tables["U"],
            "X": self._tables["X"],
            "history": first.history,
            "C": first.C,
            "F": first.F,
            "h": first.h,
            "state": list(first.state),
            "equations": first.equations() + "; each matrix linear in omega_e between "
            "neighbouring speeds of electrical_speed",
        }
