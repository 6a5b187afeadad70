"""gym-electric-motor as a plant: a :class:`~selftune.tuning.Drive` on its PMSM environment.

:class:`GemDrive` runs a surface PMSM in gym-electric-motor's (GEM's) continuous
current-control environment ``Cont-CC-PMSM-v0`` (an ideal DC supply, a continuous B6
bridge, the PMSM, a constant-speed load) sample by sample under a
:class:`~selftune.core.ControlLaw`, and logs what a drive logs; so an RL user can tune a
GEM current loop with selftune and compare. GEM is an optional extra
(``pip install 'selftune[gem]'``), imported only when an episode runs.

GEM's timing convention (``SynchronousMotorSystem.simulate`` and ``ContB6BridgeConverter``
of gym-electric-motor 3.0.3): the action given to ``env.step`` at ``t_k`` is applied at
once, over ``[t_k, t_k + tau)``, and the state returned is the one at ``t_k + tau``. The
action is three duty cycles in ``[-1, 1]``, i.e. the phase voltages over half the DC
voltage; the dynamically averaged bridge applies their mean (no PWM ripple; the
interlocking time is 0), clips them to ``[-1, 1]`` (the adapter refuses a command GEM
would clip, rather than log a voltage the controller did not mean), and the environment
turns them into dq with the rotor angle at the start of the step and holds that dq
voltage over the step. So
GEM has no computation delay, and it holds the dq voltage (the paper's and
:class:`~selftune.sim.SimulatedDrive`'s zero-order hold), not the stationary-frame vector
a PWM inverter holds.

The adapter computes the phase voltages from the dq command with that same angle (read
from GEM's state), so the motor sees exactly the dq voltage the controller held; GEM's
own dq wrapper (``DqToAbcActionProcessor``) would advance the angle by half a step and
rotate the voltage by ``w_e tau / 2``. A computation delay (``input_delay`` d) is the
adapter's: the command computed at ``t_k`` is applied over ``[t_(k+d), t_(k+d+1))`` with
the angle at ``t_(k+d)`` (a drive that compensates the rotation exactly); GEM's own
``DeadTimeProcessor`` delays the phase voltages instead, which rotates them by
``-d w_e tau``.

Accuracy: GEM integrates the motor's ODE numerically; :class:`GemDrive` uses scipy's
eighth-order ``dop853`` at ``rtol = atol = 1e-14`` by default. Measured against the exact
:class:`~selftune.sim.SimulatedDrive` (the paper's motor, 10 kHz, 500 samples, K = 20 pi
V/A, 1 V exploration), the largest current error over its peak current: 1.3e-15 at
100 rad/s, 4.5e-15 at 1000 and 1.6e-14 at 10000 rad/s (a 40 kV link); GEM's default solver
(``"dopri5"``, rtol 1e-6) 2.7e-13, 6e-8 and 3e-6; its Euler solver 3.9e-3 at 100 rad/s.
scipy's integrator only warns when it gives up within a sample (and returns the state
where it stopped): that is refused. Speed, on this 2-core machine under load: about
6,500 steps per second with dop853, 8,800 with dopri5, 14,000 with Euler (GEM's
``env.step`` is about 90% of it).
"""

from __future__ import annotations

import importlib
import math
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from ..core import Array, ControlLaw, finite_float, positive_finite, positive_integer
from ..core._validation import check_range
from ..errors import InputError
from ..learn import LoggedInput, Trajectory
from ..loop import SampledLoop
from ..model import SPMSM
from ._checks import as_float_array, as_generator
from ._exploration import Exploration
from ._signals import ExogenousSignal, check_signal_values, constant
from ._stepper import feedback_of, run_closed_loop

__all__ = ["GEM_ENVIRONMENT", "GEM_SOLVERS", "GemDrive"]

#: The gym-electric-motor environment :class:`GemDrive` runs.
GEM_ENVIRONMENT = "Cont-CC-PMSM-v0"

#: The ODE solvers :class:`GemDrive` offers: scipy's ``dop853`` at rtol = atol = 1e-14
#: (the most accurate GEM allows), GEM's default (scipy's ``dopri5`` at its default
#: tolerances, rtol 1e-6), and GEM's explicit Euler (one step per sample, its fastest).
GEM_SOLVERS = ("dop853", "dopri5", "euler")

_MISSING = "gym-electric-motor is not installed; pip install 'selftune[gem]'"

#: dop853's tolerances (its floor is 10 x the unit roundoff 2.3e-16 on rtol).
_DOP853_TOLERANCE = 1e-14


