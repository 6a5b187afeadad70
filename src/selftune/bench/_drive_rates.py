"""Study 5: at drive rates (5-50 kHz, one-sample computation delay).

Two questions a drive engineer asks before trusting a learned current controller:

1. **How exact is each learner at the drive's sampling rate?** On noise-free data of the
   ideal digital loop with a one-sample delay (:func:`selftune.sim.simulate_loop`), for
   three motors (one above 1,000 rad/s electrical): the paper's continuous-time ADP
   against the continuous optimum, the discrete-time ADP and identify-then-design
   against the digital optimum of the delayed loop.
2. **What does the target cost?** Running the continuous optimum K* on the true sampled
   loop with its one-sample delay, instead of the digital optimum, at closed-loop
   bandwidths from f_s/40 to f_s/8: the excess of the digital cost
   ``sum_k h (x' Q x + u' R u)`` from a unit random initial current (``trace P_xx``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..core import Array, ControlLaw, discretize, lqr
from ..errors import UnsolvableError
from ..learn import LearningOptions, LearningProblem
from ..loop import SampledLoop
from ..model import SPMSM, solve_digital_regulation, solve_optimal_regulation
from ..sim import simulate_loop
from ._common import progress_bar, sci, table
from ._experiment import DC_VOLTAGE, Refused, attempt
from ._targets import TargetOutcome

__all__ = [
    "DelayCost",
    "DriveRates",
    "RateErrors",
    "drive_rates_target",
    "markdown_drive_rates",
    "measure_drive_rates",
]

#: The motors of the study: name, motor, mechanical speed (rad/s), torque reference (N m).
RATE_MOTORS = (
    ("A: 0.6 ohm, 8 mH, 150 rad/s el.", SPMSM(R_s=0.6, L_s=8e-3, phi_pm=0.35, p=3), 50.0, 5.0),
    ("B: 0.9 ohm, 3 mH, 800 rad/s el.", SPMSM(R_s=0.9, L_s=3e-3, phi_pm=0.1, p=4), 200.0, 2.0),
    ("C: 0.2 ohm, 3 mH, 1500 rad/s el.", SPMSM(R_s=0.2, L_s=3e-3, phi_pm=0.05, p=5), 300.0, 1.0),
)
#: Sampling frequencies of the accuracy sweep, Hz.
RATE_FREQUENCIES = (5e3, 1e4, 2e4, 5e4)
#: Bandwidths of the cost study, as fractions f_s / N of the sampling frequency.
BANDWIDTH_DIVISORS = (40, 30, 20, 15, 10, 8)


@dataclass(frozen=True)
class RateErrors:
    """Each learner's relative error at one motor and sampling frequency (noise-free).

    Attributes
    ----------
    motor_text : str
        The motor.
    sampling_frequency_hz : float
        f_s.
    samples_count : int
        Samples learned from (0.1 s of data).
    continuous_adp_K_relative_error, continuous_adp_U_relative_error : float or None
        The paper's continuous ADP against the continuous optimum.
    digital_adp_K_relative_error, digital_adp_U_relative_error : float or None
        The discrete-time ADP against the digital optimum with the delay.
    identify_K_relative_error, identify_U_relative_error : float or None
        Identify-then-design (digital target) against the digital optimum.
    identify_continuous_K_relative_error : float or None
        Identify-then-design (continuous target) against the continuous optimum.
    refusals_text : str
        The learners that refused, with the cause (:func:`~._causes.refusal_cause`): None
        above. The continuous optimum of a fast motor may not stabilize the loop with its
        delay at a low rate; the learner then refuses it rather than return it.
    """

    motor_text: str
    sampling_frequency_hz: float
    samples_count: int
    continuous_adp_K_relative_error: float | None
    continuous_adp_U_relative_error: float | None
    digital_adp_K_relative_error: float | None
    digital_adp_U_relative_error: float | None
    identify_K_relative_error: float | None
    identify_U_relative_error: float | None
    identify_continuous_K_relative_error: float | None
    refusals_text: str


@dataclass(frozen=True)
class DelayCost:
    """The digital cost of the continuous K* on the delayed sampled loop.

    Attributes
    ----------
    motor_text : str
        The motor.
    sampling_to_bandwidth_ratio : int
        N: the continuous optimum's closed-loop bandwidth is f_s / N.
    bandwidth_rad_per_second : float
        That bandwidth (the slowest closed-loop decay rate), rad/s.
    excess_cost_no_delay_percent : float
        K* against the digital optimum without delay, %.
    excess_cost_one_sample_delay_percent : float or None
        K* against the digital optimum with a one-sample delay, %; None if K* does not
        stabilize the delayed loop.
    """

    motor_text: str
    sampling_to_bandwidth_ratio: int
    bandwidth_rad_per_second: float
    excess_cost_no_delay_percent: float
    excess_cost_one_sample_delay_percent: float | None


@dataclass(frozen=True)
class DriveRates:
    """Study 5's results.

    Attributes
    ----------
    sampling_frequency_hz : float
        f_s of the cost study, Hz.
    errors : tuple of RateErrors
        The accuracy sweep.
    costs : tuple of DelayCost
        The cost study.
    wall_seconds : float
        Time the study took, s.
    """

    sampling_frequency_hz: float
    errors: tuple[RateErrors, ...]
    costs: tuple[DelayCost, ...]
    wall_seconds: float


def _rate_errors(name: str, motor: SPMSM, speed: float, torque: float, f_s: float) -> RateErrors:
    h = 1.0 / f_s
    count = round(0.1 * f_s)
    problem = motor.regulation_problem(speed)
    Q, R = 1e3 * np.eye(2), np.eye(2)
    K0 = 0.0125 * motor.L_s / h * np.eye(2)
    rng = np.random.default_rng(0)
    t = np.arange(count + 1) * h
    w = np.tile(motor.exogenous(speed, torque), (count + 1, 1))
    w[:, 1] += 0.3 * torque * np.sign(np.sin(2 * np.pi * 30.0 * t)) + 0.1 * torque * np.sin(
        2 * np.pi * 170.0 * t
    )
    law = ControlLaw.regulator(K0, -problem.F, np.zeros((2, 2)))
    rho = rng.uniform(-0.02 * DC_VOLTAGE, 0.02 * DC_VOLTAGE, size=(count, 2))
    logs = simulate_loop(
        (problem.A, problem.B, problem.D), law, w, h=h, num_samples=count, delay=1, exploration=rho
    )
    known = (LearningProblem(Q, R, C=np.eye(2), F=problem.F), K0)
    continuous = solve_optimal_regulation(problem, Q, R)
    digital = solve_digital_regulation(problem, Q, R, h, input_delay=1)

    refusals: list[str] = []

    def errors(target: str, method: str) -> tuple[float | None, float | None]:
        """Relative errors of K and U against the target's optimum; None if refused."""
        options = LearningOptions(target=target, method=method, input_delay=1)  # type: ignore[arg-type]
        truth = continuous if target == "continuous" else digital
        tried = attempt(logs.applied, known, options)
        if isinstance(tried, Refused):
            refusals.append(f"{method} ({target}): {tried.cause}")
            return None, None
        return tried.errors((truth.K, truth.U))

    continuous_adp = errors("continuous", "adp")
    digital_adp = errors("digital", "adp")
    identify = errors("digital", "identify")
    identify_continuous = errors("continuous", "identify")
    return RateErrors(
        motor_text=name,
        sampling_frequency_hz=f_s,
        samples_count=count,
        continuous_adp_K_relative_error=continuous_adp[0],
        continuous_adp_U_relative_error=continuous_adp[1],
        digital_adp_K_relative_error=digital_adp[0],
        digital_adp_U_relative_error=digital_adp[1],
        identify_K_relative_error=identify[0],
        identify_U_relative_error=identify[1],
        identify_continuous_K_relative_error=identify_continuous[0],
        refusals_text="; ".join(refusals),
    )


