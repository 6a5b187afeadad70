"""A saturating PM motor commissioned over its load: its incremental model learned at
several current levels, the digital optimum designed at each and scheduled over the
q-axis current reference.

A saturating motor's incremental inductances move with its current (its q-axis one
falls by 20-40 % from no load to rated on many machines), so a law designed at one
current is not the optimum at another. At each level (a share of rated torque, its
current reference ``i* = [i_d*, i_q*]`` the nameplate motor's MTPA, which the engineer
knows) one log holds the references at ``i*`` plus the interior commissioning's steps
(:func:`~._interior.current_steps` of :data:`STEP_SHARE` of the rated q current: q
through +-1 and +-1/3 of it, d through 0 and -1 of it, each with its own dwell)
under the nameplate motor's digital optimum (it tracks ``i*``, so the currents stay about
the operating point), with the settings' exploration. The first :data:`SETTLE` s (the
climb from rest through the saturation) are cut off, and the rest is learned by
identify-then-design with the incremental structure (``structure = "incremental"``,
:class:`~selftune.learn.IncrementalStructure`): ``R_s``, the incremental ``L_dd``,
``L_qq``, ``L_dq`` and the flux offset at the operating current, with their standard
errors and the verdict.

The schedule is over ``i_q*`` (A): where the identified ``L_dd``, ``L_qq`` or ``L_dq`` of
two neighbouring levels differ by more than :data:`INDUCTANCE_MOVE` of the larger
diagonal inductance, a level is learned between them (up to :data:`MAX_LEVELS`). Then
:func:`~selftune.model.design_current_schedule` designs the optimum at each level's
identified model and checks the interpolated law on a fine grid between the levels
against the pointwise optimum of the identified models interpolated linearly in ``i_q*``
(refining the grid by bisection there). Levels whose R_s disagrees with the highest
level's or the nameplate's are left out of it (:func:`~._resistance.kept_levels`), and so
are the lowest levels whose every log the learner refused
(:attr:`CurrentCommissioning.unlearned`): levels halfway towards the lowest learned are
tried then (:data:`LOW_BISECTIONS`), and the schedule starts at the lowest level kept.
Each level's inductances' standard errors include their curvature over its log's
currents (:func:`~._curvature.with_curvature`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from itertools import pairwise

import numpy as np

from ..core import Array
from ..errors import SelftuneError, TooLittleData
from ..learn import (
    IncrementalStructure,
    LearnedController,
    LearningOptions,
    LearningProblem,
    Trajectory,
    learn_controller,
)
from ..learn._speeds import _part
from ..model import (
    IPMSM,
    CurrentScheduleDesign,
    SpeedCurrentDesign,
    solve_digital_regulation,
)
from ..sim import DriveSettings, RealisticDrive, Saturation, held, uniform
from ._curvature import precise_levels, with_curvature
from ._interior import CURRENT_REFERENCE_F, D_SHARE, check_current_range, current_steps
from ._learning import learning_options, longer_batch
from ._level_schedule import (
    level_plants,
    schedule_over_levels,
    schedule_over_speed_and_levels,
)
from ._resistance import kept_levels, small_levels
from ._settings import TuningSettings

__all__ = [
    "INDUCTANCE_MOVE",
    "LEVEL_ATTEMPTS",
    "LOW_BISECTIONS",
    "MAX_LEVELS",
    "SETTLE",
    "STEP_SHARE",
    "CurrentCommissioning",
    "CurrentLevel",
    "commission_over_current",
    "incremental_parameters",
    "incremental_theta",
    "inductances_move",
    "learn_level",
    "level_log",
    "level_plants",
    "schedule_over_levels",
    "schedule_over_speed_and_levels",
]

#: The steps about each level's current reference, a share of the rated q current: small
#: enough that the incremental model holds over them, large enough to be learned at the
#: lowest level, where the drive's dead time (2 V) is large against the steps' voltages.
#: On the 2/6 mH study motor (docs/saturation.md), at 10 % of rated current, 3 % steps
#: were refused on one of two seeds (by the consistency or the structure's likelihood-ratio
#: test, with saturation and without it); 8 % steps learned both seeds at 10, 40, 70 and
#: 100 %, the inductances within 1.8 standard errors of the truth at the mean current.
STEP_SHARE = 0.08

#: The start of each level's log that is not learned, s: the climb from rest to the
#: operating current crosses the saturation's knee, which no one linear model explains.
SETTLE = 0.05

#: A level is learned between two neighbours whose identified incremental inductances
#: (``L_dd``, ``L_qq``, ``L_dq``) differ by more than this share of the larger diagonal
#: inductance. 5 %: the digital optimum's gains move about in proportion to the
#: inductances, and a law whose plant's inductance is off by 5 % costs about 0.1-0.3 %
#: more than the optimum (the excess is quadratic in the error), so the linear
#: interpolation between levels stays well inside the 2 % target; the design's own check
#: then refines the grid between the levels if the interpolation of the gains needs it.
INDUCTANCE_MOVE = 0.05

#: The most levels learned (the initial ones and those added).
MAX_LEVELS = 9

#: Where the lowest initial levels are refused (every log of each), the levels tried
#: halfway between the highest refused and the lowest learned, one after the other, so
#: that the schedule starts nearer the currents below it, where the firmware holds its
#: first law. On a 0.18/0.44 mH motor on 48 V whose 10 % level was refused (its currents
#: cross zero under the dead time), the law of 40 % held at 10 % cost 2.2 % over the
#: optimum there; the levels at 25 % and 17.5 % were learned.
LOW_BISECTIONS = 2

#: The logs a level may take: a level whose log the learner refuses is logged again
#: with the next seed (as an engineer reruns a refused experiment), the refusals kept
#: in :attr:`CurrentCommissioning.refusals` (the study in docs/saturation.md: 2 logs for 27 levels).
#: A log refused as too short for its noise (TooLittleData) is logged again as long as
#: the learner asks (:func:`~._learning.longer_batch`: a quarter more than it names, up
#: to :data:`~._learning.LONGEST_BATCH_FACTOR` times ``seconds``).
LEVEL_ATTEMPTS = 3


@dataclass(frozen=True)
class CurrentLevel:
    """A level learned: its reference, the identified incremental model, the law.

    Attributes
    ----------
    share : float
        The share of rated torque.
    reference : ndarray, shape (2,)
        ``[i_d*, i_q*]``, A (the nameplate motor's MTPA at that torque).
    theta : ndarray, shape (6,)
        ``[R_s, L_dd, L_qq, L_dq, kappa, kappa_q]`` identified (ohm, H, H, H, -, -).
    standard_errors : ndarray, shape (6,)
        Their standard errors.
    mean_current : ndarray, shape (2,)
        The log's mean ``[i_d, i_q]`` over the learned part, A (the operating current).
    learned : LearnedController
        The law designed on the level's identified model, with its verdict.
    current_spread : ndarray, shape (2,)
        The log's standard deviation of ``[i_d, i_q]`` about that mean, A.
    curvature_errors : ndarray, shape (3,)
        The part of the standard errors of ``[L_dd, L_qq, L_dq]`` (H) that is the
        inductances' curvature over the log's currents (:func:`~._curvature.curvature_errors`;
        zeros until the levels are compared).
    """

    share: float
    reference: Array
    theta: Array
    standard_errors: Array
    mean_current: Array
    learned: LearnedController
    current_spread: Array
    curvature_errors: Array = field(default_factory=lambda: np.zeros(3))

    @property
    def inductances(self) -> Array:
        """``[L_dd, L_qq, L_dq]``, H."""
        return self.theta[1:4]


@dataclass(frozen=True)
class CurrentCommissioning:
    """A saturating motor commissioned over its load.

    Attributes
    ----------
    levels : tuple of CurrentLevel
        The levels learned, by rising ``i_q*``.
    design : CurrentScheduleDesign
        The schedule over ``i_q*`` (A) and its check.
    integral_weight : ndarray, shape (2, 2), or None
        The integral weight the learner and the design used (None without integral
        action).
    refusals : tuple of (float, str)
        The logs refused and logged again: the level (share of rated torque) and the
        learner's message.
    left_out : tuple of CurrentLevel
        Levels learned but left out of the schedule: their R_s disagrees with the highest
        level's or the nameplate's (:func:`~._resistance.misled_levels`), or their
        inductances are too imprecise (:func:`~._curvature.precise_levels`).
    left_out_text : str
        Why, and which lowest levels were not learned ("" when none were).
    unlearned : tuple of float
        The lowest levels (shares of rated torque) whose every log was refused, below
        every level learned (:data:`LEVEL_ATTEMPTS`; the initial ones, then those tried
        halfway towards the lowest learned, :data:`LOW_BISECTIONS`): the schedule
        starts above them.
    speed_design : SpeedCurrentDesign or None
        With the speeds of a ``[schedule]``: the law scheduled over speed and ``i_q*``
        together on the same levels (:func:`schedule_over_speed_and_levels`).
    """

    levels: tuple[CurrentLevel, ...]
    design: CurrentScheduleDesign
    integral_weight: Array | None
    refusals: tuple[tuple[float, str], ...] = ()
    left_out: tuple[CurrentLevel, ...] = ()
    left_out_text: str = ""
    unlearned: tuple[float, ...] = ()
    speed_design: SpeedCurrentDesign | None = None


def incremental_theta(saturation: Saturation, R_s: float, current: Array, flux: float) -> Array:
    """The incremental structure's parameters of a saturation model at a current:
    ``L = d psi / d i`` there and the offset ``c = psi(i0) - L i0`` over ``flux``
    (the flux the reference channel assumes), the truth a level's fit estimates.

    Parameters
    ----------
    saturation : SaturationModel or FluxMap
        The flux linkages.
    R_s : float
        ohm.
    current : ndarray, shape (2,)
        ``[i_d, i_q]``, A.
    flux : float
        ``phi_assumed``, Wb.
    """
    L = saturation.incremental(current[0], current[1])
    psi = np.array(saturation.flux(current[0], current[1]), dtype=float)
    offset = psi - L @ np.asarray(current, dtype=float)
    return np.array([R_s, L[0, 0], L[1, 1], L[0, 1], offset[0] / flux, offset[1] / flux])


def level_log(
    motor: IPMSM,
    saturation: Saturation,
    settings: TuningSettings,
    drive: DriveSettings,
    share: float,
    *,
    seconds: float = 0.4,
    seed: int = 0,
) -> tuple[Trajectory, LearningOptions]:
    """One level's log (see the module docstring) and the options it is learned with
    (identify-then-design with the incremental structure at the drive's speed, delay and
    hold).

    Parameters
    ----------
    motor : IPMSM
        The nameplate motor (its R_s and p are the drive's; its L_d, L_q, flux what the
        engineer knows; a surface motor is the interior one with ``L_d = L_q``).
    saturation : SaturationModel or FluxMap
        The true flux linkages.
    settings : TuningSettings
        Operating point (speed, rad/s; rated torque ``T*``, N m), cost, exploration.
    drive : DriveSettings
        The drive.
    share : float
        The level, a share of rated torque.
    seconds : float
        The log's length after :data:`SETTLE`, s.
    seed : int
        Seed of the exploration and noise.
    """
    plant = RealisticDrive(motor, settings.speed, settings.h, drive, saturation=saturation)
    back_emf = motor.p * settings.speed * motor.phi_pm
    reference = motor.current_reference(share * settings.torque)
    step = STEP_SHARE * float(motor.current_reference(settings.torque)[1])

    def references(t: Array) -> Array:
        d, q = current_steps(t, step)
        d = d / D_SHARE  # d steps as large as q's (half as large: 85% within one se, not 68%)
        return np.column_stack([np.full_like(t, back_emf), reference[0] + d, reference[1] + q])

    problem = _learning_problem(settings)
    nameplate = solve_digital_regulation(
        motor.regulation_problem(settings.speed), settings.Q, settings.R, settings.h,
        input_delay=plant.loop.input_delay, integral_weight=problem.integral_weight,
        plant=motor.sampled_plant(settings.speed, settings.h, plant.loop.hold),
    )  # fmt: skip
    settle = round(SETTLE / settings.h)
    record = plant.record(
        nameplate.law, held(references), num_samples=settle + round(seconds / settings.h),
        exploration=uniform(settings.exploration), seed=seed,
    )  # fmt: skip
    rated = float(np.hypot(*motor.current_reference(settings.torque)))
    check_current_range(
        record, drive, rated, f"the level at {share:.0%} of rated torque",
        "the references and steps of this level need a drive whose ADC range covers them",
    )  # fmt: skip
    log = _part(record.trajectory, settle, record.trajectory.num_samples + 1)
    options = replace(learning_options(plant, settings), method="identify", structure="incremental")
    return log, options


def learn_level(
    motor: IPMSM,
    saturation: Saturation,
    settings: TuningSettings,
    drive: DriveSettings,
    share: float,
    *,
    seconds: float = 0.4,
    seed: int = 0,
) -> CurrentLevel:
    """One level learned (see the module docstring): :func:`level_log`'s log learned.

    Parameters
    ----------
    motor, saturation, settings, drive, share, seconds, seed
        As :func:`level_log` takes them.

    Raises
    ------
    SelftuneError
        The learner's refusal.
    """
    log, options = level_log(motor, saturation, settings, drive, share, seconds=seconds, seed=seed)
    reference = motor.current_reference(share * settings.torque)
    learned = learn_controller(log, _learning_problem(settings), settings.K0, options)
    values, errors = incremental_parameters(learned, motor.phi_pm)
    mean, spread = np.mean(log.x, axis=0), np.std(log.x, axis=0)
    return CurrentLevel(share, reference, values, errors, mean, learned, spread)


def incremental_parameters(learned: LearnedController, flux: float) -> tuple[Array, Array]:
    """The incremental structure's parameters a level's fit identified, and their
    standard errors: ``[R_s, L_dd, L_qq, L_dq, kappa, kappa_q]`` (ohm, H, H, H, -, -).

    Parameters
    ----------
    learned : LearnedController
        Learned with ``structure = "incremental"`` (its verdict states the motor).
    flux : float
        The flux the log's first reference channel assumes, ``w_1 / w_e``, Wb: the flux
        offset ``c`` (Wb) over it is ``[kappa, kappa_q]``.
    """
    assert learned.quality is not None and learned.quality.motor is not None  # the verdict
    found = learned.quality.motor
    names = ("R_s", "L_d", "L_q", "L_dq", "phi_pm", "phi_q")
    values = np.array([float(getattr(found, name)) for name in names])
    errors = np.array([float(getattr(found, f"{name}_se")) for name in names])
    values[4:] /= flux
    errors[4:] /= flux
    return values, errors


def inductances_move(low: Array, high: Array) -> bool:
    """Whether two neighbouring levels' identified incremental inductances (``theta[1:4]``
    of :func:`incremental_parameters`) differ by more than :data:`INDUCTANCE_MOVE` of the
    larger diagonal inductance.

    Parameters
    ----------
    low, high : ndarray, shape (6,)
        The two levels' parameters.
    """
    scale = float(max(np.max(low[1:3]), np.max(high[1:3])))
    return bool(np.max(np.abs(high[1:4] - low[1:4])) > INDUCTANCE_MOVE * scale)


def _learning_problem(settings: TuningSettings) -> LearningProblem:
    """The current-reference form's learning problem of the settings' cost."""
    return LearningProblem(
        settings.Q, settings.R, C=np.eye(2), F=CURRENT_REFERENCE_F,
        integral_action=settings.integral_action, integral_weight=settings.Q_i,
    )  # fmt: skip


def commission_over_current(
    motor: IPMSM,
    saturation: Saturation,
    settings: TuningSettings,
    drive: DriveSettings,
    *,
    shares: Sequence[float] = (0.1, 0.4, 0.7, 1.0),
    seconds: float = 0.4,
    seed: int = 0,
    progress: Callable[[int], None] | None = None,
    speeds: Sequence[float] | None = None,
) -> CurrentCommissioning:
    """The levels learned, refined where the inductance moves, and the schedule over
    ``i_q*`` designed on them (see the module docstring).

    Parameters
    ----------
    motor : IPMSM
        The nameplate motor (a surface motor: ``L_d = L_q``).
    saturation : SaturationModel or FluxMap
        The true flux linkages.
    settings : TuningSettings
        Operating point (speed; rated torque), cost, exploration, integral action.
    drive : DriveSettings
        The drive.
    shares : sequence of float
        The initial levels, shares of rated torque, rising.
    seconds : float
        Each level's learned log, s (longer where the learner asks, :data:`LEVEL_ATTEMPTS`).
    seed : int
        Seed of the first level's log (the others' follow it).
    progress : callable, optional
        Called with the number of levels learned so far, after each (at most
        :data:`MAX_LEVELS`).
    speeds : sequence of float, optional
        Mechanical speeds, rad/s, strictly increasing (a ``[schedule]``'s grid, or its
        range's ends): the law is also scheduled over speed and ``i_q*`` together
        (:attr:`CurrentCommissioning.speed_design`), the levels learned at the
        operating speed.

    Raises
    ------
    SelftuneError
        A level's refusal (but for the lowest levels' while another is learned: they are
        left out, :attr:`CurrentCommissioning.unlearned`), or the design's.
    """
    w_e = motor.p * settings.speed
    refusals: list[tuple[float, str]] = []
    logs = iter(range(seed, seed + MAX_LEVELS * LEVEL_ATTEMPTS))

    planned = round(seconds / settings.h)

    def attempted(share: float) -> CurrentLevel:
        samples = planned
        for _ in range(LEVEL_ATTEMPTS - 1):
            try:
                return learn_level(
                    motor, saturation, settings, drive, share, seconds=samples * settings.h,
                    seed=next(logs),
                )  # fmt: skip
            except SelftuneError as error:
                refusals.append((share, str(error)))
                if isinstance(error, TooLittleData):  # logged again as long as it asks
                    samples = longer_batch(error, samples, planned, settings.h) or samples
        return learn_level(
            motor, saturation, settings, drive, share, seconds=samples * settings.h,
            seed=next(logs),
        )  # fmt: skip

    def learned(share: float) -> CurrentLevel:
        level = attempted(share)
        count[0] += 1
        if progress is not None:
            progress(count[0])
        return level

    def refused(error: SelftuneError, share: float) -> SelftuneError:
        """A level's refusal that refuses the commissioning, told as that level's."""
        current = float(motor.current_reference(share * settings.torque)[1])
        return error.retold(
            f"the level at {share:.0%} of rated torque (i_q* = {current:.4g} A), all "
            f"{LEVEL_ATTEMPTS} of its logs refused; the last: {error}"
        )

    count = [0]
    levels: dict[float, CurrentLevel] = {}
    unlearned: list[tuple[float, SelftuneError]] = []

    def left_below(share: float, error: SelftuneError) -> None:
        """A level below every one learned, refused on its every log: left out."""
        refusals.append((share, str(error)))
        unlearned.append((share, error))

    for share in shares:
        try:
            levels[share] = learned(share)
        except SelftuneError as error:
            if levels or share == shares[-1]:  # only levels below every one learned
                raise refused(error, share) from error
            left_below(share, error)
    if len(levels) < 2:
        raise refused(unlearned[-1][1], unlearned[-1][0])
    for _ in range(LOW_BISECTIONS if unlearned else 0):  # nearer the currents held below
        middle = 0.5 * (max(share for share, _ in unlearned) + min(levels))
        try:
            levels[middle] = learned(middle)
        except SelftuneError as error:
            left_below(middle, error)
    while len(levels) < MAX_LEVELS:
        moving = [
            (a, b)
            for a, b in pairwise(sorted(levels))
            if inductances_move(levels[a].theta, levels[b].theta)
        ]
        if not moving:
            break
        middle = 0.5 * sum(moving[0])
        try:
            levels[middle] = learned(middle)
        except SelftuneError as error:
            raise refused(error, middle) from error
    learned_levels = tuple(levels[share] for share in sorted(levels))
    names = [f"{level.share:.0%}" for level in learned_levels]
    kept, why = kept_levels(
        names, np.array([level.theta for level in learned_levels]),
        np.array([level.standard_errors for level in learned_levels]), motor.R_s, settings.h,
        small_levels(float(np.hypot(*learned_levels[-1].reference)), settings.torque),
    )  # fmt: skip
    found, imprecise, loose = precise_levels(
        with_curvature([learned_levels[k] for k in kept]), [names[k] for k in kept]
    )
    currents = np.array([level.reference[1] for level in found])
    thetas = np.array([level.theta for level in found])
    structure = IncrementalStructure(w_e, settings.h, False, drive.voltage_hold)
    integral_weight = _learning_problem(settings).integral_weight
    design = schedule_over_levels(
        currents, thetas, structure, settings.Q, settings.R,
        input_delay=found[-1].learned.law.history, integral_weight=integral_weight,
    )  # fmt: skip
    speed_design = None
    if speeds is not None:
        speed_design = schedule_over_speed_and_levels(
            currents, thetas, structure, settings.Q, settings.R,
            [motor.p * float(speed) for speed in speeds],
            input_delay=found[-1].learned.law.history, integral_weight=integral_weight,
        )  # fmt: skip
    left_out = tuple(level for k, level in enumerate(learned_levels) if k not in kept)
    left_out += imprecise
    why = "; ".join(text for text in (why, loose) if text)
    if unlearned:
        cause = str(unlearned[-1][1]).split(":")[0]
        named = ", ".join(f"{share:.0%}" for share, _ in unlearned)
        note = (
            f"{named} not learned, all {LEVEL_ATTEMPTS} logs of each refused (the last: "
            f"{cause}): the schedule starts at the lowest level learned, "
            f"{found[0].share:.0%}, whose law the firmware holds below it"
        )
        why = f"{note}; {why}" if why else note
    return CurrentCommissioning(
        found, design, integral_weight, tuple(refusals), left_out, why,
        tuple(share for share, _ in unlearned), speed_design,
    )  # fmt: skip
