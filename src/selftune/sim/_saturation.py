"""Magnetic saturation: current-dependent flux linkages, and a motor propagated with them.

A saturated motor's flux linkages ``psi_d(i_d, i_q)``, ``psi_q(i_d, i_q)`` (Wb, the magnet
flux included in ``psi_d``; currents in A) are given in one of two forms:

**The analytic model** (:class:`SaturationModel`) is the gradient of a magnetic
co-energy, so its cross-saturation terms are reciprocal (``d psi_d / d i_q = d psi_q /
d i_d``) by construction (the co-energy principle, e.g. Fitzgerald, Kingsley and Umans,
*Electric Machinery*, ch. 3; the same reciprocity Hinkkanen et al., "Sensorless
self-commissioning of synchronous reluctance motors at standstill without rotor
locking", IEEE Trans. Ind. Appl. 2017, build into their algebraic model, which is given
as current of flux; this one is flux of current, so neither the drive nor the learner
inverts it)::

    W'(i_d, i_q) = phi_pm i_d + L_dinf i_d^2 / 2 + L_qinf i_q^2 / 2 + dL i_s^2 log cosh(m / i_s)
    m = sqrt(i_q^2 + c i_d^2),   dL = drop L_q,   L_qinf = L_q - dL,   L_dinf = L_d - c dL
    psi_d = dW'/di_d = phi_pm + (L_dinf + c dL f) i_d,   psi_q = dW'/di_q = (L_qinf + dL f) i_q
    f = tanh(x) / x,   x = m / i_s

One iron path saturates with the current ``m`` it carries (the q current, and the d
current with the weight ``c``): ``drop`` (in ``[0, 1)``) of ``L_q`` saturates, at the
scale ``i_s`` (A). The secant inductances are ``L_dinf + c dL f`` and ``L_qinf + dL f``;
the incremental inductance matrix is the co-energy's Hessian::

    L_inc = diag(L_dinf + c dL f, L_qinf + dL f) + dL g [c i_d, i_q]^T [c i_d, i_q]
    g = f'(m) / m = q(x) / i_s^2,   q(x) = (x sech(x)^2 - tanh(x)) / x^3   (-2/3 at x = 0)

symmetric, between ``diag(L_dinf, L_qinf)`` and ``diag(L_d, L_q)`` (``log cosh`` of a norm
is convex and ``g <= 0``), so the flux rises with the current everywhere. With ``drop =
0`` it is the motor's constant ``L_d``, ``L_q`` to the bit.

**The flux-map table** (:class:`FluxMap`): ``psi_d``, ``psi_q`` on a grid of ``(i_d,
i_q)`` (a measured machine's maps), interpolated by scipy's ``RectBivariateSpline``,
bicubic, through the nodes (``s = 0``): linear interpolation's derivative, the
incremental inductance the learner reports, would jump at every grid line, and a
propagation by fixed steps would lose its order there; the spline is twice continuously
differentiable and gives its derivatives in closed form (``RegularGridInterpolator``'s
cubic method gives none). Maps whose ``psi_d`` does not rise strictly along ``i_d`` or
``psi_q`` along ``i_q``, or with a non-finite value, are refused; so is a current outside
the grid (no extrapolation).

**The motor** (:class:`SaturatedMotors`): at a held electrical speed ``w_e`` (rad/s) in
the rotor frame, ``d psi/dt = u - R_s i - w_e J psi``, ``J = [[0, -1], [1, 0]]``; in the
currents, ``di/dt = L_inc(i)^-1 (u - R_s i - w_e J psi(i))``. Nonlinear, so not exact: one
sample is ``n`` fixed steps of the classical Runge-Kutta method (RK4) in the currents,
the voltage (a stationary vector held over the sample, turning as ``exp(-j w_e s)`` in
the rotor frame, plus a rotor-frame one) evaluated at each stage's instant; with carrier
PWM each of the period's constant segments so (:meth:`SaturatedMotors.carrier`). ``n`` is the
smallest with both ``rate h / n <= STEP_RATE`` and ``|di/dt| h / n <= STEP_RATE scale``
(``di/dt`` at the sample's start; ``scale`` the current over which the inductances
change): ``rate = R_s / L_min + |w_e|`` bounds the linearized dynamics' eigenvalues
(``L_inc^-1 J L_inc`` is similar to J; ``L_min`` the smallest incremental inductance),
and the second rule keeps a step from crossing the knee of the saturation curve (without
it a large voltage step at low speed erred by 6e-4). RK4's global error is of the order
``STEP_RATE^4 = 6e-6`` of the current; against DOP853 at ``rtol = 1e-10`` the currents
agree to 9e-9 to 2.2e-7 of their scale over 300 samples (tests/test_saturation.py;
docs/saturation.md). Each step evaluates the flux linkages and ``L_inc`` four times in
numpy on arrays of P: about 0.07 ms per evaluation, so a sample costs about ``0.3 n``
ms, not the exact paths' microseconds.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from math import ceil
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike
from scipy.interpolate import RectBivariateSpline

from ..core import Array, finite_float, positive_finite
from ..core._phases import ComplexArray
from ..errors import InputError
from ..model import Motor

if TYPE_CHECKING:
    from ._pwm import PwmSegments

__all__ = ["STEP_RATE", "FluxMap", "SaturatedMotors", "Saturation", "SaturationModel"]

#: The largest ``rate tau`` of one RK4 step (see the module docstring).
STEP_RATE = 0.05

#: The analytic model's smallest ``i_s``, a share of the motor's characteristic current
#: ``phi_pm / L_d`` (a short circuit's; rated currents are about 10-50% of it, and iron
#: saturates at a sizable share of rated). The step rule resolves the knee, so the cost of
#: a sample grows as ``1 / i_s``: on examples/saturating_motor.toml ``tune`` took 16 s at
#: its ``i_s`` of 6 A, 45 s at 0.6 A, 97 s at 0.15 A, and did not end in 15 minutes at
#: 1e-6 A, which this refuses.
NARROWEST_KNEE = 0.01

#: A flux map's smallest grid spacing, a share of the grid's span: the step rule resolves
#: the finest cell, so a sample costs about ``1 / spacing``, as for the analytic knee (a
#: measured map has tens of currents an axis; a pair of nodes 1e-9 A apart would not end).
FINEST_SPACING = 0.002

#: Below this ``x = m / i_s`` the series of ``f`` and ``q`` replace their closed forms,
#: whose error in ``q`` is ``eps / x^2`` (below 3e-12 above it; the series' below 1e-17).
_SERIES_BELOW = 1e-2


def _shape_functions(x: Array) -> tuple[Array, Array]:
    """``f(x) = tanh(x) / x`` and ``q(x) = (x sech(x)^2 - tanh(x)) / x^3`` (x >= 0, one
    ``tanh``), by their series near 0 (q's closed form cancels there)."""
    small = x < _SERIES_BELOW
    y = np.where(small, 1.0, x)
    t = np.tanh(y)
    z = x * x
    f = np.where(small, 1.0 + z * (-1.0 / 3.0 + z * (2.0 / 15.0 - z * (17.0 / 315.0))), t / y)
    series = -2.0 / 3.0 + z * (8.0 / 15.0 + z * (-34.0 / 105.0 + z * (496.0 / 2835.0)))
    q = np.where(small, series, (y * (1.0 - t * t) - t) / (y * y * y))
    return f, q


class _Magnetics:
    """What both forms give: the flux linkages and inductances at currents (A; arrays of
    any one shape, broadcast together)."""

    def _evaluate(self, i_d: Array, i_q: Array) -> tuple[Array, Array, Array]:
        """``psi_d``, ``psi_q`` (Wb) and ``L_inc`` (..., 2, 2) (H), unchecked."""
        raise NotImplementedError

    def _currents(self, i_d: ArrayLike, i_q: ArrayLike) -> tuple[Array, Array]:
        d = np.asarray(i_d, dtype=float)
        q = np.asarray(i_q, dtype=float)
        if not (np.all(np.isfinite(d)) and np.all(np.isfinite(q))):
            raise InputError("i_d, i_q: expected finite currents")
        d, q = np.broadcast_arrays(d, q)
        return d, q

    def flux(self, i_d: ArrayLike, i_q: ArrayLike) -> tuple[Array, Array]:
        """``psi_d``, ``psi_q`` (Wb) at the currents ``i_d``, ``i_q`` (A).

        Parameters
        ----------
        i_d, i_q : array_like
            The currents, A (broadcast together).
        """
        d, q = self._currents(i_d, i_q)
        psi_d, psi_q, _ = self._evaluate(d, q)
        return psi_d, psi_q

    def incremental(self, i_d: ArrayLike, i_q: ArrayLike) -> Array:
        """The incremental inductance matrix ``L_inc = d psi / d i`` (..., 2, 2), H: rows
        ``psi_d``, ``psi_q``, columns ``i_d``, ``i_q``.

        Parameters
        ----------
        i_d, i_q : array_like
            The currents, A (broadcast together).
        """
        d, q = self._currents(i_d, i_q)
        return self._evaluate(d, q)[2]

    def secant(self, i_d: ArrayLike, i_q: ArrayLike) -> tuple[Array, Array]:
        """The secant inductances ``(psi_d(i_d, i_q) - psi_d(0, i_q)) / i_d`` and
        ``(psi_q(i_d, i_q) - psi_q(i_d, 0)) / i_q``, H (the incremental diagonal where
        the current is 0): ``(psi_d - phi_pm) / i_d`` and ``psi_q / i_q`` of a map whose
        d flux at ``i_d = 0`` is the magnet's and whose q flux at ``i_q = 0`` is 0.

        Parameters
        ----------
        i_d, i_q : array_like
            The currents, A (broadcast together).
        """
        d, q = self._currents(i_d, i_q)
        zero = np.zeros_like(d)
        psi_d, psi_q, L = self._evaluate(d, q)
        magnet, _, _ = self._evaluate(zero, q)
        _, unloaded, _ = self._evaluate(d, zero)
        with np.errstate(divide="ignore", invalid="ignore"):
            L_d = np.where(d == 0.0, L[..., 0, 0], (psi_d - magnet) / np.where(d == 0, 1, d))
            L_q = np.where(q == 0.0, L[..., 1, 1], (psi_q - unloaded) / np.where(q == 0, 1, q))
        return L_d, L_q

    @property
    def bounds(self) -> tuple[float, float]:
        """``(L_min, L_max)``, H: the smallest and largest incremental inductance (the
        eigenvalues of ``L_inc``'s symmetric part), the step rule's."""
        raise NotImplementedError

    @property
    def scale(self) -> float:
        """The current over which the inductances change, A (the step rule's)."""
        raise NotImplementedError

    def check_current(self, current: ComplexArray, where: str) -> None:
        """Refuse currents the form does not cover (none here).

        Parameters
        ----------
        current : ndarray of complex
            The currents ``i_d + j i_q``, A.
        where : str
            What the refusal names.

        Raises
        ------
        InputError
            Naming ``where``, if a current is outside the form's range.
        """


@dataclass(frozen=True)
class SaturationModel(_Magnetics):
    """The analytic saturation model (see the module docstring).

    Attributes
    ----------
    L_d, L_q : float
        The unsaturated inductances at zero current, H.
    phi_pm : float
        Magnet flux linkage, Wb.
    i_sat : float
        ``i_s``, the saturation current scale, A: at least :data:`NARROWEST_KNEE` of
        ``phi_pm / L_d``.
    drop : float
        The saturating share of ``L_q``, in ``[0, 1)`` (0: no saturation).
    cross : float
        ``c >= 0``, the weight of ``i_d^2`` in the saturating path's current (0: no
        cross-saturation; ``L_d - c drop L_q`` must stay positive).
    """

    L_d: float
    L_q: float
    phi_pm: float
    i_sat: float
    drop: float
    cross: float = 0.0

    def __post_init__(self) -> None:
        for name in ("L_d", "L_q", "i_sat"):
            object.__setattr__(self, name, positive_finite(getattr(self, name), name))
        object.__setattr__(self, "phi_pm", finite_float(self.phi_pm, "phi_pm"))
        drop = finite_float(self.drop, "drop")
        if not 0.0 <= drop < 1.0:
            raise InputError(f"drop: expected a share in [0, 1), got {drop!r}")
        cross = finite_float(self.cross, "cross")
        if cross < 0.0:
            raise InputError(f"cross: expected a weight >= 0, got {cross!r}")
        if self.L_d - cross * drop * self.L_q <= 0.0:
            raise InputError(
                f"cross: L_d - cross drop L_q = {self.L_d - cross * drop * self.L_q!r} H is "
                "not positive; the d-axis inductance would vanish"
            )
        object.__setattr__(self, "drop", drop)
        object.__setattr__(self, "cross", cross)
        characteristic = abs(self.phi_pm) / self.L_d
        if self.i_sat < NARROWEST_KNEE * characteristic:
            raise InputError(
                f"i_sat: {self.i_sat:.3g} A is below {NARROWEST_KNEE:.0%} of the motor's "
                f"characteristic current phi_pm / L_d = {characteristic:.3g} A: the "
                "inductance would step within a hair of zero current, which no iron does "
                "(and the simulated motor would take that many more integration steps a "
                "sample); give the knee's current scale in A"
            )

    @classmethod
    def of(cls, motor: Motor, *, i_sat: float, drop: float, cross: float = 0.0) -> SaturationModel:
        """The model of a motor's unsaturated ``L_d``, ``L_q`` and ``phi_pm``.

        Parameters
        ----------
        motor : SPMSM or IPMSM
            The motor (its nameplate inductances and flux).
        i_sat : float
            ``i_s``, A.
        drop : float
            The saturating share of ``L_q``, in ``[0, 1)``.
        cross : float
            ``c``, the weight of ``i_d^2`` (default 0: no cross-saturation).
        """
        return cls(motor.L_d, motor.L_q, motor.phi_pm, i_sat, drop, cross)

    def _evaluate(self, i_d: Array, i_q: Array) -> tuple[Array, Array, Array]:
        c, dL = self.cross, self.drop * self.L_q
        L_dinf, L_qinf = self.L_d - c * dL, self.L_q - dL
        x = np.sqrt(i_q * i_q + c * (i_d * i_d)) / self.i_sat
        f, q = _shape_functions(x)
        L_dsec, L_qsec = L_dinf + c * dL * f, L_qinf + dL * f
        dg = dL * q / self.i_sat**2
        cd = c * i_d
        L = np.empty((*i_d.shape, 2, 2))
        L[..., 0, 0] = L_dsec + dg * cd * cd
        L[..., 0, 1] = L[..., 1, 0] = dg * cd * i_q
        L[..., 1, 1] = L_qsec + dg * i_q * i_q
        return self.phi_pm + L_dsec * i_d, L_qsec * i_q, L

    @property
    def scale(self) -> float:
        """``i_s / max(1, sqrt(c))``, A: ``x = m / i_s`` moves by at most 1 per scale."""
        return self.i_sat / max(1.0, float(np.sqrt(self.cross)))

    @property
    def bounds(self) -> tuple[float, float]:
        """``(min(L_dinf, L_qinf), max(L_d, L_q))``, H (see the module docstring)."""
        dL = self.drop * self.L_q
        return min(self.L_d - self.cross * dL, self.L_q - dL), max(self.L_d, self.L_q)


def _grid(values: ArrayLike, name: str) -> Array:
    grid = np.asarray(values, dtype=float)
    if grid.ndim != 1 or grid.shape[0] < 4:
        raise InputError(f"{name}: expected a 1-D grid of at least 4 currents, got {grid.shape}")
    if not np.all(np.isfinite(grid)) or not np.all(np.diff(grid) > 0.0):
        raise InputError(f"{name}: expected finite, strictly increasing currents")
    span, spacing = float(grid[-1] - grid[0]), float(np.min(np.diff(grid)))
    if spacing < FINEST_SPACING * span:
        at = int(np.argmin(np.diff(grid)))
        raise InputError(
            f"{name}: the currents {grid[at]:.6g} and {grid[at + 1]:.6g} A are "
            f"{spacing:.3g} A apart, below {FINEST_SPACING:.1%} of the grid's span "
            f"({span:.6g} A): finer than any measured map, and the simulated motor's "
            "integration steps resolve its finest cell; leave one of the two out"
        )
    return grid


@dataclass(frozen=True, eq=False)
class FluxMap(_Magnetics):
    """The flux-map table (see the module docstring): bicubic through the nodes.

    Attributes
    ----------
    i_d, i_q : ndarray, shapes (M,) and (N,)
        The grid, A, strictly increasing (at least 4 each; no two currents closer than
        :data:`FINEST_SPACING` of the span).
    psi_d, psi_q : ndarray, shape (M, N)
        The flux linkages at the nodes, Wb: ``psi_d`` strictly rising along ``i_d``,
        ``psi_q`` along ``i_q``.
    """

    i_d: Array
    i_q: Array
    psi_d: Array
    psi_q: Array
    _splines: tuple[RectBivariateSpline, RectBivariateSpline] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        i_d, i_q = _grid(self.i_d, "i_d"), _grid(self.i_q, "i_q")
        shape = (i_d.shape[0], i_q.shape[0])
        maps = []
        for name, axis in (("psi_d", 0), ("psi_q", 1)):
            values = np.asarray(getattr(self, name), dtype=float)
            if values.shape != shape:
                raise InputError(f"{name}: expected shape {shape} (i_d, i_q), got {values.shape}")
            if not np.all(np.isfinite(values)):
                raise InputError(f"{name}: expected finite flux linkages")
            if not np.all(np.diff(values, axis=axis) > 0.0):
                along = "i_d" if axis == 0 else "i_q"
                raise InputError(f"{name}: not strictly increasing along {along}")
            values.setflags(write=False)
            maps.append(values)
        for name, value in (("i_d", i_d), ("i_q", i_q), ("psi_d", maps[0]), ("psi_q", maps[1])):
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        splines = tuple(RectBivariateSpline(i_d, i_q, m, kx=3, ky=3, s=0) for m in maps)
        object.__setattr__(self, "_splines", splines)

    @classmethod
    def sampled(cls, model: _Magnetics, i_d: ArrayLike, i_q: ArrayLike) -> FluxMap:
        """The table of another form's flux linkages on a grid.

        Parameters
        ----------
        model : SaturationModel or FluxMap
            What is sampled.
        i_d, i_q : array_like
            The grid, A (strictly increasing, at least 4 each).
        """
        d, q = np.meshgrid(_grid(i_d, "i_d"), _grid(i_q, "i_q"), indexing="ij")
        psi_d, psi_q = model.flux(d, q)
        return cls(d[:, 0], q[0], psi_d, psi_q)

    def check_current(self, current: ComplexArray, where: str) -> None:
        """Refuse currents outside the grid, or not finite.

        Parameters
        ----------
        current : ndarray of complex
            The currents ``i_d + j i_q``, A.
        where : str
            What the refusal names.

        Raises
        ------
        InputError
            Naming ``where``, if a current is outside the grid or not finite.
        """
        d, q = np.real(current), np.imag(current)
        outside = (d < self.i_d[0]) | (d > self.i_d[-1]) | (q < self.i_q[0]) | (q > self.i_q[-1])
        if np.any(outside | ~np.isfinite(current)):
            index = int(np.flatnonzero(outside | ~np.isfinite(current))[0])
            raise InputError(
                f"{where}: the current (i_d, i_q) = ({d.flat[index]:.6g}, {q.flat[index]:.6g}) "
                f"A is outside the flux map's grid [{self.i_d[0]:g}, {self.i_d[-1]:g}] x "
                f"[{self.i_q[0]:g}, {self.i_q[-1]:g}] A: a map over the currents the drive "
                "reaches holds it (its i_d, i_q grid)"
            )

    def _currents(self, i_d: ArrayLike, i_q: ArrayLike) -> tuple[Array, Array]:
        d, q = super()._currents(i_d, i_q)
        self.check_current(d + 1j * q, "i_d, i_q")
        return d, q

    def _evaluate(self, i_d: Array, i_q: Array) -> tuple[Array, Array, Array]:
        d_spline, q_spline = self._splines
        L = np.empty((*i_d.shape, 2, 2))
        L[..., 0, 0] = d_spline.ev(i_d, i_q, dx=1)
        L[..., 0, 1] = d_spline.ev(i_d, i_q, dy=1)
        L[..., 1, 0] = q_spline.ev(i_d, i_q, dx=1)
        L[..., 1, 1] = q_spline.ev(i_d, i_q, dy=1)
        return d_spline.ev(i_d, i_q), q_spline.ev(i_d, i_q), L

    @property
    def scale(self) -> float:
        """The grid's smallest spacing, A (one cubic piece of the spline)."""
        return float(min(np.min(np.diff(self.i_d)), np.min(np.diff(self.i_q))))

    @property
    def bounds(self) -> tuple[float, float]:
        """The extreme eigenvalues of ``L_inc``'s symmetric part over the grid's nodes
        and cell centers, H (the spline between them is not bounded exactly)."""
        centers_d = np.concatenate([self.i_d, 0.5 * (self.i_d[1:] + self.i_d[:-1])])
        centers_q = np.concatenate([self.i_q, 0.5 * (self.i_q[1:] + self.i_q[:-1])])
        d, q = np.meshgrid(centers_d, centers_q, indexing="ij")
        L = self._evaluate(d, q)[2]
        eigenvalues = np.linalg.eigvalsh(0.5 * (L + np.swapaxes(L, -1, -2)))
        low, high = float(np.min(eigenvalues)), float(np.max(eigenvalues))
        if low <= 0.0:
            raise InputError(
                f"psi_d, psi_q: the incremental inductance is not positive definite "
                f"(smallest eigenvalue {low:.3g} H)"
            )
        return low, high


#: A saturation description: the analytic model or a flux-map table.
Saturation = SaturationModel | FluxMap


class SaturatedMotors:
    """P motors with one :data:`Saturation` over one sample, by RK4 (see the module
    docstring); the rotor-frame path's :meth:`advance`.

    Parameters
    ----------
    saturation : SaturationModel or FluxMap
        The flux linkages (common to the motors).
    R_s, speed : ndarray, shape (P,)
        Stator resistances, ohm, and electrical speeds ``w_e``, rad/s.
    period : float
        The sample's length h, s.
    """

    def __init__(self, saturation: Saturation, R_s: Array, speed: Array, period: float) -> None:
        self.saturation, self.R_s, self.speed, self.period = saturation, R_s, speed, period
        #: ``rate``, 1/s (see the module docstring)
        self.bound = float(np.max(R_s / saturation.bounds[0] + np.abs(speed)))

    def motor(self, index: int) -> SaturatedMotors:
        """Motor ``index`` alone (P = 1; the carrier PWM's)."""
        pick = slice(index, index + 1)
        return SaturatedMotors(self.saturation, self.R_s[pick], self.speed[pick], self.period)

    def rate(self, current: ComplexArray, voltage: ComplexArray) -> ComplexArray:
        """``di/dt = L_inc^-1 (u - R_s i - w_e J psi)`` (A/s, ``d + j q``) at the
        rotor-frame ``current`` (A) and ``voltage`` (V), (P,)."""
        psi_d, psi_q, L = self.saturation._evaluate(current.real, current.imag)
        e = voltage - self.R_s * current - 1j * self.speed * (psi_d + 1j * psi_q)
        a, b, c, d = L[:, 0, 0], L[:, 0, 1], L[:, 1, 0], L[:, 1, 1]
        det = a * d - b * c
        return ((d * e.real - b * e.imag) + 1j * (a * e.imag - c * e.real)) / det

    def propagate(
        self,
        current: ComplexArray,
        stationary: ComplexArray,
        rotor: ComplexArray | None,
        duration: float | None = None,
    ) -> ComplexArray:
        """The rotor-frame current (P,) at the interval's end from ``current`` at its
        start (A), under ``stationary`` (V, the rotor-frame value at the start of a
        stationary vector held over the interval: ``exp(-j w_e s) stationary`` at ``s``)
        and ``rotor`` (a rotor-frame vector held, V; None: none); the interval is
        ``duration`` (s; None: the sample), its step count the module docstring's rule
        over it."""
        held = 0.0 if rotor is None else rotor
        length = self.period if duration is None else duration

        def voltage(s: float) -> ComplexArray:
            return np.exp(-1j * self.speed * s) * stationary + held

        i, start = current, self.rate(current, voltage(0.0))
        # the current moves by at most STEP_RATE of the saturation's scale per step
        steps = max(1, ceil(self.bound * length / STEP_RATE))
        moves = float(np.max(np.abs(start))) * length / (STEP_RATE * self.saturation.scale)
        steps = max(steps, ceil(moves)) if np.isfinite(moves) else steps
        tau = length / steps
        for n in range(steps):
            s = n * tau
            middle = voltage(s + 0.5 * tau)
            k1 = start if n == 0 else self.rate(i, voltage(s))
            k2 = self.rate(i + 0.5 * tau * k1, middle)
            k3 = self.rate(i + 0.5 * tau * k2, middle)
            k4 = self.rate(i + tau * k3, voltage(s + tau))
            i = i + (tau / 6.0) * (k1 + 2.0 * (k2 + k3) + k4)
        self.saturation.check_current(i, "the drive's currents")
        return i

    def advance(
        self,
        current: ComplexArray,
        steady: ComplexArray,
        turning: ComplexArray | None,
        rotor: ComplexArray,
        following: ComplexArray,
    ) -> ComplexArray:
        """As :meth:`~selftune.sim._salient.RotorFrames.advance`: ``i_ab`` (P,) at the
        sample's end from ``current`` (``i_ab`` at its start), a stationary vector
        ``steady`` held over it and ``turning`` (``exp(j theta_0) u``, u held in the rotor
        frame; None: none), V, with the rotor at ``rotor`` and ``following`` at the start
        and end."""
        turn = np.conj(rotor)
        held = None if turning is None else turn * turning
        return following * self.propagate(turn * current, turn * steady, held)

    def carrier(
        self, current: complex, segments: PwmSegments, rotor: complex, following: complex
    ) -> complex:
        """One motor's (P = 1) ``i_ab`` at the carrier period's end from ``current``
        (``i_ab`` at its start), A, segment by segment (its
        :func:`~selftune.sim._pwm.carrier_segments`, each stationary voltage held), the
        rotor at ``rotor`` and ``following`` (``exp(j theta)``) at the period's start
        and end."""
        turn = rotor.conjugate()
        i = np.array([turn * current])
        bounds, voltages = segments.boundaries[0].tolist(), segments.voltages[0]
        for j in range(voltages.shape[0]):
            start, end = bounds[j], bounds[j + 1]
            if end > start:
                held = turn * voltages[j : j + 1] * np.exp(-1j * self.speed * start)
                i = self.propagate(i, held, None, end - start)
        return following * complex(i[0])
