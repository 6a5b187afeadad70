"""Study: on a realistic drive. selftune against the industrial recipe and nominal designs.

**The drive.** :class:`~selftune.sim.RealisticDrive` with
:meth:`~selftune.sim.DriveSettings.hardware_like` at 10 kHz (one-sample computation delay,
carrier PWM, 2 V dead time, 10 mA noise, 12-bit ADC over +-50 A, 540 V bus), the motor
:data:`TEMPERATURE_RISE` = 40 K above its nameplate temperature (R_s +15.6%, phi_pm -4%).

**The motors** (:func:`~._drive_designs.drive_cases`): drawn by a seeded generator from
plausible ranges (:func:`~._drive_designs.motor_ranges`: L_s 1.5-12 mH, L_s/R_s 3-15 ms,
back-EMF 40-120 V, i_q* 3-12 A, 2-5 pole pairs), the first at 1,000-1,500 rad/s
electrical, none of them a motor of the tests. Each is built within
:data:`~._drive_designs.TOLERANCES` of its nameplate (R_s and L_s +-10%, phi_pm +-5%,
uniform), then heated by the drive: the true motor differs from the nameplate by both.

**The cost** (the same for every controller): the digital servo cost
``sum_k h (xbar' Q xbar + ubar' R ubar + z' Q_i z)`` with ``R = I``, ``Q = (w_t L_s)^2 I``
from the nameplate's L_s and ``w_t = 2 pi f_s / 20`` (the bandwidth the engineer asks for:
for a large Q the optimal gain is about ``sqrt(q)`` V/A, so the loop's bandwidth is about
``w_t``), and the learner's default integral weight ``Q_i`` (:class:`~selftune.learn.
LearningProblem`). The settings are exactly ``selftune tune``'s for a MOTOR.toml with this
``[drive]`` table and ``[learning] integral_action = true`` (:func:`~selftune.tuning.
tuning_settings`): digital target, integral action, dead time modelled, the torque
reference stepping through +-T*, a 0.1 s batch, K0 = 1.25% of the nameplate's L_s/h,
exploration 2% of V_dc.

**What every controller knows**: p, the speed, T*, Q and R, h and the one-sample delay,
and the flux at the operating temperature (measured, the premise of the known-flux
algorithms); every learned controller learns from the SAME 0.1 s batch (the off-policy
run's, kept by :class:`~._drive_designs.RecordingDrive`). The controllers:

- ``selftune``: off-policy self-tuning (:func:`~selftune.tuning.offpolicy`), the digital
  servo controller learned by ADP from the batch;
- ``identify``: identify-then-design from the same batch (:func:`~selftune.learn.
  learn_controller`, ``method = "identify"``, the same options);
- ``industrial_pi``: the industrial recipe. R_s and L_s identified from the same batch
  (the structured output-error fit, :class:`~selftune.learn.SpmsmStructure`, with the dead
  time); a PI with decoupling (:func:`~._drive_designs.pi_law`): ``k_p = w_c L``,
  ``k_i = w_c R``, ``u_d += -w_e L i_q``, ``u_q += w_e L i_d + w_e phi`` (measured currents;
  the back-EMF fed forward from the known flux); as a :class:`~selftune.core.ControlLaw`
  on ``[x_k; u_(k-1)]`` with ``e = i - i*``: ``K = [[k_p, w_e L, 0, 0], [-w_e L, k_p, 0,
  0]]``, ``K_i = k_i I``, ``X = -F`` (``X w = i* = [0, 2 T* / (3 p phi)]``) and the
  feedforward ``U = [[0, -w_e L 2 / (3 p phi)], [1, 0]]`` on ``w = [w_e phi, T*]``, i.e.
  ``U w = [-w_e L i_q*, w_e phi]``. **The same bandwidth**: the bandwidth of
  a loop is the -3 dB frequency of its q current's response to its reference on the
  sampled model with the delay (:func:`~._drive_designs.current_bandwidth`); ``w_c`` is
  chosen (:func:`~._drive_designs.matched_pi`) so that the PI's loop on the identified
  model has the bandwidth selftune's controller has on that model. (Setting ``w_c`` to
  that number instead makes the PI's loop about 2.5 times faster: the one-and-a-half
  samples of delay give it a resonance.)
- ``nominal_optimum``: the digital servo optimum (:func:`~selftune.model.
  solve_digital_regulation`) of the NAMEPLATE R_s, L_s with the known flux; no data;
- ``nominal_pi``: the PI recipe with the nameplate R_s, L_s and the known flux, as fast as
  the nominal optimum on the nameplate model; no data;
- ``nominal_nameplate_flux``: the nominal optimum with the nameplate flux too (a wrong
  flux: tolerance and temperature);
- ``algorithm3``: Algorithm 3 (:func:`~selftune.tuning.algorithm3`), told the nameplate
  flux as a guess only: it identifies the flux from its own 0.2 s step, then learns from
  its own 0.1 s batch;
- ``optimum``: the digital servo optimum of the true motor on the true sampled loop (the
  model, evaluation only).

**Metrics** (evaluation only: the true motor is used for these and for the optimum):
the steady torque error at T* on the simulated drive (:func:`~selftune.report.
steady_torque_error`), at the tuning conditions and after R_s rises by
:data:`~selftune.report.HOT_RESISTANCE` without re-tuning; the excess digital cost of the
controller's feedback over the optimum of the same sampled loop (true motor, delay,
stationary hold, integral weight; :func:`~selftune.report.feedback_excess_cost`), the
torque step from rest (of the feedback ``[K, K_i]`` only: the feedforward's error moves
the integrator's steady state, not the cost of the transient); the -3 dB bandwidth on the
true loop; data used, s; wall time to learn, s (the drive's simulation excluded). Ranges
are min..max over motors and seeds.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from ..config import MotorConfig
from ..core import Array, ControlLaw
from ..errors import SelftuneError
from ..learn import (
    LearningOptions,
    LearningProblem,
    SpmsmStructure,
    Trajectory,
    fit_output_error,
    gather_evidence,
)
from ..loop import SampledLoop
from ..model import SPMSM, ModelBasedSolution, solve_digital_regulation
from ..report import HOT_RESISTANCE, drive_text, feedback_excess_cost, steady_torque_error
from ..sim import DriveSettings, RealisticDrive
from ..tuning import TuningSettings, algorithm3, known_flux_form, offpolicy, tuning_settings
from ._common import progress_bar
from ._drive_designs import (
    HOLD,
    TOLERANCES,
    DriveCase,
    RecordingDrive,
    current_bandwidth,
    drive_cases,
    matched_pi,
)
from ._experiment import Refused, attempt
from ._realistic_results import (
    REALISTIC_CONTROLLERS,
    DriveControllerOutcome,
    DriveMotorOutcome,
    DriveSeedRun,
    RealisticDriveComparison,
    markdown_realistic_drive,
)

__all__ = [
    "DC_VOLTAGE",
    "REALISTIC_CONTROLLERS",
    "SAMPLING_SECONDS",
    "TEMPERATURE_RISE",
    "DriveControllerOutcome",
    "DriveMotorOutcome",
    "DriveSeedRun",
    "RealisticDriveComparison",
    "markdown_realistic_drive",
    "measure_realistic_drive",
]

#: The drive's sampling (and switching) period, s: 10 kHz.
SAMPLING_SECONDS = 1e-4
#: DC-bus voltage, V.
DC_VOLTAGE = 540.0
#: Winding and magnet temperature above the nameplate's while tuning, K.
TEMPERATURE_RISE = 40.0
#: The bandwidth the cost asks for, ``w_t = 2 pi f_s / BANDWIDTH_DIVISOR``.
BANDWIDTH_DIVISOR = 20
#: Motors and exploration seeds of the full run and of the quick one.
FULL_SIZES = (3, (0, 1, 2, 3, 4))
QUICK_SIZES = (1, (0, 1))


@dataclass(frozen=True)
class _Truth:
    """The true motor while tuning and the optimum of its sampled loop (evaluation only)."""

    motor: SPMSM
    plant: tuple[Array, Array]
    w: Array
    optimum: ModelBasedSolution


@dataclass(frozen=True)
class _Candidate:
    """A controller as made: its law and ``w``, or why it could not be made."""

    law: ControlLaw | None
    w: Array | None
    data_seconds: float
    learn_seconds: float
    failure_text: str = ""


def _failed(error: SelftuneError, data_seconds: float = 0.0) -> _Candidate:
    text = f"{type(error).__name__}: {error}"
    return _Candidate(
        None, None, data_seconds, 0.0, text if len(text) <= 300 else text[:297] + "..."
    )


def _optimum(model: SPMSM, settings: TuningSettings, Q_i: Array | None) -> ModelBasedSolution:
    """The digital servo optimum of ``model`` on the drive's loop (delay, hold, Q_i)."""
    speed, h = settings.speed, settings.h
    return solve_digital_regulation(
        model.regulation_problem(speed), settings.Q, settings.R, h, input_delay=1,
        integral_weight=Q_i, plant=model.sampled_plant(speed, h, HOLD),
    )  # fmt: skip


