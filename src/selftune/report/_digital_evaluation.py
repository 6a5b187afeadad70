"""A digital-target result against the optimum of the same sampled loop (evaluation only).

The truth is :func:`selftune.model.solve_digital_regulation` of the true motor (heated
as the drive's temperature says) on the drive's hold, with its computation delay and,
for a servo controller, the same integral weight the learner used. The excess cost is
that of the learned feedback on the same loop: ``zeta_0' P(K) zeta_0 / zeta_0' P* zeta_0 -
1`` (:func:`feedback_excess_cost`), ``zeta_0`` the deviation of rest from the true
equilibrium (the torque step), ``P(K)`` the value of the learned ``[K, K_i]`` on the true
sampled plant; it is never negative, and the feedforward's error is reported beside it
(it shifts the steady state, or, with integral action, the integrator's).
:func:`digital_step_cost` measures the same cost by simulating the loop (a check).
"""

from __future__ import annotations

from dataclasses import replace
from typing import TypeVar

import numpy as np

from ..core import Array, ControlLaw
from ..errors import UnsolvableError
from ..model import IPMSM, SPMSM, ModelBasedSolution, solve_digital_regulation
from ..sim import DriveSettings, RealisticDrive, constant, simulate_loop
from ..tuning import TuningResult, TuningSettings
from ._evaluate import TuningEvaluation, block_error, learner_integral_weight

__all__ = [
    "STEP_SECONDS",
    "digital_step_cost",
    "evaluate_digital",
    "feedback_excess_cost",
    "step_cost",
    "true_motor",
]

MotorT = TypeVar("MotorT", SPMSM, IPMSM)

#: Length of the torque step over which a digital loop's cost is summed, s.
STEP_SECONDS = 0.5


def true_motor(motor: MotorT, drive: DriveSettings | None) -> MotorT:
    """The motor at the drive's temperature (the nameplate's without a drive).

    Parameters
    ----------
    motor : SPMSM or IPMSM
        Nameplate values.
    drive : DriveSettings or None
        The drive (its ``temperature_rise``).
    """
    if drive is None:
        return motor
    settings = replace(drive, dead_time=0.0, pwm="average")
    return RealisticDrive(motor, 0.0, 1.0, settings).true_motor


def evaluate_digital(
    result: TuningResult, motor: SPMSM, settings: TuningSettings, drive: DriveSettings | None
) -> TuningEvaluation:
    """``result`` against the optimum of the same sampled loop (see the module docstring).

    Parameters
    ----------
    result : TuningResult
        A digital-target result.
    motor : SPMSM
        The true motor (nameplate values).
    settings : TuningSettings
        The settings it was learned with.
    drive : DriveSettings or None
        The drive it was learned on.
    """
    truth = true_motor(motor, drive)
    law = result.law
    weight = learner_integral_weight(truth, settings) if law.K_i is not None else None
    hold = "rotor" if drive is None else drive.voltage_hold
    optimum = solve_digital_regulation(
        truth.regulation_problem(settings.speed), settings.Q, settings.R, settings.h,
        input_delay=law.history, integral_weight=weight,
        plant=truth.sampled_plant(settings.speed, settings.h, hold),
    )  # fmt: skip
    nan = np.full(len(result.history), np.nan)
    w_true = truth.exogenous(settings.speed, settings.torque)
    excess = feedback_excess_cost(optimum, law, w_true)
    return TuningEvaluation(
        optimum=optimum,
        theta_error=nan,
        learned_cost=nan,
        true_cost=nan,
        final_theta_error=float("nan"),
        K_error=block_error(law.K, optimum.law.K),
        U_error=block_error(law.U, optimum.U),
        excess_cost=excess,
        K_i_error=block_error(law.K_i, optimum.law.K_i),
    )


