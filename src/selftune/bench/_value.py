"""Study 4: the value of self-tuning: designs on 30%-wrong parameters against self-tuned."""

from __future__ import annotations

import dataclasses
import itertools
import math
import time
from dataclasses import dataclass

import numpy as np
import scipy
import scipy.linalg

from ..core import (
    Array,
)
from ..model import SPMSM, ModelBasedSolution
from ..tuning import TuningResult, TuningSettings, run_algorithm
from ._common import (
    CONTROLLER_TITLES,
    CONTROLLERS,
    COST_HORIZON_SECONDS,
    MISMATCH,
    BenchConfig,
    model_optimum,
    relative,
    table,
    with_progress,
)


@dataclass(frozen=True)
class ControllerOutcome:
    """One controller's torque step on one motor.

    Attributes
    ----------
    cost_volt2_seconds : float
        The cost (5) of the step over the horizon, V^2 s (Q in V^2/A^2, R dimensionless).
    excess_cost_percent : float
        ``100 (cost / cost of the true optimum - 1)``, %.
    steady_torque_error_newton_meters : float
        Steady-state torque minus T* (t -> infinity), N m.
    steady_torque_error_percent : float
        The same relative to T*, %.
    """

    cost_volt2_seconds: float
    excess_cost_percent: float
    steady_torque_error_newton_meters: float
    steady_torque_error_percent: float


@dataclass(frozen=True)
class MismatchCase:
    """One true motor (R_s, L_s, phi_pm each 30% above or below nominal) and the controllers.

    Attributes
    ----------
    R_s_factor, L_s_factor, phi_pm_factor : float
        True value over nominal (0.7 or 1.3), dimensionless.
    R_s_ohm, L_s_henry, phi_pm_weber : float
        The true values, ohm, H, Wb.
    lqr_nominal, lqr_true_flux, pi_nominal, pi_true_flux : ControllerOutcome
        The nominal designs (see :class:`SelfTuningValue`).
    self_tuned, self_tuned_unknown_flux, optimum : ControllerOutcome
        The self-tuned controllers and the true optimum.
    self_tuned_data_seconds : float
        Motor data the off-policy self-tuning used, s.
    self_tuned_K_relative_error, self_tuned_U_relative_error : float
        Its ``||K - K*||/||K*||`` and ``||U - U*||/||U*||`` against the true optimum.
    unknown_flux_data_seconds : float
        Motor data Algorithm 3 used, s.
    unknown_flux_phi_pm_relative_error : float
        ``|identified phi_pm / true phi_pm - 1|``.
    """

    R_s_factor: float
    L_s_factor: float
    phi_pm_factor: float
    R_s_ohm: float
    L_s_henry: float
    phi_pm_weber: float
    lqr_nominal: ControllerOutcome
    lqr_true_flux: ControllerOutcome
    pi_nominal: ControllerOutcome
    pi_true_flux: ControllerOutcome
    self_tuned: ControllerOutcome
    self_tuned_unknown_flux: ControllerOutcome
    optimum: ControllerOutcome
    self_tuned_data_seconds: float
    self_tuned_K_relative_error: float
    self_tuned_U_relative_error: float
    unknown_flux_data_seconds: float
    unknown_flux_phi_pm_relative_error: float