def _plant(model: SPMSM, settings: TuningSettings) -> tuple[Array, Array]:
    Ad, Bd, _ = model.sampled_plant(settings.speed, settings.h, HOLD)
    return Ad, Bd


def _timed(make: Callable[[], ControlLaw]) -> tuple[ControlLaw, float]:
    started = time.perf_counter()
    law = make()
    return law, time.perf_counter() - started


class _Study:
    """One motor: its settings, its truth and the designs that need no data."""

    def __init__(self, case: DriveCase, drive: DriveSettings) -> None:
        self.case, self.drive = case, drive
        h = SAMPLING_SECONDS
        q = (2.0 * math.pi / (h * BANDWIDTH_DIVISOR) * case.nameplate.L_s) ** 2
        self.config = MotorConfig(
            motor=case.nameplate, speed=case.speed, torque=case.torque, Q=q * np.eye(2),
            R=np.eye(2), learning={"integral_action": True}, source=case.name_text,
            drive=drive, drive_h=h,
        )  # fmt: skip
        settings = tuning_settings(self.config)
        true = self.simulated().true_motor
        self.known_flux = true.phi_pm
        C, _, F, self.w = known_flux_form(case.nameplate.p, case.speed, case.torque, true.phi_pm)
        self.problem = LearningProblem(
            settings.Q, settings.R, C=C, F=F, integral_action=settings.integral_action,
            integral_weight=settings.Q_i,
        )  # fmt: skip
        self.K0 = settings.K0
        Q_i = self.problem.integral_weight
        started = time.perf_counter()
        self.truth = _Truth(true, _plant(true, settings), self.w, _optimum(true, settings, Q_i))
        self.optimum_seconds = time.perf_counter() - started
        self.nominal_w_c: float | None = None
        self.designs = self._designs(settings, Q_i)

    def _designs(self, settings: TuningSettings, Q_i: Array | None) -> dict[str, _Candidate]:
        """The controllers made without data: from the nameplate, or from the truth."""
        case, h = self.case, SAMPLING_SECONDS
        nameplate = case.nameplate
        known = replace(nameplate, phi_pm=self.known_flux)
        started = time.perf_counter()
        nominal = _optimum(known, settings, Q_i).law
        nominal_seconds = time.perf_counter() - started
        plant = _plant(known, settings)
        target = current_bandwidth(plant, nominal, h)
        matched = None if target is None else matched_pi(
            plant, nameplate.R_s, nameplate.L_s, target, case, self.known_flux, h
        )  # fmt: skip
        pi = _Candidate(None, None, 0.0, 0.0, "no PI reaches the nominal optimum's bandwidth")
        if matched is not None:
            law, self.nominal_w_c = matched
            pi = _Candidate(law, self.w, 0.0, time.perf_counter() - started)
        wrong_flux, wrong_seconds = _timed(lambda: _optimum(nameplate, settings, Q_i).law)
        return {
            "nominal_optimum": _Candidate(nominal, self.w, 0.0, nominal_seconds),
            "nominal_pi": pi,
            "nominal_nameplate_flux": _Candidate(
                wrong_flux, nameplate.exogenous(case.speed, case.torque), 0.0, wrong_seconds
            ),
            "optimum": _Candidate(self.truth.optimum.law, self.w, 0.0, self.optimum_seconds),
        }

    def simulated(self) -> RealisticDrive:
        """The simulated drive with the motor as built."""
        return RealisticDrive(self.case.as_built, self.case.speed, SAMPLING_SECONDS, self.drive)

    def options(self, settings: TuningSettings) -> LearningOptions:
        """Identify-then-design with the options the off-policy session learns with."""
        drive = self.drive
        return LearningOptions(
            target="digital", method="identify", input_delay=drive.input_delay,
            logged_input=drive.logged_input, interval=settings.regression_interval(),
            max_iterations=max(settings.max_iterations, 50), dead_time=settings.dead_time,
            electrical_speed=self.case.nameplate.p * self.case.speed,
            voltage_hold=drive.voltage_hold,
        )  # fmt: skip

    def outcome(self, candidate: _Candidate, seed: int) -> DriveControllerOutcome:
        """The controller on the true loop and on the simulated drive (evaluation only)."""
        law, w = candidate.law, candidate.w
        if law is None or w is None:
            return DriveControllerOutcome(
                None, None, None, None, candidate.data_seconds, candidate.learn_seconds,
                candidate.failure_text,
            )  # fmt: skip
        truth, case = self.truth, self.case
        loop = SampledLoop.of_law(law, SAMPLING_SECONDS)
        stable = loop.spectral_radius(truth.plant, law) < 1.0
        torque: list[float | None] = [None, None]
        if stable:
            torque = [
                100.0 * steady_torque_error(
                    case.as_built, case.speed, SAMPLING_SECONDS, law, w, settings=self.drive,
                    resistance_factor=factor, seed=seed,
                )
                for factor in (1.0, HOT_RESISTANCE)
            ]  # fmt: skip
        return DriveControllerOutcome(
            torque_error_percent=torque[0],
            hot_torque_error_percent=torque[1],
            excess_cost_percent=100.0 * feedback_excess_cost(truth.optimum, law, truth.w),
            bandwidth_rad_per_second=current_bandwidth(truth.plant, law, SAMPLING_SECONDS),
            data_seconds=candidate.data_seconds,
            learn_seconds=candidate.learn_seconds,
        )

    def run(self, seed: int) -> DriveSeedRun:
        """Every controller for one exploration seed."""
        settings = tuning_settings(self.config, seed=seed)
        recorder = RecordingDrive(self.simulated())
        started = time.perf_counter()
        try:
            tuned = offpolicy(recorder, settings, self.known_flux)
            selftune = _Candidate(
                tuned.law, tuned.w, tuned.data_seconds,
                time.perf_counter() - started - recorder.drive_seconds,
            )  # fmt: skip
        except SelftuneError as error:
            selftune = _failed(error, settings.episode_length)
        batch = recorder.logs[0]
        options = self.options(settings)
        tried = attempt(batch, (self.problem, self.K0), options)
        if isinstance(tried, Refused):
            identify = _failed(tried.error, batch.duration)
        else:
            identify = _Candidate(tried.controller.law, self.w, batch.duration, tried.seconds)
        industrial, fitted = self._industrial(batch, options, selftune, settings)
        flux, phi_error, step = self._algorithm3(settings)
        candidates = {
            **self.designs, "selftune": selftune, "identify": identify,
            "industrial_pi": industrial, "algorithm3": flux,
        }  # fmt: skip
        outcomes = {name: self.outcome(candidates[name], seed) for name in REALISTIC_CONTROLLERS}
        return DriveSeedRun(
            **outcomes,
            fitted_R_s_relative_error=fitted[0],
            fitted_L_s_relative_error=fitted[1],
            industrial_w_c_rad_per_second=fitted[2],
            phi_pm_relative_error=phi_error,
            flux_step_seconds=step,
        )

    def _industrial(
        self, batch: Trajectory, options: LearningOptions, selftune: _Candidate,
        settings: TuningSettings,
    ) -> tuple[_Candidate, tuple[float | None, float | None, float | None]]:  # fmt: skip
        """R_s and L_s fitted from the batch; the PI as fast as selftune on that model.

        The structured output-error fit (R_s, L_s, flux ratio, dead-time voltage) starts
        from the batch's evidence; it is not put to the consistency test (the recipe takes
        R_s and L_s whatever the fit's residuals say).
        """
        seconds, h = settings.episode_length, SAMPLING_SECONDS
        none: tuple[float | None, float | None, float | None] = (None, None, None)
        started = time.perf_counter()
        try:
            evidence = gather_evidence([batch], self.problem, options)
            structure = SpmsmStructure(
                self.case.nameplate.p * self.case.speed, h, options.dead_time,
                options.voltage_hold,
            )  # fmt: skip
            fit = fit_output_error(
                evidence.episodes, evidence.alignment.shift, evidence.alignment.model, structure
            )
        except SelftuneError as error:
            return _failed(error, seconds), none
        if fit is None:
            return _Candidate(None, None, seconds, 0.0, "the fitted plant is unstable"), none
        resistance, inductance = (float(value) for value in fit.parameters[:2])
        true = self.truth.motor
        errors = (resistance / true.R_s - 1.0, inductance / true.L_s - 1.0)
        model = (fit.model.Ad, fit.model.Bd)
        target = None if selftune.law is None else current_bandwidth(model, selftune.law, h)
        matched = None if target is None else matched_pi(
            model, resistance, inductance, target, self.case, self.known_flux, h
        )  # fmt: skip
        if matched is None:
            reason = "no bandwidth of selftune's controller on the identified model to match"
            return _Candidate(None, None, seconds, 0.0, reason), (*errors, None)
        law, w_c = matched
        made = _Candidate(law, self.w, seconds, time.perf_counter() - started)
        return made, (*errors, w_c)

    def _algorithm3(
        self, settings: TuningSettings
    ) -> tuple[_Candidate, float | None, float | None]:
        """Algorithm 3 from the nameplate flux as a guess, on its own data."""
        recorder = RecordingDrive(self.simulated())
        started = time.perf_counter()
        try:
            result = algorithm3(recorder, settings, self.case.nameplate.phi_pm)
        except SelftuneError as error:
            return _failed(error, settings.flux_length + settings.episode_length), None, None
        seconds = time.perf_counter() - started - recorder.drive_seconds
        candidate = _Candidate(result.law, result.w, result.data_seconds, seconds)
        phi_error = result.identified["phi_pm"] / self.known_flux - 1.0
        return candidate, phi_error, recorder.logs[0].duration


