"""A control law scheduled over speed: the gain tables a drive interpolates.

A firmware stores the law at a grid of electrical speeds ``omega_e = p speed`` and
interpolates ``K``, ``K_i``, ``U`` and ``X`` entrywise, linearly between the two
neighbours of the speed it runs at (:meth:`SpeedSchedule.law_at`); it refuses a speed
outside the grid (a firmware clamps there instead: :mod:`selftune.report._firmware`).
The design of such a schedule is :func:`~selftune.model.design_schedule`.

A saturating motor's law changes with its load instead (its incremental inductances move
with the current): :class:`CurrentSchedule` is the same table over the q-axis current
reference ``i_q*`` (A), designed by :func:`~selftune.model.design_current_schedule`. The
interpolation and its checks are :class:`GainSchedule`'s, one for both.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike

from ..core import Array, ControlLaw, finite_float
from ..errors import InputError

__all__ = ["CurrentSchedule", "GainSchedule", "SpeedSchedule", "same_structure"]


def same_structure(laws: Sequence[ControlLaw], names: Sequence[str] | None = None) -> None:
    """Raise unless the laws share their structure, C, F and h (only gains may vary).

    Parameters
    ----------
    laws : sequence of ControlLaw
        The laws of a schedule.
    names : sequence of str, optional
        What each law is called in the message (default ``law 0``, ``law 1``, ...).

    Raises
    ------
    InputError
        Naming the first law that differs from the first.
    """
    label = list(names) if names is not None else [f"law {index}" for index in range(len(laws))]
    first = laws[0]
    for index, law in enumerate(laws[1:], start=1):
        shape = (law.n, law.m, law.q, law.r, law.history)
        if shape != (first.n, first.m, first.q, first.r, first.history):
            raise InputError(
                f"laws: {label[index]} has (n, m, q, r, d) = {shape}, {label[0]} "
                f"{(first.n, first.m, first.q, first.r, first.history)}"
            )
        for name in ("C", "F"):
            mine, theirs = getattr(law, name), getattr(first, name)
            if mine is not None and theirs is not None and not np.array_equal(mine, theirs):
                raise InputError(f"laws: {label[index]} has another {name} than {label[0]}")
        if law.h != first.h:
            raise InputError(f"laws: {label[index]} has h = {law.h}, {label[0]} h = {first.h}")


@dataclass(frozen=True, init=False, eq=False)
class GainSchedule:
    """Control laws at a grid of a scheduling variable, interpolated linearly between
    them: what :class:`SpeedSchedule` and :class:`CurrentSchedule` share (each names its
    variable and unit in its messages).

    Parameters
    ----------
    grid : array_like, shape (g,)
        The grid, strictly increasing, at least two points.
    laws : sequence of ControlLaw
        The law at each grid point: the same structure, ``C``, ``F`` and ``h``.

    Raises
    ------
    InputError
        If the grid is not strictly increasing finite numbers, has fewer than two points,
        or the laws do not fit it or each other.
    """

    grid: Array
    laws: tuple[ControlLaw, ...]
    _tables: dict[str, Array] = field(repr=False, compare=False)

    #: The variable's name (the argument the messages name).
    variable: ClassVar[str] = "grid"
    #: What one point of the grid is, and many.
    point: ClassVar[str] = "point"
    points: ClassVar[str] = "points"
    #: The unit, and what follows the covered range in the refusal.
    unit: ClassVar[str] = ""
    frame: ClassVar[str] = ""
    #: The variable in the equations' text.
    symbol: ClassVar[str] = "the grid's variable"

    def __init__(self, grid: ArrayLike, laws: Sequence[ControlLaw]) -> None:
        values = np.asarray(grid, dtype=float)
        if values.ndim != 1 or values.size < 2 or not np.all(np.isfinite(values)):
            raise InputError(
                f"{self.variable}: needs at least two finite {self.points}, got {grid!r}"
            )
        if not np.all(np.diff(values) > 0.0):
            raise InputError(f"{self.variable}: must increase strictly, got {values.tolist()}")
        if len(laws) != values.size:
            raise InputError(f"laws: {len(laws)} laws for {values.size} {self.points}")
        same_structure(laws)
        values.setflags(write=False)
        tables = {
            name: np.array([getattr(law, name) for law in laws])
            for name in ("K", "X", "U", "K_i")
            if getattr(laws[0], name) is not None
        }
        object.__setattr__(self, "grid", values)
        object.__setattr__(self, "laws", tuple(laws))
        object.__setattr__(self, "_tables", tables)

    @property
    def covered(self) -> tuple[float, float]:
        """The range the schedule covers: its first and last grid point."""
        return float(self.grid[0]), float(self.grid[-1])

    @property
    def first_law(self) -> ControlLaw:
        """The law at the grid's first point (its structure is every law's)."""
        return self.laws[0]

    def document(self) -> dict[str, object]:
        """The schedule for a JSON result: the grid under :attr:`variable`'s name
        (``electrical_speed``, rad/s; ``current``, A) and, per grid point, ``K``, ``K_i``
        (null without integral action), ``U``, ``X`` in the convention of
        :meth:`~selftune.core.ControlLaw.document`, with what every entry shares:
        ``history``, ``C``, ``F``, ``h``, ``state``, ``equations``."""
        first = self.laws[0]
        return {
            self.variable: self.grid,
            "K": self._tables["K"],
            "K_i": self._tables.get("K_i"),
            "U": self._tables["U"],
            "X": self._tables["X"],
            "history": first.history,
            "C": first.C,
            "F": first.F,
            "h": first.h,
            "state": list(first.state),
            "equations": first.equations() + f"; each matrix linear in {self.symbol} between "
            f"neighbouring {self.points} of {self.variable}",
        }

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

    def law_at(self, value: float) -> ControlLaw:
        """The law the firmware runs at ``value``: each matrix interpolated linearly
        between the two neighbouring grid points (the grid's own law on a grid point).

        Parameters
        ----------
        value : float
            The scheduling variable, within :attr:`covered`.

        Raises
        ------
        InputError
            If the value is outside the grid (naming it and the covered range).
        """
        at = finite_float(value, self.variable)
        low, high = self.covered
        if not low <= at <= high:
            raise InputError(
                f"{self.variable}: {at:g} {self.unit} is outside the schedule, which covers "
                f"{low:g} to {high:g} {self.unit}{self.frame}; the data do not cover that "
                f"{self.point}"
            )
        grid = self.grid
        index = min(int(np.searchsorted(grid, at, side="right")) - 1, grid.size - 2)
        share = (at - grid[index]) / (grid[index + 1] - grid[index])
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


@dataclass(frozen=True, init=False, eq=False)
class SpeedSchedule(GainSchedule):
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

    variable: ClassVar[str] = "electrical_speed"
    point: ClassVar[str] = "speed"
    points: ClassVar[str] = "speeds"
    unit: ClassVar[str] = "rad/s"
    frame: ClassVar[str] = " (electrical)"
    symbol: ClassVar[str] = "omega_e"

    def __init__(self, electrical_speed: ArrayLike, laws: Sequence[ControlLaw]) -> None:
        super().__init__(electrical_speed, laws)

    @property
    def electrical_speed(self) -> Array:
        """The grid, rad/s (electrical)."""
        return self.grid

    def law_at(self, electrical_speed: float) -> ControlLaw:
        """The law the firmware runs at ``electrical_speed`` (:meth:`GainSchedule.law_at`).

        Parameters
        ----------
        electrical_speed : float
            rad/s (electrical), within :attr:`covered`.

        Raises
        ------
        InputError
            If the speed is outside the grid (naming it and the covered range).
        """
        return super().law_at(electrical_speed)


@dataclass(frozen=True, init=False, eq=False)
class CurrentSchedule(GainSchedule):
    """Control laws at a grid of q-axis current references ``i_q*`` (A), interpolated
    linearly between them: a saturating motor's law over its load
    (:func:`~selftune.model.design_current_schedule`).

    Parameters
    ----------
    current : array_like, shape (g,)
        The grid of ``i_q*``, A, strictly increasing, at least two currents.
    laws : sequence of ControlLaw
        The law at each grid current: the same structure, ``C``, ``F`` and ``h``.

    Raises
    ------
    InputError
        If the grid is not strictly increasing finite numbers, has fewer than two
        currents, or the laws do not fit it or each other.
    """

    variable: ClassVar[str] = "current"
    point: ClassVar[str] = "current"
    points: ClassVar[str] = "currents"
    unit: ClassVar[str] = "A"
    frame: ClassVar[str] = " (i_q*)"
    symbol: ClassVar[str] = "i_q*"

    def __init__(self, current: ArrayLike, laws: Sequence[ControlLaw]) -> None:
        super().__init__(current, laws)

    @property
    def current(self) -> Array:
        """The grid of ``i_q*``, A."""
        return self.grid