def _power_of_two_above(value: float) -> float:
    """The smallest power of two >= ``value`` (> 0): a normalization that is exact."""
    return float(2.0 ** math.ceil(math.log2(value)))


@contextmanager
def _quiet() -> Iterator[list[warnings.WarningMessage]]:
    """Capture every warning GEM, gymnasium and scipy raise, so none reaches a terminal."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        yield caught


def _check_solver(caught: list[warnings.WarningMessage], solver: str, k: int) -> None:
    """Raise if scipy's integrator gave up within sample k: it only warns (e.g.
    ``"dop853: larger nsteps is needed"``) and returns the state where it stopped."""
    for item in caught:
        message = str(item.message)
        if message.startswith(f"{solver}:"):
            raise InputError(
                f"h: GEM's ODE solver failed within sample {k} ({message}); "
                "shorten the sampling period (the rotor turns too far within one)"
            )
    caught.clear()


def _import_gem() -> tuple[Any, Any, Any]:
    """``(gym_electric_motor, its physical_systems, its reference_generators)``.

    Raises
    ------
    InputError
        One line naming the extra to install, if gym-electric-motor is missing.
    """
    try:
        with _quiet():
            gem = importlib.import_module("gym_electric_motor")
            systems = importlib.import_module("gym_electric_motor.physical_systems")
            references = importlib.import_module("gym_electric_motor.reference_generators")
    except ImportError:
        raise InputError(_MISSING) from None
    return gem, systems, references


def _exploration(exploration: Exploration | None, t: Array, seed: int) -> Array:
    """``rho`` (N, 2), V, drawn from ``numpy.random.default_rng(seed)`` (zeros for None)."""
    rng = as_generator(seed)
    count = t.shape[0] - 1
    if exploration is None:
        return np.zeros((count, 2))
    if not isinstance(exploration, Exploration):
        raise InputError(
            f"exploration: expected an Exploration (uniform, prbs, sum_of_sines) or None, "
            f"got {type(exploration).__name__}"
        )
    rho = as_float_array(exploration.sample(t.copy(), 2, rng), "exploration.sample")
    if rho.shape != (count, 2):
        raise InputError(f"exploration.sample: expected shape {(count, 2)}, got {rho.shape}")
    return rho


def _checked_law(law: object, q: int) -> ControlLaw:
    if not isinstance(law, ControlLaw):
        raise InputError(f"law: expected a ControlLaw, got {type(law).__name__}")
    if (law.n, law.m, law.q) != (2, 2, q):
        raise InputError(
            f"law: has (n, m, q) = {(law.n, law.m, law.q)}; the drive needs (2, 2, {q}) "
            "(currents, voltages, the reference's channels)"
        )
    return law


@dataclass
class _Plant:
    """One GEM environment and where its state keeps the dq currents, voltages and angle."""

    env: Any
    systems: Any
    half_dc: float
    scale: Array
    currents: list[int]
    voltages: list[int]
    angle: int

    def read(self, observation: Any) -> tuple[Array, Array, float]:
        """``(i_dq (A), u_dq applied over the last step (V), rotor angle (rad))``."""
        state = np.asarray(observation[0], dtype=float) * self.scale
        return state[self.currents], state[self.voltages], float(state[self.angle])

    def reset(self) -> tuple[Array, float]:
        """Start from rest: ``(i_dq, angle)`` at t = 0."""
        observation, _ = self.env.reset(seed=0)
        current, _, angle = self.read(observation)
        return current, angle

    def step(self, u_dq: Array, angle: float, k: int) -> tuple[Array, Array, float]:
        """Apply the dq voltage ``u_dq`` (V) over one sample from the rotor angle ``angle``.

        Returns ``(i_dq at the end, u_dq GEM applied, angle at the end)``.
        """
        motor = self.systems.ThreePhaseMotor
        action = np.asarray(motor.t_32(motor.q(u_dq / self.half_dc, angle)), dtype=float)
        if not np.all(np.abs(action) <= 1.0):  # GEM would clip it: refuse, do not distort
            raise InputError(
                f"dc_voltage: the command at sample {k} needs |u_dq| = "
                f"{float(np.hypot(*u_dq)):.6g} V, more than the bridge's {self.half_dc:.6g} V "
                "(half the DC voltage); GEM would clip it: raise dc_voltage, or stabilize "
                "the loop"
            )
        observation, _, _, _, _ = self.env.step(action)
        return self.read(observation)


class _GemLoop:
    """A GEM environment as the stepper's plant (a ``LoopPlant``, P = 1): the dq currents
    it measures, the voltages it applied and the rotor angles, sample by sample."""

    def __init__(
        self, plant: _Plant, caught: list[warnings.WarningMessage], solver: str, count: int
    ) -> None:
        self.plant, self.caught, self.solver = plant, caught, solver
        self.x, self.u = np.empty((count + 1, 2)), np.empty((count, 2))
        self.angles = np.empty(count + 1)
        self.x[0], self.angles[0] = plant.reset()

    def measure(self, k: int) -> Array:
        """``i_dq`` at sample k, shape (1, 2)."""
        return self.x[k][np.newaxis]

    def advance(self, k: int, applied: Array, computed_at: int) -> None:
        """One ``env.step`` with the dq voltage ``applied[0]``."""
        self.x[k + 1], self.u[k], self.angles[k + 1] = self.plant.step(
            applied[0], self.angles[k], k
        )
        if self.caught:
            _check_solver(self.caught, self.solver, k)


@dataclass(frozen=True)
class GemDrive:
    """A motor in gym-electric-motor's ``Cont-CC-PMSM-v0``, held at a speed; a ``Drive``.

    Episodes start from rest (currents, rotor angle, past commands and integrator zero);
    each builds a new environment. See the module docstring for GEM's timing convention
    and the measured accuracy. Needs the extra ``gem`` (gym-electric-motor), imported when
    an episode runs.

    Attributes
    ----------
    motor : SPMSM
        The motor GEM simulates (``l_d = l_q = L_s``; ``J`` is irrelevant at held speed,
        1 kg m^2 if not given).
    speed : float
        Mechanical speed held by GEM's constant-speed load, rad/s.
    h : float
        Sampling period, s: GEM's ``tau``, one ``env.step`` per sample.
    dc_voltage : float
        DC-link voltage of GEM's supply, V (2 kV: nothing saturates in the usual runs;
        a command GEM would clip, ``|u_dq| > dc_voltage / 2``, is refused).
    input_delay : int
        d, computation delay in samples (0: GEM's own timing, see the module docstring);
        the command computed at ``t_k`` is applied over ``[t_(k+d), t_(k+d+1))``.
    ode_solver : {"dop853", "dopri5", "euler"}
        GEM's ODE solver (:data:`GEM_SOLVERS`): ``"dop853"`` at rtol = atol = 1e-14 (the
        most accurate), ``"dopri5"`` (GEM's default), ``"euler"`` (GEM's fastest).

    Raises
    ------
    InputError
        Naming the field, if a value is invalid.
    """

    motor: SPMSM
    speed: float
    h: float
    dc_voltage: float = 2000.0
    input_delay: int = 0
    ode_solver: Literal["dop853", "dopri5", "euler"] = "dop853"

    def __post_init__(self) -> None:
        if not isinstance(self.motor, SPMSM):
            raise InputError(f"motor: expected an SPMSM, got {type(self.motor).__name__}")
        object.__setattr__(self, "speed", check_range(finite_float(self.speed, "speed"), "speed"))
        object.__setattr__(self, "h", positive_finite(self.h, "h"))
        object.__setattr__(self, "dc_voltage", positive_finite(self.dc_voltage, "dc_voltage"))
        delay = positive_integer(self.input_delay, "input_delay", minimum=0)
        object.__setattr__(self, "input_delay", delay)
        if self.ode_solver not in GEM_SOLVERS:
            raise InputError(
                f"ode_solver: expected one of {', '.join(map(repr, GEM_SOLVERS))}, "
                f"got {self.ode_solver!r}"
            )

    @property
    def pole_pairs(self) -> int:
        """Number of pole pairs."""
        return self.motor.p

    @property
    def loop(self) -> SampledLoop:
        """GEM's loop: sampled at h with the given delay, the dq voltage held over each
        step (see the module)."""
        return SampledLoop(self.h, self.input_delay, "rotor")

    @property
    def logged_input(self) -> LoggedInput:
        """``"applied"``: row k of the log holds the dq voltage GEM applied during sample k."""
        return "applied"

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
        """One known-flux episode from rest: what the drive logs.

        Parameters
        ----------
        law : ControlLaw
            The controller (n = m = 2; q of the reference), with its past inputs and
            integrator as :class:`~selftune.core.ControlLaw` defines them.
        reference : ExogenousSignal
            ``w = [p speed phi, T*]`` as the controller sees it (held over each sample).
        num_samples : int
            N, samples.
        exploration : Exploration or None
            ``rho``, V, added to each command; None for none.
        seed : int
            Seed of ``numpy.random.default_rng``, which draws the exploration.
        assumed_flux : float, optional
            Accepted and ignored, Wb: GEM's back-EMF is always the motor's own; the
            controller's assumption is already in ``reference``.

        Returns
        -------
        Trajectory
            ``t = k h``; ``x``, the dq currents GEM measured, A; ``u``, the dq voltage GEM
            applied over each sample, V; ``w``, the reference the controller used.

        Raises
        ------
        InputError
            If gym-electric-motor is not installed (one line naming the extra), an
            argument is invalid, or a command exceeds the DC link's range.
        """
        count = positive_integer(num_samples, "num_samples")
        t = self.h * np.arange(count + 1, dtype=float)
        if not isinstance(reference, ExogenousSignal):
            raise InputError(
                f"reference: expected an exogenous signal, got {type(reference).__name__}"
            )
        w = check_signal_values(reference.values(t), count + 1, "reference")
        if w.ndim != 2:
            raise InputError(f"reference: a batch of {w.shape[0]} signals; the drive runs one")
        law = _checked_law(law, w.shape[1])
        return self._episode(law, t, w, _exploration(exploration, t, seed))

    def run_no_load(
        self, law: ControlLaw, *, num_samples: int, exploration: Exploration | None, seed: int
    ) -> Trajectory:
        """One no-load episode from rest: ``T* = 0``, ``w = [p speed]`` (q = 1).

        Parameters
        ----------
        law : ControlLaw
            The controller, with q = 1.
        num_samples : int
            N, samples.
        exploration : Exploration or None
            ``rho``, V, added to each command; None for none.
        seed : int
            Seed of ``numpy.random.default_rng``, which draws the exploration.

        Returns
        -------
        Trajectory
            As :meth:`run`, with ``w = [p speed]``, rad/s.
        """
        reference = constant(self.motor.no_load_exogenous(self.speed))
        return self.run(law, reference, num_samples=num_samples, exploration=exploration, seed=seed)

    def _episode(self, law: ControlLaw, t: Array, w: Array, rho: Array) -> Trajectory:
        """Step GEM sample by sample under ``law`` plus ``rho``; log what it measured."""
        with _quiet() as caught, self._plant() as plant:
            loop = _GemLoop(plant, caught, self.ode_solver, rho.shape[0])
            run_closed_loop(
                loop, feedback_of([law]), w[np.newaxis], rho[np.newaxis], self.input_delay
            )
        return Trajectory(t=t, x=loop.x, u=loop.u, w=w, angle=loop.angles)

    @contextmanager
    def _plant(self) -> Iterator[_Plant]:
        """A new ``Cont-CC-PMSM-v0`` with this motor, speed, DC link and solver; closed after.

        The limits only normalize GEM's state (no constraint ends an episode); they are
        powers of two, so the adapter's denormalization is exact.
        """
        gem, systems, references = _import_gem()
        motor, half_dc = self.motor, 0.5 * self.dc_voltage
        limits = {
            "i": _power_of_two_above(half_dc / motor.R_s),
            "u": _power_of_two_above(half_dc),
            "omega": _power_of_two_above(2.0 * max(abs(self.speed), 1.0)),
        }
        env = gem.make(
            GEM_ENVIRONMENT,
            motor={
                "motor_parameter": {
                    "p": motor.p,
                    "l_d": motor.L_s,
                    "l_q": motor.L_s,
                    "j_rotor": 1.0 if motor.J is None else motor.J,
                    "r_s": motor.R_s,
                    "psi_p": motor.phi_pm,
                },
                "limit_values": limits,
                "nominal_values": limits,
            },
            load={"omega_fixed": self.speed},
            supply={"u_nominal": self.dc_voltage},
            ode_solver=_solver(systems, self.ode_solver),
            tau=self.h,
            reference_generator=references.ConstReferenceGenerator("i_sq", 0.0),
            visualization=(),
            constraints=(),
            disable_env_checker=True,
        )
        try:
            system = env.unwrapped.physical_system
            names = list(system.state_names)
            yield _Plant(
                env=env,
                systems=systems,
                half_dc=half_dc,
                scale=np.asarray(system.limits, dtype=float),
                currents=[names.index("i_sd"), names.index("i_sq")],
                voltages=[names.index("u_sd"), names.index("u_sq")],
                angle=names.index("epsilon"),
            )
        finally:
            env.close()


def _solver(systems: Any, name: str) -> Any:
    """GEM's ODE solver of that name (see :data:`GEM_SOLVERS`)."""
    if name == "euler":
        return systems.EulerSolver()
    if name == "dopri5":
        return systems.ScipyOdeSolver("dopri5")
    return systems.ScipyOdeSolver("dop853", rtol=_DOP853_TOLERANCE, atol=_DOP853_TOLERANCE)
