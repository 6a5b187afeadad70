"""An interior PMSM's structure for the output-error fit: ``(Ad, Bd, Ed)`` from ``R_s``,
``L_d``, ``L_q``, the back-EMF ratio ``kappa`` (and the dead-time voltage) at a known
speed, for the current-reference form ``w = [w_1, i_d*, i_q*]``."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar, Literal

import numpy as np

from ...core import Array, discretize, rotating_hold
from ...errors import InputError
from ._discrete_model import DiscreteModel

__all__ = ["IpmsmStructure"]


@dataclass(frozen=True)
class IpmsmStructure:
    """An interior PMSM's current dynamics at a known electrical speed: parameters
    ``[R_s, L_d, L_q, kappa]`` (and ``v`` with dead time).

    The current-reference form of the data (``w = [w_1, i_d*, i_q*]``, ``w_1 = p speed
    phi_assumed``, q = 3; :meth:`selftune.model.IPMSM.regulation_problem`)::

        A = [[-R_s/L_d, w_e L_q/L_d], [-w_e L_d/L_q, -R_s/L_q]],  B = diag(1/L_d, 1/L_q),
        D = [[0, 0, 0], [-kappa/L_q, 0, 0]]

    ``kappa = phi_pm / phi_assumed``, so ``phi_pm = kappa w_1 / w_e``. A is not a complex
    number on ``i_d + j i_q`` (the surface motor's closed forms,
    :class:`~selftune.learn.SpmsmStructure`, do not apply): the blocks are the matrix
    exponentials of :func:`selftune.core.discretize` and
    :func:`selftune.core.rotating_hold`, row by row.

    Parameters
    ----------
    electrical_speed : float
        ``w_e = p speed``, rad/s.
    h : float
        Sampling period, s.
    dead_time : bool
        The data carry the phase signs' dq vector as two extra exogenous channels (as
        :class:`~selftune.learn.SpmsmStructure`'s): a fifth parameter ``v``, V.
    hold : {"stationary", "rotor"}
        What the drive holds over a sample (as :class:`~selftune.learn.SpmsmStructure`).
    """

    #: The structure's name in messages.
    title: ClassVar[str] = "IPMSM"

    electrical_speed: float
    h: float
    dead_time: bool = False
    hold: Literal["stationary", "rotor"] = "stationary"

    #: The number of reference channels of the form (``w_1, i_d*, i_q*``).
    references = 3

    def __call__(self, theta: Array) -> tuple[Array, Array, Array]:
        """``(Ad, Bd, Ed)`` of ``theta = [R_s (ohm), L_d (H), L_q (H), kappa]`` (and ``v``, V).

        Parameters
        ----------
        theta : ndarray, shape (4,) or (5,)
            The parameters.

        Raises
        ------
        InputError
            If an inductance is not positive, or the discretization overflows.
        """
        A, B = self.continuous(theta)
        kappa, L_q = float(theta[3]), float(theta[2])
        D = np.zeros((2, self.references))
        D[1, 0] = -kappa / L_q
        v = float(theta[4]) if self.dead_time else None
        return sampled_blocks(A, B, D, self.h, self.electrical_speed, self.hold, v)

    def continuous(self, theta: Array) -> tuple[Array, Array]:
        """The continuous current dynamics ``(A, B)`` (1/s, 1/H) of ``theta``.

        Parameters
        ----------
        theta : ndarray, shape (4,) or (5,)
            The parameters (as :meth:`__call__`'s).

        Raises
        ------
        InputError
            If an inductance is not positive.
        """
        R_s, L_d, L_q = (float(value) for value in np.asarray(theta, dtype=float)[:3])
        for name, value in (("L_d", L_d), ("L_q", L_q)):
            if not value > 0.0:
                raise InputError(f"{name}: must be positive, got {value:.4g} H")
        w_e = self.electrical_speed
        A = np.array([[-R_s / L_d, w_e * L_q / L_d], [-w_e * L_d / L_q, -R_s / L_q]])
        return A, np.diag([1.0 / L_d, 1.0 / L_q])

    def stack(self, thetas: Array) -> tuple[Array, Array, Array]:
        """:meth:`__call__` of each row of ``thetas``, stacked.

        Parameters
        ----------
        thetas : ndarray, shape (P, 4) or (P, 5)
            Rows of parameters.

        Returns
        -------
        Ad, Bd, Ed : ndarray, shape (P, 2, 2), (P, 2, 2), (P, 2, 3) or (P, 2, 5)
        """
        return stacked_rows(self, thetas)

    def initial(self, model: DiscreteModel) -> Array:
        """``[R_s, L_d, L_q, kappa]`` (and ``v``) read off an unstructured model (a start).

        Parameters
        ----------
        model : DiscreteModel
            The least-squares model.
        """
        # as the surface structure's start: one inductance from the mean of Bd's diagonal
        # (the least-squares model's entries are biased by the noise in the currents, one
        # entry alone can be far off) and R_s from the decay, det Ad = exp(trace(A) h)
        L = self.h / float(np.mean(np.diag(model.Bd)))
        decay = -np.log(max(float(np.abs(np.linalg.det(model.Ad))), 1e-300)) / (2 * self.h)
        gains = np.linalg.solve(model.Bd, model.Ed)  # B^-1 D, nearly [[0...], [-kappa, 0...]]
        start = [max(decay * L, 1e-9), L, L, -float(gains[1, 0])]
        if self.dead_time:
            start.append(-float(np.trace(gains[:, self.references :])) / 2.0)  # -v I
        return np.array(start)

    @staticmethod
    def names(dead_time: bool) -> tuple[str, ...]:
        """The parameters' names, in order.

        Parameters
        ----------
        dead_time : bool
            With the dead-time voltage.
        """
        names = ("R_s", "L_d", "L_q", "kappa")
        return (*names, "v") if dead_time else names


def sampled_blocks(
    A: Array, B: Array, D: Array, h: float, electrical_speed: float,
    hold: Literal["stationary", "rotor"], v: float | None,
) -> tuple[Array, Array, Array]:  # fmt: skip
    """``(Ad, Bd, Ed)`` of a motor's continuous ``(A, B, D)`` in the current-reference
    form, sampled as the drive holds its voltage, with the dead time's two channels.

    Parameters
    ----------
    A, B, D : ndarray
        The continuous current dynamics (2 x 2, 2 x 2, 2 x q).
    h : float
        Sampling period, s.
    electrical_speed : float
        ``w_e``, rad/s.
    hold : {"stationary", "rotor"}
        What the drive holds over a sample (as :class:`~selftune.learn.SpmsmStructure`).
    v : float or None
        The dead-time voltage, V (None: no dead-time channels).
    """
    w_e = electrical_speed
    exact = discretize(A, B, h, D=D)
    Bd = exact.Bd
    if hold == "stationary":  # the angle compensation centres the command
        Bd = rotating_hold(A, B, h, w_e, advance=0.5 * w_e * h)
    if v is None:
        return exact.Ad, Bd, exact.Ed
    held = rotating_hold(A, B, h, w_e)  # set in the stationary frame at the start
    return exact.Ad, Bd, np.concatenate([exact.Ed, -v * held], axis=1)


def stacked_rows(
    structure: Callable[[Array], tuple[Array, Array, Array]], thetas: Array
) -> tuple[Array, Array, Array]:
    """A structure's ``(Ad, Bd, Ed)`` of each row of ``thetas``, stacked (P, ...).

    Parameters
    ----------
    structure : callable
        ``theta -> (Ad, Bd, Ed)``.
    thetas : ndarray, shape (P, parameters)
        Rows of parameters.
    """
    blocks = [structure(theta) for theta in np.asarray(thetas, dtype=float)]
    return tuple(np.stack(items) for items in zip(*blocks, strict=True))  # type: ignore[return-value]
