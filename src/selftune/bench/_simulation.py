"""Study 3: time per control step of the current loop, exact against the closed form."""

from __future__ import annotations

import statistics
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy
import scipy.linalg

from ..core import (
    Array,
    discretize,
)
from ..model import SPMSM
from ..sim import constant, simulate, simulate_batch
from ._common import MISMATCH, TARGET_SPEEDUP, BenchConfig, progress_bar, sci, table, timed
from ._gem import GymElectricMotor, measure_gem
from ._loop import Loop, SimulatorMeasurement, exact_states, exogenous_matrix, max_relative_error
from ._motors import as_built


@dataclass(frozen=True)
class BatchMeasurement:
    """:func:`~selftune.simulate.simulate_batch` on a batch of motors.

    Attributes
    ----------
    motors_count : int
        Motors (parameter sets) in the batch.
    samples_per_motor : int
        Steps simulated for each motor.
    steps_per_second : float
        Motor-steps simulated per second of wall time.
    wall_seconds : float
        Median wall time of the batch run, s, with fresh motors each repeat (so the
        discretization of every motor, a matrix exponential each, is included).
    warm_steps_per_second : float
        The same run again on the same motors, whose discretization is then cached.
    max_relative_error : float
        Error of the first motor's trajectory against its exact solution (as above).
    """

    motors_count: int
    samples_per_motor: int
    steps_per_second: float
    wall_seconds: float
    warm_steps_per_second: float
    max_relative_error: float


@dataclass(frozen=True)
class Simulation:
    """Simulation speed and exactness on the SPMSM current loop at 10 us sampling.

    Every run is the closed loop of the paper's motor at 10 rad/s under the optimal
    controller ``u = -K* (x - X* w) + U* w + rho`` from rest, T* = 10 N m, with the same
    uniform exploration ``rho`` (1 V) in all simulators.

    Attributes
    ----------
    sampling_seconds : float
        Control period, s.
    selftune_simulate : SimulatorMeasurement
        :func:`~selftune.simulate.simulate`: the whole closed loop in one call.
    selftune_step_loop : SimulatorMeasurement
        An interactive Python loop, one step at a time, on
        :func:`~selftune.simulate.discretize` (what a user with their own controller code
        would write).
    solve_ivp_rk45 : SimulatorMeasurement
        ``scipy.integrate.solve_ivp`` (RK45, default tolerances), sample by sample with the
        input held.
    solve_ivp_rk45_tight : SimulatorMeasurement
        The same with ``rtol = 1e-10``, ``atol = 1e-12``.
    gym_electric_motor : GymElectricMotor
    batch : BatchMeasurement
    speedup_vs_gem : float or None
        gym-electric-motor's time per step (default solver) over ``selftune_simulate``'s.
    speedup_vs_gem_euler : float or None
        The same against its Euler solver.
    step_loop_speedup_vs_gem : float or None
        gym-electric-motor's (default solver) over the interactive loop's.
    speedup_target : float
        Target of ``speedup_vs_gem`` (50).
    wall_seconds : float
        Time this comparison took, s.
    """

    sampling_seconds: float
    selftune_simulate: SimulatorMeasurement
    selftune_step_loop: SimulatorMeasurement
    solve_ivp_rk45: SimulatorMeasurement
    solve_ivp_rk45_tight: SimulatorMeasurement
    gym_electric_motor: GymElectricMotor
    batch: BatchMeasurement
    speedup_vs_gem: float | None
    speedup_vs_gem_euler: float | None
    step_loop_speedup_vs_gem: float | None
    speedup_target: float
    wall_seconds: float


def _under_optimum(loop: Loop, rho: Array, samples: int) -> dict[str, Any]:
    """The arguments of :func:`~selftune.sim.simulate` (and of its batch form) that run the
    loop under the optimal controller plus ``rho`` for ``samples`` steps from rest."""
    return {
        "exogenous": constant(loop.w),
        "K": loop.K,
        "X": loop.optimum.X,
        "U": loop.optimum.U,
        "exploration": rho,
        "h": loop.h,
        "num_samples": samples,
    }


def _measurement(
    loop: Loop, rho: Array, samples: int, seconds: float, states: Array
) -> SimulatorMeasurement:
    """``samples`` steps in ``seconds`` of wall time, and ``states`` against the exact ones."""
    return SimulatorMeasurement(
        us_per_step=seconds / samples * 1e6,
        timed_samples=samples,
        max_relative_error=max_relative_error(states, exact_states(loop, loop.motor, rho)),
        compared_samples=samples,
    )


