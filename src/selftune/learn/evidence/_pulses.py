"""What a carrier inverter's pulses leave in a structured fit that the dead-time model
does not carry, as a shift of the fitted motor's parameters.

The dead-time model (:mod:`._dead_time`) takes each phase's error as ``-v sign(i_x)``,
the pulse's width. Two effects of the same dead time are left out:

- a pulse (or gap) shorter than the dead time loses only its own length
  (:func:`~._dead_time.lost_signs`): near the modulation's limit the model's full
  voltage is too large by ``v c_k``;
- every pulse comes ``t_d / 2`` late, so the held voltage moves the current more than
  the held model says (:func:`~._dead_time.pulse_delay_gain`; an interior motor's d and
  q voltages each by the factor of their own axis's inductance).

Both are inputs the fit does not see. Their effect on the measured currents is the fitted
model's response to them, and the output-error fit would move by one Gauss-Newton step on
that response (:func:`pulse_shift`): the bias they leave, to first order. The reported
motor's standard errors hold it (:func:`with_pulse_shift`); no decision of the verdict
reads them. It needs the DC bus (``t_d = v h / V_dc`` from the fitted dead-time voltage
``v``, one carrier period a sample) and the stationary hold of a PWM inverter.

On carrier PWM with dead time (the ramp and interior draws, docs/schedule.md and
docs/interior.md) the flux (once L_q) came out 0.004-0.02% low at 3.2-8.0 standard errors
on motors whose voltages reached 31-79% of the modulation's limit (no short pulses),
within 0.2-2.7 on average PWM with the same dead time; the delay's shift predicted those
errors in sign and size (-0.003% to -0.026% of the flux against -0.0045% to -0.020%).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...core import Array
from ._alignment import applied_inputs
from ._dead_time import DeadTimeChannels, lost_signs, pulse_delay_gain
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

__all__ = ["pulse_shift", "with_pulse_shift"]


def pulse_shift(
    fit: OutputErrorFit, channels: DeadTimeChannels, shift: int, dc_voltage: float
) -> Array | None:
    """The shift of the fit's parameters that the short pulses' lost dead time and every
    pulse's delay leave (see the module); None where it does not apply (no surface or
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
    kinds = (SpmsmStructure, IpmsmStructure)
    if not isinstance(structure, kinds) or not structure.dead_time or channels.angles is None:
        return None
    if structure.hold != "stationary":
        return None
    values = dict(zip(structure.names(True), fit.parameters.tolist(), strict=True))
    v, h = max(values["v"], 0.0), structure.h
    Ad, Bd, Ed = structure(fit.parameters)
    n = Ad.shape[0]
    t_d = v * h / dc_voltage
    axes = [values["L_s"]] * 2 if "L_s" in values else [values["L_d"], values["L_q"]]
    gains = np.array([pulse_delay_gain(values["R_s"], float(L), t_d) for L in axes])
    delayed = Bd * (gains - 1.0)  # Bd diag(g) - Bd: the voltage's missing effect
    effect = -Ed[:, -2:]  # v times the held signs' gain: the lost part's effect
    advance = 0.5 * structure.electrical_speed * h  # the modulator's angle compensation
    logs, responses = [], []
    for episode, angle in zip(channels.episodes, channels.angles, strict=True):
        a, first = applied_inputs(episode, shift)
        count = min(a.shape[0], episode.num_samples - first)
        x, a = episode.x[first : first + count + 1], a[:count]
        assert episode.w is not None
        logs.append(_Log(x=x, a=a, w=episode.w[first : first + count]))
        lost = lost_signs(x[:-1], a, angle[first : first + count], advance, dc_voltage, v)
        omitted = a @ delayed.T + lost @ effect.T
        held = (Ad, np.eye(n), np.zeros((n, 0)))  # the omitted input, held a sample
        responses.append(simulate_model(held, np.zeros(n), omitted, np.zeros((count, 0))))
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