def _bandwidth(A: Array, B: Array, weight: float) -> tuple[float, Array]:
    """The slowest decay rate of the continuous optimum with ``Q = weight I``, and K*."""
    K, _ = lqr(A, B, weight * np.eye(2), np.eye(2))
    return -float(np.max(np.linalg.eigvals(A - B @ K).real)), K


def _weight_for(A: Array, B: Array, target: float) -> tuple[float, Array]:
    """``Q = q I`` whose continuous optimum has the target bandwidth (bisection in log q)."""
    low, high = -6.0, 14.0
    for _ in range(80):
        middle = 0.5 * (low + high)
        rate, _ = _bandwidth(A, B, 10.0**middle)
        low, high = (middle, high) if rate < target else (low, middle)
    return 10.0 ** (0.5 * (low + high)), _bandwidth(A, B, 10.0 ** (0.5 * (low + high)))[1]


def _digital_cost(A: Array, B: Array, h: float, weights: tuple[float, Array], delay: int) -> float:
    """``trace P_xx`` of the policy ``K`` on the sampled loop with the delay (inf if it
    does not stabilize it), relative to the digital optimum's."""
    q, K = weights
    exact = discretize(A, B, h)
    loop, plant = SampledLoop(h, delay), (exact.Ad, exact.Bd)
    cost = loop.weights(q * np.eye(2), np.eye(2))
    _, P_opt = loop.optimum(plant, cost)
    try:
        P = loop.value(plant, ControlLaw.regulator(K, np.zeros((2, 0)), np.zeros((2, 0))), cost)
    except UnsolvableError:
        return float("inf")
    return float(np.trace(P[:2, :2]) / np.trace(P_opt[:2, :2]))


