"""The verdict on a learned controller: how good it is, and whether the data support it.

Every :class:`~selftune.learn.LearnedController` carries a :class:`Quality`:

- the alignment used and how clearly the data showed it; the measurement noise estimated
  from the output errors; the consistency test of the model against the data;
- standard errors of K, U and P. The parameters of the output-error model have a
  covariance (the inverse Fisher information under the estimated noise); the controller
  is a smooth function of them (the design of the target on that model), so its
  covariance follows by the delta method, with a numerical Jacobian. For the paper's
  continuous ADP, whose quadrature leaves an O(h^2) error that no noise explains, the
  difference to the continuous optimum of the same model is added in quadrature
  (``floor``). These errors are what the data support, and they are calibrated
  (tests/test_quality.py checks the coverage on motors not in the tests);
- the stability margin of the learned loop on the fitted model, with the delay, and on
  models drawn from the parameters' uncertainty.

:func:`check_safety` refuses a controller the data do not support: one that does not
stabilize every plausible model with a margin, whose standard errors exceed the
tolerance (too little data for the noise: it says how much would do), or whose policy
iteration did not lower the value step by step as theory says it must.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ...core import RANK_TOLERANCE, Array, ControlLaw
from ...errors import NotStabilizing, PolicyIterationFailure, TooLittleData
from ...loop import SampledLoop
from ..evidence._discrete_model import DiscreteModel
from ..evidence._evidence import INFLATION_LIMIT, Evidence
from ..learners._policy_iteration import IterationRecord

__all__ = [
    "SERVO_FEEDFORWARD_LIMIT",
    "STABILITY_MARGIN",
    "BlockErrors",
    "MotorEstimate",
    "Quality",
    "block_errors",
    "check_precision",
    "check_safety",
    "closed_loop_radii",
    "closed_loop_radius",
    "largest_radius",
    "relative_size",
    "standard_errors",
]

#: The least stability margin ``1 - spectral radius`` of the learned sampled loop on
#: every plausible model, per sample; a loop whose optimum is itself slower (a slow plant
#: sampled fast) needs only :data:`OPTIMUM_MARGIN_FRACTION` of the optimum's own margin.
STABILITY_MARGIN = 1e-4

#: The fraction of the optimum's own margin the learned loop must keep when that margin is
#: below :data:`STABILITY_MARGIN` (see :func:`largest_radius`).
OPTIMUM_MARGIN_FRACTION = 0.5

#: Models drawn from the parameters' uncertainty on which the learned loop must be stable.
PLAUSIBLE_MODELS = 24

Design = Callable[[DiscreteModel], tuple[Array, Array, Array]]


@dataclass(frozen=True)
class BlockErrors:
    """Relative standard errors by block: each ``||se|| / ||value||`` over the block.

    Attributes
    ----------
    K : float
        Of K, the feedback of the currents and the delayed voltages: what sets the fast
        dynamics (the headline and the ``max_relative_error`` gate).
    K_i : float or None
        Of the integral gain (None without integral action): reported apart, as its
        entries are often two orders of magnitude larger than K's.
    U : float
        Of the feedforward U (0 without a reference).
    """

    K: float
    K_i: float | None
    U: float


def block_errors(
    gain: tuple[Array, Array], feedforward: tuple[Array, Array], width: int
) -> BlockErrors:
    """The relative standard errors of ``[K, K_i]`` split after ``width`` columns, and of U.

    Parameters
    ----------
    gain : (ndarray, ndarray)
        Standard errors of ``[K, K_i]`` and its value.
    feedforward : (ndarray, ndarray)
        Standard errors of U and its value.
    width : int
        The columns of K (the rest are K_i's).
    """
    (gain_se, K), (U_se, U) = gain, feedforward
    K_i = None
    if K.shape[1] > width:
        K_i = relative_size(gain_se[:, width:], K[:, width:])
    return BlockErrors(relative_size(gain_se[:, :width], K[:, :width]), K_i, relative_size(U_se, U))


def relative_size(se: Array, value: Array) -> float:
    size = float(np.linalg.norm(value))
    ratio = float(np.linalg.norm(se)) / size if size > 0 else 0.0
    return ratio if np.isfinite(ratio) else 0.0


@dataclass(frozen=True)
class MotorEstimate:
    """A PMSM's parameters identified by the structured fit (``structure = "spmsm"`` or
    ``"ipmsm"``), with their standard errors (the fit's covariance: the inverse Fisher
    information under the estimated noise, robust to correlated output errors).

    Attributes
    ----------
    R_s, R_s_se : float
        The stator resistance and its standard error, ohm.
    L_s, L_s_se : float or None
        A surface motor's inductance and its standard error, H (None: an interior one).
    phi_pm, phi_pm_se : float
        The magnet's flux linkage and its standard error, Wb: ``kappa w_1 / w_e``, the
        back-EMF ratio times the flux the log's first reference channel assumes.
    v, v_se : float or None
        The inverter's dead-time voltage per phase and its standard error, V; None
        unless the dead time is modelled.
    L_d, L_d_se, L_q, L_q_se : float or None
        An interior motor's inductances and their standard errors, H (``structure =
        "ipmsm"``; None for a surface one); with ``structure = "incremental"`` the
        incremental ``L_dd`` and ``L_qq`` at the operating current.
    L_dq, L_dq_se : float or None
        The incremental cross-saturation inductance ``d psi_d / d i_q = d psi_q / d i_d``
        at the operating current and its standard error, H (``structure =
        "incremental"``; else None). ``phi_pm`` is then the offset's d component.
    phi_q, phi_q_se : float or None
        The flux offset's q component ``psi_q(i0) - L_qd i_d0 - L_qq i_q0`` and its
        standard error, Wb (``structure = "incremental"``; else None).
    """

    R_s: float
    R_s_se: float
    L_s: float | None
    L_s_se: float | None
    phi_pm: float
    phi_pm_se: float
    v: float | None = None
    v_se: float | None = None
    L_d: float | None = None
    L_d_se: float | None = None
    L_q: float | None = None
    L_q_se: float | None = None
    L_dq: float | None = None
    L_dq_se: float | None = None
    phi_q: float | None = None
    phi_q_se: float | None = None

    def text(self) -> str:
        """The parameters with their standard errors in one line."""
        parts = [f"R_s = {self.R_s:.6g} +- {self.R_s_se:.2g} ohm"]
        for name in ("L_s", "L_d", "L_q", "L_dq"):
            value, se = getattr(self, name), getattr(self, f"{name}_se")
            if value is not None:
                parts.append(f"{name} = {value:.6g} +- {se:.2g} H")
        parts.append(f"phi_pm = {self.phi_pm:.6g} +- {self.phi_pm_se:.2g} Wb")
        if self.phi_q is not None:
            parts.append(f"phi_q = {self.phi_q:.6g} +- {self.phi_q_se:.2g} Wb")
        return ", ".join(parts)


@dataclass(frozen=True)
class Quality:
    """How good a learned controller is, from the data alone.

    Attributes
    ----------
    shift : int
        The alignment used: the voltage applied during sample k is in row k - shift.
    detected_shift : int
        The shift that explains the data best.
    alignment_ratio : float
        The best other shift's one-step residual over the one used (above 2: clear).
    noise_rms : ndarray or None
        Estimated measurement noise of each state (standard deviation, the state's unit);
        None without an output-error model.
    residual_rms : ndarray
        Root mean square of the model's output (or one-step) errors, per state.
    consistency_statistic : float
        The input-residual cross-correlation statistic.
    consistency_threshold : float
        Its threshold (chi-square at p = 1e-6); the data were refused above it.
    consistency_exact : bool
        The model explains the data to rounding (noise-free data): the test, and every
        test of the output errors, does not apply.
    noise_handling : str
        ``"smoothed"``, ``"instruments"`` or ``"none"`` (see LearningOptions).
    K_se : ndarray
        Standard errors of the entries of ``[K, K_i]`` (columns as the law's ``state``).
    U_se : ndarray
        Standard errors of U's entries.
    P_se : ndarray
        Standard errors of P's entries.
    K_relative_se : float
        ``||K_se|| / ||K||`` over K, the feedback of the currents and the delayed
        voltages (the headline, and what ``max_relative_error`` gates).
    K_i_relative_se : float or None
        ``||K_i_se|| / ||K_i||``, reported apart; None without integral action.
    U_relative_se : float
        ``||U_se|| / ||U||`` (0 without a reference).
    stability_margin : float
        ``1 - spectral radius`` of the learned loop on the fitted model (with the delay).
    voltage_error : float or None
        The inverter's dead-time voltage ``v = t_d f_sw V_dc`` per phase, V (its average
        along the current is ``4 v / pi``); None unless modelled.
    log_precision : str
        The precision the states were logged with (float64, float32, significant digits).
    notes : tuple of str
        What else the user should know.
    motor : MotorEstimate or None
        The motor's parameters, where the method identified them (identify-then-design
        with ``structure = "spmsm"``); None otherwise.
    """

    shift: int
    detected_shift: int
    alignment_ratio: float
    noise_rms: Array | None
    residual_rms: Array
    consistency_statistic: float
    consistency_threshold: float
    consistency_exact: bool
    noise_handling: str
    K_se: Array
    U_se: Array
    P_se: Array
    K_relative_se: float
    K_i_relative_se: float | None
    U_relative_se: float
    stability_margin: float
    voltage_error: float | None
    log_precision: str
    notes: tuple[str, ...]
    motor: MotorEstimate | None = None

    @property
    def relative_se(self) -> BlockErrors:
        """The relative standard errors of K, K_i and U, block by block."""
        return BlockErrors(self.K_relative_se, self.K_i_relative_se, self.U_relative_se)

    def errors_text(self) -> str:
        """The relative standard errors as the verdict states them: ``"K within +-1.66%,
        K_i within +-1.27%, U within +-4.51% (one standard error, relative)"``."""
        integral = ""
        if self.K_i_relative_se is not None:
            integral = f", K_i within +-{_relative(self.K_i_relative_se)}"
        return (
            f"K within +-{_relative(self.K_relative_se)}{integral}, U within "
            f"+-{_relative(self.U_relative_se)} (one standard error, relative)"
        )

    def lines(self) -> list[str]:
        """The verdict as report lines (what the command line prints)."""
        noise = (
            "none estimated"
            if self.noise_rms is None
            else ", ".join(f"{value:.3g}" for value in self.noise_rms)
        )
        consistency = (
            "the model explains the data to rounding (noise-free: no consistency test)"
            if self.consistency_exact
            else f"consistency statistic {self.consistency_statistic:.3g} (refused above "
            f"{self.consistency_threshold:.3g})"
        )
        lines = [
            "quality (from the data alone):",
            f"  {self.errors_text()}",
            f"  measurement noise {noise} (the states' unit); {consistency}",
            f"  log alignment: the voltage applied during sample k is in row k - {self.shift}"
            f" (the data show {self.detected_shift}); stability margin "
            f"{self.stability_margin:.3g}; logged as {self.log_precision}",
        ]
        if self.voltage_error is not None:
            lines.append(f"  inverter dead-time voltage {self.voltage_error:.3g} V per phase")
        if self.motor is not None:
            lines.append(f"  identified motor: {self.motor.text()}")
        return lines + [f"  note: {note}" for note in self.notes]


