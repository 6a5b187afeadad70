"""The realistic-drive study's results (:mod:`._realistic_drive`), its targets and its table."""

from __future__ import annotations

import math
import statistics
from collections.abc import Callable
from dataclasses import dataclass

from ..report import HOT_RESISTANCE
from ._common import table
from ._targets import TargetOutcome

__all__ = [
    "CONTROLLER_KNOWLEDGE",
    "EXCESS_TARGET",
    "FLUX_TARGET",
    "REALISTIC_CONTROLLERS",
    "TORQUE_TARGET_PERCENT",
    "DriveControllerOutcome",
    "DriveMotorOutcome",
    "DriveSeedRun",
    "RealisticDriveComparison",
    "markdown_realistic_drive",
]

#: The controllers, in table order (see :mod:`._realistic_drive`).
REALISTIC_CONTROLLERS = (
    "selftune",
    "identify",
    "industrial_pi",
    "nominal_optimum",
    "nominal_pi",
    "nominal_nameplate_flux",
    "algorithm3",
    "optimum",
)
#: Each controller's title and what it is made from beyond what all know (p, speed, T*,
#: Q, R, h, the delay, K0 and the flux at the operating temperature).
CONTROLLER_KNOWLEDGE = {
    "selftune": ("(a) selftune, off-policy", "the batch"),
    "identify": ("(b) identify-then-design", "the same batch"),
    "industrial_pi": (
        "(c) industrial PI",
        "the same batch: R_s, L_s fitted; as fast as (a) on that model",
    ),
    "nominal_optimum": ("(d) nominal optimum", "nameplate R_s, L_s"),
    "nominal_pi": ("(d) nominal PI", "nameplate R_s, L_s; as fast as (d) optimum on them"),
    "nominal_nameplate_flux": (
        "(d') nominal optimum, nameplate flux",
        "nameplate R_s, L_s, phi_pm (not the measured flux)",
    ),
    "algorithm3": (
        "(e) Algorithm 3",
        "nameplate flux as a guess only; its own flux step, then its own batch",
    ),
    "optimum": ("true optimum", "the true motor (evaluation only)"),
}
#: The issue's targets: |torque error| (%), excess cost (%) from at most this much data
#: (s), flux error (%) from a flux step of at most this much data (s).
TORQUE_TARGET_PERCENT = 0.1
EXCESS_TARGET = (1.0, 0.1)
FLUX_TARGET = (0.5, 0.2)


@dataclass(frozen=True)
class DriveControllerOutcome:
    """One controller on one motor, one seed.

    Attributes
    ----------
    torque_error_percent : float or None
        Steady ``(torque - T*) / T*`` on the simulated drive at the tuning conditions, %;
        None if the loop is unstable or the controller could not be made.
    hot_torque_error_percent : float or None
        The same after R_s rose by ``HOT_RESISTANCE`` without re-tuning, %.
    excess_cost_percent : float or None
        Digital cost of its feedback over the optimum's on the true sampled loop, %
        (inf: unstable; None: not made).
    bandwidth_rad_per_second : float or None
        -3 dB bandwidth of its q-current response on the true sampled loop, rad/s (None:
        unstable or not made).
    data_seconds : float
        Motor data it was made from, s (0 for a design from the nameplate or the model).
    learn_seconds : float
        Wall time to make it, s (the drive's simulation excluded).
    failure_text : str
        Why it could not be made (the error), or empty.
    """

    torque_error_percent: float | None
    hot_torque_error_percent: float | None
    excess_cost_percent: float | None
    bandwidth_rad_per_second: float | None
    data_seconds: float
    learn_seconds: float
    failure_text: str = ""