def _delay_costs(name: str, motor: SPMSM, speed: float, f_s: float) -> list[DelayCost]:
    A, B = motor.torque_mode(speed)
    costs = []
    for divisor in BANDWIDTH_DIVISORS:
        target = 2 * np.pi * f_s / divisor
        q, K = _weight_for(A, B, target)
        no_delay = _digital_cost(A, B, 1.0 / f_s, (q, K), 0)
        delayed = _digital_cost(A, B, 1.0 / f_s, (q, K), 1)
        costs.append(
            DelayCost(
                motor_text=name,
                sampling_to_bandwidth_ratio=divisor,
                bandwidth_rad_per_second=target,
                excess_cost_no_delay_percent=100.0 * (no_delay - 1.0),
                excess_cost_one_sample_delay_percent=(
                    None if not np.isfinite(delayed) else 100.0 * (delayed - 1.0)
                ),
            )
        )
    return costs


def measure_drive_rates(
    progress: bool = False, frequencies: tuple[float, ...] = RATE_FREQUENCIES
) -> DriveRates:
    """Study 5 (see the module docstring).

    Parameters
    ----------
    progress : bool
        Show a progress bar on stderr (only when it is a terminal).
    frequencies : tuple of float
        Sampling frequencies of the accuracy sweep, Hz.

    Returns
    -------
    DriveRates
    """
    started = time.perf_counter()
    errors, costs = [], []
    with progress_bar(len(RATE_MOTORS) * (len(frequencies) + 1), "drive rates", progress) as bar:
        for name, motor, speed, torque in RATE_MOTORS:
            for f_s in frequencies:
                errors.append(_rate_errors(name, motor, speed, torque, f_s))
                bar.update(1)
            costs += _delay_costs(name, motor, speed, 1e4)
            bar.update(1)
    return DriveRates(
        sampling_frequency_hz=1e4,
        errors=tuple(errors),
        costs=tuple(costs),
        wall_seconds=time.perf_counter() - started,
    )


def _error(value: float | None) -> str:
    return "refused" if value is None else sci(value)