def _relative(value: float) -> str:
    """A relative error as a percentage, or in scientific notation when tiny."""
    return f"{value:.2%}" if value >= 1e-4 else f"{value:.1e}"


def closed_loop_radius(model: DiscreteModel, law: ControlLaw, delay: int) -> float:
    """Spectral radius of the sampled loop of ``law`` on ``model`` with a delay of d
    samples (integral action included).

    Parameters
    ----------
    model : DiscreteModel
        The plant.
    law : ControlLaw
        The controller (its ``history`` at most ``delay``).
    delay : int
        The drive's computation delay, samples.
    """
    return float(closed_loop_radii([model], law, delay)[0])


def closed_loop_radii(models: Sequence[DiscreteModel], law: ControlLaw, delay: int) -> Array:
    """:func:`closed_loop_radius` on each of several models of one sampling period (the
    plausible models), their eigenvalues in one call.

    Parameters
    ----------
    models : sequence of DiscreteModel
        The plants (the first one's h is the loop's).
    law : ControlLaw
        The controller (its ``history`` at most ``delay``).
    delay : int
        The drive's computation delay, samples.
    """
    loop = SampledLoop.of_law(law, models[0].h, delay)
    return loop.spectral_radii([(model.Ad, model.Bd) for model in models], law)


def standard_errors(
    design: Design,
    matrices: Callable[[Array], tuple[Array, Array, Array]],
    parameters: Array,
    covariance: Array,
    h: float,
) -> tuple[Array, Array, Array]:
    """Standard errors of ``(K, U, P) = design(model(parameters))`` by the delta method.

    Parameters
    ----------
    design : callable
        Maps a model to ``(K, U, P)``.
    matrices : callable
        Maps parameters to ``(Ad, Bd, Ed)``.
    parameters : ndarray, shape (p,)
        The fitted parameters.
    covariance : ndarray, shape (p, p)
        Their covariance.
    h : float
        Sampling period of the model, s.

    Returns
    -------
    K_se, U_se, P_se : ndarray
        Entry by entry.
    """

    def outputs(theta: Array) -> list[Array]:
        Ad, Bd, Ed = matrices(theta)
        model = DiscreteModel.given(Ad, Bd, Ed, h)
        return list(design(model))

    base = outputs(parameters)
    deviations = np.sqrt(np.maximum(np.diag(covariance), 0.0))
    variances = [np.zeros_like(part) for part in base]
    derivatives = []
    for index in range(parameters.shape[0]):
        step = max(deviations[index], 1e-9 * max(abs(float(parameters[index])), 1e-12))
        shifted = parameters.copy()
        shifted[index] += step
        changed = outputs(shifted)
        derivatives.append([(part - ref) / step for part, ref in zip(changed, base, strict=True)])
    for k, _ in enumerate(base):
        J = np.stack([d[k].ravel() for d in derivatives], axis=1)
        variances[k] = np.einsum("ij,jk,ik->i", J, covariance, J).reshape(base[k].shape)
    K_var, U_var, P_var = variances
    return np.sqrt(np.abs(K_var)), np.sqrt(np.abs(U_var)), np.sqrt(np.abs(P_var))


