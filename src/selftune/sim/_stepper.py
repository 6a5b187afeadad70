"""The closed loop of digital control laws, sample by sample: the one stepper of every drive.

At sample k the drive measures the state ``y_k`` of each of its P plants; the law
(:class:`~selftune.core.ControlLaw`) computes, from it, the reference ``w_k``, the H inputs
it computed before and its integrator ``z_k``::

    u_k = limit(command(y_k, w_k, u_(k-H) .. u_(k-1), z_k) + rho_k)
    z_(k+1) = z_k + h (C y_k + F w_k)

and the drive applies ``u_(k-d)`` (zero before the first) over ``[t_k, t_(k+1))``, which
advances its plant to ``t_(k+1)``. The plant is the drive's: :class:`SampledPlant` (the
exact zero-order-hold discretization, :func:`selftune.core.discretize`), the inverter
model of :mod:`._inverter`, or gym-electric-motor (:mod:`._gem`); the stepper itself only
knows :class:`LoopPlant`.

The laws act through one linear map (:class:`Feedback`), read off
:meth:`ControlLaw.command` (:func:`feedback_of`), so P different laws step at once and the
equations stay the law's own.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ..core import Array, ControlLaw
from ..errors import InputError

__all__ = [
    "ClosedLoop",
    "Feedback",
    "LoopPlant",
    "SampledPlant",
    "feedback_of",
    "run_closed_loop",
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
    """

    commands: Array
    pad: int
    delay: int

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
) -> ClosedLoop:
    """Step the laws and the plant from rest (past inputs and integrators zero), N samples.

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
    past = slice(n + q, n + q + m * history)
    for k in range(count):
        state[:, :n, 0] = plant.measure(k)
        state[:, n : n + q, 0] = w[:, k]
        state[:, past, 0] = commands[:, pad + k - history : pad + k].reshape(plants, m * history)
        output = (feedback.gains @ state)[:, :, 0]
        u = output[:, :m] + rho[:, k]
        commands[:, pad + k] = u if limit is None else limit(u)
        if integrators:
            state[:, state.shape[1] - integrators :, 0] += output[:, m:]
        plant.advance(k, commands[:, pad + k - delay], k - delay)
    plant.measure(count)
    return ClosedLoop(commands=commands, pad=pad, delay=delay)


class SampledPlant:
    """One LTI plant sampled exactly: ``x_(k+1) = Ad x_k + Bd a_k + Ed w_k`` (a
    :class:`LoopPlant`, P = 1).

    ``(Ad, Bd, Ed)`` is the plant's exact discretization at the sampling period
    (:func:`selftune.core.discretize`), ``a_k`` the input applied over sample k and ``w_k``
    the exogenous input at ``t_k`` (held, or an exosystem's value with ``Ed`` from E).

    Parameters
    ----------
    Ad, Bd, Ed : ndarray, shapes (n, n), (n, m), (n, q)
        The sampled plant.
    w : ndarray, shape (N or N + 1, q)
        The exogenous input the plant sees at each sample.
    num_samples : int
        N.

    Attributes
    ----------
    x : ndarray, shape (N + 1, n)
        The states, from rest; filled as the loop runs.
    """

    def __init__(self, Ad: Array, Bd: Array, Ed: Array, w: Array, num_samples: int) -> None:
        self.Ad, self.Bd, self.Ed, self.w = Ad, Bd, Ed, w
        self.x = np.zeros((num_samples + 1, Ad.shape[0]))

    def measure(self, k: int) -> Array:
        """``x_k``, shape (1, n)."""
        return self.x[k][np.newaxis]

    def advance(self, k: int, applied: Array, computed_at: int) -> None:
        """``x_(k+1)`` from ``x_k`` and ``a_k = applied[0]``."""
        self.x[k + 1] = self.Ad @ self.x[k] + self.Bd @ applied[0] + self.Ed @ self.w[k]
