"""A surface PMSM's structure for the output-error fit: ``(Ad, Bd, Ed)`` from ``R_s``,
``L_s``, the back-EMF ratio ``kappa`` (and the dead-time voltage) at a known speed."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar, Literal

import numpy as np
from numpy.typing import NDArray

from ...core import Array, discretize, rotating_hold
from ...errors import InputError
from ._discrete_model import DiscreteModel

__all__ = ["SpmsmStructure"]


@dataclass(frozen=True)
class SpmsmStructure:
    """A surface PMSM's current dynamics at a known electrical speed: parameters
    ``[R_s, L_s, kappa]`` (and ``v`` with dead time).

    The known-flux form of the data (``w = [w_1, T*]``, ``w_1 = p speed phi_assumed`` the
    back-EMF the controller assumes, q = 2)::

        A = [[-R_s/L_s, w_e], [-w_e, -R_s/L_s]],  B = I / L_s,  D = [[0, 0], [-kappa/L_s, 0]]

    ``kappa = phi_pm / phi_assumed`` is the true back-EMF per unit of ``w_1``: the flux is
    fitted, not assumed (``phi_pm = kappa w_1 / w_e``).

    Parameters
    ----------
    electrical_speed : float
        ``w_e = p speed``, rad/s.
    h : float
        Sampling period, s.
    dead_time : bool
        The data carry the dq vector ``s_k`` of the phase currents' signs as two extra
        exogenous channels (:mod:`._dead_time`): an inverter's dead-time voltage ``v =
        t_d f_sw V_dc`` per phase, V, a fourth parameter. It is held in the stationary
        frame from the sample's start, so in dq it turns by ``-w_e s`` within the sample.
    hold : {"stationary", "rotor"}
        What the drive holds over a sample: the stationary-frame voltage (a PWM inverter),
        rotated by the usual angle compensation so that its dq mean is the command (it
        turns from ``+w_e h / 2`` to ``-w_e h / 2`` in dq), or the dq voltage (an ideal
        zero-order hold, e.g. :class:`selftune.sim.SimulatedDrive`).
    """

    #: The structure's name in messages.
    title: ClassVar[str] = "SPMSM"

    electrical_speed: float
    h: float
    dead_time: bool = False
    hold: Literal["stationary", "rotor"] = "stationary"

    #: The number of reference channels of the form (``w_1, T*``).
    references = 2

    def __call__(self, theta: Array) -> tuple[Array, Array, Array]:
        """``(Ad, Bd, Ed)`` of ``theta = [R_s (ohm), L_s (H), kappa]`` (and ``v``, V).

        Parameters
        ----------
        theta : ndarray, shape (3,) or (4,)
            ``[R_s, L_s, kappa]``, and ``v`` with dead time.

        Raises
        ------
        InputError
            If ``L_s`` is not positive, or the discretization overflows (the fit treats
            such parameters as giving no model).
        """
        Ad, Bd, Ed = self.stack(np.asarray(theta, dtype=float)[np.newaxis])
        return Ad[0], Bd[0], Ed[0]

    def stack(self, thetas: Array) -> tuple[Array, Array, Array]:
        """``(Ad, Bd, Ed)`` of a stack of parameters at once (as a Jacobian's steps or the
        plausible plants need): each the same numbers as :meth:`__call__` of its row.

        The exponentials are closed forms: ``A = -(R_s / L_s) I + w_e J`` acts on ``i_d +
        j i_q`` as the complex number ``mu = -R_s / L_s - j w_e``, so ``Ad`` is
        ``exp(mu h)``, the zero-order hold's ``(exp(mu h) - 1) / (mu L_s)``, and the
        rotating hold (which commutes with A) ``exp(-j w_e h) (1 - exp(-a h)) / (a L_s)``
        (``a = R_s / L_s``), each without cancellation for small arguments. They agree
        with the matrix exponentials of the augmented matrices to rounding, stiff plants
        included, at a tenth of the time.

        Parameters
        ----------
        thetas : ndarray, shape (P, 3) or (P, 4)
            Rows ``[R_s, L_s, kappa]``, and ``v`` with dead time.

        Returns
        -------
        Ad : ndarray, shape (P, 2, 2)
        Bd : ndarray, shape (P, 2, 2)
        Ed : ndarray, shape (P, 2, 2) or (P, 2, 4)

        Raises
        ------
        InputError
            As :meth:`__call__`, for the first row that fails.
        """
        thetas = np.asarray(thetas, dtype=float)
        P = thetas.shape[0]
        R_s, L_s, kappa = thetas[:, 0], thetas[:, 1], thetas[:, 2]
        w_e, h = self.electrical_speed, self.h
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            # A = -a I + w_e J acts on [i_d, i_q] as the complex number mu = -a - j w_e
            # on i_d + j i_q; every block is a power series in A: closed forms
            a = R_s / L_s
            mu = -a - 1j * w_e
            growth = np.exp(mu * h)  # Ad
            gamma = h * _phi(mu * h) / L_s  # int_0^h expm(A s) ds B: the zero-order hold
            # a held vector turning by [[0, w_e], [-w_e, 0]] (exp(-j w_e s)) commutes with
            # A: int_0^h expm(A (h - s)) B Rot(-w_e s) ds = Rot(-w_e h) (1 - exp(-a h)) / (a L)
            turning = np.exp(-1j * w_e * h) * h * _phi(-a * h) / L_s
            Ed = np.zeros((P, 2, 2))  # the back-EMF's: gamma L_s D, D = -kappa/L_s e_2 e_1'
            Ed[:, 0, 0], Ed[:, 1, 0] = kappa * gamma.imag, -kappa * gamma.real
            blocks = [growth, gamma, turning, Ed[:, :, 0]]
        failed = ~(L_s > 0.0) | ~np.all(np.isfinite(np.column_stack(blocks)), axis=1)
        if np.any(failed):
            A, B, D = self._continuous(R_s, L_s, kappa)
            self._refuse(A, B, D, L_s, int(np.flatnonzero(failed)[0]))
        Ad = _real(growth)
        if self.hold == "rotor" and not self.dead_time:
            return Ad, _real(gamma), Ed
        # the angle compensation centres the command: it starts w_e h / 2 ahead
        advance = 0.5 * w_e * h if self.hold == "stationary" else 0.0
        Bd = _real(turning * np.exp(1j * advance)) if self.hold == "stationary" else _real(gamma)
        if not self.dead_time:
            return Ad, Bd, Ed
        # set at the sample's start, then held (no advance)
        dead_time = _real(turning)
        return Ad, Bd, np.concatenate([Ed, -thetas[:, 3, None, None] * dead_time], axis=2)

    def continuous(self, theta: Array) -> tuple[Array, Array]:
        """The continuous current dynamics ``(A, B)`` (1/s, 1/H) of ``theta``.

        Parameters
        ----------
        theta : ndarray, shape (3,) or (4,)
            The parameters (as :meth:`__call__`'s).
        """
        rows = np.asarray(theta, dtype=float)[np.newaxis, :3]
        A, B, _ = self._continuous(rows[:, 0], rows[:, 1], rows[:, 2])
        return A[0], B[0]

    def _continuous(self, R_s: Array, L_s: Array, kappa: Array) -> tuple[Array, Array, Array]:
        """The continuous-time ``A``, ``B``, ``D`` of a stack of parameters."""
        P, w_e = R_s.size, self.electrical_speed
        A, B, D = np.zeros((P, 2, 2)), np.zeros((P, 2, 2)), np.zeros((P, 2, 2))
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            A[:, 0, 0] = A[:, 1, 1] = -R_s / L_s
            A[:, 0, 1], A[:, 1, 0] = w_e, -w_e
            B[:, 0, 0] = B[:, 1, 1] = 1.0 / L_s
            D[:, 1, 0] = -kappa / L_s
        return A, B, D

    def _refuse(self, A: Array, B: Array, D: Array, L_s: Array, row: int) -> None:
        """Raise the error of a row whose matrices cannot be made (:func:`discretize`'s
        and :func:`rotating_hold`'s own messages)."""
        if not L_s[row] > 0.0:
            raise InputError(f"L_s: must be positive, got {float(L_s[row]):.4g} H")
        discretize(A[row], B[row], self.h, D=D[row])
        rotating_hold(A[row], B[row], self.h, self.electrical_speed)
        raise InputError("theta: the discretization overflows")  # not reached

    def initial(self, model: DiscreteModel) -> Array:
        """``[R_s, L_s, kappa]`` (and ``v``) read off an unstructured model (a start).

        Parameters
        ----------
        model : DiscreteModel
            The least-squares model.
        """
        L_s = self.h / float(np.mean(np.diag(model.Bd)))
        decay = -np.log(max(float(np.abs(np.linalg.det(model.Ad))), 1e-300)) / (2 * self.h)
        gains = np.linalg.solve(model.Bd, model.Ed)  # B^-1 D, nearly: [[0, 0], [-kappa, 0]]
        start = [max(decay * L_s, 1e-9), L_s, -float(gains[1, 0])]
        if self.dead_time:
            start.append(-float(np.trace(gains[:, 2:])) / 2.0)  # -v I
        return np.array(start)

    @staticmethod
    def names(dead_time: bool) -> tuple[str, ...]:
        """The parameters' names, in order.

        Parameters
        ----------
        dead_time : bool
            With the dead-time voltage.
        """
        return ("R_s", "L_s", "kappa", "v") if dead_time else ("R_s", "L_s", "kappa")


def _phi(z: NDArray[Any]) -> NDArray[Any]:
    """``(exp(z) - 1) / z`` (1 at 0), accurate for small ``|z|`` too, real or complex."""
    z = np.asarray(z)
    if np.iscomplexobj(z):  # exp(z) - 1 without cancellation: expm1 is real-only
        x, y = z.real, z.imag
        less_one = np.expm1(x) * np.cos(y) - 2.0 * np.sin(0.5 * y) ** 2 + 1j * np.exp(x) * np.sin(y)
    else:
        less_one = np.expm1(z)
    small = np.abs(z) < 1e-5  # the series: its next term is below 1e-16
    safe = np.where(small, 1.0, z)
    return np.where(small, 1.0 + z / 2.0 + z * z / 6.0, less_one / safe)


def _real(g: NDArray[Any]) -> Array:
    """The 2 x 2 real matrices acting on ``[x, y]`` as the complex numbers ``g`` act on
    ``x + j y``: ``[[Re g, -Im g], [Im g, Re g]]``, shape (P, 2, 2)."""
    M = np.empty((g.size, 2, 2))
    M[:, 0, 0] = M[:, 1, 1] = g.real
    M[:, 1, 0] = g.imag
    M[:, 0, 1] = -g.imag
    return M
