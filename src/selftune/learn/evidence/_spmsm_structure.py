"""A surface PMSM's structure for the output-error fit: ``(Ad, Bd, Ed)`` from ``R_s``,
``L_s``, the back-EMF ratio ``kappa`` (and the dead-time voltage) at a known speed."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

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
        R_s, L_s, kappa = float(theta[0]), float(theta[1]), float(theta[2])
        if not L_s > 0.0:
            raise InputError(f"L_s: must be positive, got {L_s:.4g} H")
        w_e, h = self.electrical_speed, self.h
        A = np.array([[-R_s / L_s, w_e], [-w_e, -R_s / L_s]])
        B = np.eye(2) / L_s
        D = np.array([[0.0, 0.0], [-kappa / L_s, 0.0]])
        exact = discretize(A, B, h, D=D)
        Bd = exact.Bd
        if self.hold == "stationary":  # the angle compensation centres the command
            Bd = rotating_hold(A, B, h, w_e, advance=0.5 * w_e * h)
        if not self.dead_time:
            return exact.Ad, Bd, exact.Ed
        dead_time = rotating_hold(A, B, h, w_e)  # set at the sample's start, then held
        return exact.Ad, Bd, np.hstack([exact.Ed, -float(theta[3]) * dead_time])

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
