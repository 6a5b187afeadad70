"""What a self-tuning session needs of a drive: run an episode, return what it measured.

Any object with these methods works: :class:`selftune.sim.SimulatedDrive` (the exact
simulation), a realistic drive simulation, or a real drive's logger.
"""

from __future__ import annotations

from typing import Protocol

from ..core import Array
from ..learn import Trajectory
from ..sim import ExogenousSignal, Exploration

__all__ = ["Drive"]


class Drive(Protocol):
    """A drive in torque-control mode that runs episodes and returns what it measured."""

    @property
    def pole_pairs(self) -> int:
        """Number of pole pairs (nameplate)."""
        ...

    @property
    def sampling(self) -> float:
        """Sampling period, s."""
        ...

    def run(
        self,
        K: Array,
        X: Array,
        U: Array,
        reference: ExogenousSignal,
        *,
        num_samples: int,
        exploration: Exploration | None,
        seed: int,
        assumed_flux: float | None = None,
    ) -> Trajectory:
        """One episode from rest under ``u = -K (x - X w) + U w + rho`` (known-flux form).

        Parameters
        ----------
        K : ndarray, shape (2, 2)
            Feedback gain, V/A.
        X : ndarray, shape (2, 2)
            Steady-state map, ``x_ss = X w``.
        U : ndarray, shape (2, 2)
            Feedforward, ``u_ss = U w``.
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

        Returns
        -------
        Trajectory
            The measured currents, inputs and ``w`` at the sample times.
        """
        ...

    def run_no_load(
        self, K: Array, *, num_samples: int, exploration: Exploration | None, seed: int
    ) -> Trajectory:
        """One episode at no load (``T* = 0``), ``u = -K x + rho``, ``w = [p speed]``.

        Parameters
        ----------
        K : ndarray, shape (2, 2)
            Feedback gain, V/A.
        num_samples : int
            Length of the episode, samples.
        exploration : Exploration or None
            Exploration ``rho`` added to the input; None for none.
        seed : int
            Seed of the exploration.

        Returns
        -------
        Trajectory
            The measured currents, inputs and ``w`` at the sample times.
        """
        ...
