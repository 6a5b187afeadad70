"""The one home of every input rule and numerical threshold selftune applies.

Each check raises :class:`~selftune.errors.InputError` with a message that names the value
(the argument, field or key the caller passes as ``name``) and says what is wrong.

Thresholds, each defined once and used everywhere:

- :data:`DEFINITENESS_TOLERANCE`: a symmetric matrix counts as positive definite when its
  smallest eigenvalue exceeds this fraction of its largest entry (and as symmetric when
  ``M - M'`` is within the same fraction);
- :data:`RANK_TOLERANCE`: singular values below this fraction of the largest count as
  zero, in every rank test (controllability, the regulator equations, the data equation);
- :data:`TIME_RESOLUTION_TOLERANCE`: the spacing of the numbers a time column is stored
  in, at its largest time, must be at most this fraction of the smallest sampling step
  (:func:`check_time_resolution`);
- :data:`PLAUSIBLE_RANGES`: the range of each physical input (:func:`check_range`), and
  :data:`MATRIX_ENTRY_LIMIT`, :data:`DATA_VALUE_LIMIT`,
  :data:`ELECTRICAL_STIFFNESS_LIMIT`, :data:`WEIGHT_RATIO_LIMIT`: the largest matrix
  entry, data value, motor stiffness and ratio of the cost weights the numerics stay
  meaningful for;
- :data:`LIMITS`: the sizes and counts bounded before anything is allocated (file sizes,
  samples, channels, samples per episode, iterations).
"""

from __future__ import annotations

import operator
from collections.abc import Mapping
from types import MappingProxyType

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import CoarseTimeResolution, InputError

