"""The current loop every simulator of the bench runs, its exact solution, and the measurement
type (shared by the simulation study and the gym-electric-motor adapter)."""

from __future__ import annotations

import cmath
from dataclasses import dataclass

import numpy as np

from ..core import (
    Array,
)
from ..model import SPMSM, ModelBasedSolution
from ._common import paper_setting


@dataclass(frozen=True)
class SimulatorMeasurement:
    """Time per control step and error against the exact solution, for one simulator.

    Attributes
    ----------
    us_per_step : float
        Wall time per simulated control step (10 us of motor time), microseconds.
    timed_samples : int
        Steps in the timed run.
    max_relative_error : float
        ``max_k ||x_k - x_exact,k||_inf / max_k ||x_exact,k||_inf`` over the compared run.
    compared_samples : int
        Steps compared with the exact solution.
    """

    us_per_step: float
    timed_samples: int
    max_relative_error: float
    compared_samples: int


@dataclass(frozen=True)
class Loop:
    """The closed loop every simulator runs: plant, controller, exploration."""

    motor: SPMSM
    speed: float
    h: float
    A: Array
    B: Array
    D: Array
    w: Array
    K: Array
    L: Array  # u = -K x + L w + rho
    optimum: ModelBasedSolution

    @classmethod
    def paper(cls) -> Loop:
        motor, settings, optimum = paper_setting()
        problem = motor.regulation_problem(settings.speed)
        return cls(
            motor=motor,
            speed=settings.speed,
            h=settings.h,
            A=np.asarray(problem.A),
            B=np.asarray(problem.B),
            D=np.asarray(problem.D),
            w=motor.exogenous(settings.speed, settings.torque),
            K=np.asarray(optimum.K),
            L=np.asarray(optimum.L),
            optimum=optimum,
        )

    def exploration(self, samples: int, seed: int = 0) -> Array:
        """The exploration ``rho`` (samples, 2), V: uniform in [-1, 1] V."""
        return np.random.default_rng(seed).uniform(-1.0, 1.0, size=(samples, 2))


def exact_states(loop: Loop, motor: SPMSM, rho: Array) -> Array:
    """The closed loop's states at the sample times, exact up to rounding, (N + 1, 2).

    Independent of the matrix exponential: in complex form ``z = i_d + j i_q`` the current
    dynamics are ``z' = lambda z + f`` with ``lambda = -R_s/L_s - j p speed`` and the forcing
    ``f = u / L_s + D w`` held over a sample, so ``z_(k+1) = exp(lambda h) z_k +
    expm1(lambda h)/lambda f_k`` exactly.
    """
    rate = complex(-motor.gamma, -motor.p * loop.speed)
    decay = cmath.exp(rate * loop.h)
    gain = complex(np.expm1(rate * loop.h)) / rate
    feedforward = loop.L @ loop.w
    back_emf = exogenous_matrix(motor, loop.speed) @ loop.w  # D w, A/s
    z = 0j
    K = loop.K
    states = np.empty((rho.shape[0] + 1, 2))
    states[0] = 0.0
    for k in range(rho.shape[0]):
        i_d, i_q = z.real, z.imag
        u_d = -K[0, 0] * i_d - K[0, 1] * i_q + feedforward[0] + rho[k, 0]
        u_q = -K[1, 0] * i_d - K[1, 1] * i_q + feedforward[1] + rho[k, 1]
        forcing = complex(u_d / motor.L_s + back_emf[0], u_q / motor.L_s + back_emf[1])
        z = decay * z + gain * forcing
        states[k + 1] = (z.real, z.imag)
    return states


def exogenous_matrix(motor: SPMSM, speed: float) -> Array:
    return np.asarray(motor.regulation_problem(speed).D)


def max_relative_error(states: Array, exact: Array) -> float:
    return float(np.max(np.abs(states - exact))) / float(np.max(np.abs(exact)))
