"""What a self-tuning session needs of a drive: run an episode, return what it measured.

Any object with these methods works: :class:`selftune.sim.SimulatedDrive` (the exact
simulation), a realistic drive simulation, or a real drive's logger.
"""

from __future__ import annotations

from typing import Protocol

from ..core import ControlLaw
from ..learn import LoggedInput, Trajectory
from ..loop import SampledLoop
from ..sim import ExogenousSignal, Exploration

__all__ = ["Drive"]


class Drive(Protocol):
    """A drive in torque-control mode that runs episodes and returns what it logged.

    The session hands it a :class:`~selftune.core.ControlLaw` (the controller to run,
    ``u_k = U w_k - K [...] + rho_k``) and reads back a log. The drive says what its loop
    is (:class:`~selftune.loop.SampledLoop`: the sampling period h, the computation delay
    d, the voltage computed at sample k acting over ``[t_(k+d), t_(k+d+1))``, and what it
    holds over a sample) and whether row k of its log holds the voltage applied during
    sample k or the one computed at it.
    """

    @property
    def pole_pairs(self) -> int:
        """Number of pole pairs (nameplate)."""
        ...

    @property
    def loop(self) -> SampledLoop:
        """The drive's current loop: sampling period h (s), computation delay (samples)
        and voltage hold (``"stationary"`` for a PWM inverter, ``"rotor"`` for an ideal
        zero-order hold of the dq voltage); no integrator (that is the controller's)."""
        ...

    @property
    def logged_input(self) -> LoggedInput:
        """``"applied"`` or ``"commanded"``: what row k of the log's voltages holds."""
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