@dataclass(frozen=True)
class DriveSeedRun:
    """Every controller on one motor for one exploration seed (the study's ``seeds``, in
    order; the seed also drives the noise of the torque check).

    Attributes
    ----------
    selftune, identify, industrial_pi, nominal_optimum : DriveControllerOutcome
        See :mod:`._realistic_drive`.
    nominal_pi, nominal_nameplate_flux, algorithm3, optimum : DriveControllerOutcome
        See :mod:`._realistic_drive`.
    fitted_R_s_relative_error, fitted_L_s_relative_error : float or None
        The industrial recipe's identified R_s and L_s over the true ones, minus 1.
    industrial_w_c_rad_per_second : float or None
        Its w_c, rad/s: its loop on the identified model is as fast (-3 dB) as selftune's.
    phi_pm_relative_error : float or None
        Algorithm 3's identified flux over the true one, minus 1.
    flux_step_seconds : float or None
        The data of Algorithm 3's flux step, s.
    """

    selftune: DriveControllerOutcome
    identify: DriveControllerOutcome
    industrial_pi: DriveControllerOutcome
    nominal_optimum: DriveControllerOutcome
    nominal_pi: DriveControllerOutcome
    nominal_nameplate_flux: DriveControllerOutcome
    algorithm3: DriveControllerOutcome
    optimum: DriveControllerOutcome
    fitted_R_s_relative_error: float | None
    fitted_L_s_relative_error: float | None
    industrial_w_c_rad_per_second: float | None
    phi_pm_relative_error: float | None
    flux_step_seconds: float | None


@dataclass(frozen=True)
class DriveMotorOutcome:
    """One motor: its nameplate, the true motor while tuning, its operating point, its runs.

    Attributes
    ----------
    name_text : str
        A short description (from the nameplate).
    pole_pairs_count : int
        p.
    nameplate_R_s_ohm, nameplate_L_s_henry, nameplate_phi_pm_weber : float
        The nameplate.
    true_R_s_ohm, true_L_s_henry, true_phi_pm_weber : float
        The motor as built, at the drive's temperature.
    speed_rad_per_second, electrical_speed_rad_per_second : float
        Held mechanical speed and ``p speed``.
    torque_newton_meters : float
        T*.
    Q_diagonal_volt2_per_ampere2 : float
        ``Q = q I``.
    nominal_pi_w_c_rad_per_second : float or None
        The nominal PI's w_c, rad/s: its loop on the nameplate model is as fast (-3 dB)
        as the nominal optimum's (None: no w_c is).
    runs : tuple of DriveSeedRun
        One per seed.
    """

    name_text: str
    pole_pairs_count: int
    nameplate_R_s_ohm: float
    nameplate_L_s_henry: float
    nameplate_phi_pm_weber: float
    true_R_s_ohm: float
    true_L_s_henry: float
    true_phi_pm_weber: float
    speed_rad_per_second: float
    electrical_speed_rad_per_second: float
    torque_newton_meters: float
    Q_diagonal_volt2_per_ampere2: float
    nominal_pi_w_c_rad_per_second: float | None
    runs: tuple[DriveSeedRun, ...]


@dataclass(frozen=True)
class RealisticDriveComparison:
    """The study's results (see :mod:`._realistic_drive`).

    Attributes
    ----------
    quick : bool
        The CI-sized run.
    drive_text : str
        The drive in words.
    sampling_seconds : float
        h, s.
    bandwidth_target_rad_per_second : float
        ``w_t``, the bandwidth Q is chosen for.
    hot_resistance_factor : float
        R_s after tuning over R_s while tuning.
    tolerance_R_s_relative, tolerance_L_s_relative, tolerance_phi_pm_relative : float
        The tolerances of the motors as built.
    seeds : tuple of int
        The exploration seeds of each motor's runs.
    motors : tuple of DriveMotorOutcome
        The motors and their runs.
    wall_seconds : float
        Time the study took, s.
    """

    quick: bool
    drive_text: str
    sampling_seconds: float
    bandwidth_target_rad_per_second: float
    hot_resistance_factor: float
    tolerance_R_s_relative: float
    tolerance_L_s_relative: float
    tolerance_phi_pm_relative: float
    seeds: tuple[int, ...]
    motors: tuple[DriveMotorOutcome, ...]
    wall_seconds: float

    def outcomes(self, controller: str) -> list[DriveControllerOutcome]:
        """``controller``'s outcome on every motor and seed.

        Parameters
        ----------
        controller : str
            One of :data:`REALISTIC_CONTROLLERS`.
        """
        return [getattr(run, controller) for motor in self.motors for run in motor.runs]

    def runs(self) -> list[DriveSeedRun]:
        """Every run, motor by motor."""
        return [run for motor in self.motors for run in motor.runs]

    def targets(self) -> tuple[TargetOutcome, ...]:
        """The issue's targets for ``tune`` on this drive, each met or missed."""
        return _targets(self)


def _worst(values: list[float | None]) -> tuple[float | None, int]:
    """Largest finite magnitude (None if there is none), and how many are missing or
    infinite (not made, or unstable)."""
    finite = [abs(value) for value in values if value is not None and math.isfinite(value)]
    return (max(finite) if finite else None), len(values) - len(finite)


