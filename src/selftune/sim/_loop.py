"""The ideal digital loop: an LTI plant under a ControlLaw with a computation delay, exactly.

The plant ``x' = A x + B u + D w`` is sampled at h; at sample k the law computes
``u_k`` from ``x_k``, the held reference ``w_k``, its past inputs and its integrator
(:class:`~selftune.core.ControlLaw`), plus the exploration ``rho_k``; the drive applies it
``delay`` samples later, held over ``[t_(k+d), t_(k+d+1))`` (zero before the first). Each
sample is propagated by the exact zero-order-hold discretization, so the samples satisfy
``x_(k+1) = Ad x_k + Bd a_k + Ed w_k`` to rounding: the digital learners are exact on
these data at any sampling period. A real inverter holds its voltage in the stationary
frame and adds dead time and noise: that is :mod:`._realistic`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..core import Array, ControlLaw, as_matrix, discretize, positive_finite, positive_integer
from ..errors import InputError
from ..learn import Trajectory
from ._checks import Seed, as_generator
from ._exploration import Exploration
from ._signals import ExogenousSignal, check_signal_values
from ._stepper import feedback_of, run_sampled_loop

__all__ = ["LoopLogs", "exploration_inputs", "simulate_loop"]


@dataclass(frozen=True)
class LoopLogs:
    """The same run logged both ways.

    Attributes
    ----------
    applied : Trajectory
        Row k of ``u`` is the input applied during sample k.
    commanded : Trajectory
        Row k of ``u`` is the input computed at sample k (applied ``delay`` later).
    """

    applied: Trajectory
    commanded: Trajectory


def exploration_inputs(
    law: ControlLaw, exploration: Exploration | ArrayLike | None, t: Array, seed: Seed
) -> Array:
    """``rho`` (N, m) for the times ``t`` (N + 1,): drawn from one generator made from
    ``seed``, given as an array, or zeros (None)."""
    count = t.shape[0] - 1
    if exploration is None:
        return np.zeros((count, law.m))
    if isinstance(exploration, Exploration):
        return np.asarray(exploration.sample(t, law.m, as_generator(seed)), dtype=float)
    rho = as_matrix(exploration, "exploration", (count, law.m))
    return rho


def simulate_loop(
    plant: tuple[ArrayLike, ArrayLike, ArrayLike],
    law: ControlLaw,
    reference: ExogenousSignal | ArrayLike,
    *,
    h: float,
    num_samples: int,
    delay: int = 0,
    exploration: Exploration | ArrayLike | None = None,
    seed: Seed = None,
    discrete: bool = False,
) -> LoopLogs:
    """Run the sampled loop of ``law`` with a computation delay on ``x' = A x + B u + D w``.

    Parameters
    ----------
    plant : (A, B, D)
        The continuous plant (A n x n, 1/s; B n x m; D n x q), held by a zero-order hold;
        or, with ``discrete``, the exact sampled plant ``(Ad, Bd, Ed)`` itself (e.g. a
        stationary-frame hold, :meth:`selftune.model.SPMSM.sampled_plant`).
    law : ControlLaw
        The controller (its ``history`` may differ from ``delay``).
    reference : ExogenousSignal or array_like, shape (N + 1, q)
        The held reference ``w`` (E = 0).
    h : float
        Sampling period, s.
    num_samples : int
        N.
    delay : int
        d, samples between computing an input and applying it.
    exploration : Exploration or array_like, shape (N, m), optional
        Added to each computed input.
    seed : int, numpy Generator or None
        Source of the exploration's randomness.
    discrete : bool
        ``plant`` is ``(Ad, Bd, Ed)`` at this h.

    Returns
    -------
    LoopLogs
        The run from rest (``x = 0``, past inputs 0, integrator 0), logged both ways.

    Raises
    ------
    InputError
        On inconsistent shapes, a non-held reference, or a state that overflows.
    """
    A, B, D = (np.asarray(matrix, dtype=float) for matrix in plant)
    h = positive_finite(h, "h")
    count = positive_integer(num_samples, "num_samples")
    delay = positive_integer(delay, "delay", minimum=0)
    if discrete:
        Ad, Bd, Ed = A, B, D
    else:
        exact = discretize(A, B, h, D=D)
        Ad, Bd, Ed = exact.Ad, exact.Bd, exact.Ed
    t = np.arange(count + 1, dtype=np.float64) * h
    if isinstance(reference, ExogenousSignal):
        if reference.E is not None:
            raise InputError("reference: the digital loop needs a held reference (E = 0)")
        w = check_signal_values(reference.values(t), count + 1, "reference")
    else:
        w = check_signal_values(reference, count + 1, "reference")
    rho = exploration_inputs(law, exploration, t, seed)
    with np.errstate(over="ignore", invalid="ignore"):
        x, loop = run_sampled_loop((Ad, Bd, Ed), feedback_of([law]), w, rho, delay)
    computed, applied = loop.computed[0], loop.applied[0]
    if not np.all(np.isfinite(x)):
        raise InputError("the state overflows: the law does not stabilize the sampled loop")
    held = None if w.shape[1] == 0 else w
    return LoopLogs(
        applied=Trajectory(t, x, applied, held), commanded=Trajectory(t, x, computed, held)
    )
