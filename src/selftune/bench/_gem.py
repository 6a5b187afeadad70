"""gym-electric-motor, the peer simulator the bench times against (optional extra ``[bench]``)."""

from __future__ import annotations

import importlib
import importlib.metadata
import time
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from ._loop import Loop, SimulatorMeasurement, exact_states, max_relative_error


@dataclass(frozen=True)
class GymElectricMotor:
    """gym-electric-motor's ``Cont-CC-PMSM-v0`` with the same motor, if installed.

    Attributes
    ----------
    available : bool
        Whether it was installed and ran.
    version_text : str or None
        Its version.
    reason_text : str or None
        Why it was not measured.
    default_solver : SimulatorMeasurement or None
        Its default ODE solver (scipy ``ode``, dopri5).
    euler_solver : SimulatorMeasurement or None
        Its explicit Euler solver (its fastest).
    """

    available: bool
    version_text: str | None
    reason_text: str | None
    default_solver: SimulatorMeasurement | None
    euler_solver: SimulatorMeasurement | None


def gem_version() -> str | None:
    try:
        return importlib.metadata.version("gym-electric-motor")
    except importlib.metadata.PackageNotFoundError:
        return None


def _run_gem(loop: Loop, samples: int, euler: bool) -> SimulatorMeasurement:
    """gym-electric-motor's continuous current-control PMSM env with the paper's motor.

    The action is the phase-voltage vector of a B6 bridge, normalized by half the DC
    voltage; it is computed from the dq voltage with the rotor angle at the start of the
    step, which the environment uses to transform it back, so the motor sees exactly the
    held dq voltage (the angle advance of gym-electric-motor's dq wrapper would rotate it
    by half a step). The DC link (2 kV) and the limits (1 kA) are set so that nothing
    saturates or terminates.
    """
    gem: Any = importlib.import_module("gym_electric_motor")
    systems: Any = importlib.import_module("gym_electric_motor.physical_systems")
    references: Any = importlib.import_module("gym_electric_motor.reference_generators")
    motor = loop.motor
    half_dc = 1000.0
    options: dict[str, Any] = {}
    if euler:
        options["ode_solver"] = systems.EulerSolver()
    limits = {"i": 1000.0, "u": 1000.0, "omega": 10.0 * loop.speed}
    env = gem.make(
        "Cont-CC-PMSM-v0",
        motor={
            "motor_parameter": {
                "p": motor.p,
                "l_d": motor.L_s,
                "l_q": motor.L_s,
                "j_rotor": motor.J or 0.0163,
                "r_s": motor.R_s,
                "psi_p": motor.phi_pm,
            },
            "limit_values": limits,
            "nominal_values": limits,
        },
        load={"omega_fixed": loop.speed},
        supply={"u_nominal": 2.0 * half_dc},
        tau=loop.h,
        reference_generator=references.ConstReferenceGenerator("i_sq", 0.0),
        visualization=(),
        constraints=(),
        **options,
    )
    names = list(env.unwrapped.physical_system.state_names)
    scale = np.asarray(env.unwrapped.physical_system.limits, dtype=float)
    index_d, index_q, index_angle = (names.index(n) for n in ("i_sd", "i_sq", "epsilon"))
    to_abc = systems.ThreePhaseMotor.t_32
    rotate = systems.ThreePhaseMotor.q
    rho = loop.exploration(samples)
    reference = loop.L @ loop.w
    states = np.empty((samples + 1, 2))
    (observation, _), _ = env.reset(seed=0)
    x = observation[[index_d, index_q]] * scale[[index_d, index_q]]
    states[0] = x
    start = time.perf_counter()
    for k in range(samples):
        u = reference - loop.K @ x + rho[k]
        angle = observation[index_angle] * scale[index_angle]
        action = to_abc(rotate(u / half_dc, angle))
        (observation, _), _, terminated, truncated, _ = env.step(action)
        x = observation[[index_d, index_q]] * scale[[index_d, index_q]]
        states[k + 1] = x
        if terminated or truncated:
            raise RuntimeError(f"the environment ended the episode at step {k}")
    seconds = time.perf_counter() - start
    env.close()
    return SimulatorMeasurement(
        us_per_step=seconds / samples * 1e6,
        timed_samples=samples,
        max_relative_error=max_relative_error(states, exact_states(loop, motor, rho)),
        compared_samples=samples,
    )


def measure_gem(loop: Loop, samples: int) -> GymElectricMotor:
    version = gem_version()
    if version is None:
        return GymElectricMotor(
            available=False,
            version_text=None,
            reason_text="not installed (pip install 'selftune[bench]')",
            default_solver=None,
            euler_solver=None,
        )
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            default = _run_gem(loop, samples, euler=False)
            euler = _run_gem(loop, samples, euler=True)
    except Exception as exc:  # an optional third-party package: report, do not fail
        return GymElectricMotor(
            available=False,
            version_text=version,
            reason_text=f"installed but failed: {type(exc).__name__}: {exc}",
            default_solver=None,
            euler_solver=None,
        )
    return GymElectricMotor(
        available=True,
        version_text=version,
        reason_text=None,
        default_solver=default,
        euler_solver=euler,
    )