def _percent(value: float | None) -> float | None:
    return None if value is None else 100.0 * value


def _met(worst: float | None, missing: int, limit: float) -> bool | None:
    """Met when every run has a value within the limit; missing runs miss it."""
    if worst is None and not missing:
        return None
    return not missing and worst is not None and worst <= limit


def _worst_text(worst: float | None, missing: int, total: int, form: str) -> str:
    text = "none made" if worst is None else f"worst {worst:{form}}%"
    return text + (f" ({missing} of {total} runs refused or unstable)" if missing else "")


def _within_from(
    values: list[float | None],
    target: tuple[float, float],
    seconds: float,
    total: int,
    form: str,
) -> tuple[str, bool | None]:
    """The value text and verdict of a target ``(limit %, most seconds of data)``: every
    run's value within the limit, from at most that much data."""
    worst, missing = _worst(values)
    met = _met(worst, missing, target[0])
    return (
        _worst_text(worst, missing, total, form) + f" from {seconds:g} s",
        None if met is None else met and seconds <= target[1],
    )


def _targets(comparison: RealisticDriveComparison) -> tuple[TargetOutcome, ...]:
    tuned = comparison.outcomes("selftune")
    total = len(tuned)
    cold, cold_missing = _worst([o.torque_error_percent for o in tuned])
    hot, hot_missing = _worst([o.hot_torque_error_percent for o in tuned])
    floor, _ = _worst([o.torque_error_percent for o in comparison.outcomes("optimum")])
    runs = comparison.runs()
    torque_met = _met(max(cold or 0.0, hot or 0.0), max(cold_missing, hot_missing),
                      TORQUE_TARGET_PERCENT)  # fmt: skip
    return (
        TargetOutcome(
            "torque error, integral action",
            f"steady torque error within +-{TORQUE_TARGET_PERCENT:g}% at tuning and after R_s "
            f"+{HOT_RESISTANCE - 1:.0%}, every motor and seed (selftune)",
            f"at tuning {_worst_text(cold, cold_missing, total, '.3f')}; hot "
            f"{_worst_text(hot, hot_missing, total, '.3f')}; the true optimum's worst "
            + ("n/a" if floor is None else f"{floor:.3f}%"),
            torque_met,
            "integral action makes the steady state exact whatever the dead-time voltage "
            "and R_s; what is left is the drive's measurement floor (noise, ADC, PWM), and a "
            "run whose batch the learner refuses has no controller",
        ),
        TargetOutcome(
            "excess cost",
            f"excess cost <= {EXCESS_TARGET[0]:g}% over the optimum of the same digital loop "
            f"from <= {EXCESS_TARGET[1]:g} s of data (selftune)",
            *_within_from(
                [o.excess_cost_percent for o in tuned],
                EXCESS_TARGET,
                max(o.data_seconds for o in tuned),
                total,
                ".3g",
            ),
            "the batch's output-error model is consistent under noise and carries the "
            "dead time, so the learned feedback is the true loop's optimum to its noise",
        ),
        TargetOutcome(
            "flux",
            f"phi_pm error within +-{FLUX_TARGET[0]:g}% from a flux step of <= "
            f"{FLUX_TARGET[1]:g} s (Algorithm 3)",
            *_within_from(
                [_percent(run.phi_pm_relative_error) for run in runs],
                FLUX_TARGET,
                max((run.flux_step_seconds or 0.0) for run in runs),
                total,
                ".3f",
            ),
            "the torque reference steps through +-T*: the dead-time voltage follows the "
            "current's sign, the back-EMF does not",
        ),
    )


# -- markdown ----------------------------------------------------------------------------


def _span(values: list[float | None], form: Callable[[float], str]) -> str:
    """``min .. max`` of the finite values (the others are counted in the "made" column)."""
    finite = [value for value in values if value is not None and math.isfinite(value)]
    if not finite:
        return "n/a"
    low, high = form(min(finite)), form(max(finite))
    return low if low == high else f"{low} .. {high}"


def _made(outcomes: list[DriveControllerOutcome]) -> str:
    """How many runs gave a stable controller, and why the others did not."""
    refused = sum(1 for o in outcomes if o.failure_text)
    unstable = sum(1 for o in outcomes if not o.failure_text and o.torque_error_percent is None)
    text = f"{len(outcomes) - refused - unstable} of {len(outcomes)}"
    notes = [f"{count} {why}" for count, why in ((refused, "not made"), (unstable, "unstable"))
             if count]  # fmt: skip
    return text + (f" ({', '.join(notes)})" if notes else "")


