"""A surface PMSM's structure for the output-error fit: ``(Ad, Bd, Ed)`` from ``R_s``,
``L_s``, the back-EMF ratio ``kappa`` (and the dead-time voltage) at a known speed."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from ...core import Array, augmented, discretize, expm_stack, rotating_hold
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

    electrical_speed: float
    h: float
    dead_time: bool = False
    hold: Literal["stationary", "rotor"] = "stationary"

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
        """``(Ad, Bd, Ed)`` of a stack of parameters at once (one matrix exponential
        call for all of them, as a Jacobian's steps or the plausible plants need): each
        the same numbers as :meth:`__call__` of its row.

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
        A = np.zeros((P, 2, 2))
        B = np.zeros((P, 2, 2))
        D = np.zeros((P, 2, 2))
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            A[:, 0, 0] = A[:, 1, 1] = -R_s / L_s
            A[:, 0, 1], A[:, 1, 0] = w_e, -w_e
            B[:, 0, 0] = B[:, 1, 1] = 1.0 / L_s
            D[:, 1, 0] = -kappa / L_s
            turns = self.hold == "stationary" or self.dead_time
            # the zero-order hold's and the rotating hold's exponentials (rotating_hold:
            # a held vector turning by [[0, w_e], [-w_e, 0]]), one stack
            M = augmented(A, B, D, None)
            if turns:
                rotation = np.array([[0.0, w_e], [-w_e, 0.0]])
                M = np.concatenate([M, augmented(A, B, B, rotation)])
            exp = expm_stack(M, np.array([h]), uniform=P == 1)[:, 0]
        failed = ~(L_s > 0.0) | ~np.all(np.isfinite(exp.reshape(-1, P, 36)), axis=(0, 2))
        if np.any(failed):
            self._refuse(A, B, D, L_s, int(np.flatnonzero(failed)[0]))
        Ad, Bd, Ed = exp[:P, :2, :2].copy(), exp[:P, :2, 2:4].copy(), exp[:P, :2, 4:].copy()
        if not turns:
            return Ad, Bd, Ed
        turning = np.ascontiguousarray(exp[P:, :2, 4:])
        if self.hold == "stationary":  # the angle compensation centres the command
            advance = 0.5 * w_e * h
            c, s = np.cos(advance), np.sin(advance)
            Bd = turning @ np.array([[c, -s], [s, c]])
        if not self.dead_time:
            return Ad, Bd, Ed
        # set at the sample's start, then held (no advance)
        dead_time = turning @ np.array([[1.0, -0.0], [0.0, 1.0]])
        return Ad, Bd, np.concatenate([Ed, -thetas[:, 3, None, None] * dead_time], axis=2)

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
