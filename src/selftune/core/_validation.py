"""The one home of every input rule and numerical threshold selftune applies.

Each check raises :class:`~selftune.errors.InputError` with a message that names the value
(the argument, field or key the caller passes as ``name``) and says what is wrong.

Thresholds, each defined once and used everywhere:

- :data:`DEFINITENESS_TOLERANCE`: a symmetric matrix counts as positive definite when its
  smallest eigenvalue exceeds this fraction of its largest entry (and as symmetric when
  ``M - M'`` is within the same fraction);
- :data:`RANK_TOLERANCE`: singular values below this fraction of the largest count as
  zero, in every rank test (controllability, the regulator equations, the data equation).
"""

from __future__ import annotations

import operator

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import InputError

__all__ = [
    "DEFINITENESS_TOLERANCE",
    "RANK_TOLERANCE",
    "Array",
    "as_matrix",
    "as_vector",
    "check_positive_definite",
    "check_positive_semidefinite",
    "check_symmetric",
    "check_weights",
    "finite_float",
    "first_non_increasing",
    "is_positive_definite",
    "numerical_rank",
    "positive_finite",
    "positive_integer",
    "symmetric_tolerance",
]

Array = NDArray[np.float64]

#: Relative threshold of symmetry and positive definiteness (see the module docstring).
DEFINITENESS_TOLERANCE = 1e-10

#: Relative singular-value threshold of every rank test (see the module docstring).
RANK_TOLERANCE = 1e-9