def _signed(value: float) -> str:
    return f"{value:+.3f}"


def _excess(value: float) -> str:
    return f"{value:.3g}"


def _seconds(outcomes: list[DriveControllerOutcome]) -> str:
    data = sorted({round(o.data_seconds, 9) for o in outcomes})
    return ", ".join("none" if value == 0 else f"{value:g}" for value in data)


def _learn_time(outcomes: list[DriveControllerOutcome]) -> str:
    times = [o.learn_seconds for o in outcomes]
    return f"{statistics.median(times):.3g} (max {max(times):.3g})"


def _summary(comparison: RealisticDriveComparison) -> list[str]:
    rows = []
    for name in REALISTIC_CONTROLLERS:
        outcomes = comparison.outcomes(name)
        title, knows = CONTROLLER_KNOWLEDGE[name]
        rows.append(
            [
                title,
                knows,
                _seconds(outcomes),
                _made(outcomes),
                _span([o.torque_error_percent for o in outcomes], _signed),
                _span([o.hot_torque_error_percent for o in outcomes], _signed),
                _span([o.excess_cost_percent for o in outcomes], _excess),
                _span([o.bandwidth_rad_per_second for o in outcomes], lambda v: f"{v:.0f}"),
                _learn_time(outcomes),
            ]
        )
    return table(
        ["controller", "made from (beyond what all know)", "data (s)", "stable runs",
         "torque error (%)",
         f"after R_s +{comparison.hot_resistance_factor - 1:.0%} (%)", "excess cost (%)",
         "bandwidth (rad/s)", "time to make (s)"],
        rows,
    )  # fmt: skip


def _motor_rows(comparison: RealisticDriveComparison) -> list[str]:
    rows = []
    for motor in comparison.motors:
        runs = motor.runs
        rows.append(
            [
                motor.name_text,
                f"{motor.true_R_s_ohm:.3g} ohm, {motor.true_L_s_henry * 1e3:.3g} mH, "
                f"{motor.true_phi_pm_weber * 1e3:.3g} mWb",
                f"{motor.speed_rad_per_second:.4g}",
                f"{motor.torque_newton_meters:.3g}",
                f"{motor.Q_diagonal_volt2_per_ampere2:.4g}",
                _span([_percent(r.fitted_R_s_relative_error) for r in runs], _signed),
                _span([_percent(r.fitted_L_s_relative_error) for r in runs], _signed),
                _span([r.industrial_w_c_rad_per_second for r in runs], lambda v: f"{v:.0f}"),
                "n/a" if motor.nominal_pi_w_c_rad_per_second is None
                else f"{motor.nominal_pi_w_c_rad_per_second:.0f}",
                _span([_percent(r.phi_pm_relative_error) for r in runs], _signed),
            ]
        )  # fmt: skip
    return table(
        ["motor (nameplate)", "true while tuning", "speed (rad/s)", "T* (N m)", "Q (V^2/A^2)",
         "(c) R_s fit (%)", "(c) L_s fit (%)", "(c) w_c (rad/s)", "(d) PI w_c (rad/s)",
         "(e) phi_pm (%)"],
        rows,
    )  # fmt: skip


def _worst_rows(comparison: RealisticDriveComparison) -> list[str]:
    rows = []
    for name in REALISTIC_CONTROLLERS:
        cells = [CONTROLLER_KNOWLEDGE[name][0]]
        for motor in comparison.motors:
            outcomes = [getattr(run, name) for run in motor.runs]
            worst = [
                _worst([o.torque_error_percent for o in outcomes]),
                _worst([o.hot_torque_error_percent for o in outcomes]),
                _worst([o.excess_cost_percent for o in outcomes]),
            ]
            text = " / ".join("n/a" if value is None else f"{value:.3g}" for value, _ in worst)
            missing = max(count for _, count in worst)
            cells.append(text + (f" ({missing} of {len(outcomes)} missing)" if missing else ""))
        rows.append(cells)
    return table(["controller", *(motor.name_text.split(":")[0] for motor in comparison.motors)],
                 rows)  # fmt: skip