@dataclass(frozen=True)
class SelfTuningValue:
    """Torque-step cost and torque error on mismatched motors, four kinds of controller.

    The engineer knows the nominal (paper's) motor; the true motor has each of R_s, L_s,
    phi_pm 30% above or below (8 cases). Controllers, all acting in continuous time:
    (a) ``lqr_nominal``: the optimal ``u = -K (x - X w) + U w`` of the nominal model, with
    the nominal flux in ``w`` and ``X``; (a') ``lqr_true_flux``: the same design with the
    true flux (measured) and the nominal R_s, L_s; (b) ``pi_nominal``: a PI current
    controller on each axis, ``u = k_p (i* - i) + k_i int (i* - i)``, ``k_p = alpha_c L_s``,
    ``k_i = alpha_c R_s`` (nominal values; no decoupling), ``i*`` from the nominal flux;
    (b') ``pi_true_flux``: the same PI with ``i*`` from the true flux; (c) ``self_tuned``: the
    off-policy self-tuning run on the true motor from ``K0`` = the nominal LQR gain, with
    the flux known (measured, the premise of the paper's known-flux algorithms);
    (c') ``self_tuned_unknown_flux``: Algorithm 3 (flux identified at no load, on-policy)
    from the same ``K0``; (d) ``optimum``: the model-based optimum of the true motor.

    Attributes
    ----------
    horizon_seconds : float
        Horizon of the cost, s.
    speed_rad_per_second : float
        Held mechanical speed, rad/s.
    torque_reference_newton_meters : float
        T*, N m (the step is 0 -> T* at t = 0).
    mismatch_relative : float
        Relative parameter error (0.3).
    Q_diagonal_volt2_per_ampere2 : float
        ``Q = q I``, V^2/A^2.
    R_diagonal_relative : float
        ``R = r I``, dimensionless.
    pi_bandwidth_rad_per_second : float
        alpha_c: the bandwidth of the nominal LQR loop, ``-max Re eig(A - B K*)``.
    cases : tuple of MismatchCase
    wall_seconds : float
        Time this comparison took, s.
    """

    horizon_seconds: float
    speed_rad_per_second: float
    torque_reference_newton_meters: float
    mismatch_relative: float
    Q_diagonal_volt2_per_ampere2: float
    R_diagonal_relative: float
    pi_bandwidth_rad_per_second: float
    cases: tuple[MismatchCase, ...]
    wall_seconds: float

    def worst_excess_cost_percent(self, controller: str) -> float:
        """Largest excess cost of ``controller`` over the cases, %.

        Parameters
        ----------
        controller : str
            A :class:`ControllerOutcome` field of :class:`MismatchCase`, e.g. ``"lqr_nominal"``.
        """
        return max(getattr(case, controller).excess_cost_percent for case in self.cases)

    def worst_torque_error_percent(self, controller: str) -> float:
        """Largest ``|steady-state torque error|`` of ``controller`` over the cases, %.

        Parameters
        ----------
        controller : str
            A :class:`ControllerOutcome` field of :class:`MismatchCase`, e.g. ``"lqr_nominal"``.
        """
        return max(
            abs(getattr(case, controller).steady_torque_error_percent) for case in self.cases
        )


def _quadratic_cost(M: Array, W: Array, z0: Array, horizon: float) -> float:
    """``int_0^horizon z' W z dt`` along ``z' = M z``, ``z(0) = z0``, exactly.

    Van Loan's block exponential gives the integral over a piece short enough for the
    exponential of ``-M'`` to stay well conditioned; the pieces are chained by
    ``G(t + d) = G(d) + Phi(d)' G(t) Phi(d)`` with ``Phi(d) = expm(M d)``.
    """
    size = M.shape[0]
    radius = float(np.max(np.abs(np.linalg.eigvals(M))))
    pieces = max(1, math.ceil(horizon * radius))
    piece = horizon / pieces
    block = np.zeros((2 * size, 2 * size))
    block[:size, :size] = -M.T
    block[:size, size:] = W
    block[size:, size:] = M
    exp = scipy.linalg.expm(block * piece)
    Phi = exp[size:, size:]
    G_piece = Phi.T @ exp[:size, size:]
    G = np.zeros((size, size))
    for _ in range(pieces):
        G = G_piece + Phi.T @ G @ Phi
    G = 0.5 * (G + G.T)
    return float(z0 @ G @ z0)


@dataclass(frozen=True)
class _TrueMotor:
    """The true motor's model and optimum at the operating point (for evaluation only)."""

    motor: SPMSM
    A: Array
    B: Array
    D: Array
    w: Array
    x_e: Array
    u_e: Array
    optimum: ModelBasedSolution

    @classmethod
    def of(cls, motor: SPMSM, settings: TuningSettings) -> _TrueMotor:
        problem = motor.regulation_problem(settings.speed)
        optimum = model_optimum(motor, settings)
        x_e, u_e = motor.equilibrium(settings.speed, settings.torque)
        return cls(
            motor=motor,
            A=np.asarray(problem.A),
            B=np.asarray(problem.B),
            D=np.asarray(problem.D),
            w=motor.exogenous(settings.speed, settings.torque),
            x_e=x_e,
            u_e=u_e,
            optimum=optimum,
        )