__all__ = [
    "DATA_VALUE_LIMIT",
    "DEFINITENESS_TOLERANCE",
    "ELECTRICAL_STIFFNESS_LIMIT",
    "LIMITS",
    "MATRIX_ENTRY_LIMIT",
    "PLAUSIBLE_RANGES",
    "RANK_TOLERANCE",
    "TIME_RESOLUTION_TOLERANCE",
    "WEIGHT_RATIO_LIMIT",
    "Array",
    "as_matrix",
    "as_vector",
    "check_electrical_speed",
    "check_electrical_time_constant",
    "check_entries",
    "check_positive_definite",
    "check_positive_semidefinite",
    "check_range",
    "check_symmetric",
    "check_time_resolution",
    "check_weight_ratio",
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

#: Largest spacing of a time column's numbers (at its largest time) relative to its
#: smallest sampling step. The learners use only time differences, but a difference of
#: two rounded times carries their rounding: near 1e9 s float64 times are 1.2e-7 s apart,
#: and a 10 us step is then off by 1%. On the paper's motor a relative timing error of
#: 2e-11 already moves K by 2e-7 and one of 1e-5 by 25%; at 1e-9 K moves by 5e-5 (float64
#: times up to 64 s at 10 us sampling).
TIME_RESOLUTION_TOLERANCE = 1e-9

#: Plausible range of each physical input: (smallest, largest, unit). Values outside are
#: refused at the door, named by their key, before they can overflow the model.
PLAUSIBLE_RANGES: Mapping[str, tuple[float, float, str]] = MappingProxyType(
    {
        "R_s": (1e-6, 1e3, "ohm"),
        "L_s": (1e-7, 10.0, "H"),
        "phi_pm": (1e-5, 10.0, "Wb"),
        "p": (1.0, 100.0, "pole pairs"),
        "J": (1e-9, 1e6, "kg m^2"),
        "speed": (-1e5, 1e5, "rad/s"),
        "torque": (-1e6, 1e6, "N m"),
        "h": (1e-8, 0.1, "s"),
        "episode_length": (1e-6, 100.0, "s"),
        "exploration": (1e-9, 1e4, "V"),
        # a drive's: one PWM period per sample (1 / h within h's range); the DC bus, whose
        # 2% is the default exploration
        "switching_frequency": (10.0, 1e8, "Hz"),
        "dc_voltage": (1.0, 1e5, "V"),
    }
)

#: Largest magnitude of an entry of a cost weight, a gain or a known matrix
#: (Q, R, K0, C, E, F); a nonzero entry must be at least its inverse, 1e-12.
MATRIX_ENTRY_LIMIT = 1e12

#: Largest ratio of the state weight's largest eigenvalue to the input weight's smallest:
#: beyond it the Riccati equation's Hamiltonian is too ill-conditioned to solve.
WEIGHT_RATIO_LIMIT = 1e16

#: Largest magnitude of a value in a data file: its squares and products (the data
#: equation) must stay far from overflow.
DATA_VALUE_LIMIT = 1e50

#: Largest ``R_s^2 / L_s + (p speed)^2 L_s`` (ohm/s), half of it for each term: the
#: condition number of the motor's ``[[A, B], [C, 0]]`` is about this, and beyond it the
#: matrices span more than the rank tests (:data:`RANK_TOLERANCE`) resolve, so the
#: optimum would be numerically meaningless (the paper's motor: 27).
ELECTRICAL_STIFFNESS_LIMIT = 1e7

#: Sizes and counts bounded before anything is read or allocated.
LIMITS: Mapping[str, int] = MappingProxyType(
    {
        "toml_bytes": 1 << 20,  # a configuration file
        "csv_bytes": 256 << 20,  # a CSV data file
        "npz_bytes": 256 << 20,  # the arrays of an NPZ file, uncompressed
        "header_bytes": 1 << 16,  # the header line of a CSV file
        "samples": 1_000_000,  # sample times in a data file
        "channels": 12,  # n + m + q of a data file
        "episode_samples": 200_000,  # samples per episode of a self-tuning session
        "iterations": 1000,  # max_iterations
    }
)


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


def _as_float(value: object, name: str, expected: str) -> float:
    """``float(value)`` for a number (not a bool or a string), else an error naming it."""
    if isinstance(value, bool | str | bytes):
        raise InputError(f"{name}: must be {expected}, got {value!r}")
    try:
        return float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{name}: must be {expected}, got {value!r}") from None


def positive_finite(value: object, name: str) -> float:
    """A finite, strictly positive float (a number, not a bool or a string).

    Parameters
    ----------
    value : object
        The value checked.
    name : str
        Name of the value in error messages.
    """
    number = _as_float(value, name, "a positive number")
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
    number = _as_float(value, name, "a number")
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


def check_time_resolution(t: ArrayLike, name: str) -> None:
    """Raise unless the numbers ``t`` is stored in resolve its sampling steps.

    The spacing of the numbers of ``t``'s dtype (float64 for integers) at its largest
    magnitude must be at most :data:`TIME_RESOLUTION_TOLERANCE` times the smallest step
    ``t[k + 1] - t[k]``. Times whose steps are not all equal and which are all float16 or
    float32 numbers were rounded to that type on their way (a float32 log written out as
    text, say): its spacing is the one that counts. Call it on the times as given (before
    any conversion), after checking that they are finite and strictly increasing.

    Parameters
    ----------
    t : array_like, shape (N + 1,)
        Sample times, s.
    name : str
        Name of the times in error messages.
    """
    times = np.asarray(t)
    if times.ndim != 1 or times.shape[0] < 2:
        return
    kind = times.dtype if times.dtype.kind == "f" else np.dtype(np.float64)
    values = times.astype(kind, copy=False)
    steps = np.diff(values.astype(np.float64))
    step = float(np.min(steps))
    if not step > 0.0:
        return  # not increasing: for the caller's own check to report
    rounded = "" if step == float(np.max(steps)) else _narrower(values)
    if rounded:
        kind = np.dtype(rounded)
        values = values.astype(kind)
    largest = np.max(np.abs(values))
    resolution = float(np.spacing(largest))
    if resolution > TIME_RESOLUTION_TOLERANCE * step:
        wider = "" if kind.itemsize >= 8 else " in float64"
        why = f" (every time is a {rounded} number: they were rounded to it)" if rounded else ""
        raise CoarseTimeResolution(
            f"{name}: the times reach {float(largest):.6g} s, where {kind.name} numbers are"
            f" {resolution:.2g} s apart{why}: too coarse for sampling steps of {step:.2g} s (the"
            f" resolution must be at most {TIME_RESOLUTION_TOLERANCE:g} of the smallest step);"
            f" store the times relative to the first sample{wider}",
            resolution=resolution,
            step=step,
        )


def _narrower(values: NDArray[np.floating]) -> str:
    """The narrowest float type narrower than ``values``' that holds each of them exactly
    ("" if none): times stored wide but rounded narrow on the way keep the narrow rounding.

    Times that are all short decimals (at most 6 significant digits: 0, 1, 3, 0.25) are
    exact in every type, and say nothing of a rounding: "" for them."""
    if _short_decimals(values):
        return ""
    for narrow in ("float16", "float32"):
        if np.dtype(narrow).itemsize < values.dtype.itemsize:
            with np.errstate(over="ignore", invalid="ignore"):
                if np.array_equal(values.astype(narrow).astype(values.dtype), values):
                    return narrow
    return ""


def _short_decimals(values: NDArray[np.floating]) -> bool:
    """``float(f"{v:.6g}") == v`` for every v, not formatting each: v is such a decimal iff
    ``M / 10**j`` (``M * 10**-j``) rounds to it for an integer ``|M| < 10**6``; with M and
    ``10**|j| <= 10**22`` exact, that one operation rounds as ``float`` of the text does."""
    if values.dtype.itemsize > 8:  # wider than float64: only its text is exact
        return all(float(f"{value:.6g}") == value for value in values.tolist())
    v = values.astype(np.float64).ravel()
    pending = v[np.isfinite(v) & (v != 0.0)]  # not yet shown to be such a decimal
    decade = np.floor(np.log10(np.abs(pending)))
    inexact = np.zeros(pending.shape, dtype=bool)  # a j tried was beyond 22: as text
    for digits in (5.0, 4.0, 6.0):
        j = digits - decade
        inexact |= np.abs(j) > 22
        power = np.array([float(f"1e{k}") for k in range(23)])[np.minimum(abs(j), 22).astype(int)]
        with np.errstate(over="ignore"):
            scaled = np.rint(np.where(j >= 0, pending * power, pending / power))
            back = np.where(j >= 0, scaled / power, scaled * power)
        other = (np.abs(scaled) >= 1e6) | (back != pending)  # j from the decade, +-1
        pending, decade, inexact = pending[other], decade[other], inexact[other]
    as_text = np.concatenate([pending, v[~np.isfinite(v)]]).tolist()
    return bool(np.all(inexact)) and all(float(f"{value:.6g}") == value for value in as_text)


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


def check_range(value: float, name: str, key: str | None = None) -> float:
    """``value`` if it lies in the plausible range of ``key`` (:data:`PLAUSIBLE_RANGES`).

    Parameters
    ----------
    value : float
        The value checked (already a finite number).
    name : str
        Name of the value in error messages.
    key : str, optional
        The entry of :data:`PLAUSIBLE_RANGES` (default: ``name``).
    """
    low, high, unit = PLAUSIBLE_RANGES[name if key is None else key]
    if not low <= value <= high:
        raise InputError(f"{name}: must be between {low:g} and {high:g} {unit}, got {value!r}")
    return value


def check_entries(
    M: Array, name: str, limit: float = MATRIX_ENTRY_LIMIT, floor: bool = False
) -> Array:
    """``M`` if no entry exceeds ``limit`` in magnitude (and, with ``floor``, every nonzero
    entry is at least ``1 / limit``: what a user writes, not a computed matrix).

    Parameters
    ----------
    M : ndarray
        The matrix checked (finite).
    name : str
        Name of the matrix in error messages.
    limit : float, optional
        Largest magnitude allowed (default :data:`MATRIX_ENTRY_LIMIT`).
    floor : bool, optional
        Also refuse nonzero entries below ``1 / limit`` (default False).
    """
    magnitudes = np.abs(M)
    largest = float(np.max(magnitudes, initial=0.0))
    smallest = float(np.min(magnitudes[magnitudes > 0.0], initial=np.inf)) if floor else np.inf
    if largest > limit or smallest < 1.0 / limit:
        value = largest if largest > limit else smallest
        bounds = f"0 or between {1.0 / limit:g} and {limit:g}" if floor else f"at most {limit:g}"
        raise InputError(f"{name}: entries must be {bounds} in magnitude, got {value:.3g}")
    return M


def check_electrical_time_constant(R_s: float, L_s: float, name: str = "R_s") -> float:
    """``R_s`` unless ``R_s^2 / L_s`` exceeds half :data:`ELECTRICAL_STIFFNESS_LIMIT`.

    Parameters
    ----------
    R_s : float
        Stator resistance, ohm.
    L_s : float
        Stator inductance, H.
    name : str, optional
        Name of the resistance in error messages.
    """
    limit = 0.5 * ELECTRICAL_STIFFNESS_LIMIT
    if R_s * R_s / L_s > limit:
        raise InputError(
            f"{name}: {R_s:g} ohm is too large for L_s = {L_s:g} H (time constant"
            f" L_s / R_s = {L_s / R_s:.3g} s): the model is numerically meaningful up to"
            f" R_s^2 / L_s = {limit:g}, i.e. R_s <= {(limit * L_s) ** 0.5:.4g} ohm"
        )
    return R_s


def check_electrical_speed(speed: float, p: int, L_s: float, name: str = "speed") -> float:
    """``speed`` unless ``(p speed)^2 L_s`` exceeds half :data:`ELECTRICAL_STIFFNESS_LIMIT`.

    Parameters
    ----------
    speed : float
        Mechanical speed, rad/s.
    p : int
        Pole pairs.
    L_s : float
        Stator inductance, H.
    name : str, optional
        Name of the speed in error messages.
    """
    electrical, limit = p * speed, 0.5 * ELECTRICAL_STIFFNESS_LIMIT
    if electrical * electrical * L_s > limit:
        fastest = (limit / L_s) ** 0.5 / p
        raise InputError(
            f"{name}: {speed:g} rad/s is too fast for this motor (p = {p}, L_s = {L_s:g} H):"
            f" the model is numerically meaningful up to (p speed)^2 L_s = {limit:g},"
            f" i.e. |speed| <= {fastest:.4g} rad/s"
        )
    return speed


def check_weight_ratio(Q: Array, R: Array, name: str = "Q") -> None:
    """Raise if ``Q``'s largest eigenvalue exceeds :data:`WEIGHT_RATIO_LIMIT` times ``R``'s
    smallest.

    Parameters
    ----------
    Q : ndarray, shape (n, n)
        State weight, symmetric.
    R : ndarray, shape (m, m)
        Input weight, symmetric positive definite.
    name : str, optional
        Name of the weights in error messages.
    """
    largest = float(np.max(np.linalg.eigvalsh(Q), initial=0.0))
    smallest = float(np.min(np.linalg.eigvalsh(R), initial=np.inf))
    if largest > WEIGHT_RATIO_LIMIT * smallest:
        raise InputError(
            f"{name}: the cost weights are too far apart: Q's largest eigenvalue {largest:.3g}"
            f" is more than {WEIGHT_RATIO_LIMIT:g} times R's smallest {smallest:.3g}"
        )
