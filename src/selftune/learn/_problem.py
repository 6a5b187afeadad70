"""What a learner is told, and how it is asked to learn: the two inputs of every learner.

:class:`LearningProblem` holds what an engineer knows without a model of the plant: the
regulated output and the reference (C, E, F), the cost weights, a stabilizing feedback
K0 and, for integral action, the weight of the integrated error. :class:`LearningOptions`
says which controller to learn (``target``), how (``method``), how the log is aligned
(``input_delay``, ``logged_input``) and how long to iterate.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from ..core import (
    Array,
    as_matrix,
    check_positive_definite,
    check_weights,
    finite_float,
    positive_finite,
    positive_integer,
)
from ..errors import InputError, SelftuneDeprecationWarning
from ..loop import SampledLoop
from .evidence._alignment import LoggedInput, stated_shift
from .learners._policy_iteration import check_iteration_settings

__all__ = ["LearningOptions", "LearningProblem", "Method", "Target"]

Target = Literal["continuous", "digital"]
Method = Literal["adp", "identify"]

#: Default integral bandwidth, rad/s: the integral weight is this squared times the
#: weight of the regulated error (see :class:`LearningProblem`).
INTEGRAL_BANDWIDTH = 200.0


@dataclass(frozen=True, init=False)
class LearningProblem:
    """What the learner knows of the problem: the output to regulate and the cost.

    The plant ``x' = A x + B u + D w`` (A, B, D unknown) is to be regulated so that
    ``e = C x + F w -> 0``, with ``w`` held over each sample (``E = 0``) or an exosystem
    ``w' = E w``, at the least cost ``integral of xbar' Q xbar + ubar' R ubar`` (continuous
    target) or ``sum_k h (xbar_k' Q xbar_k + ubar_k' R ubar_k)`` (digital target), plus
    ``z' Q_i z`` with integral action, ``z`` the integral of ``e``. Every learner takes
    the data, this problem, the stabilizing feedback K0 the data start from, and the
    options, in that order.

    Parameters
    ----------
    Q : array_like, shape (n, n)
        State weight, symmetric positive semidefinite.
    R : array_like, shape (m, m)
        Input weight, symmetric positive definite.
    C : array_like, shape (r, n), optional
        Regulated output; None for plain optimal state feedback (no ``w``).
    E : array_like, shape (q, q), optional
        Exosystem; all zeros (the default with C): ``w`` is held over each sample.
    F : array_like, shape (r, q), optional
        Reference part of the regulated output.
    integral_action : bool
        Learn the optimal servo controller: the state is augmented with ``z``, the
        integral of ``e``, weighted by ``integral_weight``.
    integral_weight : array_like, shape (r, r), optional
        ``Q_i``, symmetric positive definite; default ``(200 rad/s)^2 C Q C'`` regularized
        (:data:`INTEGRAL_BANDWIDTH`), i.e. an integral corner near 200 rad/s.
    K0 : array_like, optional
        Deprecated: give K0 to the learner (``learn_controller(data, problem, K0,
        options)``). Still kept here, with a deprecation warning, for code written for
        ``learn_controller(data, problem, options)``.

    Attributes
    ----------
    n, m, q, r : int
        Dimensions of x, u, w and e (q = r = 0 for plain state feedback).
    """

    Q: Array
    R: Array
    C: Array | None
    E: Array | None
    F: Array | None
    integral_weight: Array | None
    K0: Array | None

    def __init__(
        self,
        Q: ArrayLike,
        R: ArrayLike,
        C: ArrayLike | None = None,
        E: ArrayLike | None = None,
        F: ArrayLike | None = None,
        integral_action: bool = False,
        integral_weight: ArrayLike | None = None,
        *,
        K0: ArrayLike | None = None,
    ) -> None:
        R_ = as_matrix(R, "R")
        m = R_.shape[0]
        Q_ = as_matrix(Q, "Q")
        n = Q_.shape[0]
        Q_, R_ = check_weights(Q_, R_, n, m)
        values: dict[str, Array | None] = {"Q": Q_, "R": R_, "K0": None}
        values.update(_regulation(C, E, F, n))
        values["integral_weight"] = _integral_weight(
            integral_action, integral_weight, values["C"], Q_
        )
        if K0 is not None:
            warnings.warn(
                "LearningProblem(K0=...) is deprecated: give K0 to the learner, "
                "learn_controller(data, problem, K0, options)",
                SelftuneDeprecationWarning,
                stacklevel=2,
            )
            values["K0"] = as_matrix(K0, "K0", (m, n))
        for name, value in values.items():
            if value is not None:
                value.setflags(write=False)
            object.__setattr__(self, name, value)

    @property
    def n(self) -> int:
        """State dimension."""
        return int(self.Q.shape[0])

    @property
    def m(self) -> int:
        """Input dimension."""
        return int(self.R.shape[0])

    def with_F(self, F: ArrayLike | None) -> LearningProblem:
        """This problem with another F (and E = 0: ``w`` held), the rest kept.

        Parameters
        ----------
        F : array_like, shape (r, q'), or None
            The new reference part of the regulated output.
        """
        q = 0 if F is None else np.shape(F)[1]
        problem = LearningProblem(
            self.Q, self.R, C=self.C, E=None if F is None else np.zeros((q, q)), F=F,
            integral_action=self.integral_weight is not None,
            integral_weight=self.integral_weight,
        )  # fmt: skip
        object.__setattr__(problem, "K0", self.K0)  # the deprecated K0 travels with it
        return problem

    def loop(self, h: float, delay: int) -> SampledLoop:
        """The loop of the problem's integral action (none without it), sampled at h (0
        for the continuous loop) with a delay of d samples.

        Parameters
        ----------
        h : float
            Sampling period, s (0: continuous).
        delay : int
            d, the drive's computation delay, samples.
        """
        if self.integral_weight is None:
            return SampledLoop(h, delay)
        return SampledLoop(h, delay, C=self.C, F=self.F, Q_i=self.integral_weight)

    def initial_policy(self, K0: ArrayLike, extra: int = 0) -> Array:
        """K0 validated for this problem, over x and ``extra`` more states (a delay's past
        inputs, an integrator): given ``(m, n)`` it is padded with zeros (no feedback of
        the extra states); ``(m, n + extra)`` is taken as it is.

        Parameters
        ----------
        K0 : array_like
            The stabilizing feedback the data start from (V/A on the motor's currents).
        extra : int
            The augmented state's extra columns (0: none).

        Raises
        ------
        InputError
            Naming K0 and the shapes it may have.
        """
        return padded_policy(as_matrix(K0, "K0", (self.m, None)), self.n, self.n + extra)

    @property
    def q(self) -> int:
        """Exogenous-signal dimension (0 without regulation)."""
        return 0 if self.F is None else int(self.F.shape[1])

    @property
    def r(self) -> int:
        """Regulated-output dimension (0 without regulation)."""
        return 0 if self.C is None else int(self.C.shape[0])

    @property
    def held(self) -> bool:
        """Whether ``w`` is held over each sample (E = 0)."""
        return self.E is None or not np.any(self.E)


def padded_policy(K0: Array, n: int, width: int) -> Array:
    """``[K0, 0]`` over a state of ``width`` (the first n: x), or K0 if already that wide.

    Parameters
    ----------
    K0 : ndarray, shape (m, n) or (m, width)
        A policy on x, or on the whole state.
    n : int
        The dimension of x.
    width : int
        The dimension of the whole state.

    Raises
    ------
    InputError
        If K0 has another number of columns.
    """
    if K0.shape[1] == width:
        return K0
    if K0.shape[1] != n:
        shapes = f"({K0.shape[0]}, {n})" + (f" or ({K0.shape[0]}, {width})" if width != n else "")
        raise InputError(f"K0: expected shape {shapes}, got {K0.shape}")
    return np.hstack([K0, np.zeros((K0.shape[0], width - n))])


def _regulation(
    C: ArrayLike | None, E: ArrayLike | None, F: ArrayLike | None, n: int
) -> dict[str, Array | None]:
    if C is None:
        if E is not None or F is not None:
            raise InputError("C: E and F are given, so C is needed too")
        return {"C": None, "E": None, "F": None}
    C_ = as_matrix(C, "C", (None, n))
    if F is None:
        raise InputError("F: the regulated output e = C x + F w needs F (r x q)")
    F_ = as_matrix(F, "F", (C_.shape[0], None))
    q = F_.shape[1]
    E_ = np.zeros((q, q)) if E is None else as_matrix(E, "E", (q, q))
    return {"C": C_, "E": E_, "F": F_}


def _integral_weight(
    integral_action: bool, weight: ArrayLike | None, C: Array | None, Q: Array
) -> Array | None:
    if not isinstance(integral_action, bool):
        raise InputError(f"integral_action: must be true or false, got {integral_action!r}")
    if not integral_action:
        if weight is not None:
            raise InputError("integral_weight: given, but integral_action is off")
        return None
    if C is None:
        raise InputError("integral_action: needs a regulated output e = C x + F w (give C, E, F)")
    r = C.shape[0]
    if weight is not None:
        return check_positive_definite(
            as_matrix(weight, "integral_weight", (r, r)), "integral_weight"
        )
    projected = C @ Q @ C.T
    scale = max(float(np.max(np.abs(projected))), float(np.max(np.abs(Q))))
    default = INTEGRAL_BANDWIDTH**2 * (projected + 1e-6 * scale * np.eye(r))
    return 0.5 * (default + default.T)


@dataclass(frozen=True)
class LearningOptions:
    """How to learn: which controller, by which method, from which alignment of the log.

    Attributes
    ----------
    target : {"continuous", "digital"}
        ``"continuous"``: the optimum of the continuous cost in continuous time (the
        paper's K*). ``"digital"``: the optimum of the digital cost of the sampled loop
        the drive runs, with its computation delay (``input_delay``).
    method : {"adp", "identify"}
        ``"adp"``: adaptive dynamic programming, learning the controller without a model
        (the paper's continuous-time learner for the continuous target, the discrete-time
        one for the digital target). ``"identify"``: identify-then-design (least squares
        for the exact discrete model, then the model-based optimum of the target).
        Where ADP's policy iteration fails on a noisy batch (a value matrix that is not
        positive definite, a value that rises) and the output-error model exists, the
        controller is designed from that model instead: the result's ``method`` is then
        ``"identify"`` and its quality notes why.
    input_delay : int
        d, the drive's computation delay in samples (0, 1 or 2): the voltage computed at
        sample k acts over ``[t_(k+d), t_(k+d+1))``.
    logged_input : {"applied", "commanded", "auto"}
        What row k of the log holds: the voltage applied during sample k (default), the
        one commanded at sample k, or ``"auto"``: read the alignment off the data.
    interval : int
        Samples summed into each regression row of the ADP learners (at most: shorter
        when the logs would otherwise give fewer than two rows per unknown).
    max_iterations : int
        Upper bound on policy-iteration steps.
    tolerance : float
        Relative change of P at which policy iteration stops (at most 1e-3).
    structure : {"none", "spmsm", "ipmsm", "incremental"}
        Identify-then-design only: fit every entry of the discrete model (``"none"``), or
        only a surface PMSM's R_s, L_s and flux at ``electrical_speed`` (the known-flux form,
        n = m = q = 2), which needs far less data for the same accuracy, or an interior
        PMSM's R_s, L_d, L_q and flux (the current-reference form ``w = [w_1, i_d*,
        i_q*]``, q = 3; :class:`~selftune.learn.IpmsmStructure`), or a saturating PMSM's
        R_s, incremental inductance matrix and flux offset at the operating current (the
        same form; :class:`~selftune.learn.IncrementalStructure`).
    voltage_hold : {"stationary", "rotor"}
        What the drive holds over a sample, for ``structure = "spmsm"``: the
        stationary-frame voltage vector (a PWM inverter, with the usual angle
        compensation) or the dq voltage (an ideal zero-order hold, e.g. the library's
        ideal drive); see :class:`~selftune.learn.SpmsmStructure`.
    electrical_speed : float, optional
        ``p speed``, rad/s (constant over the logs): needed by ``structure = "spmsm"``; with
        ``dead_time`` it gives the rotor angle of logs without an angle column.
    dead_time : bool
        Model an inverter's dead time: an unlogged phase-voltage error ``-v sign(i_x)``,
        fitted and reported (``v``, V), so that it is not mistaken for back-EMF or
        feedforward and the consistency test does not refuse the data. It needs the rotor
        angle: the logs' angle column, else ``electrical_speed``; without either, the
        current's direction stands in for it, less accurately
        (:mod:`selftune.learn.evidence._dead_time`).
    noise : {"smoothed", "instruments", "none"}
        How the ADP learners meet measurement noise on the states (errors in variables):
        ``"smoothed"`` (default) builds their regressions from the output-error model's
        noise-free simulation of the log (consistent and efficient); ``"instruments"``
        keeps the measured states and uses that simulation as instruments (consistent,
        but several times noisier); ``"none"`` uses the measured states as they are
        (biased under noise; exact on noise-free data).
    max_relative_error : float
        The largest relative standard error of K and of U a result may have; beyond it
        the data are too short for their noise and the learner says how much longer they
        must be. With integral action U may reach 25% (it only shapes the transient:
        the integrator removes its steady error).
    dc_voltage : float, optional
        The inverter's DC bus, V, if known (a carrier PWM inverter, one carrier period a
        sample): with ``dead_time``, a surface or interior structure and the
        ``"stationary"`` hold, the reported motor's standard errors (``quality.motor``)
        then hold the shift the carrier's pulses leave in its parameters, which the held
        model does not carry (:mod:`selftune.learn.evidence._pulses`), and the fit on the
        phase signs the next sample shows is reported where it explains the data better
        and passes the tests (:func:`~selftune.learn.evidence._model_signs.reported_next_signs`).
    nameplate_resistance : float, optional
        The motor's nameplate R_s, ohm, if known: a structured fit whose R_s is beyond 2
        times it either way, by enough to move the sampled plant, is refused
        (:func:`~selftune.learn.verdict._nameplate.check_fit_against_nameplate`): the fit
        took something else for resistance, most likely the dead time near zero current,
        and its inductances with it (the commissionings of ``selftune tune`` check so).
    compare_without_structure : bool
        With a structure: where the structured fit is refused, fit the same data without
        it and say in the refusal what they give (True; one unstructured fit more).
        False where the caller cannot learn without the structure (a log over several
        speeds, :func:`~selftune.learn.learn_over_speeds`), so that the refusal does not
        suggest it.
    """

    target: Target = "continuous"
    method: Method = "adp"
    input_delay: int = 0
    logged_input: LoggedInput = "applied"
    interval: int = 10
    max_iterations: int = 50
    tolerance: float = 1e-9
    structure: Literal["none", "spmsm", "ipmsm", "incremental"] = "none"
    voltage_hold: Literal["stationary", "rotor"] = "stationary"
    electrical_speed: float | None = None
    dead_time: bool = False
    noise: Literal["smoothed", "instruments", "none"] = "smoothed"
    max_relative_error: float = 0.05
    dc_voltage: float | None = None
    nameplate_resistance: float | None = None
    compare_without_structure: bool = True

    def __post_init__(self) -> None:
        if self.target not in ("continuous", "digital"):
            raise InputError(f"target: must be 'continuous' or 'digital', got {self.target!r}")
        if self.method not in ("adp", "identify"):
            raise InputError(f"method: must be 'adp' or 'identify', got {self.method!r}")
        delay = positive_integer(self.input_delay, "input_delay", minimum=0)
        if delay > 2:
            raise InputError(f"input_delay: must be 0, 1 or 2 samples, got {delay}")
        stated_shift(self.logged_input, delay)
        positive_integer(self.interval, "interval")
        check_iteration_settings(self.max_iterations, self.tolerance)
        if self.structure not in ("none", "spmsm", "ipmsm", "incremental"):
            raise InputError(
                "structure: must be 'none', 'spmsm', 'ipmsm' or 'incremental', got "
                f"{self.structure!r}"
            )
        if self.voltage_hold not in ("stationary", "rotor"):
            raise InputError(
                f"voltage_hold: must be 'stationary' or 'rotor', got {self.voltage_hold!r}"
            )
        if self.noise not in ("smoothed", "instruments", "none"):
            raise InputError(
                f"noise: must be 'smoothed', 'instruments' or 'none', got {self.noise!r}"
            )
        for name in ("dead_time", "compare_without_structure"):
            if not isinstance(getattr(self, name), bool):
                raise InputError(f"{name}: must be true or false, got {getattr(self, name)!r}")
        positive_finite(self.max_relative_error, "max_relative_error")
        if self.dc_voltage is not None:
            positive_finite(self.dc_voltage, "dc_voltage")
        if self.nameplate_resistance is not None:
            positive_finite(self.nameplate_resistance, "nameplate_resistance")
        if self.electrical_speed is not None:
            finite_float(self.electrical_speed, "electrical_speed")
        if self.structure != "none":
            if self.method != "identify":
                raise InputError("structure: a model structure is for method = 'identify'")
            if self.electrical_speed is None:
                raise InputError(
                    f'electrical_speed: structure = "{self.structure}" needs p speed (rad/s)'
                )
