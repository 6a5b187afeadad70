"""Input checks shared by every public entry point; each raises InputError naming the value."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import InputError

Array = NDArray[np.float64]


def as_matrix(
    value: ArrayLike, name: str, shape: tuple[int | None, int | None] = (None, None)
) -> Array:
    """A finite 2-D float array; ``shape`` entries that are not None must match."""
    try:
        matrix = np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
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
    """A finite 1-D float array of the given length (if given)."""
    try:
        vector = np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
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
    """Absolute tolerance for symmetry and definiteness tests on ``M``."""
    return 1e-10 * max(1.0, float(np.max(np.abs(M))) if M.size else 1.0)


def check_symmetric(M: Array, name: str) -> Array:
    """Raise unless ``M`` is square and symmetric; return its exact symmetric part."""
    if M.shape[0] != M.shape[1]:
        raise InputError(f"{name}: must be square, got shape {M.shape}")
    if np.max(np.abs(M - M.T), initial=0.0) > symmetric_tolerance(M):
        raise InputError(f"{name}: must be symmetric")
    return 0.5 * (M + M.T)


def check_positive_definite(M: Array, name: str) -> Array:
    """Raise unless ``M`` is symmetric positive definite; return its symmetric part."""
    M = check_symmetric(M, name)
    smallest = float(np.min(np.linalg.eigvalsh(M))) if M.size else 1.0
    if smallest <= symmetric_tolerance(M):
        raise InputError(f"{name}: must be positive definite (smallest eigenvalue {smallest:.3g})")
    return M


def check_positive_semidefinite(M: Array, name: str) -> Array:
    """Raise unless ``M`` is symmetric positive semidefinite; return its symmetric part."""
    M = check_symmetric(M, name)
    smallest = float(np.min(np.linalg.eigvalsh(M))) if M.size else 0.0
    if smallest < -symmetric_tolerance(M):
        raise InputError(
            f"{name}: must be positive semidefinite (smallest eigenvalue {smallest:.3g})"
        )
    return M


def positive_finite(value: object, name: str) -> float:
    """A finite, strictly positive float (a number, not a bool or a string)."""
    if isinstance(value, bool | str | bytes):
        raise InputError(f"{name}: must be a positive number, got {value!r}")
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise InputError(f"{name}: must be a positive number, got {value!r}") from None
    if not np.isfinite(number) or number <= 0.0:
        raise InputError(f"{name}: must be a positive finite number, got {value!r}")
    return number


def finite_float(value: object, name: str) -> float:
    """A finite float (a number, not a bool or a string)."""
    if isinstance(value, bool | str | bytes):
        raise InputError(f"{name}: must be a number, got {value!r}")
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise InputError(f"{name}: must be a number, got {value!r}") from None
    if not np.isfinite(number):
        raise InputError(f"{name}: must be finite, got {value!r}")
    return number


def check_weights(Q: ArrayLike, R: ArrayLike, n: int, m: int) -> tuple[Array, Array]:
    """Cost weights: Q (n x n) symmetric positive semidefinite, R (m x m) positive definite."""
    Q = check_positive_semidefinite(as_matrix(Q, "Q", (n, n)), "Q")
    R = check_positive_definite(as_matrix(R, "R", (m, m)), "R")
    return Q, R
