"""Plain-text rendering of numbers and matrices: the one home of how selftune prints them."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ._validation import Array

__all__ = ["compact", "fixed", "labels", "matrix_block", "scientific", "vector"]


def fixed(value: float, width: int = 0) -> str:
    """Four decimals, never ``-0.0000``; ``-`` for a non-finite value; right-aligned in
    ``width`` characters.

    Parameters
    ----------
    value : float
        The number.
    width : int, optional
        Field width, characters (default 0: no padding).
    """
    if not np.isfinite(value):
        return f"{'-':>{width}}"
    text = f"{value:.4f}"
    if text == "-0.0000":
        text = "0.0000"
    return f"{text:>{width}}"


def scientific(value: float, width: int = 10) -> str:
    """One significant decimal in scientific notation (``3.2e-07``); ``-`` if not finite.

    Parameters
    ----------
    value : float
        The number.
    width : int, optional
        Field width, characters (default 10).
    """
    return f"{value:>{width}.1e}" if np.isfinite(value) else f"{'-':>{width}}"


def vector(values: Array) -> str:
    """``[a, b, ...]`` with four decimals.

    Parameters
    ----------
    values : ndarray, shape (k,)
        The entries.
    """
    return "[" + ", ".join(fixed(float(value)) for value in values) + "]"


def compact(M: Array) -> str:
    """A small matrix on one line, ``[[1000, 0], [0, 1000]]``.

    Parameters
    ----------
    M : ndarray, shape (rows, cols)
        The matrix.
    """
    return "[" + ", ".join("[" + ", ".join(f"{v:g}" for v in row) + "]" for row in M) + "]"


def labels(prefix: str, count: int) -> list[str]:
    """``["x1", "x2", ...]``: the names of a data file's columns.

    Parameters
    ----------
    prefix : str
        Name of the quantity, e.g. ``"x"``.
    count : int
        Number of labels.
    """
    return [f"{prefix}{index + 1}" for index in range(count)]


def matrix_block(
    title: str, matrix: Array, rows: Sequence[str], columns: Sequence[str]
) -> list[str]:
    """A titled matrix with labelled rows and columns, four decimals.

    Parameters
    ----------
    title : str
        First line of the block.
    matrix : ndarray, shape (len(rows), len(columns))
        The matrix.
    rows : sequence of str
        Row labels, one per row.
    columns : sequence of str
        Column labels, one per column.

    Returns
    -------
    list of str
        The lines of the block, without line ends.
    """
    cells = [[fixed(float(value)) for value in row] for row in matrix]
    width = max([len(cell) for row in cells for cell in row] + [len(c) for c in columns])
    label_width = max(len(label) for label in rows)
    lines = [title, " " * (2 + label_width) + "".join(f"  {c:>{width}}" for c in columns)]
    for label, row in zip(rows, cells, strict=True):
        lines.append(f"  {label:<{label_width}}" + "".join(f"  {c:>{width}}" for c in row))
    return lines
