"""What a carrier inverter's pulses leave in a structured fit that the held model does
not carry, as a shift of the fitted motor's parameters.

The structures hold each sample's voltage (and the dead time's ``-v sign(i_x)``, the
pulses' lost width, :mod:`._dead_time`) evenly over the sample. A centre-aligned
carrier applies it as one pulse a leg, ``d_x T`` long about the period's middle
(duty ``d_x``), with one edge ``t_d`` late by the sign of the leg's current. Three
effects of that are left out of the held model:

- a pulse (or gap) shorter than the dead time loses only its own length
  (:func:`lost_signs`): near the modulation's limit the model's full
  dead-time voltage is too large;
- every pulse comes ``t_d / 2`` late (:func:`pulse_delay_gain`);
- the volt-seconds sit about the period's middle, not spread over it: over an interior
  motor's sample its rotor frame turns ``w_e T``, and its saliency makes the current's
  response to a stationary volt-second depend on when in the sample it comes. A held
  and a centred pulse of the same volt-seconds then move the current differently, by
  about ``(w_e T)^2`` of the saliency's part (a surface motor's response turns with
  the rotor and is the same at any time, but for the decay ``R_s T / L_s``).

:func:`carrier_increments` computes each sample's state increment of the carrier's
pulses exactly (the motor's response to a stationary volt-second at each time of the
sample, integrated over each leg's pulse as the carrier places it) less the held
model's; their effect on the measured currents is the fitted model's response to them,
and the output-error fit would move by one Gauss-Newton step on that response
(:func:`pulse_shift`): the bias they leave, to first order. The reported motor's
standard errors hold it (:func:`with_pulse_shift`); no decision of the verdict reads
them, but where they can be held (:func:`holds_pulses`) the fit on the signs the next
sample shows may be reported (:func:`~._model_signs.adopted_next_signs`). It needs
the DC bus (``t_d = v h / V_dc`` from the fitted dead-time voltage ``v``, one carrier
period a sample) and the stationary hold of a PWM inverter.

On carrier PWM with dead time (the ramp and interior draws, docs/schedule.md and
docs/interior.md) the flux (once L_q) came out 0.004-0.02% low at 3.2-8.0 standard errors
on motors whose voltages reached 31-79% of the modulation's limit (no short pulses),
within 0.2-2.7 on average PWM with the same dead time; the delay's shift predicted those
errors in sign and size (-0.003% to -0.026% of the flux against -0.0045% to -0.020%).
On the interior draws' fits on the next sample's signs, whose bars are the noise's, L_q
came out 0.03-0.06% low at 3.0-3.6 standard errors at rated speed (0.014-0.017% at
2.2-2.8 without dead time), within 1.0 on average PWM: the centred pulses' part.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np
from scipy.linalg import expm

from ...core import Array
from ...core._phases import CLARKE, from_phases, space_vector_duties
from ...errors import ConfigurationMismatch
from ._alignment import applied_inputs
from ._dead_time import DeadTimeChannels, phase_sign_values
from ._ipmsm_structure import IpmsmStructure
from ._output_error import (
    OutputErrorFit,
    _jacobian_map,
    _Log,
    _normal_equations,
    _residuals_and_jacobian,
    simulate_model,
)
from ._propagation import _run_searches
from ._rounding import noise_root
from ._spmsm_structure import SpmsmStructure

__all__ = [
    "RESPONSE_GRID",
    "carrier_increments",
    "check_bus",
    "holds_pulses",
    "lost_signs",
    "pulse_delay_gain",
    "pulse_shift",
    "with_pulse_shift",
]

#: Points of the grid over a sample on which the motor's response to a volt-second is
#: integrated (:func:`carrier_increments`): the pulses' edges fall between them, read by
#: linear interpolation of the integral, within ``(T / 2000)^2`` of it relative.
RESPONSE_GRID = 2001


def check_bus(voltages: Sequence[Array], dc_voltage: float) -> None:
    """Refuse a DC bus that cannot have applied the logged voltages: their median size
    beyond ``2 V_dc / pi``, the largest fundamental an inverter on that bus applies
    (six-step; space-vector PWM's linear range ends at ``V_dc / sqrt(3)``). The median
    leaves a few saturated commands in a transient alone; a bus given in the wrong unit
    or a wrong drive's is beyond it in most samples, and the carrier's pulses computed on
    it (:func:`pulse_shift`) are nonsense (the example log at 58 V, with 10 V stated:
    the flux's standard error 6,000 times the one at its true 540 V).

    Parameters
    ----------
    voltages : sequence of ndarray, shape (T, 2)
        The logs' dq (or stationary) voltages, V.
    dc_voltage : float
        The stated ``V_dc``, V.

    Raises
    ------
    ConfigurationMismatch
        Naming ``dc_voltage``, the voltages' median size and the bound.
    """
    sizes = np.concatenate([np.hypot(u[:, 0], u[:, 1]) for u in voltages if u.shape[1] == 2])
    if sizes.size == 0:
        return
    median, bound = float(np.median(sizes)), 2.0 * dc_voltage / math.pi
    if median > bound:
        raise ConfigurationMismatch(
            f"dc_voltage: says {dc_voltage:.6g} V, but the logged voltages' median size is "
            f"{median:.4g} V, beyond the {bound:.4g} V (2 V_dc / pi) an inverter on that bus "
            "can apply; check the DC bus (V) and the voltage columns' unit",
            key="dc_voltage",
        )


def holds_pulses(structure: object, dc_voltage: float | None) -> bool:
    """Whether a fit of ``structure`` has its reported bars hold the carrier's pulses
    (:func:`pulse_shift`): a surface or interior structure with dead time on a stationary
    hold, and the DC bus given."""
    return (
        isinstance(structure, (SpmsmStructure, IpmsmStructure))
        and structure.dead_time
        and structure.hold == "stationary"
        and dc_voltage is not None
    )


def pulse_shift(
    fit: OutputErrorFit, channels: DeadTimeChannels, shift: int, dc_voltage: float
) -> Array | None:
    """The shift of the fit's parameters that the carrier's pulses leave
    (:func:`carrier_increments`, see the module); None where it does not apply (no surface or
    interior structure with dead time on a stationary hold, or no angle to place the
    phases by).

    Parameters
    ----------
    fit : OutputErrorFit
        The structured fit with dead time.
    channels : DeadTimeChannels
        The logs as fitted, with their angles.
    shift : int
        The alignment of the logged inputs.
    dc_voltage : float
        ``V_dc``, V.

    Returns
    -------
    ndarray, shape (p,) or None
        In the structure's parameters' units.
    """
    structure = fit.structure
    if not holds_pulses(structure, dc_voltage) or channels.angles is None:
        return None
    assert isinstance(structure, (SpmsmStructure, IpmsmStructure))
    values = dict(zip(structure.names(True), fit.parameters.tolist(), strict=True))
    v = max(values["v"], 0.0)
    Ad, Bd, Ed = structure(fit.parameters)
    A, B = structure.continuous(fit.parameters)
    n = Ad.shape[0]
    advance = 0.5 * structure.electrical_speed * structure.h  # the modulator's compensation
    held = (A, B, structure.h, structure.electrical_speed)
    logs, responses = [], []
    for episode, angle in zip(channels.episodes, channels.angles, strict=True):
        a, first = applied_inputs(episode, shift)
        count = min(a.shape[0], episode.num_samples - first)
        x, a = episode.x[first : first + count + 1], a[:count]
        assert episode.w is not None
        logs.append(_Log(x=x, a=a, w=episode.w[first : first + count]))
        pulses = (angle[first : first + count], advance, dc_voltage, v)
        omitted = carrier_increments(held, x[:-1], a, pulses)
        step = (Ad, np.eye(n), np.zeros((n, 0)))  # the omitted increment, a sample on
        responses.append(simulate_model(step, np.zeros(n), omitted, np.zeros((count, 0))))
    chain = _jacobian_map(structure, fit.parameters, True)
    x0s = [xhat[0] for xhat in fit.simulated]
    [(_, jacobians, _)] = _run_searches(
        [_residuals_and_jacobian(logs, (Ad, Bd, Ed), x0s, chain, list(fit.simulated))]
    )
    floor = np.sqrt(np.diag(fit.noise_covariance))  # the fit's own weight
    root = noise_root(np.concatenate(fit.residuals), floor)
    p = fit.parameters.size
    normal, gradient = _normal_equations(responses, jacobians, root, p)
    return np.asarray(np.linalg.lstsq(normal, gradient, rcond=None)[0][:p])


def with_pulse_shift(fit: OutputErrorFit, moved: Array) -> OutputErrorFit:
    """The fit with ``moved`` (:func:`pulse_shift`) in its parameters' covariance as
    independent standard errors, one a parameter: what the reported motor is read from,
    never the verdict's plants or gates."""
    covariance = fit.parameter_covariance + np.diag(np.asarray(moved) ** 2)
    return replace(fit, parameter_covariance=covariance)


def carrier_increments(
    motor: tuple[Array, Array, float, float],
    x: Array,
    a: Array,
    pulses: tuple[Array, float, float, float],
) -> Array:
    """Each sample's state increment of a centre-aligned carrier's pulses less the held
    model's (see the module), A.

    Over a sample ``[0, T)`` a stationary volt-second at time ``s`` moves the next
    sample's dq current by ``G(s) = expm(A (T - s)) B Rot(-w_e s)`` (in the dq frame of
    the sample's start). Leg ``x`` is high over ``[r_x, f_x)``: ``r_x = (1 - d_x) T / 2``,
    ``f_x = (1 + d_x) T / 2``, the rise ``t_d`` late where ``i_x > 0``, the fall where
    ``i_x < 0``; a leg at duty 0 or 1 does not switch, and no pulse outlasts the period
    or is shorter than nothing. The carrier moves the state by ``sum_x V_dc (F(f_x) -
    F(r_x)) CLARKE_x`` with ``F(s) = int_0^s G``; the held model by ``F(T) (Rot(advance)
    a_k - v s_k)``, ``s_k`` the phase signs' vector (:func:`~._dead_time.phase_signs`).

    Parameters
    ----------
    motor : (A, B, h, w_e)
        The fitted continuous dynamics (1/s, 1/H), the sample (= carrier) period ``T``, s,
        and the electrical speed, rad/s.
    x : ndarray, shape (T, 2)
        ``[i_d, i_q]`` at the samples' starts (whose signs the dead time acts with), A.
    a : ndarray, shape (T, 2)
        The dq voltage applied over each sample, V.
    pulses : (angle, advance, dc_voltage, v)
        The electrical angle at each sample's start (T,), rad; the angle the modulator
        turns the command ahead, rad; ``V_dc``, V; the dead-time voltage ``v = t_d V_dc /
        T``, V.

    Returns
    -------
    ndarray, shape (T, 2)
        The carrier's increment less the held model's, A.
    """
    A, B, h, w_e = motor
    angle, advance, dc_voltage, v = pulses
    s = np.linspace(0.0, h, RESPONSE_GRID)
    c, n = np.cos(w_e * s), np.sin(w_e * s)
    turning = np.stack([np.stack([c, n], -1), np.stack([-n, c], -1)], -2)  # Rot(-w_e s)
    G = expm(A[np.newaxis] * (h - s)[:, np.newaxis, np.newaxis]) @ B @ turning
    F = np.zeros_like(G)
    F[1:] = np.cumsum(0.5 * (G[1:] + G[:-1]) * np.diff(s)[:, np.newaxis, np.newaxis], axis=0)
    turn = np.exp(1j * np.asarray(angle, dtype=float))
    signs = phase_sign_values(x, angle)
    ahead = (a[:, 0] + 1j * a[:, 1]) * np.exp(1j * advance)  # Rot(advance) a_k
    duties = space_vector_duties(ahead * turn, dc_voltage)
    t_d = v * h / dc_voltage
    switching = (duties > 0.0) & (duties < 1.0)
    fall = np.minimum((1.0 + duties) * h / 2 + t_d * ((signs < 0.0) & switching), h)
    rise = np.minimum((1.0 - duties) * h / 2 + t_d * ((signs > 0.0) & switching), fall)
    flat = F.reshape(RESPONSE_GRID, 4)
    width = np.stack([np.interp(fall, s, f) - np.interp(rise, s, f) for f in flat.T], -1)
    legs = dc_voltage * CLARKE[np.newaxis, :] * np.conj(turn)[:, np.newaxis]  # dq at the start
    leg_dq = np.stack([legs.real, legs.imag], -1)  # (T, 3, 2)
    carrier = np.einsum("tkij,tkj->ti", width.reshape(*width.shape[:2], 2, 2), leg_dq)
    commanded = ahead - v * from_phases(signs) * np.conj(turn)  # s_k: phase_signs
    return np.asarray(carrier - np.column_stack([commanded.real, commanded.imag]) @ F[-1].T)


def lost_signs(
    x: Array, a: Array, angle: Array, advance: float, dc_voltage: float, voltage: float
) -> Array:
    """The part of the phase signs' vector whose dead time a short pulse does not carry.

    A leg whose current flows out (``i_x > 0``) rises ``t_d`` late, so its pulse, ``d_x
    T`` long in a carrier period ``T`` (duty ``d_x``), loses ``t_d``; one whose current
    flows in falls ``t_d`` late, so the pulse gains ``t_d`` of the ``(1 - d_x) T`` it
    does not fill: hence ``-v sign(i_x)``, ``v = t_d V_dc / T``. A pulse cannot be
    shorter than nothing nor longer than the period: where the room, ``m_x T`` (``m_x
    = d_x`` for ``i_x > 0``, ``1 - d_x`` for ``i_x < 0``), is shorter than ``t_d`` the
    leg loses only ``m_x T``, and a leg held at duty 0 or 1 does not switch and loses
    nothing. The error is then ``-v sign(i_x) (1 - l_x)`` with the share lost::

        l_x = max(0, 1 - m_x T / t_d) = max(0, 1 - m_x V_dc / v)   (1 where d_x is 0 or 1)

    so the model's ``-v s_k`` (:func:`~._dead_time.phase_signs`) leaves out ``+v c_k``,
    ``c_k = (2/3) sum_x sign(i_x) l_x exp(j 2 pi x / 3)`` in dq: nonzero only where a leg's room is
    within ``t_d`` of none, i.e. at the voltage limit (``|u| = V_dc / sqrt(3)`` leaves
    two legs at duties 0 and 1 only at six angles, and within ``t_d / T`` of them over
    a band of angles around those).

    Parameters
    ----------
    x : ndarray, shape (T, 2)
        ``[i_d, i_q]`` at the rows (whose signs the dead time acts with), A.
    a : ndarray, shape (T, 2)
        The dq voltage applied over each row's sample, V.
    angle : ndarray, shape (T,)
        Electrical rotor angle at each row, rad.
    advance : float
        The angle the modulator turns the command ahead of the row's, rad (the drive's
        angle compensation: ``w_e h / 2`` from the sample's start to its middle).
    dc_voltage : float
        ``V_dc``, V.
    voltage : float
        ``v = t_d V_dc / T``, V (not positive: nothing lost).

    Returns
    -------
    ndarray, shape (T, 2)
        ``c_k`` in dq, dimensionless (0 where every leg has room).
    """
    turn = np.exp(1j * np.asarray(angle, dtype=float))
    signs = phase_sign_values(x, angle)
    modulated = (a[:, 0] + 1j * a[:, 1]) * turn * np.exp(1j * advance)
    duties = space_vector_duties(modulated, dc_voltage)
    room = np.where(signs > 0.0, duties, 1.0 - duties)
    lost = np.clip(1.0 - room * dc_voltage / voltage, 0.0, 1.0) if voltage > 0.0 else 0.0 * room
    lost[(duties <= 0.0) | (duties >= 1.0)] = 1.0 if voltage > 0.0 else 0.0
    vector = from_phases(signs * lost) * np.conj(turn)
    return np.column_stack([vector.real, vector.imag])


def pulse_delay_gain(R_s: float, L_s: float, dead_time: float) -> float:
    """How much more a voltage held over a sample moves a surface PMSM's current when the
    inverter's dead time delays every pulse by half of it.

    The dead time moves one edge of each switching leg's pulse by ``t_d``: the rise of a
    leg whose current flows out, the fall of one whose current flows in. Either way the
    pulse's middle comes ``t_d / 2`` later in the carrier period: besides the dead-time
    voltage (the pulse's width, :func:`~._dead_time.phase_signs`), the inverter's output
    is the held voltage ``t_d / 2`` late. In the stationary frame a surface motor's current decays
    at ``R_s / L_s`` (the rotation is in the back-EMF), so a volt-second applied ``t_d /
    2`` later has decayed by ``exp(-R_s t_d / (2 L_s))`` less at the sample's end: the
    voltage's effect on the next sample, ``Bd`` per volt, is ``exp(R_s t_d / (2 L_s))``
    times the held model's. A centred pulse (no dead time) is not late, and its
    volt-seconds' spread about the middle is second order in ``R_s T / L_s``. In an
    interior motor's rotor frame the rotation cancels the same way to first order in
    ``t_d``: its d and q voltages each take the factor of their own axis's inductance.

    Parameters
    ----------
    R_s : float
        Stator resistance, ohm.
    L_s : float
        Inductance, H (an interior motor's ``L_d`` or ``L_q``).
    dead_time : float
        ``t_d``, s.

    Returns
    -------
    float
        The factor on ``Bd``: 1 without dead time.
    """
    return math.exp(R_s * dead_time / (2.0 * L_s))