def _monotone(history: tuple[IterationRecord, ...]) -> int | None:
    """The first step whose value exceeds the previous one's beyond rounding (policy
    iteration must lower the value matrix at every step), or None. A step numbered 0
    starts a new iteration (a new discount of the schedule, whose values are larger).
    The values are compared in the coordinates the step's regression was solved in
    (:meth:`IterationRecord.visited`), less the step's rounding there
    (:attr:`IterationRecord.rounding`, relative to the value's norm): a direction that
    carries little of the value (a fast mode's, beside a slow one's 1e5 times larger) would
    otherwise show the rounding of the whole as a rise of its own."""
    for index in range(1, len(history)):
        record = history[index]
        if history[index - 1].P.shape != record.P.shape or record.iteration == 0:
            continue
        before, after = record.visited(history[index - 1].P), record.visited(record.P)
        allowance = record.rounding * float(np.linalg.norm(after, 2))
        after = after - allowance * np.eye(after.shape[0])
        # scaled by P's diagonal, so that a large block (an integrator's) does not hide
        # or fake a rise in a small one (the currents')
        diagonal = np.abs(np.diag(before))
        scale = 1.0 / np.sqrt(np.maximum(diagonal, 1e-12 * float(np.max(diagonal))))
        rise = float(np.max(np.linalg.eigvalsh(scale[:, None] * (after - before) * scale)))
        if rise > 1e3 * RANK_TOLERANCE:
            return index
    return None


