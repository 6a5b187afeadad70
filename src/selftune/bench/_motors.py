"""The bench's one random-motor generator: a motor and its operating point from stated ranges.

:func:`draw_motor` draws the quantities of a :class:`MotorRanges` in the order it lists
them, with the caller's :class:`numpy.random.Generator` (each study seeds its own, so its
motors are not the tests'), and builds the nameplate, the motor as built (:func:`as_built`:
within relative tolerances of the nameplate) and the operating point from them. The order
is part of the ranges: it fixes which motor a seed gives.

Symbols (SI units): ``w_e = p speed`` electrical speed, rad/s; ``i_q*`` the q current at
the torque reference ``T* = 1.5 p phi_pm i_q*``, A; ``e = w_e phi_pm`` the back-EMF, V.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import overload

import numpy as np

from ..model import IPMSM, SPMSM, Motor

__all__ = ["Choice", "MotorRanges", "RandomMotor", "Span", "as_built", "draw_motor"]


@dataclass(frozen=True)
class Span:
    """A range a quantity is drawn from, uniformly or log-uniformly.

    Attributes
    ----------
    low, high : float
        The bounds.
    log : bool
        Log-uniform (``exp`` of a uniform draw between the bounds' logarithms).
    """

    low: float
    high: float
    log: bool = False

    def draw(self, rng: np.random.Generator) -> float:
        """One number from the range (one uniform draw of ``rng``).

        Parameters
        ----------
        rng : numpy.random.Generator
            The generator.
        """
        if self.log:
            return float(np.exp(rng.uniform(np.log(self.low), np.log(self.high))))
        return float(rng.uniform(self.low, self.high))


@dataclass(frozen=True)
class Choice:
    """A quantity drawn from a few values, each equally likely.

    Attributes
    ----------
    values : tuple of float
    """

    values: tuple[float, ...]

    def draw(self, rng: np.random.Generator) -> float:
        """One of the values (one integer draw of ``rng``).

        Parameters
        ----------
        rng : numpy.random.Generator
            The generator.
        """
        return float(rng.choice(self.values))


@dataclass(frozen=True)
class MotorRanges:
    """Where a random motor and its operating point are drawn from, in the order drawn.

    Attributes
    ----------
    draws : tuple of (str, Span or Choice)
        The quantities in the order drawn: ``pole_pairs``; ``L_s_henry``; ``R_s_ohm`` or
        ``time_constant_seconds`` (then ``R_s = L_s / tau``); ``phi_pm_weber`` or
        ``back_emf_volts`` (then ``phi_pm = e / w_e``); ``current_amperes`` (i_q*);
        ``electrical_speed_rad_per_second``; optionally ``sampling_frequency_hz`` and
        ``saliency`` (``L_q / L_d``, with ``L_d`` the drawn ``L_s``; above 1 an interior
        motor).
    tolerances : (float, float, float) or None
        Relative tolerances of R_s, L_s and phi_pm of the motor as built, drawn after the
        nameplate (:func:`as_built`); None: the motor is its nameplate (nothing drawn).
    speed_cap_volts : float or None
        ``w_e`` is capped so that ``w_e phi_pm`` and ``w_e L_s i_q*`` stay under it, V.
    voltage_limit_volts : float or None
        A draw is kept only if the steady voltage at T* with R_s at twice its nameplate,
        ``|(w_e phi_pm + 2 R_s i_q*, w_e L_s i_q*)|``, stays below it (redrawn
        otherwise, tolerances included), V.
    """

    draws: tuple[tuple[str, Span | Choice], ...]
    tolerances: tuple[float, float, float] | None = None
    speed_cap_volts: float | None = None
    voltage_limit_volts: float | None = None


@dataclass(frozen=True)
class RandomMotor:
    """A drawn motor and its operating point.

    Attributes
    ----------
    nameplate : SPMSM or IPMSM
        The motor as drawn.
    as_built : SPMSM or IPMSM
        The motor itself (the nameplate when the ranges state no tolerances).
    electrical_speed : float
        ``w_e``, rad/s.
    current : float
        ``i_q*`` at the torque reference, A.
    sampling_frequency : float or None
        f_s, Hz (None when the ranges draw none).
    """

    nameplate: Motor
    as_built: Motor
    electrical_speed: float
    current: float
    sampling_frequency: float | None

    def surface(self) -> tuple[SPMSM, SPMSM]:
        """The nameplate and the motor as built, of ranges that draw no saliency.

        Raises
        ------
        TypeError
            If the motor is an interior one.
        """
        if not (isinstance(self.nameplate, SPMSM) and isinstance(self.as_built, SPMSM)):
            raise TypeError("an interior motor was drawn where a surface one was expected")
        return self.nameplate, self.as_built

    @property
    def speed(self) -> float:
        """Mechanical speed ``w_e / p``, rad/s."""
        return self.electrical_speed / self.nameplate.p

    @property
    def torque(self) -> float:
        """The torque reference ``T* = 1.5 p phi_pm i_q*`` of the nameplate, N m."""
        return 1.5 * self.nameplate.p * self.nameplate.phi_pm * self.current


@overload
def as_built(
    rng: np.random.Generator, nameplate: SPMSM, tolerances: tuple[float, float, float]
) -> SPMSM: ...
@overload
def as_built(
    rng: np.random.Generator, nameplate: IPMSM, tolerances: tuple[float, float, float]
) -> IPMSM: ...
def as_built(
    rng: np.random.Generator, nameplate: Motor, tolerances: tuple[float, float, float]
) -> Motor:
    """The motor as built: R_s, the inductance (both of an interior motor's, by one
    factor) and phi_pm each uniform within its relative tolerance of the nameplate's
    (drawn in that order).

    Parameters
    ----------
    rng : numpy.random.Generator
        The generator.
    nameplate : SPMSM or IPMSM
        The motor as stated.
    tolerances : (float, float, float)
        Relative tolerances of R_s, the inductance and phi_pm.
    """
    R, L, phi = (1.0 + rng.uniform(-tolerance, tolerance) for tolerance in tolerances)
    return _built(
        nameplate.R_s * R, nameplate.L_d * L, nameplate.L_q / nameplate.L_d,
        nameplate.phi_pm * phi, nameplate.p,
    )  # fmt: skip


def _built(R_s: float, L_d: float, saliency: float, phi_pm: float, p: int) -> Motor:
    """A surface motor (``saliency`` 1) or an interior one with ``L_q = saliency L_d``."""
    if saliency == 1.0:
        return SPMSM(R_s=R_s, L_s=L_d, phi_pm=phi_pm, p=p)
    return IPMSM(R_s=R_s, L_d=L_d, L_q=saliency * L_d, phi_pm=phi_pm, p=p)


def _motor(values: Mapping[str, float], ranges: MotorRanges) -> tuple[Motor, float]:
    """The nameplate and ``w_e`` from the drawn values."""
    L_s, current = values["L_s_henry"], values["current_amperes"]
    w_e = values["electrical_speed_rad_per_second"]
    R_s = values["R_s_ohm"] if "R_s_ohm" in values else L_s / values["time_constant_seconds"]
    phi_pm = values["phi_pm_weber"] if "phi_pm_weber" in values else values["back_emf_volts"] / w_e
    saliency = values.get("saliency", 1.0)
    if ranges.speed_cap_volts is not None:
        w_e = min(
            w_e,
            ranges.speed_cap_volts / phi_pm,
            ranges.speed_cap_volts / (saliency * L_s * current),
        )
    return _built(R_s, L_s, saliency, phi_pm, int(values["pole_pairs"])), w_e


def draw_motor(rng: np.random.Generator, ranges: MotorRanges) -> RandomMotor:
    """A motor and its operating point drawn from ``ranges`` (see :class:`MotorRanges`).

    Parameters
    ----------
    rng : numpy.random.Generator
        The generator (the studies seed their own: their motors are not the tests').
    ranges : MotorRanges
        What is drawn, from where, in which order.

    Returns
    -------
    RandomMotor
    """
    while True:
        values = {name: draw.draw(rng) for name, draw in ranges.draws}
        nameplate, w_e = _motor(values, ranges)
        current = values["current_amperes"]
        built = nameplate
        if ranges.tolerances is not None:
            built = as_built(rng, nameplate, ranges.tolerances)
        limit = ranges.voltage_limit_volts
        voltage = np.hypot(
            w_e * nameplate.phi_pm + 2.0 * nameplate.R_s * current, w_e * nameplate.L_q * current
        )
        if limit is None or voltage <= limit:
            f_s = values.get("sampling_frequency_hz")
            return RandomMotor(nameplate, built, w_e, current, f_s)
