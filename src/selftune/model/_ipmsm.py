"""The interior PMSM (L_d != L_q): parameters, torque-control mode and MTPA references.

With electrical speed ``w_e = p speed`` (mechanical ``speed``, rad/s) the dq model is::

    L_d di_d/dt = -R_s i_d + w_e L_q i_q                + u_d
    L_q di_q/dt = -R_s i_q - w_e L_d i_d - w_e phi_pm   + u_q
    T_e         = (3 p / 2) (phi_pm i_q + (L_d - L_q) i_d i_q)

At a held speed the current dynamics are linear, but the torque is not: the current
references of a torque reference ``T*`` follow MTPA (the least current magnitude for the
torque). So the regulation form tracks the current references themselves: ``w = [w_e
phi_pm, i_d*, i_q*]`` (V, A, A), ``e = [i_d - i_d*, i_q - i_q*]``, and
:meth:`IPMSM.current_reference` states the map from ``T*`` to ``[i_d*, i_q*]``. A surface
motor (:class:`~selftune.model.SPMSM`) keeps the paper's form ``w = [w_e phi_pm, T*]``.

MTPA: at fixed current magnitude the torque is largest where ``d T / d beta = 0``, i.e.
``c i_d^2 + phi_pm i_d - c i_q^2 = 0`` with ``c = L_d - L_q``; the root that vanishes
with ``c`` is::

    i_d = 2 c i_q^2 / (phi_pm + sqrt(phi_pm^2 + 4 c^2 i_q^2))

(negative for the usual ``L_d < L_q``, zero for a surface motor), and ``i_q`` solves
``T* = (3 p / 2) i_q (phi_pm + c i_d(i_q))``, whose right side increases with ``i_q``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import brentq

from ..core import Array, positive_finite
from ..core._validation import check_range
from ..errors import InputError
from ._forms import PmsmForms, _checked, _checked_pole_pairs
from ._motor import SPMSM
from ._problem import RegulationProblem

__all__ = ["IPMSM", "motor_from_parameters"]

#: Relative tolerance of the MTPA current solve (the torque it gives matches ``T*`` to
#: about this, relative to ``|T*|``).
MTPA_TOLERANCE = 1e-14


@dataclass(frozen=True)
class IPMSM(PmsmForms):
    """Interior permanent-magnet synchronous motor (SI units; see the module docstring).

    Parameters
    ----------
    R_s : float
        Stator resistance, ohm.
    L_d, L_q : float
        d- and q-axis inductances, H.
    phi_pm : float
        Permanent-magnet flux linkage, Wb.
    p : int
        Number of pole pairs.
    J : float, optional
        Rotor inertia, kg m^2 (kept for the file; the torque mode does not need it).

    Raises
    ------
    InputError
        (a ``ValueError``) naming the field, if a value is not positive and finite or is
        outside its plausible range (``PLAUSIBLE_RANGES`` of :mod:`selftune.core`; L_d
        and L_q take L_s's, 1e-7..10 H), or ``p`` is not a whole number.

    Examples
    --------
    >>> motor = IPMSM(R_s=0.2, L_d=2e-3, L_q=5e-3, phi_pm=0.1, p=4)
    >>> i_d, i_q = motor.current_reference(torque=5.0)
    >>> bool(i_d < 0.0)
    True
    """

    R_s: float
    L_d: float
    L_q: float
    phi_pm: float
    p: int
    J: float | None = None

    def __post_init__(self) -> None:
        for name, key in (("R_s", "R_s"), ("L_d", "L_s"), ("L_q", "L_s"), ("phi_pm", "phi_pm")):
            value = check_range(positive_finite(getattr(self, name), name), name, key)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "p", _checked_pole_pairs(self.p))
        if self.J is not None:
            object.__setattr__(self, "J", check_range(positive_finite(self.J, "J"), "J"))

    @classmethod
    def of(cls, motor: SPMSM | IPMSM) -> IPMSM:
        """The interior form of a motor: an IPMSM as it is, a surface motor with ``L_d =
        L_q = L_s`` (what the saturation model and the current schedule take).

        Parameters
        ----------
        motor : SPMSM or IPMSM
            The motor.
        """
        if isinstance(motor, IPMSM):
            return motor
        return cls(R_s=motor.R_s, L_d=motor.L_s, L_q=motor.L_s, phi_pm=motor.phi_pm, p=motor.p,
                   J=motor.J)  # fmt: skip

    @property
    def saliency(self) -> float:
        """``L_q / L_d``."""
        return self.L_q / self.L_d

    @property
    def reference_names(self) -> tuple[str, ...]:
        """What each entry of ``w`` is: ``("p speed phi_pm", "i_d*", "i_q*")``."""
        return ("p speed phi_pm", "i_d*", "i_q*")

    def _inductances(self) -> dict[str, float]:
        return {"L_d": self.L_d, "L_q": self.L_q}

    # -- torque and MTPA ----------------------------------------------------------------

    def torque(self, i_q: ArrayLike, i_d: ArrayLike) -> Array:
        """Electromagnetic torque ``(3 p / 2) (phi_pm i_q + (L_d - L_q) i_d i_q)``, N m.

        Parameters
        ----------
        i_q, i_d : array_like
            q- and d-axis currents, A (broadcast together).
        """
        i_q = np.asarray(i_q, dtype=float)
        i_d = np.asarray(i_d, dtype=float)
        return 1.5 * self.p * i_q * (self.phi_pm + (self.L_d - self.L_q) * i_d)

    def mtpa_d_current(self, i_q: ArrayLike) -> Array:
        """The MTPA d-axis current of a q-axis current (both A; see the module docstring).

        Parameters
        ----------
        i_q : array_like
            q-axis current, A.
        """
        i_q = np.asarray(i_q, dtype=float)
        c = self.L_d - self.L_q
        return 2.0 * c * i_q**2 / (self.phi_pm + np.sqrt(self.phi_pm**2 + 4.0 * c**2 * i_q**2))

    def current_reference(self, torque: float) -> Array:
        """``[i_d*, i_q*]`` (A) on the MTPA curve for the torque reference ``T*`` (N m).

        Parameters
        ----------
        torque : float
            Torque reference ``T*``, N m.
        """
        torque = _checked(torque, "torque")
        if torque == 0.0:
            return np.zeros(2)
        # the torque per ampere of i_q is at least phi_pm's: |i_q*| <= |T*| / (1.5 p phi_pm)
        # (widened by a few roundings, so that the bound's torque is not below T* by one)
        bound = torque / (1.5 * self.p * self.phi_pm) * (1.0 + 8.0 * np.finfo(float).eps)

        def excess(i_q: float) -> float:
            return float(self.torque(i_q, self.mtpa_d_current(i_q))) - torque

        low, high = sorted((0.0, bound))
        i_q = float(brentq(excess, low, high, xtol=1e-300, rtol=MTPA_TOLERANCE))
        return np.array([float(self.mtpa_d_current(i_q)), i_q])

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
            ``[[-R_s/L_d, w_e L_q/L_d], [-w_e L_d/L_q, -R_s/L_q]]``, 1/s.
        B : ndarray, shape (2, 2)
            ``diag(1/L_d, 1/L_q)``, 1/H.
        """
        w_e = self.p * _checked(speed, "speed")
        L_d, L_q = self.L_d, self.L_q
        A = np.array([[-self.R_s / L_d, w_e * L_q / L_d], [-w_e * L_d / L_q, -self.R_s / L_q]])
        return A, np.diag([1.0 / L_d, 1.0 / L_q])

    def exogenous(self, speed: float, torque: float) -> Array:
        """``w = [p speed phi_pm, i_d*, i_q*]`` (V, A, A) with MTPA references.

        Parameters
        ----------
        speed : float
            Mechanical speed, rad/s.
        torque : float
            Torque reference ``T*``, N m.
        """
        speed = _checked(speed, "speed")
        return np.concatenate([[self.p * speed * self.phi_pm], self.current_reference(torque)])

    def regulation_problem(self, speed: float) -> RegulationProblem:
        """The current-tracking regulation form, ``w = [w_e phi_pm, i_d*, i_q*]``::

            D = [[0, 0, 0], [-1/L_q, 0, 0]],  F = [[0, -1, 0], [0, 0, -1]],  C = I,  E = 0

        Parameters
        ----------
        speed : float
            Mechanical speed, rad/s, held by the load machine.
        """
        A, B = self.torque_mode(speed)
        D = np.array([[0.0, 0.0, 0.0], [-1.0 / self.L_q, 0.0, 0.0]])
        F = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
        return RegulationProblem(A=A, B=B, C=np.eye(2), D=D, E=np.zeros((3, 3)), F=F)

    def equilibrium(self, speed: float, torque: float) -> tuple[Array, Array]:
        """The operating point ``(x_e, u_e)`` in closed form.

        ``x_e = [i_d*, i_q*]`` (MTPA) and ``u_e = [R_s i_d* - w_e L_q i_q*, R_s i_q* + w_e
        L_d i_d* + w_e phi_pm]`` (A and V): ``(X* w, U* w)`` of :meth:`regulation_problem`.

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
        w_e = self.p * _checked(speed, "speed")
        i_d, i_q = x_e
        u_e = np.array(
            [
                self.R_s * i_d - w_e * self.L_q * i_q,
                self.R_s * i_q + w_e * self.L_d * i_d + w_e * self.phi_pm,
            ]
        )
        return x_e, u_e


def motor_from_parameters(values: Mapping[str, Any]) -> SPMSM | IPMSM:
    """The motor a mapping of parameters names (a JSON's ``motor``, a table).

    ``L_s`` gives a :class:`~selftune.model.SPMSM`; ``L_d`` and ``L_q`` an
    :class:`IPMSM`, or a surface motor if they are equal.

    Parameters
    ----------
    values : mapping
        ``R_s``, ``L_s`` or ``L_d`` and ``L_q``, ``phi_pm``, ``p`` and optionally ``J``
        (SI units).

    Raises
    ------
    InputError
        Naming the key, if one is missing or a value is not valid.
    """
    common: dict[str, Any] = {key: values.get(key) for key in ("R_s", "phi_pm", "p", "J")}
    for key in ("R_s", "phi_pm", "p"):
        if common[key] is None:
            raise InputError(f"{key}: missing")
    if values.get("L_s") is not None:
        return SPMSM(L_s=values["L_s"], **common)
    for key in ("L_d", "L_q"):
        if values.get(key) is None:
            raise InputError(f"{key}: missing (or L_s, for a surface motor)")
    if values["L_d"] == values["L_q"]:
        return SPMSM(L_s=values["L_d"], **common)
    return IPMSM(L_d=values["L_d"], L_q=values["L_q"], **common)