def _failures(comparison: RealisticDriveComparison) -> list[str]:
    """One line per controller that could not be made, with the error."""
    lines = []
    for motor in comparison.motors:
        for seed, run in zip(comparison.seeds, motor.runs, strict=True):
            for name in REALISTIC_CONTROLLERS:
                failure = getattr(run, name).failure_text
                if failure:
                    lines.append(
                        f"- {motor.name_text.split(':')[0]}, seed {seed}, "
                        f"{CONTROLLER_KNOWLEDGE[name][0]}: {failure}"
                    )
    return lines


def markdown_realistic_drive(comparison: RealisticDriveComparison) -> list[str]:
    """The section of bench.md: every controller on the realistic drive, and the targets.

    Parameters
    ----------
    comparison : RealisticDriveComparison
        The study's results.
    """
    runs = len(comparison.seeds) * len(comparison.motors)
    lines = [
        "## 9. On a realistic drive: selftune, the industrial recipe and nominal designs",
        "",
        f"The drive: {comparison.drive_text}, at {1e-3 / comparison.sampling_seconds:g} kHz; "
        f"{len(comparison.motors)} motors drawn from plausible ranges (seeded; none of the "
        "tests'), each built within "
        f"+-{comparison.tolerance_R_s_relative:.0%} (R_s), "
        f"+-{comparison.tolerance_L_s_relative:.0%} (L_s), "
        f"+-{comparison.tolerance_phi_pm_relative:.0%} (phi_pm) of its nameplate; "
        f"exploration seeds {', '.join(map(str, comparison.seeds))} "
        f"({runs} runs per controller). Settings: `selftune tune`'s for this [drive] with "
        "integral action (digital servo target, dead time modelled, torque reference "
        "stepping through +-T*, 0.1 s batch, K0 = 1.25% of the nameplate's L_s/h). Cost: "
        "R = I, Q = (w_t L_s)^2 I from the nameplate, w_t = "
        f"{comparison.bandwidth_target_rad_per_second:.0f} rad/s (f_s/20), the learner's "
        "integral weight. Every controller knows p, the speed, T*, Q, R, h, the one-sample "
        "delay, K0 and the flux at the operating temperature (measured); every learned one "
        "learns from the SAME batch, except Algorithm 3, which is given the nameplate flux "
        "as a guess and runs its own flux step and batch. The industrial PI: k_p = w_c L, "
        "k_i = w_c R, decoupling -w_e L i_q and w_e L i_d + w_e phi from the measured "
        "currents and the flux; w_c such that its loop on the identified model has the "
        "bandwidth (a) has there ((d) PI: the nominal optimum's, on the nameplate model); "
        "bandwidth: -3 dB of the q current's response to its reference, sampled loop with "
        "the delay.",
        "",
        "Torque error: steady (T - T*)/T* on the simulated drive (true torque, mean of the "
        f"second half of 0.2 s), at tuning and after R_s +"
        f"{comparison.hot_resistance_factor - 1:.0%} without re-tuning. Excess cost: the "
        "digital servo cost of the feedback over the optimum of the same sampled loop (true "
        "motor, delay, PWM hold), torque step from rest. Bandwidth: -3 dB of the q-current "
        "response on the true sampled loop. Ranges: min .. max over motors and seeds; time "
        "to make: median (max) wall time, the drive's simulation excluded (one BLAS thread "
        "when the environment sets it; several contend for the cores).",
        "",
    ]
    lines += _summary(comparison)
    lines += ["", "The motors (true: as built, at the drive's temperature), and what the "
              "data gave the industrial recipe and Algorithm 3 (relative errors):", ""]  # fmt: skip
    lines += _motor_rows(comparison)
    lines += ["", "Worst torque error (magnitude) at tuning / after R_s +"
              f"{comparison.hot_resistance_factor - 1:.0%} / worst excess cost, %, per motor:",
              ""]  # fmt: skip
    lines += _worst_rows(comparison)
    failures = _failures(comparison)
    if failures:
        lines += ["", "Not made (the learner's verdict, or what a controller needed):", "",
                  *failures]  # fmt: skip
    lines += ["", "Targets (issue 12, `tune` on this drive):", ""]
    for target in comparison.targets():
        verdict = {True: "met", False: "MISSED", None: "not measured"}[target.met]
        lines.append(
            f"- {target.name_text}: {target.target_text}: {target.value_text}: **{verdict}** "
            f"({target.why_text})."
        )
    return lines