def _motor_outcome(study: _Study, runs: tuple[DriveSeedRun, ...]) -> DriveMotorOutcome:
    case, true = study.case, study.truth.motor
    return DriveMotorOutcome(
        name_text=case.name_text,
        pole_pairs_count=case.nameplate.p,
        nameplate_R_s_ohm=case.nameplate.R_s,
        nameplate_L_s_henry=case.nameplate.L_s,
        nameplate_phi_pm_weber=case.nameplate.phi_pm,
        true_R_s_ohm=true.R_s,
        true_L_s_henry=true.L_s,
        true_phi_pm_weber=true.phi_pm,
        speed_rad_per_second=case.speed,
        electrical_speed_rad_per_second=case.nameplate.p * case.speed,
        torque_newton_meters=case.torque,
        Q_diagonal_volt2_per_ampere2=float(study.config.Q[0, 0]),
        nominal_pi_w_c_rad_per_second=study.nominal_w_c,
        runs=runs,
    )


def measure_realistic_drive(
    quick: bool = False, progress: bool = False
) -> RealisticDriveComparison:
    """Run the study (see the module docstring).

    Parameters
    ----------
    quick : bool
        One motor (the fast one) and two seeds, for the tests (under 10 s), instead of three
        motors and five seeds (about 70 s on 2 cores with one BLAS thread).
    progress : bool
        Show a progress bar on stderr (only when it is a terminal).

    Returns
    -------
    RealisticDriveComparison
    """
    started = time.perf_counter()
    count, seeds = QUICK_SIZES if quick else FULL_SIZES
    drive = replace(
        DriveSettings.hardware_like(DC_VOLTAGE, SAMPLING_SECONDS), temperature_rise=TEMPERATURE_RISE
    )
    motors = []
    with progress_bar(count * len(seeds), "realistic drive", progress) as bar:
        for case in drive_cases(count, DC_VOLTAGE):
            study = _Study(case, drive)
            runs = []
            for seed in seeds:
                runs.append(study.run(seed))
                bar.update(1)
            motors.append(_motor_outcome(study, tuple(runs)))
    return RealisticDriveComparison(
        quick=quick,
        drive_text=drive_text(drive),
        sampling_seconds=SAMPLING_SECONDS,
        bandwidth_target_rad_per_second=2.0 * math.pi / (SAMPLING_SECONDS * BANDWIDTH_DIVISOR),
        hot_resistance_factor=HOT_RESISTANCE,
        tolerance_R_s_relative=TOLERANCES[0],
        tolerance_L_s_relative=TOLERANCES[1],
        tolerance_phi_pm_relative=TOLERANCES[2],
        seeds=seeds,
        motors=tuple(motors),
        wall_seconds=time.perf_counter() - started,
    )
