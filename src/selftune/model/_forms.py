"""What every PMSM derives from its torque-control mode: the full model, the sampled
plant, the no-load form and the one-line description (the motor classes' shared base)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from ..core import Array, as_vector, discretize, finite_float, positive_finite, rotating_hold
from ..core._validation import check_range
from ..errors import InputError
from ._problem import RegulationProblem

__all__ = ["PmsmForms"]


def _checked(value: float, name: str) -> float:
    """A finite speed (rad/s) or torque (N m) in its plausible range."""
    return check_range(finite_float(value, name), name)


def _checked_pole_pairs(value: object) -> int:
    """The number of pole pairs ``p``, a whole number in its plausible range."""
    pole_pairs = positive_finite(value, "p")
    if pole_pairs != int(pole_pairs):
        raise InputError(f"p: the number of pole pairs must be a whole number, got {value!r}")
    return int(check_range(pole_pairs, "p"))


class PmsmForms:
    """The forms a PMSM derives from :meth:`torque_mode` and :meth:`regulation_problem`
    (the base of :class:`~selftune.model.SPMSM` and :class:`~selftune.model.IPMSM`).

    With ``w_e = p speed``, the full model is::

        L_d di_d/dt = -R_s i_d + w_e L_q i_q              + u_d
        L_q di_q/dt = -R_s i_q - w_e L_d i_d - w_e phi_pm + u_q
        J dspeed/dt = T_e(i_d, i_q) - T_L
    """

    if TYPE_CHECKING:
        R_s: float
        phi_pm: float
        p: int
        J: float | None

        @property
        def L_d(self) -> float: ...

        @property
        def L_q(self) -> float: ...

        def torque(self, i_q: ArrayLike, i_d: ArrayLike) -> Array: ...

        def torque_mode(self, speed: float) -> tuple[Array, Array]: ...

        def regulation_problem(self, speed: float) -> RegulationProblem: ...

        def _inductances(self) -> dict[str, float]: ...

    def describe(self, digits: int = 6) -> str:
        """The parameters in one line, e.g. ``"R_s = 0.439 ohm, L_s = 0.0601 H, phi_pm =
        0.46 Wb, p = 2, J = 0.0163 kg m^2"`` (J when given).

        Parameters
        ----------
        digits : int
            Significant digits of each value.
        """
        parts = [f"R_s = {self.R_s:.{digits}g} ohm"]
        parts += [f"{name} = {value:.{digits}g} H" for name, value in self._inductances().items()]
        parts += [f"phi_pm = {self.phi_pm:.{digits}g} Wb", f"p = {self.p}"]
        if self.J is not None:
            parts.append(f"J = {self.J:.{digits}g} kg m^2")
        return ", ".join(parts)

    def full_model(self, x: ArrayLike, u: ArrayLike, load_torque: float = 0.0) -> Array:
        """Time derivative of the full model with speed as a state (eq. 1, corrected; see
        the class docstring).

        Parameters
        ----------
        x : array_like, shape (3,)
            ``[i_d (A), i_q (A), speed (rad/s, mechanical)]``.
        u : array_like, shape (2,)
            ``[u_d, u_q]``, V.
        load_torque : float
            Load torque ``T_L``, N m.

        Returns
        -------
        ndarray, shape (3,)
            ``[di_d/dt, di_q/dt, dspeed/dt]``.

        Raises
        ------
        InputError
            If the inertia ``J`` was not given.
        """
        if self.J is None:
            raise InputError("J: the full model needs the rotor inertia J")
        i_d, i_q, speed = as_vector(x, "x", 3)
        u_d, u_q = as_vector(u, "u", 2)
        w_e, L_d, L_q = self.p * speed, self.L_d, self.L_q
        torque = float(self.torque(i_q, i_d)) - finite_float(load_torque, "load_torque")
        return np.array(
            [
                (-self.R_s * i_d + w_e * L_q * i_q + u_d) / L_d,
                (-self.R_s * i_q - w_e * L_d * i_d - w_e * self.phi_pm + u_q) / L_q,
                torque / self.J,
            ]
        )

    def sampled_plant(
        self, speed: float, h: float, hold: str = "rotor"
    ) -> tuple[Array, Array, Array]:
        """``(Ad, Bd, Ed)`` of :meth:`regulation_problem` sampled at h, exactly.

        ``hold = "rotor"``: the dq voltage held over each sample (zero-order hold, the
        paper's). ``"stationary"``: the stationary-frame vector held, as a PWM inverter
        does, with the usual angle compensation that centres it on the sample
        (:func:`selftune.core.rotating_hold`): Bd differs, by about ``(w_e h)^2 / 24``.

        Parameters
        ----------
        speed : float
            Mechanical speed, rad/s.
        h : float
            Sampling period, s.
        hold : {"rotor", "stationary"}
            What is held over a sample.
        """
        if hold not in ("rotor", "stationary"):
            raise InputError(f"hold: must be 'rotor' or 'stationary', got {hold!r}")
        problem = self.regulation_problem(speed)
        exact = discretize(problem.A, problem.B, h, D=problem.D)
        if hold == "rotor":
            return exact.Ad, exact.Bd, exact.Ed
        w_e = self.p * finite_float(speed, "speed")
        Bd = rotating_hold(problem.A, problem.B, h, w_e, advance=0.5 * w_e * h)
        return exact.Ad, Bd, exact.Ed

    def no_load_exogenous(self, speed: float) -> Array:
        """``w = [p speed]`` of the no-load, unknown-flux form (eq. 15).

        Parameters
        ----------
        speed : float
            Mechanical speed, rad/s.
        """
        return np.array([self.p * _checked(speed, "speed")])

    def no_load_problem(self, speed: float) -> RegulationProblem:
        """The no-load, unknown-flux form (eq. 15, corrected sign): ``T* = 0``, ``w = [p speed]``.

        ``D = [[0], [-phi_pm / L_q]]``, ``F = 0``, ``C = I``, ``E = 0``; hence ``X* = 0``
        (no torque asks for no current, MTPA included).

        Parameters
        ----------
        speed : float
            Mechanical speed, rad/s, held by the load machine.
        """
        A, B = self.torque_mode(speed)
        D = np.array([[0.0], [-self.phi_pm / self.L_q]])
        return RegulationProblem(A=A, B=B, C=np.eye(2), D=D, E=np.zeros((1, 1)), F=np.zeros((2, 1)))
