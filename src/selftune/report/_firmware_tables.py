"""The numbers of an exported law in C (:mod:`._firmware`): float32 literals, matrices,
and a schedule's tables with the function that interpolates them.

A schedule's tables are indexed by its grids (:func:`axes`): a speed schedule's by
``OMEGA_E`` (rad/s, looked up at ``omega_e``), a current schedule's by ``IQ_REF`` (A, at
``i_q* = w[2]``), and a schedule over speed and current by both, ``[current][speed]``.
``selftune_cell`` finds a value's neighbours in one grid (clamped: the first point below
it and for a NaN, the last above); ``selftune_schedule`` interpolates every entry
linearly between them along each grid: bilinearly with two.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core import Array
from ..errors import InputError
from ..model import CurrentSchedule, SpeedCurrentSchedule, SpeedSchedule

__all__ = [
    "Argument",
    "Scheduled",
    "axes",
    "c_float",
    "c_matrix",
    "grid_macros",
    "schedule_call",
    "schedule_key",
    "schedule_tables",
]

#: A schedule the firmware runs.
Scheduled = SpeedSchedule | CurrentSchedule | SpeedCurrentSchedule


def c_float(value: float, name: str) -> str:
    """``value`` as a C float literal that reads back to its float32 (``%.9g``).

    Parameters
    ----------
    value : float
        The number.
    name : str
        Where the file holds it, for the message.

    Raises
    ------
    InputError
        If it is no finite float32.
    """
    with np.errstate(over="ignore"):
        single = np.float32(value)
    if not np.isfinite(single):
        raise InputError(f"{name}: {value!r} is not a finite float32")
    text = f"{float(single):.9g}"
    if not any(mark in text for mark in ".en"):
        text += ".0"
    return f"{text}f"


def c_matrix(name: str, matrix: Array, key: str, comment: str) -> str:
    """``static const float NAME[rows][columns] = {...};`` with a comment above.

    Parameters
    ----------
    name : str
        The C name.
    matrix : ndarray, shape (rows, columns)
        The numbers.
    key : str
        Where the file holds them, for messages.
    comment : str
        What they are.
    """
    initializer = _braces(matrix, key, 0)
    return f"/* {comment} */\nstatic const float {name}{_dimensions(matrix)} = {initializer};\n"


def _dimensions(array: Array, counts: tuple[str, ...] = ()) -> str:
    """``[count]...[rows][columns]``: the grids' size macros, then the matrix's sizes."""
    sizes = [*counts, *(str(size) for size in array.shape[len(counts) :])]
    return "".join(f"[{size}]" for size in sizes)


def _braces(array: Array, key: str, depth: int) -> str:
    """The nested initializer of ``array``, a row of numbers per line."""
    indent = "    " * depth
    if array.ndim == 1:
        return "{" + ", ".join(c_float(value, key) for value in array) + "}"
    inner = ",\n".join(f"{indent}    " + _braces(part, key, depth + 1) for part in array)
    return "{\n" + inner + f"\n{indent}}}"


@dataclass(frozen=True)
class Argument:
    """What selects a scheduled law in C along one grid: the grid's table and size macro,
    the value ``selftune_step`` looks up in it and the parameter's name, and how the
    banner names them."""

    grid: str
    count: str
    value: str
    parameter: str
    points: str
    unit: str


#: Along speed, omega_e; along the q-axis current, i_q* = w[2].
SPEED = Argument("OMEGA_E", "SELFTUNE_SPEEDS", "omega_e", "omega_e", "speeds", "rad/s")
CURRENT = Argument("IQ_REF", "SELFTUNE_CURRENTS", "w[2]", "i_q", "currents", "A")


def axes(schedule: Scheduled) -> list[tuple[Argument, Array]]:
    """The schedule's grids in its tables' index order, each with its values.

    Parameters
    ----------
    schedule : SpeedSchedule, CurrentSchedule or SpeedCurrentSchedule
        The schedule.
    """
    if isinstance(schedule, SpeedCurrentSchedule):
        return [(CURRENT, schedule.current), (SPEED, schedule.electrical_speed)]
    if isinstance(schedule, CurrentSchedule):
        return [(CURRENT, schedule.grid)]
    return [(SPEED, schedule.grid)]


def schedule_key(schedule: Scheduled) -> str:
    """Where a JSON result holds the schedule.

    Parameters
    ----------
    schedule : SpeedSchedule, CurrentSchedule or SpeedCurrentSchedule
        The schedule.
    """
    if isinstance(schedule, SpeedCurrentSchedule):
        return "speed_current_schedule"
    return "current_schedule" if isinstance(schedule, CurrentSchedule) else "schedule"


def schedule_call(schedule: Scheduled) -> str:
    """The values ``selftune_step`` passes ``selftune_schedule``, in its grids' order.

    Parameters
    ----------
    schedule : SpeedSchedule, CurrentSchedule or SpeedCurrentSchedule
        The schedule.
    """
    return ", ".join(argument.value for argument, _ in axes(schedule))


def grid_macros(schedule: Scheduled) -> str:
    """The header's size macro of each grid.

    Parameters
    ----------
    schedule : SpeedSchedule, CurrentSchedule or SpeedCurrentSchedule
        The schedule.
    """
    return "".join(
        f"#define {argument.count} {values.size} /* grid {argument.points} of the schedule "
        f"over {argument.value} */\n"
        for argument, values in axes(schedule)
    )


def _interpolated(name: str, dimensions: int) -> str:
    """The C expression of ``name``'s entry ``[i][j]`` interpolated between the grids'
    neighbours ``g0`` (and ``g1``) by the shares ``s0`` (and ``s1``)."""
    table = f"{name}_TABLE"
    if dimensions == 1:
        return f"(1.0f - s0) * {table}[g0][i][j]\n                + s0 * {table}[g0 + 1][i][j]"
    return (
        f"(1.0f - s0) * ((1.0f - s1) * {table}[g0][g1][i][j] + s1 * {table}[g0][g1 + 1][i][j])"
        f"\n                + s0 * ((1.0f - s1) * {table}[g0 + 1][g1][i][j]"
        f" + s1 * {table}[g0 + 1][g1 + 1][i][j])"
    )


_CELL = """
/* The neighbours of v in grid[0 .. count - 1]: returns g with grid[g] <= v < grid[g + 1]
   and sets *share to its part of the way from grid[g] to grid[g + 1]; the first point
   below the grid (and for a NaN), the last above it. */
