"""An interior motor (``L_d != L_q``) over one sample, exactly, in the rotor frame.

In the stationary frame a salient motor is not a complex scalar (its inductance turns
with the rotor), so :mod:`._inverter`'s closed form for the surface motor does not hold.
At a held speed the rotor-frame currents are LTI (the motor's
:meth:`~selftune.model.IPMSM.torque_mode`)::

    di/dt = A i + B u + d,   A = [[-R_s/L_d, w_e L_q/L_d], [-w_e L_d/L_q, -R_s/L_q]],
                             B = diag(1/L_d, 1/L_q),  d = [0, -w_e phi_pm / L_q]

(SI units; ``i``, ``u`` real 2-vectors ``[d, q]``). Over a sample ``[0, T]`` with the
rotor at ``theta_0`` at its start, a stationary vector V held over ``[a, b]`` is the
turning rotor-frame input ``u(s) = exp(Omega s) v``, ``v = Rot(-theta_0) V``, ``Omega =
[[0, w_e], [-w_e, 0]]``; with G solving the Sylvester equation ``A G - G Omega = -B``
(``Omega``'s eigenvalues ``+-j w_e`` are never A's, whose real parts are negative)::

    int_a^b exp(A (T - s)) B exp(Omega s) ds = M(b) - M(a),  M(s) = exp(A (T - s)) G exp(Omega s)
                                           = exp(A (T - b)) H(b - a) exp(Omega b),
    H(tau) = int_0^tau exp(A u) B exp(-Omega u) du = G - exp(A tau) G exp(-Omega tau)
           = -(E G + G R + E G R),  E = exp(A tau) - I,  R = exp(-Omega tau) - I

(the last form without the cancellation of the difference: a pulse of width ``tau`` is
small beside G, by about ``max(|A|, w_e) tau``), and a rotor-frame vector u held over the
sample, with the back-EMF, gives::

    int_0^T exp(A (T - s)) ds (B u + d) = (exp(A T) - I) A^-1 (B u + d)

The matrix exponential of the 2 x 2 A is its closed form ``exp(s tau) [cosh(delta tau) I +
sinh(delta tau) / delta (A - s I)]``, ``s = trace / 2``, ``delta^2 = ((a - d) / 2)^2 + b c``
(cosine and sine for ``delta^2 < 0``, ``tau`` at 0), with ``exp(A tau) - I`` formed
without cancellation. No ODE solver. :class:`RotorFrame` is one motor in Python floats
(the carrier PWM's pulses, :func:`._pwm.carrier_sample`); :class:`RotorFrames` P
motors' sample maps as arrays (the average PWM, :func:`~selftune.sim._inverter._step`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from math import cos, exp, expm1, sin, sinh, sqrt

import numpy as np
from scipy.linalg import solve_sylvester

from ..core import Array
from ..core._phases import ComplexArray

__all__ = ["Matrix", "RotorFrame", "RotorFrames", "exp_minus_identity"]

#: A real 2 x 2 matrix ``[[a, b], [c, d]]`` as the floats ``(a, b, c, d)``.
Matrix = tuple[float, float, float, float]


def exp_minus_identity(A: Matrix, tau: float) -> Matrix:
    """``exp(A tau) - I`` of a real 2 x 2 matrix in closed form (see the module docstring),
    without cancellation at small ``tau``; ``tau`` in s, A in 1/s."""
    a, b, c, d = A
    s, half = 0.5 * (a + d), 0.5 * (a - d)
    delta2 = half * half + b * c
    x = s * tau
    grow = exp(x)
    if delta2 > 0.0:  # real eigenvalues: cosh(r tau) - 1 = 2 sinh(r tau / 2)^2
        r = sqrt(delta2)
        diagonal = expm1(x) + grow * 2.0 * sinh(0.5 * r * tau) ** 2
        along = grow * sinh(r * tau) / r
    elif delta2 < 0.0:  # complex eigenvalues: cos(r tau) - 1 = -2 sin(r tau / 2)^2
        r = sqrt(-delta2)
        diagonal = expm1(x) - grow * 2.0 * sin(0.5 * r * tau) ** 2
        along = grow * sin(r * tau) / r
    else:
        diagonal, along = expm1(x), grow * tau
    return (diagonal + along * half, along * b, along * c, diagonal - along * half)


def _product(X: Matrix, Y: Matrix) -> Matrix:
    return (
        X[0] * Y[0] + X[1] * Y[2],
        X[0] * Y[1] + X[1] * Y[3],
        X[2] * Y[0] + X[3] * Y[2],
        X[2] * Y[1] + X[3] * Y[3],
    )


def _times(X: Matrix, v: complex) -> complex:
    """The matrix X times the vector ``[v.real, v.imag]``, as a complex number."""
    return complex(X[0] * v.real + X[1] * v.imag, X[2] * v.real + X[3] * v.imag)


@dataclass(frozen=True, eq=False)
class RotorFrame:
    """One motor over one sample in the rotor frame (see the module docstring).

    Attributes
    ----------
    A : Matrix
        The current dynamics at the held speed, 1/s.
    G : Matrix
        The solution of ``A G - G Omega = -B``, A/(V s).
    speed : float
        ``w_e``, rad/s.
    period : float
        T, s.
    decay : Matrix
        ``exp(A T)``: the start's current at the end.
    stationary : Matrix
        ``M(T) - M(0) = H(T) exp(Omega T)``: a stationary vector held over the sample
        (turned to the rotor frame at its start), A/V.
    rotor : Matrix
        ``(exp(A T) - I) A^-1 B``: a rotor-frame vector held over the sample, A/V.
    emf : complex
        ``(exp(A T) - I) A^-1 d``: the back-EMF's part, A (``d + j q``).
    """

    A: Matrix
    G: Matrix
    speed: float
    period: float
    decay: Matrix
    stationary: Matrix
    rotor: Matrix
    emf: complex

    @classmethod
    def build(
        cls, R_s: float, L_d: float, L_q: float, phi_pm: float, speed: float, period: float
    ) -> RotorFrame:
        """The motor (ohm, H, H, Wb) at the electrical speed ``w_e`` (rad/s) over a sample
        of ``period`` (s)."""
        A = (-R_s / L_d, speed * L_q / L_d, -speed * L_d / L_q, -R_s / L_q)
        omega = np.array([[0.0, speed], [-speed, 0.0]])
        B = np.diag([1.0 / L_d, 1.0 / L_q])
        G: Matrix = tuple(  # type: ignore[assignment]
            float(g) for g in solve_sylvester(np.reshape(A, (2, 2)), -omega, -B).ravel()
        )
        E = exp_minus_identity(A, period)
        decay = (E[0] + 1.0, E[1], E[2], E[3] + 1.0)
        cosine, sine = cos(speed * period), sin(speed * period)
        columns = (_held(A, G, speed, period, 1.0), _held(A, G, speed, period, 1j))
        H = (columns[0].real, columns[1].real, columns[0].imag, columns[1].imag)
        stationary = _product(H, (cosine, sine, -sine, cosine))  # H(T) exp(Omega T)
        det = A[0] * A[3] - A[1] * A[2]
        inverse = (A[3] / det, -A[1] / det, -A[2] / det, A[0] / det)
        integral = _product(E, inverse)  # (exp(A T) - I) A^-1
        rotor = _product(integral, (1.0 / L_d, 0.0, 0.0, 1.0 / L_q))
        emf = _times(integral, complex(0.0, -speed * phi_pm / L_q))
        return cls(A, G, speed, period, decay, stationary, rotor, emf)

    def pulse(self, rise: float, fall: float, v: complex) -> complex:
        """The current at the sample's end (A, ``d + j q``) that the stationary vector
        held over ``[rise, fall]`` (s from the start) makes, ``v`` (V) being that vector
        in the rotor frame at the start: ``exp(A (T - b)) H(b - a) exp(Omega b) v``."""
        speed = self.speed
        turned = v * complex(cos(speed * fall), -sin(speed * fall))  # exp(Omega b) v
        held = _held(self.A, self.G, speed, fall - rise, turned)
        return held + _times(exp_minus_identity(self.A, self.period - fall), held)

    def free(self, current: complex) -> complex:
        """``exp(A T) i + (exp(A T) - I) A^-1 d``: the current at the sample's end (A, ``d
        + j q``) from ``current`` at its start, with no voltage."""
        return _times(self.decay, current) + self.emf


def _held(A: Matrix, G: Matrix, speed: float, tau: float, v: complex) -> complex:
    """``H(tau) v = -(E G v + G R v + E G R v)`` (see the module docstring; ``v`` as ``d +
    j q``, ``speed`` ``w_e``): the current a rotor-frame vector ``exp(-Omega u) v`` held
    over ``[0, tau]`` makes at ``tau``."""
    E = exp_minus_identity(A, tau)
    # R v = (exp(-Omega tau) - I) v = (exp(j w_e tau) - 1) v, without cancellation
    half = sin(0.5 * speed * tau)
    turned = v * complex(-2.0 * half * half, sin(speed * tau))
    direct, through = _times(G, v), _times(G, turned)
    return -(_times(E, direct + through) + through)


def _apply(M: Array, v: ComplexArray) -> ComplexArray:
    """The real matrices M (P, 2, 2) times the vectors v (P,) (``d + j q``)."""
    return (M[:, 0, 0] * v.real + M[:, 0, 1] * v.imag) + 1j * (
        M[:, 1, 0] * v.real + M[:, 1, 1] * v.imag
    )


class RotorFrames:
    """P motors' :class:`RotorFrame` as arrays: one sample of average PWM at once.

    Parameters
    ----------
    frames : sequence of RotorFrame
        One per motor.
    """

    def __init__(self, frames: Sequence[RotorFrame]) -> None:
        self.frames = tuple(frames)
        self.decay = np.array([f.decay for f in self.frames], dtype=float).reshape(-1, 2, 2)
        self.stationary = np.array([f.stationary for f in self.frames], dtype=float).reshape(
            -1, 2, 2
        )
        self.rotor = np.array([f.rotor for f in self.frames], dtype=float).reshape(-1, 2, 2)
        self.emf = np.array([f.emf for f in self.frames], dtype=complex)

    @classmethod
    def build(
        cls, R_s: Array, L_d: Array, L_q: Array, phi_pm: Array, speed: Array, period: float
    ) -> RotorFrames:
        """P motors (arrays (P,): ohm, H, H, Wb, electrical rad/s) over ``period`` (s)."""
        rows = zip(
            R_s.tolist(), L_d.tolist(), L_q.tolist(), phi_pm.tolist(), speed.tolist(), strict=True
        )
        return cls(tuple(RotorFrame.build(*row, period=period) for row in rows))

    def advance(
        self,
        current: ComplexArray,
        steady: ComplexArray,
        turning: ComplexArray | None,
        rotor: ComplexArray,
        following: ComplexArray,
    ) -> ComplexArray:
        """``i_ab`` (P,) at the sample's end from ``current`` (``i_ab`` at its start), a
        stationary vector ``steady`` held over it and ``turning`` (a stationary vector
        ``exp(j theta_0) u`` whose rotor-frame value u is held; None: none), V, with the
        rotor at ``rotor`` and ``following`` (``exp(j theta)``) at the start and end."""
        turn = np.conj(rotor)
        after = _apply(self.decay, turn * current) + _apply(self.stationary, turn * steady)
        if turning is not None:
            after = after + _apply(self.rotor, turn * turning)
        return following * (after + self.emf)