def largest_radius(optimum_radius: float) -> float:
    """The largest spectral radius accepted for the learned loop on a plausible model:
    ``1 - STABILITY_MARGIN``, or ``1 - OPTIMUM_MARGIN_FRACTION (1 - optimum_radius)`` when
    the optimum's own margin is smaller (but positive), so that the margin scales with
    the loop's own optimum and not with the sampling period alone.

    Parameters
    ----------
    optimum_radius : float
        The spectral radius of the target's optimum on the fitted model.
    """
    own = 1.0 - optimum_radius  # not stable with margin itself: the margin stands
    slower = 0.0 < own < STABILITY_MARGIN
    return 1.0 - (OPTIMUM_MARGIN_FRACTION * own if slower else STABILITY_MARGIN)


def check_safety(
    quality: Quality,
    evidence: Evidence,
    history: tuple[IterationRecord, ...],
    limit: float,
    radii: Array,
    servo: bool = False,
    optimum_radius: float = 0.0,
) -> None:
    """Raise unless the data support the controller (see the module docstring).

    Parameters
    ----------
    quality : Quality
        The verdict so far.
    evidence : Evidence
        The data's alignment, model and noise.
    history : tuple of IterationRecord
        Policy-iteration steps (empty for identify-then-design).
    limit : float
        The largest relative standard error of K and U accepted.
    radii : ndarray
        Spectral radii of the learned loop on plausible models (the fitted one first).
    servo : bool
        The controller has integral action (:func:`check_precision`).
    optimum_radius : float
        The spectral radius of the target's optimum on the fitted model
        (:func:`largest_radius`; default 0: the margin is :data:`STABILITY_MARGIN`).

    Raises
    ------
    NotStabilizing
        If the loop is not stable with margin on every plausible model (a
        ConvergenceError).
    PolicyIterationFailure
        If the value did not decrease as policy iteration requires (a ConvergenceError).
    TooLittleData
        If the standard errors exceed ``limit``: too little data for the noise (an
        ExcitationError).
    """
    radius_limit = largest_radius(optimum_radius)
    if radii.size and float(np.max(radii)) > radius_limit:
        unstable = int(np.sum(radii > radius_limit))
        raise NotStabilizing(
            f"the learned controller does not stabilize every plant the data allow: the "
            f"sampled loop's spectral radius reaches {float(np.max(radii)):.6f} on "
            f"{unstable} of {radii.size} plausible models "
            "(1 is the stability limit); use longer or better-excited data, or a gentler cost",
            spectral_radius=float(np.max(radii)),
            max_radius=radius_limit,
            unstable=unstable,
            plausible=int(radii.size),
        )
    # the precision first: a result too noisy to keep fails both, and this says why
    check_precision(quality.relative_se, evidence, limit, servo=servo)
    step = _monotone(history)
    if step is not None:
        raise PolicyIterationFailure(
            f"policy iteration did not behave as theory says: the learned value rose at "
            f"step {step} (it must fall at every step from a stabilizing policy); the data "
            "do not support the controller (too noisy, too short, or a plant that is not "
            "linear)",
            step=step,
            symptom="value rose",
        )


