"""Discrete-time linear-quadratic design: the generic tools a digital controller needs.

- :func:`dlqr`: the stabilizing solution of the discrete algebraic Riccati equation (DARE)
  with a cross weight, refined by one Hewer (discrete Kleinman) step;
- :func:`dpolicy_value`: the value of a given policy (a discrete Lyapunov equation);
  :func:`dpolicy_values`: the same on a stack of plants, one batched solve;
- :func:`sampled_data_weights`: the continuous cost integrated exactly over one sample
  with the input held (Van Loan 1978);
- :func:`delay_augmented`: the plant seen by a controller with a computation delay of d
  samples, state ``[x_k; u_(k-d); ...; u_(k-1)]``;
- :func:`integrator_augmented`: the plant with the integral of its regulated output
  (integral action), in continuous time or as the digital integrator a drive runs;
- :func:`continuous_from_discrete`: the inverse of the exact zero-order-hold
  discretization (the principal matrix logarithm).

They are generic numerical tools, like :mod:`._linalg` in continuous time: the
model-based digital optimum (:mod:`selftune.model`) applies them to the true plant.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike

from ..errors import InputError, UnsolvableError
from ._discretize import augmented
from ._linalg import check_plant, format_eigenvalue, pbh_rank_loss, unique_eigenvalues
from ._stein import _policy_values, _spectral_radius, _stage_weight, _stein
from ._validation import (
    Array,
    as_matrix,
    check_positive_semidefinite,
    check_weights,
    positive_finite,
    positive_integer,
)

__all__ = [
    "continuous_from_discrete",
    "delay_augmented",
    "dlqr",
    "dpolicy_value",
    "dpolicy_values",
    "integrator_augmented",
    "sampled_data_weights",
]

#: An eigenvalue counts as on or outside the unit circle when ``|lambda| >= 1 - this``.
_UNIT_CIRCLE_MARGIN = 1e-9


def _check_cost(
    A: ArrayLike, B: ArrayLike, Q: ArrayLike, R: ArrayLike, N: ArrayLike | None
) -> tuple[Array, Array, Array, Array, Array]:
    """Validated ``A, B, Q, R, N``: shapes, finite values, Q psd, R pd, the joint weight
    ``[[Q, N], [N', R]]`` psd (N defaults to zero)."""
    A_, B_ = check_plant(A, B)
    n, m = B_.shape
    Q_, R_ = check_weights(Q, R, n, m)
    N_ = np.zeros((n, m)) if N is None else as_matrix(N, "N", (n, m))
    if N is not None:
        check_positive_semidefinite(np.block([[Q_, N_], [N_.T, R_]]), "[[Q, N], [N', R]]")
    return A_, B_, Q_, R_, N_


def _outside_unit_disc(value: complex) -> bool:
    """Whether ``|value| >= 1`` (to rounding)."""
    return abs(value) >= 1.0 - _UNIT_CIRCLE_MARGIN


def _check_stabilizable(A: Array, B: Array) -> None:
    """Raise unless every mode of A with ``|lambda| >= 1`` is controllable (PBH)."""
    loss = pbh_rank_loss(A, B, _outside_unit_disc, stack="columns")
    if loss is not None:
        value, rank = loss
        raise UnsolvableError(
            f"(A, B) is not stabilizable in discrete time: the mode at eigenvalue"
            f" {format_eigenvalue(value)} of A (|lambda| = {abs(value):.6g} >= 1) is not"
            f" controllable (rank [A - lambda I, B] = {rank} < n = {A.shape[0]})"
        )


def _check_detectable(A: Array, B: Array, Q: Array, R: Array, N: Array) -> None:
    """Raise unless every mode of ``A - B R^-1 N'`` with ``|lambda| >= 1`` is seen by
    ``Q - N R^-1 N'`` (PBH); with N = 0, the detectability of ``(A, Q)``."""
    cross = np.linalg.solve(R, N.T)
    A_free, Q_free = A - B @ cross, Q - N @ cross
    pair = "(A, Q)" if not np.any(N) else "(A - B R^-1 N', Q - N R^-1 N')"
    loss = pbh_rank_loss(A_free, 0.5 * (Q_free + Q_free.T), _outside_unit_disc, stack="rows")
    if loss is not None:
        value, rank = loss
        raise UnsolvableError(
            f"{pair} is not detectable in discrete time: the mode at eigenvalue"
            f" {format_eigenvalue(value)} (|lambda| = {abs(value):.6g} >= 1) is not seen by"
            f" the cost (rank [A - lambda I; Q] = {rank} < n = {A.shape[0]}); make Q larger"
        )


def _gain(A: Array, B: Array, R: Array, N: Array, P: Array) -> Array:
    """``K = (R + B'PB)^-1 (B'PA + N')``."""
    return np.asarray(np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A + N.T), dtype=np.float64)


def _riccati_residual(A: Array, B: Array, Q: Array, R: Array, N: Array, P: Array) -> float:
    """Relative residual of the DARE ``A'PA - P - (A'PB + N)(R + B'PB)^-1(B'PA + N') + Q``."""
    coupling = A.T @ P @ B + N
    gain_term = coupling @ np.linalg.solve(R + B.T @ P @ B, coupling.T)
    propagated = A.T @ P @ A
    residual = propagated - P - gain_term + Q
    scale = sum(float(np.linalg.norm(M)) for M in (propagated, P, gain_term, Q))
    return float(np.linalg.norm(residual) / max(scale, 1e-300))


def _hewer_refined(
    A: Array, B: Array, Q: Array, R: Array, N: Array, P: Array
) -> tuple[Array, Array]:
    """One Hewer step from P (a discrete Lyapunov solve), kept if it lowers the residual;
    the gain of the P kept, and P.

    Like the Kleinman-Newton step of the continuous LQR: scipy's generalized-Schur solution
    is accurate to about cond * eps, and one Newton step from there brings the relative
    residual near eps.
    """
    K = _gain(A, B, R, N, P)
    closed_loop = A - B @ K
    if _spectral_radius(closed_loop) >= 1.0:
        return K, P
    with warnings.catch_warnings():
        # a closed loop mixing scales (a delay and an integrator: V, A and A s) gives the
        # Kronecker system a tiny rcond even where the solve is accurate; the step is
        # kept only if it lowers the Riccati residual
        warnings.simplefilter("ignore", scipy.linalg.LinAlgWarning)
        refined = _stein(closed_loop, _stage_weight(K, Q, R, N))
    if not np.all(np.isfinite(refined)):
        return K, P
    if _riccati_residual(A, B, Q, R, N, refined) < _riccati_residual(A, B, Q, R, N, P):
        return _gain(A, B, R, N, refined), refined
    return K, P


def dlqr(
    A: ArrayLike,
    B: ArrayLike,
    Q: ArrayLike,
    R: ArrayLike,
    N: ArrayLike | None = None,
    *,
    checked: bool = False,
) -> tuple[Array, Array]:
    """Discrete-time LQR: the stabilizing solution of the discrete algebraic Riccati equation.

    Minimizes ``sum_k [x_k; u_k]' [[Q, N], [N', R]] [x_k; u_k]`` subject to
    ``x_(k+1) = A x_k + B u_k``; the optimum is ``u_k = -K x_k``.

    Parameters
    ----------
    A : array_like, shape (n, n)
        State matrix of the discrete plant (dimensionless).
    B : array_like, shape (n, m)
        Input matrix of the discrete plant (for the motor, A/V).
    Q : array_like, shape (n, n)
        State weight, symmetric positive semidefinite.
    R : array_like, shape (m, m)
        Input weight, symmetric positive definite.
    N : array_like, shape (n, m), optional
        Cross weight between state and input (default zero); the joint weight
        ``[[Q, N], [N', R]]`` must be positive semidefinite.
    checked : bool, optional
        Whether the caller has made the checks of the inputs below (``InputError``):
        float ndarrays of these shapes, finite, Q psd, R pd and the joint weight psd, as
        when they are built from weights already checked. Default False: they are made.
        The stabilizability and detectability checks are made either way.

    Returns
    -------
    K : ndarray, shape (m, n)
        Optimal gain, ``u_k = -K x_k``, ``K = (R + B'PB)^-1 (B'PA + N')``.
    P : ndarray, shape (n, n)
        Stabilizing solution of ``A'PA - P - (A'PB + N)(R + B'PB)^-1 (B'PA + N') + Q = 0``;
        the optimal cost from ``x_0`` is ``x_0' P x_0``.

    Raises
    ------
    UnsolvableError
        If ``(A, B)`` is not stabilizable or the cost does not detect a mode with
        ``|lambda| >= 1`` (names the eigenvalue), or the DARE has no stabilizing solution.
    InputError
        If a shape is wrong, a value is not finite, or the weights are not as required.
    """
    if checked:
        A_, B_, Q_, R_ = (np.asarray(M, dtype=np.float64) for M in (A, B, Q, R))
        N_ = np.zeros(B_.shape) if N is None else np.asarray(N, dtype=np.float64)
    else:
        A_, B_, Q_, R_, N_ = _check_cost(A, B, Q, R, N)
    _check_stabilizable(A_, B_)
    _check_detectable(A_, B_, Q_, R_, N_)
    try:
        P = scipy.linalg.solve_discrete_are(A_, B_, Q_, R_, s=N_)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise UnsolvableError(
            f"the discrete Riccati equation has no stabilizing solution ({exc})"
        ) from None
    return _hewer_refined(A_, B_, Q_, R_, N_, 0.5 * (P + P.T))


def dpolicy_value(
    A: ArrayLike,
    B: ArrayLike,
    K: ArrayLike,
    Q: ArrayLike,
    R: ArrayLike,
    N: ArrayLike | None = None,
) -> Array:
    """The value matrix of the policy ``u_k = -K x_k``: the cost from ``x_0`` is ``x_0' P x_0``.

    Solves the discrete Lyapunov (Stein) equation
    ``P = (A - BK)' P (A - BK) + Q - N K - K'N' + K'RK``.

    Parameters
    ----------
    A : array_like, shape (n, n)
        State matrix of the discrete plant.
    B : array_like, shape (n, m)
        Input matrix of the discrete plant.
    K : array_like, shape (m, n)
        Feedback gain of the policy ``u_k = -K x_k``.
    Q : array_like, shape (n, n)
        State weight, symmetric positive semidefinite.
    R : array_like, shape (m, m)
        Input weight, symmetric positive definite.
    N : array_like, shape (n, m), optional
        Cross weight (default zero); ``[[Q, N], [N', R]]`` positive semidefinite.

    Returns
    -------
    P : ndarray, shape (n, n)
        Value matrix of the policy, symmetric.

    Raises
    ------
    UnsolvableError
        If ``A - BK`` is not Schur stable (spectral radius >= 1: the cost is infinite).
    InputError
        If a shape is wrong, a value is not finite, or the weights are not as required.
    """
    A_, B_, Q_, R_, N_ = _check_cost(A, B, Q, R, N)
    K_ = as_matrix(K, "K", (B_.shape[1], A_.shape[0]))
    P, radii = _policy_values(A_[np.newaxis], B_[np.newaxis], K_, Q_, R_, N_)
    if radii[0] >= 1.0:
        raise UnsolvableError(
            f"the policy does not stabilize the plant (spectral radius of A - BK is"
            f" {radii[0]:.6g} >= 1); its cost is infinite"
        )
    return P[0]


def _check_plants(A: ArrayLike, B: ArrayLike) -> tuple[Array, Array]:
    """A stack of plants: ``(p, n, n)`` and ``(p, n, m)`` float arrays, p >= 1, finite (the
    first plant's shapes checked, and named, as one plant's)."""
    try:
        A_, B_ = np.array(A, dtype=float), np.array(B, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
        raise InputError(f"A, B: not numeric stacks of matrices ({exc})") from None
    if A_.ndim != 3 or B_.ndim != 3 or A_.shape[0] != B_.shape[0] or A_.shape[0] == 0:
        raise InputError(
            f"A, B: expected stacks of p >= 1 plants, shapes (p, n, n) and (p, n, m), got"
            f" {A_.shape} and {B_.shape}"
        )
    check_plant(A_[0], B_[0])
    for name, stack in (("A", A_), ("B", B_)):
        if not np.all(np.isfinite(stack)):
            raise InputError(f"{name}: contains NaN or infinite values")
    return A_, B_


def _check_plant_or_stack(A: ArrayLike, B: ArrayLike) -> tuple[Array, Array]:
    """One plant (:func:`check_plant`), or a stack of them given as 3-D ndarrays."""
    if isinstance(A, np.ndarray) and A.ndim == 3:
        return _check_plants(A, B)
    return check_plant(A, B)


def dpolicy_values(
    A: ArrayLike,
    B: ArrayLike,
    K: ArrayLike,
    Q: ArrayLike,
    R: ArrayLike,
    N: ArrayLike | None = None,
) -> tuple[Array, Array]:
    """:func:`dpolicy_value` of one policy (or one per plant) on each of a stack of plants,
    in one solve.

    The weights are checked once; the discrete Lyapunov equations of the stable closed
    loops are solved as one batched Kronecker system (each plant's solution is the one
    :func:`dpolicy_value` gives). A plant the policy does not stabilize is flagged by its
    spectral radius (``>= 1``: the cost is infinite) instead of raising.

    Parameters
    ----------
    A : array_like, shape (p, n, n)
        State matrices of the discrete plants.
    B : array_like, shape (p, n, m)
        Input matrices of the discrete plants.
    K : array_like, shape (m, n)
        Feedback gain of the policy ``u_k = -K x_k`` on every plant; or an ndarray of
        shape ``(p, m, n)``, one gain per plant.
    Q : array_like, shape (n, n)
        State weight, symmetric positive semidefinite.
    R : array_like, shape (m, m)
        Input weight, symmetric positive definite.
    N : array_like, shape (n, m), optional
        Cross weight (default zero); ``[[Q, N], [N', R]]`` positive semidefinite.

    Returns
    -------
    P : ndarray, shape (p, n, n)
        Value matrix of the policy on each plant, symmetric; every entry ``inf`` on a
        plant it does not stabilize.
    radii : ndarray, shape (p,)
        Spectral radius of each ``A - BK``: the policy stabilizes the plants below 1.

    Raises
    ------
    InputError
        If a shape is wrong, a value is not finite, or the weights are not as required.
    """
    A_, B_ = _check_plants(A, B)
    _, _, Q_, R_, N_ = _check_cost(A_[0], B_[0], Q, R, N)
    count, n, m = B_.shape
    if isinstance(K, np.ndarray) and K.ndim == 3:
        K_ = np.asarray(K, dtype=float)
        if K_.shape != (count, m, n) or not np.all(np.isfinite(K_)):
            raise InputError(
                f"K: expected one finite gain of shape ({m}, {n}) or one per plant"
                f" ({count}, {m}, {n}), got shape {K_.shape}"
            )
    else:
        K_ = as_matrix(K, "K", (m, n))
    return _policy_values(A_, B_, K_, Q_, R_, N_)


def sampled_data_weights(
    A: ArrayLike, B: ArrayLike, Q: ArrayLike, R: ArrayLike, h: float
) -> tuple[Array, Array, Array]:
    """The continuous cost over one sample with the input held, as a quadratic form.

    For ``x' = A x + B u`` with ``u = u_k`` held on ``[0, h)`` from ``x(0) = x_k``::

        int_0^h (x'Qx + u'Ru) dt = [x_k; u_k]' [[Qd, N], [N', Rd]] [x_k; u_k]

    computed with one matrix exponential (Van Loan 1978): with ``F = [[A, B], [0, 0]]``
    and ``W = blockdiag(Q, R)``, ``expm([[-F', W], [0, F]] h) = [[*, G], [0, Phi]]`` and
    the integral ``int_0^h expm(F't) W expm(Ft) dt = Phi' G``.

    Parameters
    ----------
    A : array_like, shape (n, n)
        Continuous state matrix, 1/s.
    B : array_like, shape (n, m)
        Continuous input matrix (for the motor, 1/H).
    Q : array_like, shape (n, n)
        Continuous state weight, symmetric positive semidefinite (for the motor, 1/(A^2 s)
        per unit of cost).
    R : array_like, shape (m, m)
        Continuous input weight, symmetric positive definite.
    h : float
        Sampling period, s.

    Returns
    -------
    Qd : ndarray, shape (n, n)
        Weight of ``x_k`` (``h Q + O(h^2)``), symmetric positive semidefinite.
    Rd : ndarray, shape (m, m)
        Weight of ``u_k`` (``h R + O(h^3)``), symmetric positive definite.
    N : ndarray, shape (n, m)
        Cross weight (``h^2 Q B / 2 + O(h^3)``).

    Raises
    ------
    InputError
        If a shape is wrong, a value is not finite, the weights are not as required,
        ``h`` is not positive, or the exponential overflows (``A h`` far too large).
    """
    A_, B_ = check_plant(A, B)
    n, m = B_.shape
    Q_, R_ = check_weights(Q, R, n, m)
    period = positive_finite(h, "h")
    size = n + m
    F = augmented(A_[np.newaxis], B_[np.newaxis], np.zeros((1, n, 0)), None)[0]
    W = scipy.linalg.block_diag(Q_, R_)
    scale = max(float(np.linalg.norm(W)), 1e-300)  # the integral is linear in W
    block = np.block([[-F.T, W / scale], [np.zeros((size, size)), F]])
    with np.errstate(over="ignore", invalid="ignore"):
        exp = scipy.linalg.expm(block * period)
    if not np.all(np.isfinite(exp)):
        raise InputError(
            f"h: the exponential of A h overflows (h = {period:g} s); the sampling period is"
            " far too long for A"
        )
    integral = exp[size:, size:].T @ exp[:size, size:] * scale
    integral = 0.5 * (integral + integral.T)
    return integral[:n, :n].copy(), integral[n:, n:].copy(), integral[:n, n:].copy()


def delay_augmented(Ad: ArrayLike, Bd: ArrayLike, d: int) -> tuple[Array, Array]:
    """The plant seen by a digital controller with a computation delay of d samples.

    The voltage computed at sample k acts over ``[t_(k+d), t_(k+d+1))``. With the state
    ``z_k = [x_k; u_(k-d); ...; u_(k-1)]`` (the oldest delayed input first: the column
    order of :class:`ControlLaw` and :func:`state_names`) and the input ``u_k`` (the
    voltage computed at k)::

        z_(k+1) = Az z_k + Bz u_k,   x_(k+1) = Ad x_k + Bd u_(k-d)

    ``Az`` shifts the delayed inputs up by one block and ``Bz`` puts ``u_k`` last.

    Parameters
    ----------
    Ad : array_like, shape (n, n)
        Discrete state matrix (exact ZOH, :func:`discretize`); or an ndarray of shape
        ``(p, n, n)``, a stack of plants (then Bd one too), augmented each.
    Bd : array_like, shape (n, m)
        Discrete input matrix (for the motor, A/V); ``(p, n, m)`` with a stack.
    d : int
        Delay in samples, ``d >= 0``; ``d = 0`` returns ``(Ad, Bd)``.

    Returns
    -------
    Az : ndarray, shape (n + d m, n + d m)
        State matrix of the augmented plant (``(p, n + d m, n + d m)`` for a stack).
    Bz : ndarray, shape (n + d m, m)
        Input matrix of the augmented plant (``(p, n + d m, m)`` for a stack).

    Raises
    ------
    InputError
        If a shape is wrong, a value is not finite, or d is not a whole number >= 0.
    """
    Ad_, Bd_ = _check_plant_or_stack(Ad, Bd)
    delay = positive_integer(d, "d", minimum=0)
    if delay == 0:
        return Ad_, Bd_
    n, m = Bd_.shape[-2:]
    size, stack = n + delay * m, Ad_.shape[:-2]
    Az = np.zeros((*stack, size, size))
    Az[..., :n, :n] = Ad_
    Az[..., :n, n : n + m] = Bd_
    Az[..., n : size - m, n + m :] = np.eye((delay - 1) * m)
    Bz = np.zeros((*stack, size, m))
    Bz[..., size - m :, :] = np.eye(m)
    return Az, Bz


def integrator_augmented(
    A: ArrayLike, B: ArrayLike, C: ArrayLike, h: float | None = None
) -> tuple[Array, Array]:
    """The plant augmented with ``z``, the integral of its regulated output ``C x``.

    Continuous time (``h`` None), ``z' = C x``::

        A_aug = [[A, 0], [C, 0]],   B_aug = [B; 0]

    Digital (``h`` given), the forward-Euler integrator a drive runs (the integrator of
    :class:`ControlLaw`), ``z_(k+1) = z_k + h C x_k``::

        A_aug = [[A, 0], [h C, I]],   B_aug = [B; 0]

    With ``x`` the deviation ``xbar = x - X w`` and ``C X + F = 0``, ``C xbar`` is the
    regulated error ``e = C x + F w``. The augmented state is ``[x; z]``: K's last r
    columns are the integral gain ``K_i``. For a digital plant with a computation delay,
    pass the delay-augmented ``(Az, Bz)`` (:func:`delay_augmented`) and C padded with
    zeros on the delayed inputs.

    Parameters
    ----------
    A : array_like, shape (n, n)
        State matrix: continuous (1/s) without ``h``, discrete (dimensionless) with it;
        or an ndarray of shape ``(p, n, n)``, a stack of plants (then B one too),
        augmented each.
    B : array_like, shape (n, m)
        Input matrix of the same plant (for the motor, 1/H continuous, A/V discrete);
        ``(p, n, m)`` with a stack.
    C : array_like, shape (r, n)
        Regulated output, ``e = C x`` (dimensionless for the motor's currents).
    h : float, optional
        Sampling period of the digital integrator, s; None (default) for continuous time.

    Returns
    -------
    A_aug : ndarray, shape (n + r, n + r)
        State matrix of ``[x; z]`` (``(p, n + r, n + r)`` for a stack).
    B_aug : ndarray, shape (n + r, m)
        Input matrix of ``[x; z]`` (``(p, n + r, m)`` for a stack).

    Raises
    ------
    InputError
        If a shape is wrong, a value is not finite, or h is not positive.
    """
    A_, B_ = _check_plant_or_stack(A, B)
    n, m = B_.shape[-2:]
    C_ = as_matrix(C, "C", (None, n))
    r, stack = C_.shape[0], A_.shape[:-2]
    A_aug = np.zeros((*stack, n + r, n + r))
    A_aug[..., :n, :n] = A_
    if h is None:
        A_aug[..., n:, :n] = C_
    else:
        A_aug[..., n:, :n] = positive_finite(h, "h") * C_
        A_aug[..., n:, n:] = np.eye(r)
    return A_aug, np.concatenate([B_, np.zeros((*stack, r, m))], axis=-2)


def _check_real_logarithm(Ad: Array, h: float) -> None:
    """Raise unless every eigenvalue of Ad is off the closed negative real axis."""
    for value in unique_eigenvalues(Ad):
        on_axis = value.real <= 0.0 and abs(value.imag) <= 1e-8 * abs(value)
        if abs(value) <= 1e-300 or on_axis:
            raise UnsolvableError(
                f"no real principal logarithm: Ad has the eigenvalue {format_eigenvalue(value)}"
                " on the closed negative real axis; the sampling is too slow for the plant (a"
                f" mode with |Im lambda(A)| h >= pi at h = {h:g} s) or Ad is not the"
                " exponential of a real matrix"
            )


def continuous_from_discrete(
    Ad: ArrayLike, Bd: ArrayLike, h: float, Ed: ArrayLike | None = None
) -> tuple[Array, Array, Array]:
    """The continuous plant whose exact zero-order-hold discretization is ``(Ad, Bd, Ed)``.

    The principal matrix logarithm of ``[[Ad, Bd, Ed], [0, I, 0], [0, 0, I]]`` divided by
    h is ``[[A, B, D], [0, 0, 0], [0, 0, 0]]`` (the inverse of :func:`discretize` with a
    held ``w``). It is the true plant when every eigenvalue of A satisfies
    ``|Im lambda| h < pi``; a faster mode is aliased (the logarithm is then real but
    another plant, which no sampled data can tell apart).

    Parameters
    ----------
    Ad : array_like, shape (n, n)
        Discrete state matrix.
    Bd : array_like, shape (n, m)
        Discrete input matrix.
    h : float
        Sampling period, s.
    Ed : array_like, shape (n, q), optional
        Discrete effect of a held exogenous input (default none, q = 0).

    Returns
    -------
    A : ndarray, shape (n, n)
        Continuous state matrix, 1/s.
    B : ndarray, shape (n, m)
        Continuous input matrix (Bd's unit per second).
    D : ndarray, shape (n, q)
        Continuous exogenous input matrix (Ed's unit per second).

    Raises
    ------
    UnsolvableError
        If the principal logarithm is not real to rounding: Ad has an eigenvalue on the
        closed negative real axis (sampling too slow, ``|Im lambda(A)| h >= pi``, or Ad
        singular or not the exponential of a real matrix).
    InputError
        If a shape is wrong, a value is not finite or h is not positive.
    """
    Ad_, Bd_ = check_plant(Ad, Bd)
    n, m = Bd_.shape
    Ed_ = np.zeros((n, 0)) if Ed is None else as_matrix(Ed, "Ed", (n, None))
    period = positive_finite(h, "h")
    _check_real_logarithm(Ad_, period)
    size = n + m + Ed_.shape[1]
    M = np.eye(size)
    M[:n] = np.hstack([Ad_, Bd_, Ed_])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        logarithm = np.asarray(scipy.linalg.logm(M)) / period
    imaginary = float(np.max(np.abs(logarithm.imag), initial=0.0))
    if imaginary > 1e-8 * max(float(np.max(np.abs(logarithm.real))), 1.0 / period):
        raise UnsolvableError(
            f"no real principal logarithm of the discrete plant (imaginary part {imaginary:.3g}"
            f" 1/s at h = {period:g} s); the sampling is too slow for the plant"
            " (|Im lambda(A)| h >= pi)"
        )
    L = np.real(logarithm)
    return L[:n, :n].copy(), L[:n, n : n + m].copy(), L[:n, n + m :].copy()
