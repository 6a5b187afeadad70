"""The surface-mounted PMSM: parameters, the full model, and torque-control mode.

The model is the standard dq model of a surface PMSM (L_d = L_q = L_s), with the signs
corrected as in PAPER_NOTES.md section 2. With ``gamma = R_s / L_s``, mechanical speed
``speed`` (rad/s) and electrical speed ``p * speed``::

    di_d/dt = -gamma i_d + p speed i_q                        + u_d / L_s
    di_q/dt = -p speed i_d - gamma i_q - p speed phi_pm / L_s + u_q / L_s
    T_e     = (3 p / 2) phi_pm i_q
    J dspeed/dt = T_e - T_L

In torque-control mode the speed is held by the load machine, and the current dynamics
are linear. The torque reference ``T*`` asks for ``i_q* = 2 T* / (3 p phi_pm)``, ``i_d* = 0``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..core import (
    PAPER_MOTOR,
    PAPER_TABLE_MOTOR,
    Array,
    positive_finite,
)
from ..core._validation import check_range
from ._forms import PmsmForms, _checked, _checked_pole_pairs
from ._problem import RegulationProblem

__all__ = ["SPMSM"]


@dataclass(frozen=True)
class SPMSM(PmsmForms):
    """Surface-mounted permanent-magnet synchronous motor (SI units).

    Parameters
    ----------
    R_s : float
        Stator resistance, ohm.
    L_s : float
        Stator inductance (L_d = L_q), H.
    phi_pm : float
        Permanent-magnet flux linkage, Wb.
    p : int
        Number of pole pairs.
    J : float, optional
        Rotor inertia, kg m^2; needed only by the full model with speed as a state.

    Raises
    ------
    InputError
        (a ``ValueError``) naming the field, if a value is not positive and finite or is
        outside its plausible range (``PLAUSIBLE_RANGES`` of :mod:`selftune.core`: R_s
        1e-6..1e3 ohm, L_s 1e-7..10 H, phi_pm 1e-5..10 Wb, p 1..100, J 1e-9..1e6 kg m^2),
        or ``p`` is not a whole number. Speeds (at most 1e5 rad/s in magnitude) and torques
        (1e6 N m) given to the methods are checked the same way.

    Examples
    --------
    >>> motor = SPMSM.paper()
    >>> A, B = motor.torque_mode(speed=10.0)
    """

    R_s: float
    L_s: float
    phi_pm: float
    p: int
    J: float | None = None

    def __post_init__(self) -> None:
        for name in ("R_s", "L_s", "phi_pm"):
            value = check_range(positive_finite(getattr(self, name), name), name)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "p", _checked_pole_pairs(self.p))
        if self.J is not None:
            object.__setattr__(self, "J", check_range(positive_finite(self.J, "J"), "J"))

    @classmethod
    def paper(cls) -> SPMSM:
        """The reconciled parameters that reproduce every number the paper prints.

        ``R_s = 0.439 ohm, L_s = 0.0601 H, phi_pm = 0.46 Wb, p = 2, J = 0.0163 kg m^2``
        (PAPER_NOTES.md, erratum 1).
        """
        return cls(**PAPER_MOTOR)  # type: ignore[arg-type]

    @classmethod
    def paper_table(cls) -> SPMSM:
        """Table II of the paper as printed (``L_s = 0.0615 H, phi_pm = 0.5 Wb``).

        These values do not reproduce the paper's results; see :meth:`paper`.
        """
        return cls(**PAPER_TABLE_MOTOR)  # type: ignore[arg-type]

    @property
    def gamma(self) -> float:
        """``R_s / L_s``, 1/s."""
        return self.R_s / self.L_s

    @property
    def L_d(self) -> float:
        """The d-axis inductance, ``L_s``, H (as :class:`~selftune.model.IPMSM`'s)."""
        return self.L_s

    @property
    def L_q(self) -> float:
        """The q-axis inductance, ``L_s``, H."""
        return self.L_s

    @property
    def saliency(self) -> float:
        """``L_q / L_d``: 1."""
        return 1.0

    @property
    def reference_names(self) -> tuple[str, ...]:
        """What each entry of ``w`` is: ``("p speed phi_pm", "T*")``."""
        return ("p speed phi_pm", "T*")

    def _inductances(self) -> dict[str, float]:
        return {"L_s": self.L_s}

    # -- full model ---------------------------------------------------------------------

    def torque(self, i_q: ArrayLike, i_d: ArrayLike | None = None) -> Array:
        """Electromagnetic torque ``(3 p / 2) phi_pm i_q``, N m (``i_q`` in A).

        Parameters
        ----------
        i_q : array_like
            q-axis current, A.
        i_d : array_like, optional
            d-axis current, A: no torque on a surface motor (accepted so that code
            written for :class:`~selftune.model.IPMSM` serves both).
        """
        return 1.5 * self.p * self.phi_pm * np.asarray(i_q, dtype=float)

    # -- torque-control mode ------------------------------------------------------------

    def torque_mode(self, speed: float) -> tuple[Array, Array]:
        """``(A, B)`` of the current dynamics at a held mechanical speed (rad/s).

        Parameters
        ----------
        speed : float
            Mechanical speed, rad/s, held by the load machine.

        Returns
        -------
        A : ndarray, shape (2, 2)
            State matrix of ``x = [i_d, i_q]``, 1/s.
        B : ndarray, shape (2, 2)
            Input matrix ``I / L_s``, 1/H.
        """
        electrical_speed = self.p * _checked(speed, "speed")
        A = np.array([[-self.gamma, electrical_speed], [-electrical_speed, -self.gamma]])
        B = np.eye(2) / self.L_s
        return A, B

    def exogenous(self, speed: float, torque: float) -> Array:
        """``w = [p speed phi_pm, T*]`` of the known-flux regulation form (eq. 8).

        Parameters
        ----------
        speed : float
            Mechanical speed, rad/s.
        torque : float
            Torque reference ``T*``, N m.
        """
        speed = _checked(speed, "speed")
        return np.array([self.p * speed * self.phi_pm, _checked(torque, "torque")])

    def regulation_problem(self, speed: float) -> RegulationProblem:
        """The known-flux output-regulation form (eq. 8, corrected sign of D).

        ``w = [p speed phi_pm, T*]``, ``e = [i_d, i_q - i_q*]``::

            D = [[0, 0], [-1/L_s, 0]],  F = [[0, 0], [0, -2/(3 p phi_pm)]],  C = I,  E = 0

        Parameters
        ----------
        speed : float
            Mechanical speed, rad/s, held by the load machine.
        """
        A, B = self.torque_mode(speed)
        D = np.array([[0.0, 0.0], [-1.0 / self.L_s, 0.0]])
        F = np.array([[0.0, 0.0], [0.0, -2.0 / (3.0 * self.p * self.phi_pm)]])
        return RegulationProblem(A=A, B=B, C=np.eye(2), D=D, E=np.zeros((2, 2)), F=F)

    def current_reference(self, torque: float) -> Array:
        """``x_e = [0, 2 T* / (3 p phi_pm)]``, A, for the torque reference ``T*`` (N m).

        Parameters
        ----------
        torque : float
            Torque reference ``T*``, N m.
        """
        return np.array([0.0, 2.0 * _checked(torque, "torque") / (3.0 * self.p * self.phi_pm)])

    def equilibrium(self, speed: float, torque: float) -> tuple[Array, Array]:
        """The operating point ``(x_e, u_e)`` in closed form (eq. 3, corrected sign).

        ``x_e = [0, i_q*]`` and ``u_e = [-p speed L_s i_q*, R_s i_q* + p speed phi_pm]``
        (A and V). The same point is ``(X* w, U* w)`` of :meth:`regulation_problem`.

        Parameters
        ----------
        speed : float
            Mechanical speed, rad/s.
        torque : float
            Torque reference ``T*``, N m.

        Returns
        -------
        x_e : ndarray, shape (2,)
            Currents ``[i_d, i_q]``, A.
        u_e : ndarray, shape (2,)
            Voltages ``[u_d, u_q]``, V.
        """
        x_e = self.current_reference(torque)
        electrical_speed = self.p * _checked(speed, "speed")
        i_q = x_e[1]
        u_e = np.array(
            [-electrical_speed * self.L_s * i_q, self.R_s * i_q + electrical_speed * self.phi_pm]
        )
        return x_e, u_e
