"""The sampled current loop: its facts and its algebra, in one place.

A drive samples ``x_k = x(t_k)`` and the reference ``w_k`` (held over the sample) every
``h`` seconds, computes the voltage ``u_k`` with a :class:`~selftune.core.ControlLaw` and
applies it over ``[t_(k+d), t_(k+d+1))``: ``d`` is the computation delay in samples. With
integral action the controller also runs ``z_(k+1) = z_k + h e_k``, ``e_k = C x_k + F w_k``.
The plant the controller sees is the delay- and integrator-augmented one, in the state::

    zeta_k = [xbar_k; ubar_(k-d); ...; ubar_(k-1); z_k],   xbar = x - X w,  ubar = u - U w

    zeta_(k+1) = Az zeta_k + Bz ubar_k,   Az = [[Ad, Bd, 0, ..., 0], [shift], [h C, 0, I]]

(``x_(k+1) = Ad x_k + Bd u_(k-d) + Ed w_k``; with ``C X + F = 0``, ``e_k = C xbar_k``).
Every law is the gain ``Kz`` over ``zeta``: ``ubar_k = -Kz zeta_k``. Costs of the loop:

- ``"digital"``: ``sum_k h (xbar_k' Q xbar_k + ubar_k' R ubar_k + z_k' Q_i z_k)``,
  computable from samples alone: ``Qz = h blockdiag(Q, 0, ..., 0, Q_i)``, ``Rz = h R``;
- ``"sampled"``: the continuous cost ``int (xbar'Q xbar + abar'R abar) dt`` integrated
  exactly over each sample with the voltage actually applied, ``a_k = u_(k-d)``
  (Van Loan's weights ``[[Qd, N], [N', Rd]]`` of one sample,
  :func:`~selftune.core.sampled_data_weights`), plus ``h z_k' Q_i z_k`` (z is held). For
  ``d >= 1`` each stage is charged d samples early, when its voltage is computed: stage
  ``k + d`` is ``[xbar_(k+d); ubar_k]' W [xbar_(k+d); ubar_k]`` with ``xbar_(k+d) = Cz
  zeta_k`` (``Cz``: the first n rows of ``Az^d``), so ``Qz = Cz' Qd Cz``, ``Nz = Cz' N``,
  ``Rz = Rd``. The first d stages depend on ``zeta_0`` alone and no decision changes
  them: K is the infinite-horizon optimum, and the value adds them
  (:attr:`LoopWeights.first_stages`), so ``P`` is the value of the whole sampled cost.
  Shifting only the ``Rd`` term gives the same K with an indefinite joint weight, outside
  the conditions under which the Riccati equation is known to have a stabilizing
  solution; that is why the whole stage is shifted.

The optimal cost from ``zeta_0`` is ``zeta_0' P zeta_0``. The continuous loop is the one
with ``h = 0`` (as python-control's ``dt = 0``): ``[xbar; z]' = A_aug [xbar; z] + B_aug
ubar`` with ``z' = C xbar``, the cost ``int (xbar'Q xbar + ubar'R ubar + z'Q_i z) dt``
and the continuous Riccati equation; it has no delay.

The model's optimum (:mod:`selftune.model`), identify-then-design and the verdict's
safety check (:mod:`selftune.learn`), the reports and the bench all ask a
:class:`SampledLoop`; none rebuilds this algebra. SI units: h in s; for the motor x in A,
u in V.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np
from numpy.typing import ArrayLike

from ..core import (
    Array,
    ControlLaw,
    as_matrix,
    check_positive_definite,
    continuous_from_discrete,
    delay_augmented,
    dlqr,
    dpolicy_value,
    dpolicy_values,
    integrator_augmented,
    lqr,
    policy_value,
    positive_integer,
    sampled_data_weights,
)
from ..errors import InputError, UnsolvableError
from ._weights import LoopWeights

__all__ = ["Cost", "Hold", "SampledLoop"]

#: The costs of a loop (see the module docstring).
Cost = Literal["digital", "sampled"]

#: What the drive holds over a sample: the dq voltage (``"rotor"``), or the stationary-frame
#: voltage of a PWM inverter, which turns in dq as the rotor turns (``"stationary"``).
Hold = Literal["rotor", "stationary"]


def _stacked(plants: Sequence[tuple[ArrayLike, ArrayLike]]) -> tuple[Array, Array]:
    """Several plants ``(Ad, Bd)`` as the stacks ``(p, n, n)`` and ``(p, n, m)``."""
    return np.array([A for A, _ in plants], float), np.array([B for _, B in plants], float)


@dataclass(frozen=True, init=False)
class SampledLoop:
    """The facts of a drive's current loop: how it samples, delays, holds and integrates.

    Parameters
    ----------
    h : float
        Sampling period, s; 0 for the continuous-time loop.
    input_delay : int
        d, samples from computing a voltage to applying it (0 or more; 1 on most drives;
        0 for the continuous loop).
    hold : {"rotor", "stationary"}
        What the drive holds over a sample (see :data:`Hold`).
    C : array_like, shape (r, n), optional
        The regulated output of the integrator ``z_(k+1) = z_k + h (C x_k + F w_k)``;
        None (default): no integral action.
    F : array_like, shape (r, q), optional
        The integrator's reference part (with C).
    Q_i : array_like, shape (r, r), optional
        The weight of z in the cost, symmetric positive definite (with C; needed for the
        loop's weights and optimum, not for its closed loop).

    Attributes
    ----------
    r : int
        Number of integrator states (0 without integral action).
    continuous : bool
        Whether ``h = 0``.

    Raises
    ------
    InputError
        Naming the field: h negative or not finite, d not a whole number >= 0 (or a delay
        on the continuous loop), an unknown hold, or C, F, Q_i of inconsistent shapes.
    """

    h: float
    input_delay: int
    hold: Hold
    C: Array | None
    F: Array | None
    Q_i: Array | None

    def __init__(
        self,
        h: float,
        input_delay: int = 0,
        hold: Hold = "rotor",
        *,
        C: ArrayLike | None = None,
        F: ArrayLike | None = None,
        Q_i: ArrayLike | None = None,
    ) -> None:
        if isinstance(h, bool) or not isinstance(h, (int, float, np.floating, np.integer)):
            raise InputError(f"h: expected a number of seconds, got {h!r}")
        period = float(h)
        if not np.isfinite(period) or period < 0.0:
            raise InputError(f"h: must be a finite number >= 0 s (0: continuous), got {h!r}")
        delay = positive_integer(input_delay, "input_delay", minimum=0)
        if period == 0.0 and delay:
            raise InputError("input_delay: the continuous loop (h = 0) has no delay")
        if hold not in get_args(Hold):
            raise InputError(f"hold: expected 'rotor' or 'stationary', got {hold!r}")
        C_ = F_ = Q_i_ = None
        if C is not None:
            if F is None:
                raise InputError("F: integral action needs the regulated output's F with C")
            C_ = as_matrix(C, "C")
            F_ = as_matrix(F, "F", (C_.shape[0], None))
            if Q_i is not None:
                Q_i_ = check_positive_definite(
                    as_matrix(Q_i, "Q_i", (C_.shape[0], C_.shape[0])), "Q_i"
                )
        elif F is not None or Q_i is not None:
            raise InputError("C: integral action (F, Q_i) needs the regulated output C")
        for name, value in (("C", C_), ("F", F_), ("Q_i", Q_i_)):
            if value is not None:
                value.setflags(write=False)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "h", period)
        object.__setattr__(self, "input_delay", delay)
        object.__setattr__(self, "hold", hold)

    @classmethod
    def of_law(cls, law: ControlLaw, h: float, input_delay: int | None = None) -> SampledLoop:
        """The loop ``law`` runs in: its integrator (C, F, no weight), sampled at h, with a
        delay of ``input_delay`` samples (default: the past inputs the law feeds back).

        Parameters
        ----------
        law : ControlLaw
            The controller.
        h : float
            Sampling period, s.
        input_delay : int, optional
            d, samples; default ``law.history``.

        Returns
        -------
        SampledLoop
        """
        delay = law.history if input_delay is None else input_delay
        return cls(h, delay, C=law.C, F=law.F)

    @property
    def r(self) -> int:
        """Number of integrator states."""
        return 0 if self.C is None else self.C.shape[0]

    @property
    def continuous(self) -> bool:
        """Whether this is the continuous-time loop (h = 0)."""
        return self.h == 0.0

    def size(self, n: int, m: int) -> int:
        """The dimension of ``zeta`` for n states and m inputs: ``n + d m + r``.

        Parameters
        ----------
        n : int
            State dimension.
        m : int
            Input dimension.
        """
        return n + self.input_delay * m + self.r

    def augmented(self, A: ArrayLike, B: ArrayLike) -> tuple[Array, Array]:
        """The plant the controller sees: ``(Az, Bz)`` over ``zeta``.

        Parameters
        ----------
        A : array_like, shape (n, n)
            ``Ad`` of the sampled plant (A of the continuous plant when h = 0); or a
            stack of them, ``(p, n, n)`` (then B too, and the result, one more axis).
        B : array_like, shape (n, m)
            ``Bd``, the effect of the applied (held) voltage (B when h = 0).

        Returns
        -------
        Az : ndarray, shape (nz, nz)
        Bz : ndarray, shape (nz, m)
        """
        Az, Bz = delay_augmented(A, B, self.input_delay)
        if self.C is None:
            return Az, Bz
        n = np.shape(A)[-1]
        if self.C.shape[1] != n:
            raise InputError(f"C: has {self.C.shape[1]} columns, the plant has {n} states")
        C_full = np.zeros((self.r, Az.shape[-1]))
        C_full[:, :n] = self.C
        return integrator_augmented(Az, Bz, C_full, None if self.continuous else self.h)

    def weights(
        self,
        Q: ArrayLike,
        R: ArrayLike,
        cost: Cost = "digital",
        *,
        plant: tuple[ArrayLike, ArrayLike] | None = None,
        continuous_plant: tuple[ArrayLike, ArrayLike] | None = None,
    ) -> LoopWeights:
        """The weights of the loop's cost over ``(zeta_k, ubar_k)`` (the module docstring).

        Parameters
        ----------
        Q : array_like, shape (n, n)
            Continuous state weight, symmetric positive semidefinite.
        R : array_like, shape (m, m)
            Continuous input weight, symmetric positive definite.
        cost : {"digital", "sampled"}
            The cost (the continuous loop has one: its integral). The digital cost needs
            no plant: a learner computes it from samples.
        plant : (Ad, Bd), optional
            The sampled plant: needed for the sampled cost only.
        continuous_plant : (A, B), optional
            The continuous plant for the sampled cost; default: recovered from the
            sampled plant by the matrix logarithm
            (:func:`~selftune.core.continuous_from_discrete`).

        Returns
        -------
        LoopWeights

        Raises
        ------
        InputError
            An unknown cost, the sampled cost without the plant, or a loop with integral
            action but no ``Q_i``.
        """
        if cost not in get_args(Cost):
            raise InputError(f"cost: expected 'digital' or 'sampled', got {cost!r}")
        Q_ = np.asarray(Q, dtype=float)
        R_ = np.asarray(R, dtype=float)
        n, m = Q_.shape[0], R_.shape[0]
        size = n + self.input_delay * m
        Qz, Nz, first = np.zeros((size, size)), np.zeros((size, m)), np.zeros((size, size))
        if self.continuous or cost == "digital":
            scale = 1.0 if self.continuous else self.h
            Qz[:n, :n] = scale * Q_
            Rz = scale * R_
        else:
            if plant is None:
                raise InputError("plant: the sampled cost needs the sampled plant (Ad, Bd)")
            A, B = continuous_plant if continuous_plant is not None else (None, None)
            if A is None or B is None:
                A, B, _ = continuous_from_discrete(*plant, self.h)
            Qd, Rz, N = sampled_data_weights(A, B, Q_, R_, self.h)
            W = np.block([[Qd, N], [N.T, Rz]])
            Az, _ = delay_augmented(*plant, self.input_delay)
            Cz = np.linalg.matrix_power(Az, self.input_delay)[:n]
            Qz, Nz = Cz.T @ Qd @ Cz, Cz.T @ N
            power = np.eye(size)
            for _ in range(self.input_delay):  # stage j: first n + m rows of Az^j zeta_0
                selected = power[: n + m]
                first += selected.T @ W @ selected
                power = Az @ power
        return self._with_integrator(LoopWeights(Qz=Qz, Rz=Rz, Nz=Nz, first_stages=first))

    def _with_integrator(self, weights: LoopWeights) -> LoopWeights:
        """The weights padded for z: ``h Q_i`` (``Q_i`` continuous), no cross term."""
        if self.C is None:
            return weights
        if self.Q_i is None:
            raise InputError("Q_i: the cost of a loop with integral action needs Q_i")
        r, size = self.r, weights.Qz.shape[0]
        scale = 1.0 if self.continuous else self.h
        Qz = np.zeros((size + r, size + r))
        Qz[:size, :size] = weights.Qz
        Qz[size:, size:] = scale * self.Q_i
        first = np.zeros_like(Qz)
        first[:size, :size] = weights.first_stages
        Nz = np.vstack([weights.Nz, np.zeros((r, weights.Nz.shape[1]))])
        return LoopWeights(Qz=Qz, Rz=weights.Rz, Nz=Nz, first_stages=first)

    def gain(self, law: ControlLaw) -> Array:
        """The law as the gain ``Kz`` over ``zeta`` (``ubar_k = -Kz zeta_k``).

        A law that feeds back fewer past inputs than the delay (``history < d``) has zero
        gain on the older ones.

        Parameters
        ----------
        law : ControlLaw
            The controller (``history <= d``; ``K_i`` exactly when the loop integrates).

        Returns
        -------
        ndarray, shape (m, nz)

        Raises
        ------
        InputError
            If the law feeds back more past inputs than the delay, or has integral action
            where the loop has none (or the reverse).
        """
        n, m, d = law.n, law.m, self.input_delay
        if law.history > d:
            raise InputError(
                f"law: feeds back {law.history} past inputs, the loop delays by {d} samples"
            )
        if law.r != self.r:
            raise InputError(
                f"law: has {law.r} integrator states, the loop has {self.r} (C of the loop)"
            )
        Kz = np.zeros((m, self.size(n, m)))
        Kz[:, :n] = law.K_x
        for lag in range(1, law.history + 1):  # u_(k-lag) sits in block d - lag
            block = n + (d - lag) * m
            column = n + (law.history - lag) * m
            Kz[:, block : block + m] = law.K[:, column : column + m]
        if law.K_i is not None:
            Kz[:, n + d * m :] = law.K_i
        return Kz

    def law(
        self, Kz: ArrayLike, X: ArrayLike, U: ArrayLike, *, h: float | None = None
    ) -> ControlLaw:
        """The :class:`ControlLaw` of a gain over ``zeta``: its last r columns are ``K_i``.

        Parameters
        ----------
        Kz : array_like, shape (m, nz)
            The gain over ``zeta``.
        X : array_like, shape (n, q)
            Steady-state map of the state.
        U : array_like, shape (m, q)
            Feedforward map of the input.
        h : float, optional
            The period the drive runs the integrator at, s: the loop's h by default; needed
            for a continuous loop with integral action (a drive runs it digitally).

        Returns
        -------
        ControlLaw
        """
        K = np.asarray(Kz, dtype=float)
        width = K.shape[1] - self.r
        if self.C is None:
            return ControlLaw(K, X, U, history=self.input_delay)
        period = self.h if h is None else h
        if period == 0.0:
            raise InputError("h: the integral action's law needs the drive's sampling period")
        return ControlLaw(
            K[:, :width], X, U, history=self.input_delay, K_i=K[:, width:], C=self.C,
            F=self.F, h=period,
        )  # fmt: skip

    def closed_loop(
        self, plant: tuple[ArrayLike, ArrayLike], law: ControlLaw, Ed: ArrayLike | None = None
    ) -> tuple[Array, Array]:
        """The loop closed by ``law``: ``s_(k+1) = A_cl s_k + B_w w_k``.

        ``s_k = [x_k; u_(k-d); ...; u_(k-1); z_k]`` in absolute terms (the same transition
        matrix as the deviations ``zeta``, :meth:`gain`).

        Parameters
        ----------
        plant : (Ad, Bd)
            The sampled plant ((A, B) when h = 0: then ``s' = A_cl s + B_w w``); or a
            stack of them (:meth:`augmented`; then the result has one more axis).
        law : ControlLaw
            The controller.
        Ed : array_like, shape (n, q), optional
            The effect of the held reference on ``x_(k+1)`` (default zero).

        Returns
        -------
        A_cl : ndarray, shape (nz, nz)
        B_w : ndarray, shape (nz, q)
        """
        Az, Bz = self.augmented(*plant)
        Kz = self.gain(law)
        n, q = law.n, law.q
        feed = law.U + law.K_x @ law.X + (law.K[:, n:] @ np.tile(law.U, (law.history, 1)))
        B_w = Bz @ feed
        if Ed is not None:
            B_w[..., :n, :] += as_matrix(Ed, "Ed", (n, q))
        if law.F is not None:
            B_w[..., Az.shape[-1] - law.r :, :] += (1.0 if self.continuous else self.h) * law.F
        return Az - Bz @ Kz, B_w

    def spectral_radius(self, plant: tuple[ArrayLike, ArrayLike], law: ControlLaw) -> float:
        """``max |eig(A_cl)|`` of the digital loop: below 1 when ``law`` stabilizes it.

        Parameters
        ----------
        plant : (Ad, Bd)
            The sampled plant.
        law : ControlLaw
            The controller.
        """
        return float(self.spectral_radii([plant], law)[0])

    def spectral_radii(
        self, plants: Sequence[tuple[ArrayLike, ArrayLike]], law: ControlLaw
    ) -> Array:
        """:meth:`spectral_radius` of ``law`` on each of several plants (their
        eigenvalues in one call).

        Parameters
        ----------
        plants : sequence of (Ad, Bd)
            The sampled plants.
        law : ControlLaw
            The controller.

        Returns
        -------
        ndarray, shape (len(plants),)
        """
        return np.asarray(np.max(np.abs(self.poles(plants, law)), axis=1), dtype=np.float64)

    def poles(self, plants: Sequence[tuple[ArrayLike, ArrayLike]], law: ControlLaw) -> Array:
        """The z-plane poles (eigenvalues of :meth:`closed_loop`), shape ``(len(plants),
        nz)``, of the digital loop of ``law`` on each of several plants.

        Parameters
        ----------
        plants : sequence of (Ad, Bd)
            The sampled plants.
        law : ControlLaw
            The controller.
        """
        if self.continuous:
            raise InputError("h: the spectral radius is of a sampled loop (h > 0)")
        A_cl, _ = self.closed_loop(_stacked(plants), law)
        return np.asarray(np.linalg.eigvals(A_cl))

    def step_from_rest(self, X: ArrayLike, U: ArrayLike, w: ArrayLike) -> Array:
        """The loop's state ``zeta_0`` at a step of the reference from rest to ``w``: the
        state, the past inputs (``delay`` of them) and the integrators (zero) as deviations
        from the new steady state ``(X w, U w)``; the step's cost is ``zeta_0' P zeta_0``.

        Parameters
        ----------
        X : array_like, shape (n, q)
            The steady-state map.
        U : array_like, shape (m, q)
            The feedforward map.
        w : array_like, shape (q,)
            The reference after the step.
        """
        X_, U_, w_ = (np.asarray(value, dtype=float) for value in (X, U, w))
        return np.concatenate([-X_ @ w_, np.tile(-U_ @ w_, self.input_delay), np.zeros(self.r)])

    def value(
        self,
        plant: tuple[ArrayLike, ArrayLike],
        law: ControlLaw,
        weights: LoopWeights,
    ) -> Array:
        """The value matrix of ``law`` on the loop: its cost from ``zeta_0`` is
        ``zeta_0' P zeta_0`` (the first stages included).

        Parameters
        ----------
        plant : (Ad, Bd)
            The sampled plant ((A, B) when h = 0).
        law : ControlLaw
            The controller.
        weights : LoopWeights
            The cost (:meth:`weights`).

        Raises
        ------
        UnsolvableError
            If the law does not stabilize the loop (its cost is infinite).
        """
        Az, Bz = self.augmented(*plant)
        Kz = self.gain(law)
        if self.continuous:
            return policy_value(Az, Bz, Kz, weights.Qz, weights.Rz)
        P = dpolicy_value(Az, Bz, Kz, weights.Qz, weights.Rz, weights.Nz)
        return P + weights.first_stages

    def values(
        self,
        plants: Sequence[tuple[ArrayLike, ArrayLike]],
        law: ControlLaw | Sequence[ControlLaw],
        weights: LoopWeights,
    ) -> tuple[Array, Array]:
        """:meth:`value` on each of several sampled plants in one solve (the weights checked
        once, :func:`~selftune.core.dpolicy_values`), and the loop's spectral radii: the
        value is finite below 1, every entry ``inf`` otherwise (InputError on h = 0).

        Parameters
        ----------
        plants : sequence of (Ad, Bd)
            The sampled plants (at least one).
        law : ControlLaw or sequence of ControlLaw
            The controller on every plant, or one controller per plant.
        weights : LoopWeights
            The cost (:meth:`weights`).

        Returns
        -------
        P : ndarray, shape (len(plants), nz, nz)
        radii : ndarray, shape (len(plants),)
        """
        if self.continuous:
            raise InputError("h: the values of a stack of plants are of a sampled loop (h > 0)")
        Az, Bz = self.augmented(*_stacked(plants))
        laws = [law] * len(plants) if isinstance(law, ControlLaw) else law
        if len(laws) != len(plants):
            raise InputError(f"law: {len(laws)} laws for {len(plants)} plants")
        Kz = np.array([self.gain(each) for each in laws])
        P, radii = dpolicy_values(Az, Bz, Kz, weights.Qz, weights.Rz, weights.Nz)
        return P + weights.first_stages, radii

    def optimum(
        self, plant: tuple[ArrayLike, ArrayLike], weights: LoopWeights, *, checked: bool = False
    ) -> tuple[Array, Array]:
        """The optimal gain over ``zeta`` and its value (the Riccati equation of the
        augmented plant; the first stages added to the value).

        Parameters
        ----------
        plant : (Ad, Bd)
            The sampled plant ((A, B) when h = 0).
        weights : LoopWeights
            The cost (:meth:`weights`).
        checked : bool, optional
            The weights are known to be as :func:`~selftune.core.dlqr` requires (the
            digital cost of a checked Q and R): not checked again (default False).

        Returns
        -------
        Kz : ndarray, shape (m, nz)
        P : ndarray, shape (nz, nz)

        Raises
        ------
        UnsolvableError
            Naming the loop and the failing condition (stabilizability, detectability).
        """
        Az, Bz = self.augmented(*plant)
        try:
            if self.continuous:
                return lqr(Az, Bz, weights.Qz, weights.Rz)
            Kz, P = dlqr(Az, Bz, weights.Qz, weights.Rz, weights.Nz, checked=checked)
        except UnsolvableError as exc:
            raise UnsolvableError(f"{self.describe()}: {exc}") from None
        P = P + weights.first_stages
        return Kz, 0.5 * (P + P.T)

    def describe(self) -> str:
        """The loop in words, for messages: ``"the plant sampled at h = 0.0001 s with a
        delay of 1 samples and an integrator"``."""
        integrator = "" if self.C is None else " and an integrator"
        if self.continuous:
            return f"the continuous plant{integrator.replace(' and', ' with')}"
        return (
            f"the plant sampled at h = {self.h:g} s with a delay of {self.input_delay} samples"
            f"{integrator}"
        )