static int selftune_cell(float v, const float *grid, int count, float *share)
{
    int g = 0;

    *share = 0.0f;
    if (v >= grid[count - 1]) {
        *share = 1.0f;
        return count - 2;
    }
    if (v > grid[0]) {
        while (v >= grid[g + 1]) {
            ++g;
        }
        *share = (v - grid[g]) / (grid[g + 1] - grid[g]);
    }
    return g;
}
"""


def schedule_tables(schedule: Scheduled, state: str) -> list[str]:
    """The tables over the schedule's grids and the functions that interpolate them.

    Parameters
    ----------
    schedule : SpeedSchedule, CurrentSchedule or SpeedCurrentSchedule
        The schedule.
    state : str
        The names of the deviations K feeds back, for its comment.
    """
    grids = axes(schedule)
    key = schedule_key(schedule)
    counts = tuple(argument.count for argument, _ in grids)
    point = " and ".join(argument.points[:-1] for argument, _ in grids)
    parts = []
    for argument, values in grids:
        literals = ", ".join(c_float(value, f"{key}.{argument.points}") for value in values)
        parts += [
            f"/* {argument.grid}: the schedule's {argument.points}, {argument.unit}, "
            "increasing */\n",
            f"static const float {argument.grid}[{argument.count}] = {{{literals}}};\n\n",
        ]
    entries = [
        ("U", "U", f"U at each {point}: u_e = U w"),
        ("X", "X", f"X at each {point}: x_e = X w"),
        ("K", "K", f"K at each {point}: feedback on the deviations of [{state}]"),
    ]
    law = schedule.first_law
    if law.K_i is not None:
        entries.append(("K_I", "K_i", f"K_i at each {point}"))
    for index, (name, table, comment) in enumerate(entries):
        values = schedule.table(table)
        parts += [
            "\n" if index else "",
            f"/* {comment} */\nstatic const float {name}_TABLE{_dimensions(values, counts)} = "
            f"{_braces(values, f'{key}.{table}', 0)};\n",
        ]
    sizes = {"U": str(law.q), "X": str(law.q), "K": str(law.K.shape[1]),
             "K_I": "SELFTUNE_INTEGRATORS"}  # fmt: skip
    arguments = ", ".join(f"float {name}[2][{sizes[name]}]" for name, _, _ in entries)
    parameters = ", ".join(f"float {argument.parameter}" for argument, _ in grids)
    body = [
        _CELL,
        "/* The law at "
        + " and ".join(argument.parameter for argument, _ in grids)
        + ": each entry linear between the neighbours along each grid (clamped at its ends). */",
        f"static void selftune_schedule({parameters}, {arguments})",
        "{",
        "    float " + ", ".join(f"s{k}" for k in range(len(grids))) + ";",
        *(
            f"    int g{k} = selftune_cell({argument.parameter}, {argument.grid}, "
            f"{argument.count}, &s{k});"
            for k, (argument, _) in enumerate(grids)
        ),
        "    int i, j;",
        "",
        "    for (i = 0; i < 2; ++i) {",
    ]
    for name, _, _ in entries:
        body += [
            f"        for (j = 0; j < {sizes[name]}; ++j) {{",
            f"            {name}[i][j] = {_interpolated(name, len(grids))};",
            "        }",
        ]
    body += ["    }", "}\n"]
    return [*parts, "\n".join(body)]