def _measure_simulate(loop: Loop, samples: int, repeats: int) -> SimulatorMeasurement:
    rho = loop.exploration(samples)

    def run() -> Array:
        return simulate(loop.A, loop.B, D=loop.D, **_under_optimum(loop, rho, samples)).x

    return _measurement(loop, rho, samples, timed(run, repeats), run())


def _measure_step_loop(loop: Loop, samples: int, repeats: int) -> SimulatorMeasurement:
    rho = loop.exploration(samples)

    def run() -> Array:
        model = discretize(loop.A, loop.B, loop.h, D=loop.D)
        Ad, Bd = model.Ad, model.Bd
        drift = model.Ed @ loop.w
        reference = loop.L @ loop.w
        K = loop.K
        states = np.empty((samples + 1, 2))
        x = np.zeros(2)
        states[0] = x
        for k in range(samples):
            u = reference - K @ x + rho[k]
            x = Ad @ x + Bd @ u + drift
            states[k + 1] = x
        return states

    return _measurement(loop, rho, samples, timed(run, repeats), run())


def _measure_solve_ivp(
    loop: Loop, samples: int, rtol: float | None, atol: float | None
) -> SimulatorMeasurement:
    rho = loop.exploration(samples)
    A, B = loop.A, loop.B
    back_emf = loop.D @ loop.w
    reference = loop.L @ loop.w
    options: dict[str, float] = {}
    if rtol is not None:
        options["rtol"] = rtol
    if atol is not None:
        options["atol"] = atol
    states = np.empty((samples + 1, 2))
    x = np.zeros(2)
    states[0] = x
    start = time.perf_counter()
    for k in range(samples):
        u = reference - loop.K @ x + rho[k]
        forcing = B @ u + back_emf

        def derivative(_t: float, state: Array, forcing: Array = forcing) -> Array:
            return A @ state + forcing

        solution = scipy.integrate.solve_ivp(
            derivative, (k * loop.h, (k + 1) * loop.h), x, method="RK45", **options
        )
        x = solution.y[:, -1]
        states[k + 1] = x
    return _measurement(loop, rho, samples, time.perf_counter() - start, states)


def _random_motors(count: int, seed: int) -> list[SPMSM]:
    """``count`` motors with R_s, L_s, phi_pm uniform within +-30% of the paper's."""
    rng = np.random.default_rng(seed)
    return [as_built(rng, SPMSM.paper(), (MISMATCH, MISMATCH, MISMATCH)) for _ in range(count)]


def _measure_batch(loop: Loop, motors: int, samples: int, repeats: int) -> BatchMeasurement:
    rho = loop.exploration(samples)
    cold, warm = [], []
    first: tuple[SPMSM, Array] | None = None
    for repeat in range(repeats):
        batch_motors = _random_motors(motors, seed=repeat)
        A = np.stack([m.torque_mode(loop.speed)[0] for m in batch_motors])
        B = np.stack([m.torque_mode(loop.speed)[1] for m in batch_motors])
        D = np.stack([exogenous_matrix(m, loop.speed) for m in batch_motors])

        def run(A: Array = A, B: Array = B, D: Array = D) -> Array:
            result = simulate_batch(A, B, D=D, **_under_optimum(loop, rho, samples))
            return np.asarray(result.x[0])

        cold.append(timed(run, 1))
        warm.append(timed(run, 1))
        if first is None:
            first = (batch_motors[0], run())
    assert first is not None
    seconds = float(statistics.median(cold))
    error = max_relative_error(first[1], exact_states(loop, first[0], rho))
    return BatchMeasurement(
        motors_count=motors,
        samples_per_motor=samples,
        steps_per_second=motors * samples / seconds,
        wall_seconds=seconds,
        warm_steps_per_second=motors * samples / float(statistics.median(warm)),
        max_relative_error=error,
    )