#: How :func:`check_precision` begins its refusal (:class:`~selftune.errors.TooLittleData`).
TOO_LITTLE_DATA = "too little data for this noise level"

#: With integral action the feedforward U only shapes the transient (the integrator
#: removes its steady error), so its relative standard error may reach this.
SERVO_FEEDFORWARD_LIMIT = 0.25


def check_precision(
    relative: BlockErrors, evidence: Evidence, limit: float, servo: bool = False
) -> None:
    """Raise unless the relative standard errors of K and U are within ``limit`` (U within
    :data:`SERVO_FEEDFORWARD_LIMIT` for a servo controller, ``servo``). K is the feedback
    of the currents and the delayed voltages; K_i is reported, not gated (its entries,
    often 200 times K's, would hide K's error in a norm over both).

    Parameters
    ----------
    relative : BlockErrors
        Relative standard errors of K, K_i and U.
    evidence : Evidence
        The data's model and noise.
    limit : float
        The largest accepted.
    servo : bool
        The controller has integral action.

    Raises
    ------
    TooLittleData
        "too little data for this noise level" (an ExcitationError), with the length that
        would do (its ``needed_seconds``); when the
        output errors are correlated in time far beyond white noise, it says the model
        misses part of the data too.
    """
    U_limit = max(limit, SERVO_FEEDFORWARD_LIMIT) if servo else limit
    worst = max(relative.K / limit, relative.U / U_limit)
    if not worst > 1.0:
        return
    duration = sum(float(e.duration) for e in evidence.episodes)
    needed = duration * worst**2
    inflation = 1.0 if evidence.fit is None else evidence.fit.correlation_inflation
    cause = ""
    if _coarse_adc(evidence):
        assert evidence.adc_step is not None and evidence.adc_noise is not None
        noise = (
            f"about {evidence.adc_noise * 1e3:.2g} mA of noise"
            if evidence.adc_noise > 0.0
            else "no noise the errors show"
        )
        cause = (
            f"; the currents are whole {evidence.adc_step * 1e3:.3g} mA steps of an ADC with "
            f"{noise} before it: its rounding is a "
            "fixed function of the current, not noise that averages out, so more data helps "
            "less than that estimate says; a finer ADC (more bits or a smaller range) or "
            "larger currents help most"
        )
    elif inflation > INFLATION_LIMIT:
        missing = (
            "the dead-time model (which is on) near zero current, a nonlinearity"
            if evidence.extra
            else "an input error the log does not show (inverter dead time: set dead_time "
            "= true), a nonlinearity"
        )
        cause = (
            f"; the model misses part of the data (its output errors are correlated in time,"
            f" {inflation:.3g} times the variance white noise gives): likely {missing} (a "
            "saturated sensor or ADC, the voltage limit), an ADC whose steps are coarse "
            "against the noise (its rounding is then no white noise: more data does not "
            "help, a finer ADC or a larger current does) or a misaligned voltage log"
        )
    raise TooLittleData(
        f"{TOO_LITTLE_DATA}: the standard error of K is {relative.K:.2%} "
        f"and of U {relative.U:.2%} of their size (the limits are {limit:.2%} and "
        f"{U_limit:.2%}) from {duration:.4g} s of data with about {_noise_text(evidence)} of "
        f"noise; about {needed:.3g} s of the same kind of data would bring them within the "
        f"limits (or richer excitation: more exploration, reference changes, another "
        f"operating point){cause}",
        relative_se=(float(relative.K), float(relative.U)),
        max_relative_se=(float(limit), float(U_limit)),
        data_seconds=duration,
        needed_seconds=needed,
    )


def _coarse_adc(evidence: Evidence) -> bool:
    """Whether the log's currents are steps of an ADC coarse against its noise (the
    sign-bias correction simulated them only then)."""
    return evidence.adc_step is not None and evidence.adc_noise is not None


def _noise_text(evidence: Evidence) -> str:
    noise = evidence.model_noise
    if noise is None:  # no output-error model: the one-step residual bounds the noise
        residual = evidence.alignment.model.residual_rms
        return ", ".join(f"{value:.3g}" for value in residual) + " (one-step residual)"
    return ", ".join(f"{value:.3g}" for value in noise)