def _outcome(
    cost: float, steady_current_q: float, true: _TrueMotor, torque: float, optimum_cost: float
) -> ControllerOutcome:
    steady_torque = float(true.motor.torque(steady_current_q))
    return ControllerOutcome(
        cost_volt2_seconds=cost,
        excess_cost_percent=100.0 * (cost / optimum_cost - 1.0),
        steady_torque_error_newton_meters=steady_torque - torque,
        steady_torque_error_percent=100.0 * (steady_torque / torque - 1.0),
    )


def _state_feedback_step(
    true: _TrueMotor, K: Array, L_w: Array, settings: TuningSettings, horizon: float
) -> tuple[float, float]:
    """Cost and steady-state i_q of ``u = -K x + L_w`` (``L_w`` the controller's ``L w``).

    The state ``z = [i_d, i_q, 1]`` with ``z' = M z``; ``e = x - x_e``, ``v = u - u_e``.
    """
    A_cl = true.A - true.B @ K
    forcing = true.B @ L_w + true.D @ true.w
    M = np.zeros((3, 3))
    M[:2, :2] = A_cl
    M[:2, 2] = forcing
    S_e = np.hstack([np.eye(2), -true.x_e[:, None]])
    S_v = np.hstack([-K, (L_w - true.u_e)[:, None]])
    W = S_e.T @ settings.Q @ S_e + S_v.T @ settings.R @ S_v
    z0 = np.array([0.0, 0.0, 1.0])
    steady = np.linalg.solve(A_cl, -forcing)
    return _quadratic_cost(M, W, z0, horizon), float(steady[1])


def _pi_step(
    true: _TrueMotor,
    k_p: float,
    k_i: float,
    current_reference: Array,
    settings: TuningSettings,
    horizon: float,
) -> tuple[float, float]:
    """Cost and steady-state i_q of the PI loop ``u = k_p (i* - i) + k_i xi``, ``xi' = i* - i``.

    State ``z = [i_d, i_q, xi_d, xi_q, 1]``. Before the step the loop rests at zero
    torque: ``i = 0`` and the integrators hold the voltage the motor needs there,
    ``xi(0) = u_e(T* = 0) / k_i``.
    """
    eye = np.eye(2)
    M = np.zeros((5, 5))
    M[:2, :2] = true.A - k_p * true.B
    M[:2, 2:4] = k_i * true.B
    M[:2, 4] = k_p * true.B @ current_reference + true.D @ true.w
    M[2:4, :2] = -eye
    M[2:4, 4] = current_reference
    S_e = np.hstack([eye, np.zeros((2, 2)), -true.x_e[:, None]])
    S_v = np.hstack([-k_p * eye, k_i * eye, (k_p * current_reference - true.u_e)[:, None]])
    W = S_e.T @ settings.Q @ S_e + S_v.T @ settings.R @ S_v
    _, u_rest = true.motor.equilibrium(settings.speed, 0.0)
    z0 = np.concatenate([np.zeros(2), u_rest / k_i, [1.0]])
    # At steady state the integrators force i = i* exactly.
    return _quadratic_cost(M, W, z0, horizon), float(current_reference[1])


def measure_self_tuning_value(config: BenchConfig, progress: bool = False) -> SelfTuningValue:
    """Cost (5) of a torque step and steady-state torque error on 8 mismatched motors.

    The step: at ``t = 0`` the currents are zero (the zero-torque operating point of any
    motor; the PI's integrators hold the zero-torque voltage) and the reference steps from
    0 to T*. The cost is ``int_0^H (e' Q e + v' R v) dt`` with ``e = x - x_e``,
    ``v = u - u_e``, ``(x_e, u_e)`` the TRUE motor's operating point for T*, and
    ``H = COST_HORIZON_SECONDS``; evaluated exactly (augmented LTI, matrix exponential).

    Parameters
    ----------
    config : BenchConfig
        Unused sizes (every case always runs); kept for a uniform signature.
    progress : bool
        Show a progress bar on stderr (only when it is a terminal).

    Returns
    -------
    SelfTuningValue
    """
    del config
    started = time.perf_counter()
    nominal = SPMSM.paper()
    settings = TuningSettings.paper()
    design = _Designs.of(nominal, settings)
    signs = list(itertools.product((-1.0, 1.0), repeat=3))
    cases = with_progress(
        signs, lambda sign: _mismatch_case(design, sign, settings), "self-tuning value", progress
    )
    return SelfTuningValue(
        horizon_seconds=COST_HORIZON_SECONDS,
        speed_rad_per_second=settings.speed,
        torque_reference_newton_meters=settings.torque,
        mismatch_relative=MISMATCH,
        Q_diagonal_volt2_per_ampere2=float(settings.Q[0, 0]),
        R_diagonal_relative=float(settings.R[0, 0]),
        pi_bandwidth_rad_per_second=design.alpha,
        cases=tuple(cases),
        wall_seconds=time.perf_counter() - started,
    )


