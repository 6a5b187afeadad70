"""The ideal drive: a motor held at a speed by a load machine, simulated exactly.

It implements the :class:`selftune.tuning.Drive` protocol: the self-tuning algorithms
only call :meth:`SimulatedDrive.run` and :meth:`SimulatedDrive.run_no_load` and only read
the trajectories they return.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core import Array, ControlLaw, discretize, positive_integer
from ..errors import InputError
from ..learn import LoggedInput, Trajectory
from ..loop import SampledLoop
from ..model import SPMSM
from ._checks import check_finite_states
from ._exploration import Exploration
from ._loop import exploration_inputs
from ._signals import ExogenousSignal, check_signal_values, constant
from ._stepper import feedback_of, fill_held, run_sampled_loop

__all__ = ["SimulatedDrive"]


@dataclass(frozen=True)
class SimulatedDrive:
    """A motor held at a speed by a load machine, simulated exactly (the test bench).

    It stands in for a real drive: the algorithms only call :meth:`run` and
    :meth:`run_no_load` and only read the trajectories they return. Episodes start from
    rest (``x(0) = 0``, past inputs and integrator 0). It runs every
    :class:`~selftune.core.ControlLaw` (past inputs fed back, integral action) by the
    stepper every drive shares (:mod:`._stepper`), the plant sampled exactly.

    Parameters
    ----------
    motor : SPMSM
        The true motor.
    speed : float
        Held mechanical speed, rad/s.
    h : float
        Sampling period, s.
    input_hold : int
        The controller updates u every ``input_hold`` samples (1: every sample).
    """

    motor: SPMSM
    speed: float
    h: float
    input_hold: int = 1

    @property
    def pole_pairs(self) -> int:
        """Number of pole pairs."""
        return self.motor.p

    @property
    def loop(self) -> SampledLoop:
        """The ideal drive's loop: sampled at h, no delay (the voltage computed at a sample
        acts during it), the dq voltage held over each sample (zero-order hold)."""
        return SampledLoop(self.h, 0, "rotor")

    @property
    def logged_input(self) -> LoggedInput:
        """``"applied"``: row k of the log holds the voltage applied during sample k."""
        return "applied"

    def _episode(
        self,
        plant: tuple[Array, Array, Array],
        law: ControlLaw,
        reference: ExogenousSignal,
        num_samples: int,
        exploration: Exploration | None,
        seed: int,
    ) -> Trajectory:
        """The loop of ``law`` on ``x' = A x + B u + D w`` from rest, by the one stepper
        (:func:`~selftune.sim._stepper.run_sampled_loop`) at the controller's period, the
        samples in between filled in exactly (:func:`~selftune.sim._stepper.fill_held`)."""
        A, B, D = plant
        hold = positive_integer(self.input_hold, "input_hold")
        count = positive_integer(num_samples, "num_samples")
        q = D.shape[1]
        if (law.n, law.m, law.q) != (B.shape[0], B.shape[1], q):
            raise InputError(
                f"law: has (n, m, q) = {(law.n, law.m, law.q)}; the drive needs "
                f"{(B.shape[0], B.shape[1], q)} (currents, voltages, the reference's channels)"
            )
        updates = -(-count // hold)
        period = hold * self.h
        t = period * np.arange(updates + 1, dtype=float)
        exact = discretize(A, B, period, D=D, E=reference.E)
        w = check_signal_values(reference.values(t), updates + 1, "reference")
        rho = exploration_inputs(law, exploration, t, seed)
        with np.errstate(over="ignore", invalid="ignore"):
            x, loop = run_sampled_loop(
                (exact.Ad, exact.Bd, exact.Ed), feedback_of([law]), w, rho, self.loop.input_delay
            )
        check_finite_states(x[np.newaxis], t)
        coarse = Trajectory(t=t, x=x, u=loop.applied[0], w=w)
        if hold == 1:
            return coarse
        return fill_held(coarse, (A, B, D, reference.E), self.h, hold, count)

    def run(
        self,
        law: ControlLaw,
        reference: ExogenousSignal,
        *,
        num_samples: int,
        exploration: Exploration | None,
        seed: int,
        assumed_flux: float | None = None,
    ) -> Trajectory:
        """One episode of the known-flux form, ``x' = A x + B u + D w``.

        ``reference`` is the controller's ``w = [p speed phi, T*]`` (held). When the
        controller assumes a flux ``assumed_flux`` other than the true one, the back-EMF
        the motor produces is ``D w`` with the true flux, i.e. ``D diag(phi/assumed, 1) w``;
        this is exact only while ``w_1`` is constant, so the first channel must not be
        perturbed then.

        Parameters
        ----------
        law : ControlLaw
            The controller (n = m = 2, q = 2), with its past inputs and integrator.
        reference : ExogenousSignal
            The controller's ``w = [p speed phi, T*]`` (held).
        num_samples : int
            Length of the episode, samples.
        exploration : Exploration or None
            Exploration ``rho`` added to the input; None for none.
        seed : int
            Seed of the exploration.
        assumed_flux : float, optional
            Flux linkage the controller's ``w`` assumes, Wb (default: the true one).
        """
        problem = self.motor.regulation_problem(self.speed)
        D = problem.D
        if assumed_flux is not None and assumed_flux != self.motor.phi_pm:
            D = D @ np.diag([self.motor.phi_pm / assumed_flux, 1.0])
            values = reference.values(np.arange(num_samples + 1) * self.h)
            if np.ptp(values[:, 0]) > 0.0:
                raise InputError(
                    "reference: with an assumed flux, the back-EMF channel w_1 must be "
                    "constant (perturb the torque reference only)"
                )
        return self._episode(
            (problem.A, problem.B, D), law, reference, num_samples, exploration, seed
        )

    def run_no_load(
        self,
        law: ControlLaw,
        *,
        num_samples: int,
        exploration: Exploration | None,
        seed: int,
    ) -> Trajectory:
        """One no-load episode (eq. 15): ``w = [p speed]``, ``T* = 0``, ``u = -K x + rho``.

        Parameters
        ----------
        law : ControlLaw
            The controller (its feedforward on ``w = [p speed]``, usually 0).
        num_samples : int
            Length of the episode, samples.
        exploration : Exploration or None
            Exploration ``rho`` added to the input; None for none.
        seed : int
            Seed of the exploration.
        """
        problem = self.motor.no_load_problem(self.speed)
        reference = constant(self.motor.no_load_exogenous(self.speed))
        return self._episode(
            (problem.A, problem.B, problem.D), law, reference, num_samples, exploration, seed
        )
