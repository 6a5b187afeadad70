"""What the realistic-drive study (:mod:`._realistic_drive`) builds its comparison from.

- :func:`drive_cases`: the motors, drawn reproducibly from plausible ranges
  (:func:`motor_ranges`, generator seed :data:`MOTOR_SEED`), each as on its nameplate and
  as built (within :data:`TOLERANCES` of the nameplate);
- :class:`RecordingDrive`: a :class:`~selftune.tuning.Drive` that keeps every log it hands
  a session, so that every controller is learned from the very same batch, and times the
  simulation apart from the learning;
- :func:`pi_law`: the industrial PI current controller with decoupling, as the
  :class:`~selftune.core.ControlLaw` a drive runs;
- :func:`current_bandwidth`: the -3 dB bandwidth of a digital current loop, and
  :func:`matched_pi`: the PI whose loop has a given bandwidth, as fast as the controller
  it is compared with.

Symbols (SI units): ``w_e = p speed`` electrical speed, rad/s; ``h`` sampling period, s;
``w = [w_e phi, T*]`` the controller's reference (``phi`` the flux it assumes, Wb);
``i_q* = 2 T* / (3 p phi)`` the q-current reference, A.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..core import Array, ControlLaw
from ..learn import LoggedInput, Trajectory, pi_control_law
from ..loop import SampledLoop
from ..model import SPMSM
from ..sim import ExogenousSignal, Exploration, RealisticDrive
from ..tuning import known_flux_form
from ._motors import Choice, MotorRanges, RandomMotor, Span, draw_motor

__all__ = [
    "HOLD",
    "MOTOR_SEED",
    "TOLERANCES",
    "VOLTAGE_MARGIN",
    "DriveCase",
    "RecordingDrive",
    "current_bandwidth",
    "drive_cases",
    "matched_pi",
    "motor_ranges",
    "pi_law",
]

#: Seed of the generator the motors are drawn with.
MOTOR_SEED = 2026
#: The motor as built is within these relative tolerances of its nameplate (uniform): R_s,
#: L_s, phi_pm.
TOLERANCES = (0.10, 0.10, 0.05)
#: A draw is kept only if the steady voltage at T*, with R_s at twice its nameplate (the
#: tolerance, 40 K and +40% together are 1.1 x 1.156 x 1.4 = 1.78), stays below this
#: fraction of the linear range V_dc / sqrt 3 (room for the exploration and the steps).
VOLTAGE_MARGIN = 0.6


def motor_ranges(fast: bool, dc_voltage: float) -> MotorRanges:
    """The ranges the nameplates are drawn from, in the order drawn: 2-5 pole pairs; L_s
    1.5-12 mH and L_s / R_s 3-15 ms (log-uniform); the electrical speed (1,000-1,500 rad/s
    when ``fast``, 200-900 otherwise), the back-EMF ``w_e phi_pm`` 40-120 V and the q
    current at T* 3-12 A (uniform); then the motor as built (:data:`TOLERANCES`), redrawn
    until its voltage fits :data:`VOLTAGE_MARGIN` of the linear range of ``dc_voltage``.

    Parameters
    ----------
    fast : bool
        The first motor's speed range.
    dc_voltage : float
        DC-bus voltage of the drive, V.
    """
    speed = Span(1000.0, 1500.0) if fast else Span(200.0, 900.0)
    return MotorRanges(
        draws=(
            ("pole_pairs", Choice((2, 3, 4, 5))),
            ("L_s_henry", Span(1.5e-3, 12e-3, log=True)),
            ("time_constant_seconds", Span(3e-3, 15e-3, log=True)),
            ("electrical_speed_rad_per_second", speed),
            ("back_emf_volts", Span(40.0, 120.0)),
            ("current_amperes", Span(3.0, 12.0)),
        ),
        tolerances=TOLERANCES,
        voltage_limit_volts=VOLTAGE_MARGIN * dc_voltage / np.sqrt(3.0),
    )  # fmt: skip


#: What the inverter holds over a sample (a PWM inverter: the stationary-frame vector).
HOLD = "stationary"


@dataclass(frozen=True)
class DriveCase:
    """One motor of the study and its operating point.

    Attributes
    ----------
    name_text : str
        A short description (from the nameplate).
    nameplate : SPMSM
        What the engineer reads off the nameplate.
    as_built : SPMSM
        The motor itself, at the nameplate's temperature (within :data:`TOLERANCES`).
    speed : float
        Held mechanical speed, rad/s.
    torque : float
        Torque reference T*, N m.
    """

    name_text: str
    nameplate: SPMSM
    as_built: SPMSM
    speed: float
    torque: float


def _case(drawn: RandomMotor, index: int) -> DriveCase:
    nameplate, built = drawn.surface()
    name = (
        f"M{index + 1}: p = {nameplate.p}, {nameplate.R_s:.3g} ohm, {nameplate.L_s * 1e3:.3g} mH, "
        f"{nameplate.phi_pm * 1e3:.3g} mWb, {drawn.electrical_speed:.0f} rad/s el."
    )
    return DriveCase(name, nameplate, built, drawn.speed, drawn.torque)


def drive_cases(count: int, dc_voltage: float) -> tuple[DriveCase, ...]:
    """The study's motors: the first at 1,000-1,500 rad/s electrical, the others slower.

    Drawn by ``numpy.random.default_rng(MOTOR_SEED)`` from :func:`motor_ranges`, so the
    same ``count`` always gives the same motors (and a smaller count a prefix of them).

    Parameters
    ----------
    count : int
        Number of motors.
    dc_voltage : float
        DC-bus voltage of the drive, V (the draws must fit its voltage).

    Returns
    -------
    tuple of DriveCase
    """
    rng = np.random.default_rng(MOTOR_SEED)
    return tuple(
        _case(draw_motor(rng, motor_ranges(index == 0, dc_voltage)), index)
        for index in range(count)
    )


class RecordingDrive:
    """A :class:`~selftune.tuning.Drive` that keeps the logs it returns and times them.

    Parameters
    ----------
    drive : RealisticDrive
        The simulated drive it passes every episode to.

    Attributes
    ----------
    drive : RealisticDrive
    logs : list of Trajectory
        Every log returned, in order.
    drive_seconds : float
        Wall time spent simulating the episodes, s (to tell the learning time apart).
    """

    def __init__(self, drive: RealisticDrive) -> None:
        self.drive = drive
        self.logs: list[Trajectory] = []
        self.drive_seconds = 0.0

    @property
    def pole_pairs(self) -> int:
        """Number of pole pairs (nameplate)."""
        return self.drive.pole_pairs

    @property
    def loop(self) -> SampledLoop:
        """The drive's loop (its sampling period, delay and hold)."""
        return self.drive.loop

    @property
    def logged_input(self) -> LoggedInput:
        """What row k of the log's voltages holds."""
        return self.drive.logged_input

    def _kept(self, started: float, log: Trajectory) -> Trajectory:
        self.drive_seconds += time.perf_counter() - started
        self.logs.append(log)
        return log

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
        """One known-flux episode (:meth:`selftune.sim.RealisticDrive.run`), kept.

        Parameters
        ----------
        law : ControlLaw
            The controller.
        reference : ExogenousSignal
            ``w = [p speed phi, T*]`` as the controller sees it.
        num_samples : int
            Samples.
        exploration : Exploration or None
            Added to the input, V.
        seed : int
            Seed of the exploration and the noise.
        assumed_flux : float, optional
            Passed on (ignored by the simulated drive), Wb.
        """
        started = time.perf_counter()
        log = self.drive.run(
            law, reference, num_samples=num_samples, exploration=exploration, seed=seed,
            assumed_flux=assumed_flux,
        )  # fmt: skip
        return self._kept(started, log)

    def run_no_load(
        self, law: ControlLaw, *, num_samples: int, exploration: Exploration | None, seed: int
    ) -> Trajectory:
        """One no-load episode (:meth:`selftune.sim.RealisticDrive.run_no_load`), kept.

        Parameters
        ----------
        law : ControlLaw
            The controller, on ``w = [p speed]``.
        num_samples : int
            Samples.
        exploration : Exploration or None
            Added to the input, V.
        seed : int
            Seed of the exploration and the noise.
        """
        started = time.perf_counter()
        log = self.drive.run_no_load(
            law, num_samples=num_samples, exploration=exploration, seed=seed
        )
        return self._kept(started, log)