@dataclass(frozen=True)
class _Designs:
    """What the nominal designs are built from: the nominal motor's LQR and feedforward,
    and the PI gains at the same bandwidth."""

    nominal: SPMSM
    K: Array
    L_w: Array
    alpha: float

    @classmethod
    def of(cls, nominal: SPMSM, settings: TuningSettings) -> _Designs:
        design = _TrueMotor.of(nominal, settings)
        K = np.asarray(design.optimum.K)
        alpha = -float(np.max(np.linalg.eigvals(design.A - design.B @ K).real))
        return cls(nominal, K, np.asarray(design.optimum.L) @ design.w, alpha)

    @property
    def pi_gains(self) -> tuple[float, float]:
        """``(k_p, k_i) = (alpha L_s, alpha R_s)`` of the nominal motor."""
        return self.alpha * self.nominal.L_s, self.alpha * self.nominal.R_s


def _mismatch_case(
    design: _Designs, sign: tuple[float, ...], settings: TuningSettings
) -> MismatchCase:
    """Every controller's torque step on the motor whose R_s, L_s, phi_pm are off by
    ``MISMATCH`` times ``sign``."""
    nominal, horizon = design.nominal, COST_HORIZON_SECONDS
    factors = tuple(1 + MISMATCH * value for value in sign)
    motor = SPMSM(
        R_s=nominal.R_s * factors[0],
        L_s=nominal.L_s * factors[1],
        phi_pm=nominal.phi_pm * factors[2],
        p=nominal.p,
    )
    true = _TrueMotor.of(motor, settings)
    measured_flux = _TrueMotor.of(dataclasses.replace(nominal, phi_pm=motor.phi_pm), settings)
    tuning = dataclasses.replace(settings, K0=design.K)  # self-tuning starts from the design
    tuned = run_algorithm("offpolicy", motor, tuning)
    identified = run_algorithm("3", motor, tuning)
    k_p, k_i = design.pi_gains

    def state_feedback(K: Array, L_w: Array) -> tuple[float, float]:
        return _state_feedback_step(true, K, L_w, settings, horizon)

    def learned(result: TuningResult) -> tuple[float, float]:
        return state_feedback(result.K, (result.U + result.K @ result.X) @ result.w)

    steps = {
        "lqr_nominal": state_feedback(design.K, design.L_w),
        "lqr_true_flux": state_feedback(
            np.asarray(measured_flux.optimum.K),
            np.asarray(measured_flux.optimum.L) @ measured_flux.w,
        ),
        "pi_nominal": _pi_step(
            true, k_p, k_i, nominal.current_reference(settings.torque), settings, horizon
        ),
        "pi_true_flux": _pi_step(
            true, k_p, k_i, motor.current_reference(settings.torque), settings, horizon
        ),
        "self_tuned": learned(tuned),
        "self_tuned_unknown_flux": learned(identified),
        "optimum": state_feedback(np.asarray(true.optimum.K), np.asarray(true.optimum.L) @ true.w),
    }
    optimum_cost = steps["optimum"][0]
    outcomes = {
        name: _outcome(cost, i_q, true, settings.torque, optimum_cost)
        for name, (cost, i_q) in steps.items()
    }
    return MismatchCase(
        R_s_factor=factors[0],
        L_s_factor=factors[1],
        phi_pm_factor=factors[2],
        R_s_ohm=motor.R_s,
        L_s_henry=motor.L_s,
        phi_pm_weber=motor.phi_pm,
        **outcomes,
        self_tuned_data_seconds=tuned.data_seconds,
        self_tuned_K_relative_error=relative(tuned.K, true.optimum.K),
        self_tuned_U_relative_error=relative(tuned.U, true.optimum.U),
        unknown_flux_data_seconds=identified.data_seconds,
        unknown_flux_phi_pm_relative_error=abs(
            identified.identified["phi_pm"] / motor.phi_pm - 1.0
        ),
    )


