"""One entry point for every learner: evidence, learning, verdict.

:func:`learn_controller` runs the same pipeline for every target and method:

1. **evidence** (:mod:`.evidence._evidence`): the alignment of the logged inputs, checked on every
   call; the output-error model of the data with its noise estimate; the consistency
   test. Data that contradict the stated alignment or that no linear model explains are
   refused here, whatever the method.
2. **learning**, by the options' target and method:

   ==========  ========  ==========================================================
   target      method    learner (:mod:`.learners`)
   ==========  ========  ==========================================================
   continuous  adp       the paper's continuous-time ADP (``_continuous``, ``_servo``)
   digital     adp       discrete-time ADP with the computation delay (``_digital``)
   continuous  identify  discrete model, matrix logarithm, continuous optimum
   digital     identify  discrete model, optimum of the delayed sampled loop
   ==========  ========  ==========================================================

   The ADP learners meet measurement noise as ``options.noise`` says (by default they
   learn from the output-error model's noise-free simulation of the log).
3. **verdict** (:mod:`.verdict._quality`): standard errors, noise, stability margin; the
   controller is returned only if the data support it.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike

from ..core import Array, ControlLaw
from ..errors import (
    ConsistencyError,
    ExcitationError,
    InputError,
    PolicyIterationFailure,
    Refusal,
    SelftuneDeprecationWarning,
    SelftuneError,
    TooLittleData,
    UnsolvableError,
)
from ..loop import SampledLoop
from ._problem import LearningOptions, LearningProblem
from ._result import JudgedPlants, LearnedController
from .data._trajectory import Trajectory, as_trajectories
from .evidence._alignment import applied_inputs
from .evidence._evidence import Evidence, gather_evidence, reduced_problem
from .evidence._output_error import simulated_trajectories
from .evidence._pulses import with_pulse_shift
from .learners._continuous import lqr_from_moments, regulator_from_moments
from .learners._digital import (
    DigitalTransitions,
    digital_transitions,
    learn_digital_adp,
    steady_state_map,
)
from .learners._moments import IntervalMoments, WKind, interval_moments
from .learners._policy_iteration import IterationRecord
from .learners._servo import servo_from_moments
from .verdict._nameplate import check_fit_against_nameplate
from .verdict._quality import check_precision, check_safety, largest_radius
from .verdict._verdict import (
    ROUNDING_FLOOR,
    ModelErrors,
    design_target,
    model_errors,
    motor_estimate,
    verdict,
    without_extra,
)

__all__ = [
    "ROUNDING_FLOOR",
    "LearnedController",
    "aligned_trajectory",
    "assess",
    "learn_controller",
]


#: A log whose u columns change at fewer than the first fraction of its rows and whose w
#: columns change at more than the second looks like one with u and w swapped.
SWAP_RATES = (0.2, 0.8)


def aligned_trajectory(episode: Trajectory, shift: int) -> Trajectory:
    """The log with row k of ``u`` the input applied during sample k.

    Parameters
    ----------
    episode : Trajectory
        The log.
    shift : int
        The voltage applied during sample k is in row ``k - shift`` of the log.

    Returns
    -------
    Trajectory
        The samples at which the applied input is known.
    """
    if shift == 0:
        return episode
    a, first = applied_inputs(episode, shift)
    stop = first + a.shape[0] + 1
    w = None if episode.w is None else episode.w[first : min(stop, episode.w.shape[0])]
    angle = None if episode.angle is None else episode.angle[first:stop]
    return Trajectory(t=episode.t[first:stop], x=episode.x[first:stop], u=a, w=w, angle=angle)


def _check_data(episodes: Sequence[Trajectory], problem: LearningProblem) -> None:
    first = episodes[0]
    if (first.n, first.m) != (problem.n, problem.m):
        raise InputError(
            f"Q, R: are {problem.n}x{problem.n} and {problem.m}x{problem.m}, but the data "
            f"have n = {first.n} states and m = {first.m} inputs"
        )
    if problem.q and first.q != problem.q:
        raise InputError(
            f"F: has {problem.q} columns, but the data have {first.q} exogenous channels w"
        )


def learn_controller(
    data: Trajectory | Sequence[Trajectory],
    problem: LearningProblem,
    K0: ArrayLike | LearningOptions | None = None,
    options: LearningOptions | None = None,
) -> LearnedController:
    """Learn the optimal controller of ``options.target`` from logs, by ``options.method``.

    Parameters
    ----------
    data : Trajectory or sequence of Trajectory
        The logs (one or more episodes, uniform sampling, ``w`` held over each sample for
        the digital target and identify-then-design).
    problem : LearningProblem
        What the learner knows: C, E, F, the cost weights, integral action.
    K0 : array_like, shape (m, n)
        The stabilizing feedback the data were taken under (the drive's controller, on
        x): policy iteration starts from it. (The deprecated order
        ``learn_controller(data, problem, options)``, with K0 in the problem, still works,
        with a deprecation warning.)
    options : LearningOptions, optional
        Target, method, input delay, log alignment, noise handling, iteration settings
        (defaults: the paper's continuous ADP on an applied-voltage log).

    Returns
    -------
    LearnedController
        With its :class:`Quality`.

    Raises
    ------
    ConsistencyError
        If the data contradict the stated alignment of the logged inputs
        (:class:`~selftune.errors.MisalignedLog`), or the model cannot explain them
        (:class:`~selftune.errors.ModelMissesEffect`: the statistic and the likely causes).
    ExcitationError
        If the data do not excite the plant enough (:class:`~selftune.errors.NotExciting`,
        :class:`~selftune.errors.TooShort`), or are too short for their noise
        (:class:`~selftune.errors.TooLittleData`: how much longer they should be). A
        structured fit (``options.structure``) that is refused says what the data give
        without it.
    ConvergenceError
        If the learned controller does not stabilize every plant the data allow
        (:class:`~selftune.errors.NotStabilizing`), or policy iteration did not behave as
        theory says (:class:`~selftune.errors.PolicyIterationFailure`).
    UnsolvableError, InputError
        As the learners raise them.
    """
    K0_, options = _initial_policy(problem, K0, options)
    try:
        return _learned(data, problem, K0_, options)
    except Refusal as error:
        hint = _swapped_columns(as_trajectories(data))
        if not hint:
            raise
        raise error.retold(f"{error}; {hint}") from error


def _swapped_columns(episodes: Sequence[Trajectory]) -> str:
    """A hint when the u columns change as rarely as a held reference does and the w
    columns as often as voltages do (u and w swapped in the log), else ``""``."""
    if episodes[0].w is None:
        return ""
    u_rate, w_rate = (
        float(np.mean(np.concatenate([np.any(np.diff(a, axis=0) != 0.0, axis=1) for a in arrays])))
        for arrays in ([e.u for e in episodes], [e.w for e in episodes if e.w is not None])
    )
    if not (u_rate < SWAP_RATES[0] and w_rate > SWAP_RATES[1]):
        return ""
    return (
        f"the inputs u change at only {u_rate:.0%} of the rows and the reference w at "
        f"{w_rate:.0%}, as a held reference and voltages would: are the u and w columns "
        "swapped? (u: the voltages; w: the reference, held over each sample)"
    )


def _learned(
    data: Trajectory | Sequence[Trajectory],
    problem: LearningProblem,
    K0_: Array,
    options: LearningOptions,
) -> LearnedController:
    """:func:`learn_controller` with K0 and the options read."""
    try:
        evidence, known, errors = _precise(data, problem, options)
    except (ConsistencyError, UnsolvableError, ExcitationError) as error:
        if (
            options.structure == "none"
            or not options.compare_without_structure
            or isinstance(error, TooLittleData)
        ):
            raise
        raise _without_structure(error, data, problem, options) from error
    if options.method == "identify":
        law, P, B = design_target(evidence.model, known, options)
        return _judged((without_extra(law, problem.q), P, B, ()), evidence, errors, options)
    adp = _digital_adp if options.target == "digital" else _continuous_adp
    try:
        law, P, B, history = adp(
            _regression_data(evidence, options), evidence, (known, K0_), options
        )
        return _judged((without_extra(law, problem.q), P, B, history), evidence, errors, options)
    except PolicyIterationFailure as failure:
        if evidence.fit is None:  # no output-error model to design from
            raise
        radius = _initial_radius(K0_, evidence, options)
        if not radius < 1.0:  # the cause is K0, not the noise: say so, design nothing
            raise PolicyIterationFailure(
                f"{failure}; K0 does not stabilize the loop the data show: its spectral "
                f"radius on the fitted model is {radius:.4g} (at most 1 is stable); give "
                "the feedback the drive ran while it logged (V/A, u = -K0 x)",
                step=failure.step,
                symptom=failure.symptom,
            ) from failure
        law, P, B = design_target(evidence.model, known, options)
        note = (
            f"policy iteration failed on this batch ({failure}); the controller was "
            "designed from the output-error model instead (method identify), and the "
            "standard errors are that model's"
        )
        errors = replace(errors, notes=(*errors.notes, note))
        identify = replace(options, method="identify")
        return _judged((without_extra(law, problem.q), P, B, ()), evidence, errors, identify)


def _initial_radius(K0: Array, evidence: Evidence, options: LearningOptions) -> float:
    """The spectral radius of K0's sampled loop on the fitted model (its feedback of the
    states; the target's delay)."""
    model = evidence.model
    n, m = model.n, model.Bd.shape[1]
    delay = options.input_delay if options.target == "digital" else 0
    law = ControlLaw.regulator(K0[:, :n], np.zeros((n, 0)), np.zeros((m, 0)))
    return SampledLoop(model.h, delay).spectral_radius((model.Ad, model.Bd), law)


def _initial_policy(
    problem: LearningProblem,
    K0: ArrayLike | LearningOptions | None,
    options: LearningOptions | None,
) -> tuple[Array, LearningOptions]:
    """K0 validated, and the options; the deprecated order (data, problem, options) with
    K0 in the problem is read with a deprecation warning."""
    if isinstance(K0, LearningOptions) and options is None:
        K0, options = None, K0
    options = LearningOptions() if options is None else options
    if K0 is None:
        if problem.K0 is None:
            raise InputError(
                "K0: missing: give the stabilizing feedback the data were taken under, "
                "learn_controller(data, problem, K0, options)"
            )
        warnings.warn(
            "learn_controller(data, problem, options) with K0 in the problem is deprecated: "
            "call learn_controller(data, problem, K0, options)",
            SelftuneDeprecationWarning,
            stacklevel=3,
        )
        K0 = problem.K0
    assert not isinstance(K0, LearningOptions)
    return problem.initial_policy(K0), options


def assess(
    law: ControlLaw,
    data: Trajectory | Sequence[Trajectory],
    problem: LearningProblem,
    options: LearningOptions | None = None,
    *,
    P: Array | None = None,
    history: tuple[IterationRecord, ...] = (),
    feedforward: bool = True,
) -> LearnedController:
    """The verdict on a controller learned elsewhere from these data (for example by an
    on-policy session, one episode per step): the same evidence, standard errors and
    safety checks as :func:`learn_controller` gives its own results.

    Parameters
    ----------
    law : ControlLaw
        The learned controller.
    data : Trajectory or sequence of Trajectory
        Every log it was learned from.
    problem : LearningProblem
        What the learner knew.
    options : LearningOptions, optional
        How it was learned (target and method decide what its standard errors include).
    P : ndarray, optional
        Its learned value matrix (default: the target's on the fitted model).
    history : tuple of IterationRecord
        Its policy-iteration steps (checked for a monotone value).
    feedforward : bool
        Whether the law's feedforward was learned; if not (the paper's Algorithm 1), U is
        not judged and its standard errors are NaN.

    Returns
    -------
    LearnedController
        ``law`` with its :class:`Quality`.

    Raises
    ------
    ConsistencyError, ExcitationError, ConvergenceError
        As :func:`learn_controller`.
    """
    options = LearningOptions() if options is None else options
    evidence, _, errors = _prepared(data, problem, options)
    model = evidence.model
    value = errors.P if P is None else np.asarray(P, dtype=float)
    if feedforward:
        return _judged((law, value, model.Bd, history), evidence, errors, options)
    errors = replace(errors, U=law.U, U_se=np.full_like(law.U, np.nan))
    judged = _judged((law, value, model.Bd, history), evidence, errors, options)
    note = "the feedforward U was not learned, so it is not judged (U_se is NaN)"
    assert judged.quality is not None
    quality = replace(judged.quality, notes=(*judged.quality.notes, note))
    return replace(judged, quality=quality)


def _precise(
    data: Trajectory | Sequence[Trajectory], problem: LearningProblem, options: LearningOptions
) -> tuple[Evidence, LearningProblem, ModelErrors]:
    """:func:`_prepared`, refused unless the target's standard errors are small enough."""
    evidence, known, errors = _prepared(data, problem, options)
    check_precision(
        errors.relative,
        evidence,
        options.max_relative_error,
        servo=problem.integral_weight is not None,
    )
    return evidence, known, errors


def _without_structure(
    error: SelftuneError,
    data: Trajectory | Sequence[Trajectory],
    problem: LearningProblem,
    options: LearningOptions,
) -> SelftuneError:
    """The refusal of a structured fit, told with what the same data give without the
    structure: "too little data" and the length that would do, if that is what they say
    (the usual reason a short noisy log defeats the structured fit: a
    :class:`~selftune.errors.TooLittleData` with their fields), or that they suffice
    without it (the refusal's own class and fields)."""
    try:
        _precise(data, problem, replace(options, structure="none"))
    except TooLittleData as other:
        return other.retold(
            f"without the structure, {other}; with it (structure ="
            f" '{options.structure}') the fit was refused: {error}"
        )
    except SelftuneError:
        return error
    return error.retold(f"{error}; without the structure (structure = 'none') these data suffice")


def _prepared(
    data: Trajectory | Sequence[Trajectory], problem: LearningProblem, options: LearningOptions
) -> tuple[Evidence, LearningProblem, ModelErrors]:
    """The evidence of the logs, the problem as the fitted model sees it, and the target's
    optimum on that model with its standard errors."""
    episodes = as_trajectories(data)
    _check_data(episodes, problem)
    if not problem.held and (options.target == "digital" or options.method == "identify"):
        raise InputError(
            "E: the digital target and identify-then-design need w held over each sample "
            "(E = 0); with an exosystem use target = 'continuous', method = 'adp'"
        )
    evidence = gather_evidence(episodes, problem, options)
    if options.nameplate_resistance is not None:
        check_fit_against_nameplate(evidence, options.nameplate_resistance)
    known = reduced_problem(problem, evidence.extra)
    errors = model_errors(evidence, (known, problem.q), options)
    return evidence, known, errors


def _judged(
    learned: tuple[ControlLaw, Array, Array, tuple[IterationRecord, ...]],
    evidence: Evidence,
    errors: ModelErrors,
    options: LearningOptions,
) -> LearnedController:
    """The learned ``(law, P, B, history)`` with its verdict, or the error that refuses it."""
    law, P, B, history = learned
    quality, radii, models = verdict(law, errors, evidence, options)
    check_safety(
        quality,
        evidence,
        history,
        options.max_relative_error,
        radii,
        servo=law.K_i is not None,
        optimum_radius=errors.optimum_radius,
    )
    if evidence.pulse_shift is not None and evidence.fit is not None:  # reported, not judged
        widened = replace(evidence, fit=with_pulse_shift(evidence.fit, evidence.pulse_shift))
        note = (
            "the motor's standard errors include the shift the carrier's pulses leave, "
            "which its model does not carry (each leg's pulse centred in the period and one "
            "edge late by the dead time, where the model holds the voltage over the sample), "
            "from the DC bus"
        )
        quality = replace(quality, motor=motor_estimate(widened), notes=(*quality.notes, note))
    return LearnedController(
        law=law,
        P=P,
        B=B,
        target=options.target,
        method=options.method,
        h=evidence.alignment.model.h,
        input_delay=options.input_delay if options.target == "digital" else 0,
        quality=quality,
        alignment=evidence.alignment,
        history=history,
        evidence=evidence,
        judged=JudgedPlants(
            tuple(models), options.input_delay, largest_radius(errors.optimum_radius)
        ),
    )


_Logs = tuple[Sequence[Trajectory], Sequence[Trajectory] | None]


def _regression_data(evidence: Evidence, options: LearningOptions) -> _Logs:
    """The logs an ADP learner regresses on, and its instruments (see ``noise``). Logs the
    model explains to rounding (noise-free) are used as they are: a smoothed copy could
    only add the fit's own rounding."""
    if evidence.fit is None or options.noise == "none" or evidence.consistency.exact:
        return evidence.episodes, None
    simulated = simulated_trajectories(evidence.episodes, evidence.alignment.shift, evidence.fit)
    if options.noise == "smoothed":
        return simulated, None
    return evidence.episodes, simulated


def _interval(options: LearningOptions, episodes: Sequence[Trajectory], unknowns: int) -> int:
    """Samples per regression row: ``options.interval``, shortened so that the logs give
    at least two rows per unknown when they can."""
    samples = sum(episode.num_samples for episode in episodes)
    return max(1, min(options.interval, samples // (2 * unknowns)))


def _digital_adp(
    logs: _Logs,
    evidence: Evidence,
    known: tuple[LearningProblem, Array],
    options: LearningOptions,
) -> tuple[ControlLaw, Array, Array, tuple[IterationRecord, ...]]:
    problem, K0 = known
    X = steady_state_map(problem)
    integrator = problem.C if problem.integral_weight is not None else None
    episodes, instruments = logs
    nz = problem.n + options.input_delay * problem.m + (problem.r if integrator is not None else 0)
    m, q = problem.m, problem.q
    unknowns = nz * (nz + 1) // 2 + m * nz + m * (m + 1) // 2 + q * nz + m * q + q * (q + 1) // 2
    interval = _interval(options, episodes, unknowns)

    def transitions_of(trajectories: Sequence[Trajectory]) -> DigitalTransitions:
        return digital_transitions(
            trajectories,
            X,
            shift=evidence.alignment.shift,
            delay=options.input_delay,
            h=evidence.alignment.model.h,
            C=integrator,
            interval=interval,
        )

    transitions = transitions_of(episodes)
    if instruments is not None:
        transitions = replace(transitions, instruments=transitions_of(instruments))
    learned = learn_digital_adp(transitions, problem, K0, options)
    model = evidence.model
    return learned.law, learned.P, model.Bd, learned.history


def _continuous_adp(
    logs: _Logs,
    evidence: Evidence,
    known: tuple[LearningProblem, Array],
    options: LearningOptions,
) -> tuple[ControlLaw, Array, Array, tuple[IterationRecord, ...]]:
    problem, K0 = known
    episodes, instruments = logs
    w_kind: WKind = "held" if problem.held else "exosystem"
    shift = evidence.alignment.shift
    integrator = None  # with integral action: z, the integral of e = C x + F w
    if problem.integral_weight is not None:
        assert problem.C is not None and problem.F is not None
        integrator = (problem.C, problem.F)
    size = problem.n + (problem.r if integrator is not None else 0)  # [xbar; z]
    m, q = problem.m, problem.q
    interval = _interval(options, episodes, size * (size + 1) // 2 + m * size + q * size)

    def aligned(trajectories: Sequence[Trajectory]) -> list[Trajectory]:
        shifted = [aligned_trajectory(episode, shift) for episode in trajectories]
        if problem.C is None:
            return [Trajectory(t=a.t, x=a.x, u=a.u) for a in shifted]
        return shifted

    logs_aligned = aligned(episodes)
    instruments_aligned = None if instruments is None else aligned(instruments)

    def moments_at(discount: float) -> IntervalMoments:
        """The moments at a discount (0: none), with the instruments' attached."""

        def of(trajectories: Sequence[Trajectory]) -> IntervalMoments:
            return interval_moments(
                trajectories, interval, w_kind=w_kind, integrator=integrator, discount=discount
            )

        moments = of(logs_aligned)
        if instruments_aligned is not None:
            moments = moments.with_instruments(of(instruments_aligned))
        return moments

    cost = (problem.Q, problem.R, K0)
    settings = (options.max_iterations, options.tolerance)
    if problem.C is None:
        learned = lqr_from_moments(moments_at(0.0), cost, settings)
    else:
        assert problem.E is not None and problem.F is not None
        output = (problem.C, problem.E, problem.F)
        if problem.integral_weight is not None:
            h = evidence.alignment.model.h
            servo_cost = (problem.Q, problem.R, problem.integral_weight, K0)
            learned = servo_from_moments(moments_at, output, servo_cost, settings, h)
        else:
            learned = regulator_from_moments(moments_at(0.0), output, cost, "auto", settings)
    assert learned.B is not None
    return learned.law, learned.P, learned.B, learned.history
