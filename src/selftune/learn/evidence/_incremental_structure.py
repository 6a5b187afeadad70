"""A saturating PMSM's structure for the output-error fit: the current dynamics
linearized about the operating current, ``(Ad, Bd, Ed)`` of ``R_s``, the incremental
inductance matrix and the flux offset (and the dead-time voltage) at a known speed, for
the current-reference form ``w = [w_1, i_d*, i_q*]``.

About the operating current ``i0`` a saturating motor's flux linkage is ``psi(i) ~
psi(i0) + L (i - i0)``, ``L = d psi / d i`` the incremental inductance matrix (symmetric,
cross-saturation ``L_dq`` off the diagonal), so with ``J = [[0, -1], [1, 0]]``::

    L di/dt = u - R_s i - w_e J (L i + c),   c = psi(i0) - L i0

The offset ``c`` has a q component (``psi_q(i0) - L_qd i_d0 - L_qq i_q0``, zero only
without saturation) that :class:`~selftune.learn.IpmsmStructure`, whose offset is the
magnet's ``[phi_pm, 0]``, has no parameter for.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Literal

import numpy as np

from ...core import Array
from ...errors import InputError
from ._discrete_model import DiscreteModel
from ._ipmsm_structure import IpmsmStructure, sampled_blocks, stacked_rows

__all__ = ["IncrementalStructure"]

#: ``J``, the rotation by +90 degrees: ``w_e J psi`` is the rotor frame's back-EMF.
_J = np.array([[0.0, -1.0], [1.0, 0.0]])


@dataclass(frozen=True)
class IncrementalStructure:
    """A saturating PMSM's current dynamics about its operating current at a known
    electrical speed: parameters ``[R_s, L_d, L_q, L_dq, kappa, kappa_q]`` (and ``v`` with
    dead time), ``L_d``, ``L_q``, ``L_dq`` the incremental inductances ``L_dd``, ``L_qq``
    and ``L_dq = L_qd`` (H), ``kappa``, ``kappa_q`` the flux offset ``c`` over the flux
    the data assume (see the module docstring).

    The current-reference form (``w = [w_1, i_d*, i_q*]``, ``w_1 = p speed phi_assumed``,
    q = 3), ``L = [[L_d, L_dq], [L_dq, L_q]]``::

        A = -L^-1 (R_s I + w_e J L),  B = L^-1,  D = [-L^-1 J [kappa, kappa_q], 0, 0]

    so ``c = [kappa, kappa_q] w_1 / w_e``. With ``L_dq = kappa_q = 0`` it is
    :class:`~selftune.learn.IpmsmStructure`'s model (to rounding); the blocks are the same
    matrix exponentials (:func:`selftune.core.discretize`,
    :func:`selftune.core.rotating_hold`).

    Parameters
    ----------
    electrical_speed : float
        ``w_e = p speed``, rad/s.
    h : float
        Sampling period, s.
    dead_time : bool
        The data carry the phase signs' dq vector as two extra exogenous channels: a
        seventh parameter ``v``, V (as :class:`~selftune.learn.IpmsmStructure`).
    hold : {"stationary", "rotor"}
        What the drive holds over a sample (as :class:`~selftune.learn.SpmsmStructure`).
    """

    #: The structure's name in messages.
    title: ClassVar[str] = "incremental (saturating)"

    electrical_speed: float
    h: float
    dead_time: bool = False
    hold: Literal["stationary", "rotor"] = "stationary"

    #: The number of reference channels of the form (``w_1, i_d*, i_q*``).
    references = 3

    def continuous(self, theta: Array) -> tuple[Array, Array, Array]:
        """The continuous ``(A, B, D)`` of ``theta`` (see the class docstring).

        Parameters
        ----------
        theta : ndarray, shape (6,) or (7,)
            ``[R_s (ohm), L_d, L_q, L_dq (H), kappa, kappa_q]`` (and ``v``, V).

        Raises
        ------
        InputError
            If the inductance matrix is not positive definite.
        """
        R_s, L_d, L_q, L_dq, kappa, kappa_q = (
            float(value) for value in np.asarray(theta, dtype=float)[:6]
        )
        for name, value in (("L_d", L_d), ("L_q", L_q), ("det L", L_d * L_q - L_dq * L_dq)):
            if not value > 0.0:
                raise InputError(f"{name}: must be positive, got {value:.4g}")
        L = np.array([[L_d, L_dq], [L_dq, L_q]])
        B = np.linalg.inv(L)
        A = -B @ (R_s * np.eye(2) + self.electrical_speed * (_J @ L))
        D = np.zeros((2, self.references))
        D[:, 0] = -B @ (_J @ np.array([kappa, kappa_q]))
        return A, B, D

    def __call__(self, theta: Array) -> tuple[Array, Array, Array]:
        """``(Ad, Bd, Ed)`` of ``theta`` (see :meth:`continuous`).

        Parameters
        ----------
        theta : ndarray, shape (6,) or (7,)
            The parameters.

        Raises
        ------
        InputError
            If the inductance matrix is not positive definite, or the discretization
            overflows.
        """
        A, B, D = self.continuous(theta)
        v = float(theta[6]) if self.dead_time else None
        return sampled_blocks(A, B, D, self.h, self.electrical_speed, self.hold, v)

    def stack(self, thetas: Array) -> tuple[Array, Array, Array]:
        """:meth:`__call__` of each row of ``thetas``, stacked.

        Parameters
        ----------
        thetas : ndarray, shape (P, 6) or (P, 7)
            Rows of parameters.

        Returns
        -------
        Ad, Bd, Ed : ndarray, shape (P, 2, 2), (P, 2, 2), (P, 2, 3) or (P, 2, 5)
        """
        return stacked_rows(self, thetas)

    def initial(self, model: DiscreteModel) -> Array:
        """The parameters read off an unstructured model (a start): the interior
        structure's start (:meth:`IpmsmStructure.initial`) with ``L_dq = 0`` and
        ``kappa_q`` from ``B^-1 D``'s first column, ``-J [kappa, kappa_q] = [kappa_q,
        -kappa]``.

        Parameters
        ----------
        model : DiscreteModel
            The least-squares model.
        """
        interior = IpmsmStructure(self.electrical_speed, self.h, self.dead_time, self.hold)
        start = interior.initial(model)
        kappa_q = float(np.linalg.solve(model.Bd, model.Ed)[0, 0])
        return np.concatenate([start[:3], [0.0, start[3], kappa_q], start[4:]])

    @staticmethod
    def names(dead_time: bool) -> tuple[str, ...]:
        """The parameters' names, in order.

        Parameters
        ----------
        dead_time : bool
            With the dead-time voltage.
        """
        names = ("R_s", "L_d", "L_q", "L_dq", "kappa", "kappa_q")
        return (*names, "v") if dead_time else names