def markdown_value(value: SelfTuningValue) -> list[str]:
    """Section 4 of bench.md: each controller's cost and torque error on each motor."""
    lines = [
        "## 4. The value of self-tuning (R_s, L_s, phi_pm each 30% off nominal)",
        "",
        f"Torque step 0 -> {value.torque_reference_newton_meters:g} N m at "
        f"{value.speed_rad_per_second:g} rad/s. At t = 0 the currents are zero (the PI's "
        "integrators hold the zero-torque voltage). Cost (5) = int_0^H (e'Qe + v'Rv) dt with "
        f"H = {value.horizon_seconds * 1e3:g} ms, e = x - x_e, v = u - u_e, (x_e, u_e) the "
        f"TRUE motor's operating point, Q = {value.Q_diagonal_volt2_per_ampere2:g} I, "
        f"R = {value.R_diagonal_relative:g} I; in V^2 s, computed exactly (augmented LTI, "
        "matrix exponential), controllers in continuous time. Steady-state torque error at "
        "t -> infinity. Controllers: (a) LQR + feedforward of the nominal model (nominal "
        "R_s, L_s, phi_pm); (a') the same design with the true flux (measured at no load) "
        "and the nominal R_s, L_s; (b) PI per axis, k_p = alpha_c L_s, k_i = alpha_c R_s "
        f"(nominal), alpha_c = {value.pi_bandwidth_rad_per_second:.1f} rad/s = the nominal LQR "
        "loop's bandwidth -max Re eig(A - B K*), no decoupling, i* from the nominal flux; "
        "(b') the same PI with i* from the true flux; (c) off-policy self-tuning on the true "
        "motor (one 5 ms batch, flux known as in (a')) from K0 = the nominal LQR gain; "
        "(c') Algorithm 3 from the same K0, flux identified at no load (on-policy); (d) the "
        "true optimum.",
        "",
    ]
    return lines + _markdown_cases(value)


def _markdown_cases(value: SelfTuningValue) -> list[str]:
    """The cost and torque-error tables, and the worst case of each controller."""
    lines: list[str] = []
    header = ["R_s, L_s, phi_pm", *(CONTROLLER_TITLES[name] for name in CONTROLLERS)]
    cost_rows = []
    torque_rows = []
    for case in value.cases:
        label = ", ".join(
            f"{factor - 1:+.0%}"
            for factor in (case.R_s_factor, case.L_s_factor, case.phi_pm_factor)
        )
        outcomes = [getattr(case, name) for name in CONTROLLERS]
        cost_rows.append(
            [label]
            + [
                f"{o.cost_volt2_seconds:.4g} ({o.excess_cost_percent:+.3g}%)"
                if name != "optimum"
                else f"{o.cost_volt2_seconds:.4g}"
                for name, o in zip(CONTROLLERS, outcomes, strict=True)
            ]
        )
        torque_rows.append(
            [label]
            + [
                f"{o.steady_torque_error_newton_meters:+.3g} "
                f"({o.steady_torque_error_percent:+.3g}%)"
                for o in outcomes
            ]
        )
    lines += ["Cost (V^2 s), and excess over the true optimum:", ""]
    lines += table(header, cost_rows)
    lines += ["", "Steady-state torque error, N m (% of T*):", ""]
    lines += table(header, torque_rows)
    lines += [
        "",
        "Worst case over the 8 motors: "
        + "; ".join(
            f"{CONTROLLER_TITLES[name]}: excess cost {value.worst_excess_cost_percent(name):.3g}%,"
            f" |torque error| {value.worst_torque_error_percent(name):.3g}%"
            for name in CONTROLLERS[:-1]
        )
        + ".",
    ]
    return lines