def markdown_drive_rates(rates: DriveRates) -> list[str]:
    """Section 5 of bench.md: the learners' accuracy at drive rates and the cost of the
    continuous target on a delayed sampled loop.

    Parameters
    ----------
    rates : DriveRates
        The study's results.
    """
    lines = [
        "## 5. At drive rates (one-sample computation delay)",
        "",
        "Noise-free data of the ideal digital loop (ZOH, one-sample delay), 0.1 s, K0 = 1.25% "
        "of L_s/h, exploration +-2% of 540 V, torque reference with a square and a sine. "
        "Relative errors: continuous ADP (the paper's) against the continuous optimum, "
        "digital ADP and identify-then-design against the digital optimum of the delayed "
        "loop; identify (cont.) against the continuous optimum.",
        "",
    ]
    lines += table(
        ["motor", "f_s (kHz)", "cont. ADP K", "cont. ADP U", "digital ADP K", "digital ADP U",
         "identify K", "identify U", "identify (cont.) K"],
        [
            [e.motor_text, f"{e.sampling_frequency_hz / 1e3:g}",
             _error(e.continuous_adp_K_relative_error), _error(e.continuous_adp_U_relative_error),
             _error(e.digital_adp_K_relative_error), _error(e.digital_adp_U_relative_error),
             _error(e.identify_K_relative_error), _error(e.identify_U_relative_error),
             _error(e.identify_continuous_K_relative_error)]
            for e in rates.errors
        ],
    )  # fmt: skip
    refused = [e for e in rates.errors if e.refusals_text]
    if refused:
        lines += [
            "",
            "Refused (the learner's cause): "
            + "; ".join(
                f"{e.motor_text} at {e.sampling_frequency_hz / 1e3:g} kHz: {e.refusals_text}"
                for e in refused
            )
            + ". The continuous optimum of Q = 1e3 I does not stabilize these loops with "
            "their one-sample delay (see the cost table below), so the learners refuse it.",
        ]
    lines += [
        "",
        f"Cost of running the continuous optimum K* on the sampled loop at "
        f"{rates.sampling_frequency_hz / 1e3:g} kHz instead of the digital optimum of that "
        "loop (digital cost from a unit random initial current, Q = q I chosen for the "
        "bandwidth, R = I):",
        "",
    ]
    lines += table(
        ["motor", "bandwidth", "rad/s", "excess, no delay", "excess, one-sample delay"],
        [
            [c.motor_text, f"f_s/{c.sampling_to_bandwidth_ratio}",
             f"{c.bandwidth_rad_per_second:.0f}",
             f"{c.excess_cost_no_delay_percent:+.2f}%",
             "unstable" if c.excess_cost_one_sample_delay_percent is None
             else f"{c.excess_cost_one_sample_delay_percent:+.2f}%"]
            for c in rates.costs
        ],
    )  # fmt: skip
    return lines


#: The largest relative error of the exact learners on noise-free data (issue 10).
EXACT_LEARNING = 1e-9


def drive_rates_target(rates: DriveRates) -> TargetOutcome:
    """Issue 10: on noise-free data, the digital ADP and identify-then-design match the
    digital optimum, and identify-then-design the continuous one, to 1e-9.

    Parameters
    ----------
    rates : DriveRates
        The study's results.
    """
    values = [
        value
        for e in rates.errors
        for value in (
            e.digital_adp_K_relative_error,
            e.digital_adp_U_relative_error,
            e.identify_K_relative_error,
            e.identify_U_relative_error,
        )
    ]
    refused = sum(value is None for value in values)
    worst = max((value for value in values if value is not None), default=float("inf"))
    return TargetOutcome(
        name_text="exact digital learning",
        target_text=f"digital ADP and identify-then-design within {EXACT_LEARNING:g} of the "
        "digital optimum (K, U), noise-free, every motor and rate",
        value_text=f"worst {worst:.1e}" + (f", {refused} refused" if refused else ""),
        met=bool(refused == 0 and worst <= EXACT_LEARNING),
        why_text="the exact discrete model has no quadrature error at any sampling period "
        "(section 5)",
    )
