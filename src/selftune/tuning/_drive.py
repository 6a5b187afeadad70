"""What a self-tuning session needs of a drive: run an episode, return what it measured.

Any object with these methods works: :class:`selftune.sim.SimulatedDrive` (the exact
simulation), a realistic drive simulation, or a real drive's logger.
"""

from __future__ import annotations

from typing import Protocol

from ..core import ControlLaw
from ..learn import Trajectory
from ..sim import ExogenousSignal, Exploration

__all__ = ["Drive"]


class Drive(Protocol):
    """A drive in torque-control mode that runs episodes and returns what it logged.

    The session hands it a :class:`~selftune.core.ControlLaw` (the controller to run,
    ``u_k = U w_k - K [...] + rho_k``) and reads back a log. The drive says how its log
    is aligned: its computation delay (the voltage computed at sample k acts over
    ``[t_(k+d), t_(k+d+1))``) and whether row k of the log holds the voltage applied
    during sample k or the one computed at it.
    """

    @property
    def pole_pairs(self) -> int:
        """Number of pole pairs (nameplate)."""
        ...

    @property
    def sampling(self) -> float:
        """Sampling period, s."""
        ...

    @property
    def input_delay(self) -> int:
        """d, the computation delay, samples."""
        ...

    @property
    def logged_input(self) -> str:
        """``"applied"`` or ``"commanded"``: what row k of the log's voltages holds."""
        ...

    @property
    def voltage_hold(self) -> str:
        """``"stationary"`` (a PWM inverter holds the stationary-frame vector) or
        ``"rotor"`` (the dq voltage is held: an ideal zero-order hold)."""
        ...

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
        """One episode from rest under ``law`` plus exploration (known-flux form).

        Parameters
        ----------
        law : ControlLaw
            The controller, on ``w = [p speed phi, T*]``.
        reference : ExogenousSignal
            The controller's ``w = [p speed phi, T*]`` (held).
        num_samples : int
            Length of the episode, samples.
        exploration : Exploration or None
            Exploration ``rho`` added to the input; None for none.
        seed : int
            Seed of the exploration (and of the drive's noise).
        assumed_flux : float, optional
            Flux linkage the controller's ``w`` assumes, Wb (default: the true one).

        Returns
        -------
        Trajectory
            The measured currents, the logged voltages and ``w`` at the sample times.
        """
        ...

    def run_no_load(
        self,
        law: ControlLaw,
        *,
        num_samples: int,
        exploration: Exploration | None,
        seed: int,
    ) -> Trajectory:
        """One episode at no load (``T* = 0``), ``w = [p speed]``, ``X = 0``.

        Parameters
        ----------
        law : ControlLaw
            The controller, on ``w = [p speed]``.
        num_samples : int
            Length of the episode, samples.
        exploration : Exploration or None
            Exploration ``rho`` added to the input; None for none.
        seed : int
            Seed of the exploration (and of the drive's noise).

        Returns
        -------
        Trajectory
            The measured currents, the logged voltages and ``w`` at the sample times.
        """
        ...
