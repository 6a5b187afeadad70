"""The closed loop of digital control laws, sample by sample: the one stepper of every drive.

At sample k the drive measures the state ``y_k`` of each of its P plants; the law
(:class:`~selftune.core.ControlLaw`) computes, from it, the reference ``w_k``, the H inputs
it computed before and its integrator ``z_k``::

    u_k = limit(command(y_k, w_k, u_(k-H) .. u_(k-1), z_k) + rho_k)
    z_(k+1) = z_k + h (C y_k + F w_k)   (z_(k+1) = z_k where the limit acted, with
                                         anti-windup: selftune.core._voltage_limit)

and the drive applies ``u_(k-d)`` (zero before the first) over ``[t_k, t_(k+1))``, which
advances its plant to ``t_(k+1)``. The plant is the drive's: :class:`SampledPlant` (the
exact zero-order-hold discretization, :func:`selftune.core.discretize`), the inverter
model of :mod:`._inverter`, or gym-electric-motor (:mod:`._gem`); the stepper itself only
knows :class:`LoopPlant`.

The laws act through one linear map (:class:`Feedback`), read off
:meth:`ControlLaw.command` (:func:`feedback_of`), so P different laws step at once and the
equations stay the law's own. On exactly sampled plants the whole loop is linear: its
matrices are read off one step of the stepper (:func:`one_step_map`) and the samples
propagated all at once (:func:`run_sampled_loop`, and :func:`~selftune.sim.simulate`),
without a Python loop over the samples.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike

from ..core import Array, ControlLaw, discretize
from ..core._propagate import propagate_uniform
from ..core._voltage_limit import held_integrators
from ..errors import InputError
from ..learn import Trajectory

__all__ = [
    "ClosedLoop",
    "Feedback",
    "LoopPlant",
    "SampledPlant",
    "feedback_of",
    "fill_held",
    "one_step_map",
    "run_closed_loop",
    "run_sampled_loop",
]


@dataclass(frozen=True, eq=False)
class Feedback:
    """Laws as one linear map: ``gains @ [y; w; past; z] = [u; z_(k+1) - z_k]``.

    Attributes
    ----------
    gains : ndarray, shape (P, m + R, n + q + H m + R)
        The map (``u`` without exploration).
    n, m, q : int
        Dimensions of the measured state, the input and the reference.
    history, integrators : int
        H, past inputs fed back, and R, integrator states (the most of the laws').
    """

    gains: Array
    n: int
    m: int
    q: int
    history: int
    integrators: int


def feedback_of(laws: Sequence[ControlLaw]) -> Feedback:
    """The laws as one linear map (:class:`Feedback`).

    The map is read off by applying :meth:`ControlLaw.command` to the unit vectors (the
    law is linear), so the equations stay the law's own; shorter histories and fewer
    integrators are padded with zeros.

    Parameters
    ----------
    laws : sequence of ControlLaw
        P laws with the same n, m and q.

    Returns
    -------
    Feedback

    Raises
    ------
    InputError
        If the laws' dimensions differ.
    """
    n, m, q = laws[0].n, laws[0].m, laws[0].q
    for index, law in enumerate(laws):
        if (law.n, law.m, law.q) != (n, m, q):
            raise InputError(
                f"laws: item {index} has (n, m, q) = {(law.n, law.m, law.q)}, item 0 has "
                f"{(n, m, q)}"
            )
    history = max(law.history for law in laws)
    integrators = max(law.r for law in laws)
    size = n + q + m * history + integrators
    basis = np.eye(size)
    x, w = basis[:, :n], basis[:, n : n + q]
    past_all = basis[:, n + q : n + q + m * history].reshape(size, history, m)
    z_all = basis[:, size - integrators :]
    gains = np.zeros((len(laws), m + integrators, size))
    for index, law in enumerate(laws):
        past = past_all[:, history - law.history :]
        z = z_all[:, : law.r] if law.K_i is not None else None
        gains[index, :m] = law.command(x, w, past, z).T
        if law.K_i is not None and law.C is not None and law.F is not None and law.h:
            gains[index, m : m + law.r, :n] = law.h * law.C
            gains[index, m : m + law.r, n : n + q] = law.h * law.F
    return Feedback(gains=gains, n=n, m=m, q=q, history=history, integrators=integrators)


class LoopPlant(Protocol):
    """What the stepper needs of a drive's plant (P plants at once)."""

    def measure(self, k: int) -> Array:
        """The state the laws see at sample k, shape (P, n) (called for k = 0 .. N)."""
        ...

    def advance(self, k: int, applied: Array, computed_at: int) -> None:
        """Apply ``applied`` (P, m), the inputs computed at sample ``computed_at`` (< 0:
        none yet, zeros), over sample k: advance the plant to ``t_(k+1)``."""
        ...


@dataclass(frozen=True, eq=False)
class ClosedLoop:
    """The inputs the laws computed in one run.

    Attributes
    ----------
    commands : ndarray, shape (P, N + pad, m)
        Row ``pad + k`` computed at sample k (limited, exploration included); zeros before.
    pad : int
        Rows of zeros before the first command, ``max(H, d)``.
    delay : int
        d, samples between computing an input and applying it.
    integrator : ndarray, shape (P, R)
        The integrators after the last sample.
    """

    commands: Array
    pad: int
    delay: int
    integrator: Array

    @property
    def computed(self) -> Array:
        """Row k: the input computed at sample k, shape (P, N, m)."""
        count = self.commands.shape[1] - self.pad
        return self.commands[:, self.pad : self.pad + count]

    @property
    def applied(self) -> Array:
        """Row k: the input applied over sample k, shape (P, N, m)."""
        count = self.commands.shape[1] - self.pad
        start = self.pad - self.delay
        return self.commands[:, start : start + count]


def run_closed_loop(
    plant: LoopPlant,
    feedback: Feedback,
    w: Array,
    rho: Array,
    delay: int,
    limit: Callable[[Array], Array] | None = None,
    start: tuple[Array, Array] | None = None,
    anti_windup: bool = False,
) -> ClosedLoop:
    """Step the laws and the plant, N samples, from rest (past inputs and integrators zero).

    Parameters
    ----------
    plant : LoopPlant
        The drive's plant; measured at k = 0 .. N, advanced over k = 0 .. N - 1.
    feedback : Feedback
        The laws (one, or one per plant).
    w : ndarray, shape (P or 1, N or N + 1, q)
        The laws' reference at each sample.
    rho : ndarray, shape (P or 1, N, m)
        The exploration added to each computed input.
    delay : int
        d: the input computed at sample k is applied over sample k + d.
    limit : callable, optional
        Maps the computed inputs (P, m) to what the drive can apply (e.g. its voltage
        limit); what it returns is logged and fed back.
    start : (past, z), optional
        The ``max(H, d)`` inputs computed before the first sample (P, max(H, d), m), oldest
        first, and the integrators (P, R) at it (default zeros).
    anti_windup : bool, optional
        Hold a law's integrators at the samples where ``limit`` changed its command
        (conditional integration, :func:`~selftune.core._voltage_limit.held_integrators`);
        default False: they integrate whatever the limit does.

    Returns
    -------
    ClosedLoop
    """
    count = rho.shape[1]
    plants = max(feedback.gains.shape[0], rho.shape[0], w.shape[0])
    n, m, q, history = feedback.n, feedback.m, feedback.q, feedback.history
    integrators = feedback.integrators
    pad = max(history, delay)
    commands = np.zeros((plants, count + pad, m))
    state = np.zeros((plants, feedback.gains.shape[2], 1))
    if start is not None:
        commands[:, :pad], state[:, state.shape[1] - integrators :, 0] = start
    # views made once (indexing costs more than the few values it moves, per sample)
    x, w_k = state[:, :n, 0], state[:, n : n + q, 0]
    past = state[:, n + q : n + q + m * history, 0]
    z = state[:, state.shape[1] - integrators :, 0]
    gains, flat = feedback.gains, commands.reshape(plants, -1)
    product = np.empty((plants, gains.shape[1], 1))
    computed, change = product[:, :m, 0], product[:, m:, 0]
    held = w.strides[1] == 0  # one reference over the run (broadcast): set it once
    if held:
        w_k[...] = w[:, 0]
    for k in range(count):
        x[...] = plant.measure(k)
        if not held:
            w_k[...] = w[:, k]
        past[...] = flat[:, (pad + k - history) * m : (pad + k) * m]
        np.matmul(gains, state, out=product)
        u = np.add(computed, rho[:, k], out=commands[:, pad + k])
        holding = None
        if limit is not None:
            limited = limit(u)
            if limited is not u:
                if anti_windup:
                    holding = held_integrators(u, limited)
                u[...] = limited
        if integrators:
            if holding is None:
                z += change
            else:
                z += np.where(holding[:, np.newaxis], 0.0, change)
        plant.advance(k, commands[:, pad + k - delay], k - delay)
    plant.measure(count)
    integrator = state[:, state.shape[1] - integrators :, 0]
    return ClosedLoop(commands=commands, pad=pad, delay=delay, integrator=integrator)


def one_step_map(
    sampled: tuple[Array, Array, Array], feedback: Feedback, delay: int
) -> tuple[Array, Array]:
    """The loop on exactly sampled plants as matrices, read off one step of the stepper.

    On a :class:`SampledPlant` the loop is linear in ``xi = [x; the max(H, d) inputs
    computed before, oldest first; z]``, ``w`` and ``rho``: one step of
    :func:`run_closed_loop` from each unit vector of ``[xi_k; w_k; rho_k]`` gives its
    matrices (as :func:`feedback_of` reads the law off its command).

    Parameters
    ----------
    sampled : (Ad, Bd, Ed)
        The exact discretizations, shapes (P or 1, n, n), (P or 1, n, m), (P or 1, n, q),
        or one plant's (2-D).
    feedback : Feedback
        One law or P.
    delay : int
        d, samples between computing an input and applying it.

    Returns
    -------
    step : ndarray, shape (P, size + q + m, size)
        Acting on rows: ``xi_(k+1) = [xi_k, w_k, rho_k] @ step[i]`` for plant i.
    command : ndarray, shape (P, size + q + m, m)
        ``u_k = [xi_k, w_k, rho_k] @ command[i]``, the input computed at sample k.
    """
    Ad, Bd, Ed = sampled
    plants = max(Ad.shape[0] if Ad.ndim == 3 else 1, feedback.gains.shape[0])
    n, m, q, integrators = feedback.n, feedback.m, feedback.q, feedback.integrators
    pad = max(feedback.history, delay)
    size = n + pad * m + integrators
    units = size + q + m

    def each_unit(matrix: Array) -> Array:
        stack = np.broadcast_to(matrix, (plants, *matrix.shape[-2:]))
        return np.repeat(stack, units, axis=0)

    basis = np.tile(np.eye(units), (plants, 1))  # plant i's unit vectors, then plant i + 1's
    count = basis.shape[0]
    w_unit, rho_unit = basis[:, np.newaxis, size : size + q], basis[:, np.newaxis, size + q :]
    plant = SampledPlant(each_unit(Ad), each_unit(Bd), each_unit(Ed), w_unit, 1, basis[:, :n])
    start = (basis[:, n : n + pad * m].reshape(count, pad, m), basis[:, size - integrators : size])
    gains = replace(feedback, gains=each_unit(feedback.gains))
    one = run_closed_loop(plant, gains, w_unit, rho_unit, delay, start=start)
    after = np.hstack([plant.x[:, 1], one.commands[:, 1:].reshape(count, pad * m), one.integrator])
    return after.reshape(plants, units, size), one.commands[:, pad].reshape(plants, units, m)


def run_sampled_loop(
    sampled: tuple[Array, Array, Array], feedback: Feedback, w: Array, rho: Array, delay: int
) -> tuple[Array, ClosedLoop]:
    """:func:`run_closed_loop` on one exactly sampled plant (:class:`SampledPlant`), all
    samples at once: the matrices of :func:`one_step_map`, propagated as
    :func:`~selftune.sim.simulate` propagates its loop
    (:func:`selftune.core._propagate.propagate_uniform`); to rounding, the samples the
    stepper gives one by one.

    Parameters
    ----------
    sampled : (Ad, Bd, Ed)
        The plant's exact discretization at the sampling period.
    feedback : Feedback
        One law.
    w : ndarray, shape (N + 1, q)
        The reference the law and the plant see at each sample.
    rho : ndarray, shape (N, m)
        The exploration added to each computed input.
    delay : int
        d, samples between computing an input and applying it.

    Returns
    -------
    x : ndarray, shape (N + 1, n)
        The states from rest (not checked for overflow).
    loop : ClosedLoop
        The inputs computed (P = 1).
    """
    step, command = (matrix[0] for matrix in one_step_map(sampled, feedback, delay))
    count, size, m = rho.shape[0], step.shape[1], feedback.m
    pad = max(feedback.history, delay)
    inputs = np.hstack([w[:count], rho])
    xi = propagate_uniform(
        step[:size, :, np.newaxis], (inputs @ step[size:])[:, :, np.newaxis], np.zeros((size, 1))
    )[:, :, 0]
    commands = np.zeros((1, count + pad, m))
    commands[0, pad:] = np.hstack([xi[:-1], inputs]) @ command
    integrator = xi[-1:, size - feedback.integrators :]
    return xi[:, : feedback.n], ClosedLoop(commands, pad, delay, integrator)


def fill_held(
    coarse: Trajectory,
    plant: tuple[ArrayLike, ArrayLike, ArrayLike | None, ArrayLike | None],
    period: float,
    hold: int,
    num_samples: int,
) -> Trajectory:
    """The trajectory sampled every ``period`` of a loop whose input is held ``hold`` samples.

    ``coarse`` is the loop sampled at ``hold period``; the samples in between are filled
    in exactly from the discretization over ``j period``, j = 1 .. hold - 1.

    Parameters
    ----------
    coarse : Trajectory
        The loop at the controller's period ``hold period``.
    plant : (A, B, D, E)
        The continuous plant (D None: no exogenous input; E None: w held).
    period : float
        The sampling period, s.
    hold : int
        Samples per controller update.
    num_samples : int
        N, samples of the result.

    Returns
    -------
    Trajectory
        ``t`` (N + 1,), ``x`` (N + 1, n), ``u`` (N, m), ``w`` (N + 1, q) or None.
    """
    A, B, D, E = plant
    count, updates = num_samples, coarse.u.shape[0]
    n, q = coarse.n, coarse.q
    x = np.empty((updates * hold + 1, n))
    w = None if coarse.w is None else np.empty((updates * hold + 1, q))
    x[::hold] = coarse.x
    if w is not None and coarse.w is not None:
        w[::hold] = coarse.w
    w_start = np.zeros((updates, 0)) if coarse.w is None else coarse.w[:-1]
    for step in range(1, hold):
        exact = discretize(A, B, step * period, D=D, E=E)
        x[step::hold] = coarse.x[:-1] @ exact.Ad.T + coarse.u @ exact.Bd.T
        if w is not None:
            x[step::hold] += w_start @ exact.Ed.T
            w[step::hold] = w_start @ exact.Ew.T
    stop = count + 1
    return Trajectory(
        t=np.arange(stop) * period,
        x=x[:stop],
        u=np.repeat(coarse.u, hold, axis=0)[:count],
        w=None if w is None else w[:stop],
    )


class SampledPlant:
    """LTI plants sampled exactly: ``x_(k+1) = Ad x_k + Bd a_k + Ed w_k`` (a
    :class:`LoopPlant`).

    ``(Ad, Bd, Ed)`` is the plant's exact discretization at the sampling period
    (:func:`selftune.core.discretize`), ``a_k`` the input applied over sample k and ``w_k``
    the exogenous input at ``t_k`` (held, or an exosystem's value with ``Ed`` from E).

    Parameters
    ----------
    Ad, Bd, Ed : ndarray, shapes (P or 1, n, n), (P or 1, n, m), (P or 1, n, q)
        The sampled plants (2-D: one for all).
    w : ndarray, shape (P or 1, N or N + 1, q)
        The exogenous input each plant sees at each sample.
    num_samples : int
        N.
    x0 : ndarray, shape (P, n), optional
        The initial states (default: one plant at rest).

    Attributes
    ----------
    x : ndarray, shape (P, N + 1, n)
        The states; filled as the loop runs.
    """

    def __init__(
        self, Ad: Array, Bd: Array, Ed: Array, w: Array, num_samples: int, x0: Array | None = None
    ) -> None:
        self.Ad, self.Bd, self.Ed, self.w = Ad, Bd, Ed, w
        start = np.zeros((1, Ad.shape[-1])) if x0 is None else x0
        self.x = np.zeros((start.shape[0], num_samples + 1, Ad.shape[-1]))
        self.x[:, 0] = start

    def measure(self, k: int) -> Array:
        """``x_k``, shape (P, n)."""
        return self.x[:, k]

    def advance(self, k: int, applied: Array, computed_at: int) -> None:
        """``x_(k+1)`` from ``x_k`` and the applied inputs ``a_k`` (P, m)."""
        x, a, w = (
            self.x[:, k, :, np.newaxis],
            applied[:, :, np.newaxis],
            self.w[:, k, :, np.newaxis],
        )
        self.x[:, k + 1] = (self.Ad @ x + self.Bd @ a + self.Ed @ w)[:, :, 0]