def pi_law(
    resistance: float,
    inductance: float,
    bandwidth: float,
    case: DriveCase,
    phi_pm: float,
    h: float,
) -> ControlLaw:
    """The industrial PI current controller with decoupling, as a law with one past input
    (:func:`~selftune.learn.pi_control_law`, the structure of every PI selftune builds).

    ``k_p = w_c L``, ``k_i = w_c R`` (the integrator's zero cancels the pole ``R / L``, so
    on the continuous plant the closed loop is ``w_c / (s + w_c)``); with ``e = i - i*``,
    ``i* = [0, i_q*]``, ``z_(k+1) = z_k + h e_k`` and the measured currents::

        u_d = -k_p e_d - k_i z_d - w_e L i_q
        u_q = -k_p e_q - k_i z_q + w_e L i_d + w_e phi

    i.e. ``K = [[k_p, w_e L, 0, 0], [-w_e L, k_p, 0, 0]]`` (nothing on the past input),
    ``K_i = k_i I``, ``X = -F`` (``X w = i*``) and ``U = [[0, w_e L F_qq], [1, 0]]``: the
    back-EMF fed forward from the flux, and the d-axis decoupling's reference part
    (``-K X w`` puts ``+w_e L i_q*`` on u_d, which ``U w`` takes off again).

    Parameters
    ----------
    resistance, inductance : float
        R (ohm) and L (H) the PI is designed with.
    bandwidth : float
        w_c, rad/s.
    case : DriveCase
        The motor (its pole pairs) and operating point.
    phi_pm : float
        The flux the controller assumes, Wb.
    h : float
        Sampling period, s.

    Returns
    -------
    ControlLaw
    """
    p = case.nameplate.p
    C, _, F, _ = known_flux_form(p, case.speed, case.torque, phi_pm)
    k_p, k_i, cross = bandwidth * inductance, bandwidth * resistance, p * case.speed * inductance
    U = np.array([[0.0, cross * F[1, 1]], [1.0, 0.0]])
    return pi_control_law(
        np.full(2, k_p), [[0.0, cross], [-cross, 0.0]], -F, U, k_i=np.full(2, k_i), C=C, F=F,
        h=h, history=1,
    )  # fmt: skip