def measure_simulation(config: BenchConfig, progress: bool = False) -> Simulation:
    """Time per step and exactness of each simulator, and a batch of motors.

    Parameters
    ----------
    config : BenchConfig
    progress : bool
        Show a progress bar on stderr (only when it is a terminal).

    Returns
    -------
    Simulation
    """
    started = time.perf_counter()
    loop = Loop.paper()
    with progress_bar(6, "simulation", progress) as bar:
        ours = _measure_simulate(loop, config.simulate_samples, config.timing_repeats)
        bar.update(1)
        step_loop = _measure_step_loop(loop, config.loop_samples, config.timing_repeats)
        bar.update(1)
        rk45 = _measure_solve_ivp(loop, config.compare_samples, None, None)
        bar.update(1)
        rk45_tight = _measure_solve_ivp(loop, config.compare_samples, 1e-10, 1e-12)
        bar.update(1)
        gem = measure_gem(loop, config.compare_samples)
        bar.update(1)
        batch = _measure_batch(
            loop, config.batch_motors, config.batch_samples, config.batch_repeats
        )
        bar.update(1)

    def speedup(reference: SimulatorMeasurement | None, ours: SimulatorMeasurement) -> float | None:
        return None if reference is None else reference.us_per_step / ours.us_per_step

    return Simulation(
        sampling_seconds=loop.h,
        selftune_simulate=ours,
        selftune_step_loop=step_loop,
        solve_ivp_rk45=rk45,
        solve_ivp_rk45_tight=rk45_tight,
        gym_electric_motor=gem,
        batch=batch,
        speedup_vs_gem=speedup(gem.default_solver, ours),
        speedup_vs_gem_euler=speedup(gem.euler_solver, ours),
        step_loop_speedup_vs_gem=speedup(gem.default_solver, step_loop),
        speedup_target=TARGET_SPEEDUP,
        wall_seconds=time.perf_counter() - started,
    )


def markdown_simulation(simulation: Simulation) -> list[str]:
    """Section 3 of bench.md: time per step and exactness of each simulator, the batch."""
    lines = [
        "## 3. Simulation speed and exactness (SPMSM current loop, 10 us sampling)",
        "",
        "Closed loop of the paper's motor under the optimal controller plus 1 V uniform "
        "exploration, from rest, T* = 10 N m; error = max |x - x_exact| / max |x_exact| "
        "against the exact sampled solution (closed form, independent of expm).",
        "",
        *table(
            ["simulator", "us/step", "timed steps", "max rel. error", "compared steps"],
            _simulator_rows(simulation),
        ),
        "",
        *_markdown_speedup(simulation),
    ]
    return lines


def _simulator_rows(simulation: Simulation) -> list[list[str]]:
    """One table row per simulator: time per step and error against the exact solution."""
    gem = simulation.gym_electric_motor
    entries: list[tuple[str, SimulatorMeasurement | None, str]] = [
        ("selftune simulate (whole loop, one call)", simulation.selftune_simulate, ""),
        ("selftune discretize + Python step loop", simulation.selftune_step_loop, ""),
        ("scipy solve_ivp RK45, default tol.", simulation.solve_ivp_rk45, ""),
        ("scipy solve_ivp RK45, rtol 1e-10", simulation.solve_ivp_rk45_tight, ""),
        (
            "gym-electric-motor"
            + (f" {gem.version_text}" if gem.version_text else "")
            + " (default: dopri5)",
            gem.default_solver,
            gem.reason_text or "",
        ),
        ("gym-electric-motor (Euler)", gem.euler_solver, gem.reason_text or ""),
    ]
    rows: list[list[str]] = []
    for name, measured, reason in entries:
        if measured is None:
            rows.append([name, reason or "n/a", "", "", ""])
        else:
            rows.append(
                [
                    name,
                    f"{measured.us_per_step:.3g}",
                    str(measured.timed_samples),
                    sci(measured.max_relative_error),
                    str(measured.compared_samples),
                ]
            )
    return rows


def _markdown_speedup(simulation: Simulation) -> list[str]:
    """The batch run and the speed-ups against gym-electric-motor."""
    batch = simulation.batch
    speedup = simulation.speedup_vs_gem
    return [
        f"Batch: {batch.motors_count} motors (R_s, L_s, phi_pm within +-30%) x "
        f"{batch.samples_per_motor} steps in {batch.wall_seconds:.3f} s = "
        f"**{batch.steps_per_second / 1e6:.2f} M steps/s** (discretization of every motor "
        f"included; {batch.warm_steps_per_second / 1e6:.2f} M steps/s again on the same "
        f"motors, discretization cached), max rel. error {sci(batch.max_relative_error)}.",
        "",
        "speedup_vs_gem = "
        + ("not measured" if speedup is None else f"**{speedup:.0f}x**")
        + f" (target >= {simulation.speedup_target:g}x); against its Euler solver "
        + (
            "n/a"
            if simulation.speedup_vs_gem_euler is None
            else f"{simulation.speedup_vs_gem_euler:.0f}x"
        )
        + "; interactive step loop vs gym-electric-motor "
        + (
            "n/a"
            if simulation.step_loop_speedup_vs_gem is None
            else f"{simulation.step_loop_speedup_vs_gem:.0f}x"
        )
        + ".",
    ]