def feedback_excess_cost(optimum: ModelBasedSolution, law: ControlLaw, w: Array) -> float:
    """The digital cost of ``law``'s feedback over the optimum's, minus 1, for the torque
    step from rest on the optimum's sampled loop (see the module docstring).

    Parameters
    ----------
    optimum : ModelBasedSolution
        The optimum of the true sampled loop (its plant, delay, weights, integrator).
    law : ControlLaw
        The learned law (the same delay and integrator).
    w : ndarray, shape (q,)
        The true ``w`` of the step.

    Returns
    -------
    float
        ``inf`` if the feedback does not stabilize the loop.
    """
    loop = optimum.loop
    if law.history != loop.input_delay or law.r != loop.r:
        return float("nan")
    return step_cost(optimum, law, w) / step_cost(optimum, optimum.law, w) - 1.0


def step_cost(optimum: ModelBasedSolution, law: ControlLaw, w: Array) -> float:
    """``zeta_0' P(law) zeta_0``: the digital cost of ``law``'s feedback for the torque
    step from rest to the optimum's equilibrium at ``w``, on the optimum's sampled loop
    (see the module docstring).

    Parameters
    ----------
    optimum : ModelBasedSolution
        The optimum of the true sampled loop (its plant, delay, weights, integrator).
    law : ControlLaw
        The law (the same delay and integrator).
    w : ndarray, shape (q,)
        The true ``w`` of the step.

    Returns
    -------
    float
        ``inf`` if the feedback does not stabilize the loop.
    """
    loop, plant = optimum.loop, optimum.sampled_plant[:2]
    weights = loop.weights(optimum.Q, optimum.R, "digital")
    zeta0 = loop.step_from_rest(optimum.X, optimum.U, w)
    try:
        value = loop.value(plant, law, weights)
    except UnsolvableError:
        return float("inf")
    return float(zeta0 @ value @ zeta0)


def digital_step_cost(
    motor: SPMSM,
    settings: TuningSettings,
    law: ControlLaw,
    w: Array,
    integral_weight: Array | None,
    seconds: float = STEP_SECONDS,
    hold: str = "rotor",
) -> float:
    """The digital cost of ``law``'s torque step from rest on the ideal sampled loop.

    ``sum_k h (xbar_k' Q xbar_k + ubar_k' R ubar_k + zbar_k' Q_i zbar_k)``, the bars
    deviations from the loop's own final state (``seconds`` long, far past its settling),
    ``u_k`` the voltage computed at sample k; the delay is the law's history. The motor
    makes its own back-EMF whatever flux the controller's ``w`` assumes.

    Parameters
    ----------
    motor : SPMSM
        The true motor.
    settings : TuningSettings
        Speed, torque, sampling period and cost weights.
    law : ControlLaw
        The controller.
    w : ndarray, shape (2,)
        The controller's ``w``.
    integral_weight : ndarray or None
        ``Q_i`` (None without integral action).
    seconds : float
        Length of the step, s.
    hold : {"rotor", "stationary"}
        What the drive holds over a sample (:meth:`selftune.model.SPMSM.sampled_plant`).
    """
    w_true = motor.exogenous(settings.speed, settings.torque)
    w = np.asarray(w, dtype=float)
    scale = np.divide(w_true, w, out=np.ones_like(w_true), where=w != 0.0)
    Ad, Bd, Ed = motor.sampled_plant(settings.speed, settings.h, hold)
    count = max(2, round(seconds / settings.h))
    logs = simulate_loop(
        (Ad, Bd, Ed @ np.diag(scale)), law, constant(w), h=settings.h,
        num_samples=count, delay=law.history, discrete=True,
    )  # fmt: skip
    run = logs.commanded
    x, u = run.x[:-1], run.u
    dx, du = x - run.x[-1], u - u[-1]
    total = np.einsum("ki,ij,kj->", dx, settings.Q, dx)
    total += np.einsum("ki,ij,kj->", du, settings.R, du)
    if integral_weight is not None and law.C is not None and law.F is not None:
        e = x @ law.C.T + w @ law.F.T
        z = settings.h * np.vstack([np.zeros((1, e.shape[1])), np.cumsum(e, axis=0)[:-1]])
        dz = z - z[-1]
        total += np.einsum("ki,ij,kj->", dz, integral_weight, dz)
    return float(settings.h * total)