def current_bandwidth(plant: tuple[Array, Array], law: ControlLaw, h: float) -> float | None:
    """The -3 dB bandwidth of the q current's response to its reference, rad/s.

    The smallest frequency at which ``|G(e^(j w h))| = |G(1)| / sqrt 2``, G the transfer
    function of the closed loop (:meth:`selftune.loop.SampledLoop.closed_loop`) from T* to
    ``i_q`` (a grid of 600 log-spaced
    frequencies up to the Nyquist frequency ``pi / h``, then bisection). A first-order loop
    ``w_c / (s + w_c)`` (the PI recipe on its own model, without delay) has the bandwidth
    ``w_c``; with the drive's delay a PI's is larger (its resonance).

    Parameters
    ----------
    plant : (Ad, Bd)
        The sampled plant.
    law : ControlLaw
        The controller (``history = 1``, with ``K_i``).
    h : float
        Sampling period, s.

    Returns
    -------
    float or None
        None if the loop is unstable; ``pi / h`` if the response never falls that far.
    """
    A, B_w = SampledLoop.of_law(law, h).closed_loop(plant, law)
    b = B_w[:, 1]
    if np.max(np.abs(np.linalg.eigvals(A))) >= 1.0:
        return None
    identity = np.eye(A.shape[0])

    def gains(frequencies: Array) -> Array:
        z = np.exp(1j * frequencies * h)[:, np.newaxis, np.newaxis]
        column = np.broadcast_to(b[:, np.newaxis], (len(z), len(b), 1))
        response = np.linalg.solve(z * identity - A, column)
        return np.asarray(np.abs(response[:, 1, 0]))

    level = float(gains(np.zeros(1))[0]) / np.sqrt(2.0)
    grid = np.geomspace(1.0, np.pi / h, 600)
    below = np.flatnonzero(gains(grid) < level)
    if below.size == 0:
        return float(np.pi / h)
    if below[0] == 0:
        return float(grid[0])
    low, high = np.log(grid[below[0] - 1]), np.log(grid[below[0]])
    for _ in range(40):
        middle = 0.5 * (low + high)
        crossed = gains(np.array([np.exp(middle)]))[0] < level
        low, high = (low, middle) if crossed else (middle, high)
    return float(np.exp(0.5 * (low + high)))


def matched_pi(
    plant: tuple[Array, Array],
    resistance: float,
    inductance: float,
    bandwidth: float,
    case: DriveCase,
    phi_pm: float,
    h: float,
) -> tuple[ControlLaw, float] | None:
    """The PI recipe (:func:`pi_law`) whose loop on ``plant`` has the given bandwidth.

    ``w_c`` is found by bisection (in ``log w_c``, between ``bandwidth / 20`` and
    ``bandwidth``) so that :func:`current_bandwidth` of the PI on ``plant`` is
    ``bandwidth``: the PI is exactly as fast as the controller it is compared with, as
    measured on the designer's model.

    Parameters
    ----------
    plant : (Ad, Bd)
        The designer's sampled model.
    resistance, inductance : float
        R (ohm) and L (H) of the recipe.
    bandwidth : float
        The -3 dB bandwidth to match, rad/s.
    case : DriveCase
        The motor (pole pairs) and operating point.
    phi_pm : float
        The flux the controller assumes, Wb.
    h : float
        Sampling period, s.

    Returns
    -------
    (ControlLaw, float) or None
        The PI and its w_c (rad/s); None if no w_c in the range reaches the bandwidth.
    """

    def achieved(w_c: float) -> float:
        law = pi_law(resistance, inductance, w_c, case, phi_pm, h)
        value = current_bandwidth(plant, law, h)
        return np.inf if value is None else value

    low, high = np.log(bandwidth / 20.0), np.log(bandwidth)
    if not achieved(float(np.exp(low))) <= bandwidth <= achieved(float(np.exp(high))):
        return None
    for _ in range(50):
        middle = 0.5 * (low + high)
        low, high = (middle, high) if achieved(float(np.exp(middle))) < bandwidth else (low, middle)
    w_c = float(np.exp(0.5 * (low + high)))
    return pi_law(resistance, inductance, w_c, case, phi_pm, h), w_c