def as_matrix(
    value: ArrayLike, name: str, shape: tuple[int | None, int | None] = (None, None)
) -> Array:
    """A finite 2-D float array; ``shape`` entries that are not None must match.

    Parameters
    ----------
    value : array_like
        The matrix (a 1-D array is taken as one row when ``shape[0]`` is 1).
    name : str
        Name of the value in error messages.
    shape : tuple of (int or None), optional
        Expected ``(rows, columns)``; None matches any size (default: any shape).
    """
    try:
        matrix = np.array(value, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
        raise InputError(f"{name}: not a numeric matrix ({exc})") from None
    if matrix.ndim == 1 and shape[0] == 1:
        matrix = matrix.reshape(1, -1)
    if matrix.ndim != 2:
        raise InputError(f"{name}: expected a matrix (2-D), got an array of shape {matrix.shape}")
    for axis, (expected, actual) in enumerate(zip(shape, matrix.shape, strict=True)):
        if expected is not None and expected != actual:
            what = "rows" if axis == 0 else "columns"
            raise InputError(
                f"{name}: expected {expected} {what}, got shape {matrix.shape}"
                f" (expected {_shape_text(shape)})"
            )
    if not np.all(np.isfinite(matrix)):
        raise InputError(f"{name}: contains NaN or infinite values")
    return matrix


def _shape_text(shape: tuple[int | None, int | None]) -> str:
    return "(" + ", ".join("any" if s is None else str(s) for s in shape) + ")"


def as_vector(value: ArrayLike, name: str, length: int | None = None) -> Array:
    """A finite 1-D float array of the given length (if given).

    Parameters
    ----------
    value : array_like
        The vector (a scalar is taken as a vector of length 1).
    name : str
        Name of the value in error messages.
    length : int, optional
        Expected length (default: any).
    """
    try:
        vector = np.array(value, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
        raise InputError(f"{name}: not a numeric vector ({exc})") from None
    if vector.ndim == 0:
        vector = vector.reshape(1)
    if vector.ndim != 1:
        raise InputError(f"{name}: expected a vector (1-D), got an array of shape {vector.shape}")
    if length is not None and vector.shape[0] != length:
        raise InputError(f"{name}: expected length {length}, got length {vector.shape[0]}")
    if not np.all(np.isfinite(vector)):
        raise InputError(f"{name}: contains NaN or infinite values")
    return vector


def symmetric_tolerance(M: Array) -> float:
    """Absolute tolerance for symmetry and definiteness tests on ``M``.

    Parameters
    ----------
    M : ndarray, shape (n, n)
        The matrix tested.
    """
    largest = float(np.max(np.abs(M))) if M.size else 1.0
    return DEFINITENESS_TOLERANCE * max(1.0, largest)


def is_positive_definite(M: Array) -> bool:
    """Whether the symmetric matrix ``M`` is positive definite at :data:`DEFINITENESS_TOLERANCE`.

    Parameters
    ----------
    M : ndarray, shape (n, n)
        Symmetric matrix (its symmetric part is tested).
    """
    if not M.size:
        return True
    if not np.all(np.isfinite(M)):
        return False
    smallest = float(np.min(np.linalg.eigvalsh(0.5 * M + 0.5 * M.T)))
    return smallest > symmetric_tolerance(M)


def check_symmetric(M: Array, name: str) -> Array:
    """Raise unless ``M`` is square and symmetric; return its exact symmetric part.

    Parameters
    ----------
    M : ndarray, shape (n, n)
        The matrix checked.
    name : str
        Name of the matrix in error messages.
    """
    if M.shape[0] != M.shape[1]:
        raise InputError(f"{name}: must be square, got shape {M.shape}")
    if np.max(np.abs(M - M.T), initial=0.0) > symmetric_tolerance(M):
        raise InputError(f"{name}: must be symmetric")
    return 0.5 * M + 0.5 * M.T  # halves first: no overflow near the largest float


def check_positive_definite(M: Array, name: str) -> Array:
    """Raise unless ``M`` is symmetric positive definite; return its symmetric part.

    Parameters
    ----------
    M : ndarray, shape (n, n)
        The matrix checked.
    name : str
        Name of the matrix in error messages.
    """
    M = check_symmetric(M, name)
    if not is_positive_definite(M):
        eigenvalues = np.linalg.eigvalsh(M)
        smallest, largest = float(np.min(eigenvalues)), float(np.max(eigenvalues))
        if smallest > 0.0:
            raise InputError(
                f"{name}: must be symmetric positive definite; it is nearly singular"
                f" (eigenvalues from {smallest:.3g} to {largest:.3g})"
            )
        raise InputError(
            f"{name}: must be symmetric positive definite (smallest eigenvalue {smallest:.3g})"
        )
    return M


def check_positive_semidefinite(M: Array, name: str) -> Array:
    """Raise unless ``M`` is symmetric positive semidefinite; return its symmetric part.

    Parameters
    ----------
    M : ndarray, shape (n, n)
        The matrix checked.
    name : str
        Name of the matrix in error messages.
    """
    M = check_symmetric(M, name)
    smallest = float(np.min(np.linalg.eigvalsh(M))) if M.size else 0.0
    if smallest < -symmetric_tolerance(M):
        raise InputError(
            f"{name}: must be positive semidefinite (smallest eigenvalue {smallest:.3g})"
        )
    return M


def numerical_rank(M: ArrayLike, tolerance: float = RANK_TOLERANCE) -> int:
    """Number of singular values of ``M`` above ``tolerance`` times the largest.

    Parameters
    ----------
    M : array_like, shape (rows, cols)
        The matrix.
    tolerance : float, optional
        Relative singular-value threshold (default :data:`RANK_TOLERANCE`).
    """
    singular_values = np.linalg.svd(np.asarray(M), compute_uv=False)
    if singular_values.size == 0 or singular_values[0] == 0.0:
        return 0
    return int(np.sum(singular_values > tolerance * float(singular_values[0])))


def positive_finite(value: object, name: str) -> float:
    """A finite, strictly positive float (a number, not a bool or a string).

    Parameters
    ----------
    value : object
        The value checked.
    name : str
        Name of the value in error messages.
    """
    if isinstance(value, bool | str | bytes):
        raise InputError(f"{name}: must be a positive number, got {value!r}")
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{name}: must be a positive number, got {value!r}") from None
    if not np.isfinite(number) or number <= 0.0:
        raise InputError(f"{name}: must be a positive finite number, got {value!r}")
    return number


def finite_float(value: object, name: str) -> float:
    """A finite float (a number, not a bool or a string).

    Parameters
    ----------
    value : object
        The value checked.
    name : str
        Name of the value in error messages.
    """
    if isinstance(value, bool | str | bytes):
        raise InputError(f"{name}: must be a number, got {value!r}")
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{name}: must be a number, got {value!r}") from None
    if not np.isfinite(number):
        raise InputError(f"{name}: must be finite, got {value!r}")
    return number


def positive_integer(value: object, name: str, minimum: int = 1) -> int:
    """A whole number (an ``int`` or numpy integer, not a bool or a float) ``>= minimum``.

    Parameters
    ----------
    value : object
        The value checked.
    name : str
        Name of the value in error messages.
    minimum : int, optional
        Smallest value allowed (default 1).
    """
    if isinstance(value, bool):
        raise InputError(f"{name}: expected a whole number >= {minimum}, got {value!r}")
    try:
        number = operator.index(value)  # type: ignore[arg-type]
    except TypeError:
        raise InputError(f"{name}: expected a whole number >= {minimum}, got {value!r}") from None
    if number < minimum:
        raise InputError(f"{name}: expected a whole number >= {minimum}, got {number}")
    return int(number)


def first_non_increasing(t: Array) -> int | None:
    """The first index k with ``t[k + 1] <= t[k]`` (times must strictly increase), or None.

    Parameters
    ----------
    t : ndarray, shape (N + 1,)
        Sample times, s.
    """
    steps = np.diff(t)
    bad = ~(steps > 0.0)
    return int(np.argmax(bad)) if np.any(bad) else None


def check_weights(Q: ArrayLike, R: ArrayLike, n: int, m: int) -> tuple[Array, Array]:
    """Cost weights: Q (n x n) symmetric positive semidefinite, R (m x m) positive definite.

    Parameters
    ----------
    Q : array_like, shape (n, n)
        State weight, symmetric positive semidefinite.
    R : array_like, shape (m, m)
        Input weight, symmetric positive definite.
    n : int
        State dimension.
    m : int
        Input dimension.
    """
    Q = check_positive_semidefinite(as_matrix(Q, "Q", (n, n)), "Q")
    R = check_positive_definite(as_matrix(R, "R", (m, m)), "R")
    return Q, R
