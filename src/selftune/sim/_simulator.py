"""The exact sampled-data simulator of LTI plants under a linear policy, with exploration.

The plant and, optionally, an exosystem::

    x' = A x + B u + D w,        w' = E w   (or w held over each sample)

run under the sampled policy, applied with a zero-order hold over ``[t[k], t[k+1])``::

    u[k] = -K (x[k] - X w[k]) + U w[k] + rho[k]

``K`` (m x n), ``X`` (n x q) and ``U`` (m x q) default to zero; ``rho`` is the exploration
signal. The simulation is exact up to rounding: each sample is propagated by the matrix
exponential of the augmented matrix (zero-order-hold discretization, Van Loan's method)::

    expm([[A, B, D],        [[Ad, Bd, Ed],
          [0, 0, 0],    h) = [0,  I,  0 ],
          [0, 0, E]]         [0,  0,  Ew]]

so ``x[k+1] = Ad x[k] + Bd u[k] + Ed w[k]`` with no ODE solver
(:func:`selftune.core.discretize`); the loop's matrices are those of the stepper every
drive runs (:func:`~selftune.sim._stepper.one_step_map`). The exogenous
signal ``w`` is of one of two kinds (:mod:`._signals`), matching
:class:`~selftune.learn.Trajectory`:

- **held** (``E`` is None, i.e. ``E = 0`` to a learner): ``w[k]`` is held over each sample
  like ``u``; :func:`constant`, :func:`steps` and :func:`held` (sample-and-hold any
  function of time, e.g. the paper's ``w_base + w_d(t)``) make such signals.
- **exosystem** (:func:`exosystem`): ``w' = E w`` evolves continuously inside each sample,
  and the policy uses ``w[k] = w(t[k])``.

Either way the returned trajectory stores all N + 1 values ``w(t[k])``; for a held signal
the last one is unused by the learners.

Exploration generators (:func:`uniform`, :func:`prbs`, :func:`sum_of_sines`) draw from one
``numpy.random.Generator`` per run, made from ``seed``, so runs are reproducible.

:func:`simulate_batch` runs P plants (a batch of parameter sets) in one vectorized time
loop and returns a :class:`TrajectoryBatch`.

Examples
--------
The paper's motor (Sec. V): ``K0 = 20 pi I``, uniform exploration of 1 V, the held
reference ``w = w_base + w_d(t)``, 500 samples at 10 us:

>>> import numpy as np
>>> from selftune import SPMSM
>>> from selftune.sim import held, simulate, uniform
>>> motor = SPMSM.paper()
>>> problem = motor.regulation_problem(speed=10.0)
>>> w_base = motor.exogenous(speed=10.0, torque=10.0)
>>> reference = held(
...     lambda t: w_base + np.column_stack([np.sin(1000 * t), 0.1 * np.cos(3000 * t)])
... )
>>> data = simulate(problem.A, problem.B, D=problem.D, exogenous=reference,
...                 K=20 * np.pi * np.eye(2), exploration=uniform(1.0),
...                 h=1e-5, num_samples=500, seed=0)
>>> data.x.shape, data.u.shape, data.w.shape
((501, 2), (500, 2), (501, 2))
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike

from ..core import Array, ControlLaw, augmented, expm_stack, positive_finite, positive_integer
from ..core._propagate import (
    plant_last,
    propagate_steps,
    propagate_uniform,
    to_plant_last,
    to_plant_major,
)
from ..errors import InputError
from ..learn import Trajectory
from ._checks import (
    Seed,
    TimeGrid,
    as_float_array,
    as_generator,
    as_stack,
    check_finite_states,
    square_stack,
    time_grid,
)
from ._exploration import Exploration
from ._signals import ExogenousSignal, check_signal_values
from ._stepper import feedback_of, fill_held, one_step_map

__all__ = ["TrajectoryBatch", "simulate", "simulate_batch"]


@dataclass(frozen=True, eq=False)
class TrajectoryBatch:
    """Trajectories of P plants sampled at the same times (read-only arrays, SI units).

    Attributes
    ----------
    t : ndarray, shape (N + 1,)
        Sample times, s.
    x : ndarray, shape (P, N + 1, n)
        States.
    u : ndarray, shape (P, N, m)
        Inputs, held over each sample (exploration included).
    w : ndarray, shape (P, N + 1, q), or None
        Exogenous signal at each sample time (see :class:`~selftune.trajectory.Trajectory`).
    exploration : ndarray, shape (P, N, m)
        The exploration part ``rho`` of ``u``.
    """

    t: Array
    x: Array
    u: Array
    w: Array | None
    exploration: Array

    @property
    def num_plants(self) -> int:
        """P, the number of plants."""
        return int(self.x.shape[0])

    def __len__(self) -> int:
        return self.num_plants

    def trajectory(self, index: int) -> Trajectory:
        """The trajectory of plant ``index`` (0-based; negative counts from the end).

        Parameters
        ----------
        index : int
            Plant index.
        """
        plants = self.num_plants
        if isinstance(index, bool) or not isinstance(index, int | np.integer):
            raise InputError(f"index: expected an integer, got {type(index).__name__}")
        if not -plants <= index < plants:
            raise InputError(f"index: must be in [{-plants}, {plants}), got {index}")
        w = None if self.w is None else self.w[index]
        return Trajectory(t=self.t, x=self.x[index], u=self.u[index], w=w)

    def trajectories(self) -> list[Trajectory]:
        """All P trajectories."""
        return [self.trajectory(i) for i in range(self.num_plants)]


@dataclass(frozen=True, eq=False)
class _Request:
    """The arguments of one call of :func:`simulate` or :func:`simulate_batch`, as given.

    ``batch`` says which of the two was called: it changes only which shapes are accepted.
    """

    A: ArrayLike
    B: ArrayLike
    D: ArrayLike | None = None
    exogenous: ExogenousSignal | ArrayLike | None = None
    K: ArrayLike | None = None
    X: ArrayLike | None = None
    U: ArrayLike | None = None
    exploration: Exploration | ArrayLike | None = None
    x0: ArrayLike | None = None
    h: float | None = None
    num_samples: int | None = None
    t: ArrayLike | None = None
    seed: Seed = None
    batch: bool = False
    num_plants: int | None = None


@dataclass(frozen=True, eq=False)
class _Stacks:
    """The validated plant and policy, each a stack with a leading batch axis (1 or P)."""

    A: Array
    B: Array
    D: Array
    K: Array
    X: Array
    U: Array
    x0: Array

    @property
    def dimensions(self) -> tuple[int, int, int]:
        """``(n, m, q)``."""
        return int(self.A.shape[1]), int(self.B.shape[2]), int(self.D.shape[2])


def _stacks(request: _Request) -> _Stacks:
    batch = request.batch
    A = square_stack(request.A, batch)
    n = A.shape[1]
    B = as_stack(request.B, "B", (n, None), batch=batch)
    m = B.shape[2]
    if request.D is None:
        if request.exogenous is not None:
            raise InputError("exogenous: given, but the plant has no exogenous input (D is None)")
        for name, value in (("X", request.X), ("U", request.U)):
            if value is not None:
                raise InputError(f"{name}: given, but the plant has no exogenous input (D is None)")
        D = np.zeros((1, n, 0))
    else:
        D = as_stack(request.D, "D", (n, None), batch=batch)
        if request.exogenous is None:
            raise InputError(
                f"exogenous: D has {D.shape[2]} columns, so an exogenous signal w is needed "
                "(constant, steps, held or exosystem)"
            )
    q = D.shape[2]

    def optional(value: ArrayLike | None, name: str, shape: tuple[int, ...]) -> Array:
        if value is None:
            return np.zeros((1, *shape))
        return as_stack(value, name, shape, batch=batch)

    return _Stacks(
        A=A,
        B=B,
        D=D,
        K=optional(request.K, "K", (m, n)),
        X=optional(request.X, "X", (n, q)),
        U=optional(request.U, "U", (m, q)),
        x0=optional(request.x0, "x0", (n,)),
    )


def _exogenous_values(request: _Request, grid: TimeGrid, q: int) -> tuple[Array, Array | None]:
    """``w`` at the sample times as a stack (P or 1, N + 1, q), and the exosystem's E."""
    count = grid.num_samples
    exogenous = request.exogenous
    if exogenous is None:
        return np.zeros((1, count + 1, 0)), None
    E: Array | None = None
    if isinstance(exogenous, ExogenousSignal):
        if exogenous.E is not None:
            E = as_stack(exogenous.E, "exogenous: E", (q, q), batch=False)[0]
        values = check_signal_values(exogenous.values(grid.t), count + 1, "exogenous")
    else:
        values = check_signal_values(exogenous, count + 1, "exogenous")
    if values.shape[-1] != q:
        raise InputError(f"exogenous: has {values.shape[-1]} channels, but D has {q} columns")
    if values.ndim == 3 and not request.batch:
        raise InputError(
            f"exogenous: expected shape ({count + 1}, {q}), got a batch {values.shape} "
            "(use simulate_batch for a batch of plants)"
        )
    return values.reshape(-1, count + 1, q), E


def _given_exploration(request: _Request, count: int, m: int) -> Array | None:
    """An exploration given as an array, as a stack (P or 1, N, m); None otherwise."""
    exploration = request.exploration
    if exploration is None or isinstance(exploration, Exploration):
        return None
    rho = as_float_array(exploration, "exploration")
    valid = False
    if rho.ndim == 2 or (request.batch and rho.ndim == 3):
        rho = rho.reshape(-1, *rho.shape[-2:])
        valid = rho.shape[1:] == (count, m)
    if not valid:
        wanted = f"({count}, {m})" + (f" or a batch (P, {count}, {m})" if request.batch else "")
        raise InputError(
            f"exploration: expected an Exploration (uniform, prbs, sum_of_sines), None, "
            f"or an array of shape {wanted}, got shape {np.shape(exploration)}"
        )
    return rho


def _batch_size(stacks: dict[str, Array], num_plants: int | None) -> int:
    """The common batch size P of stacks whose leading axis is 1 (shared) or P."""
    size, source = num_plants, "num_plants"
    for name, stack in stacks.items():
        count = int(stack.shape[0])
        if count == 1:
            continue
        if size is None:
            size, source = count, name
        elif count != size:
            raise InputError(f"{name}: a batch of {count} plants, but {source} gives {size}")
    return 1 if size is None else size


def _exploration(
    request: _Request, given: Array | None, grid: TimeGrid, m: int, plants: int
) -> Array:
    """``rho``, shape (P, N, m): the given array, a draw from the generator, or zeros."""
    count = grid.num_samples
    rng = as_generator(request.seed)
    if given is not None:
        return np.broadcast_to(given, (plants, count, m))
    if request.exploration is None:
        return np.zeros((plants, count, m))
    assert isinstance(request.exploration, Exploration)
    drawn = request.exploration.sample(grid.t.copy(), m, rng, (plants,) if request.batch else ())
    return _check_exploration(drawn, plants, count, m)


def _loop_map(s: _Stacks, E: Array | None, periods: Array, uniform: bool) -> tuple[Array, Array]:
    """The sampled loop of each plant at each period as the stepper's matrices
    (:func:`~selftune.sim._stepper.one_step_map`): ``step`` (P'', S, n + q + m, n) and
    ``command`` (P'', n + q + m, m), acting on the rows ``[x_k, w_k, rho_k]``."""
    n, m, q = s.dimensions
    plant_count = max(s.A.shape[0], s.B.shape[0], s.D.shape[0])
    M = augmented(
        np.broadcast_to(s.A, (plant_count, n, n)),
        np.broadcast_to(s.B, (plant_count, n, m)),
        np.broadcast_to(s.D, (plant_count, n, q)),
        E,
    )
    exp = expm_stack(M, periods, uniform=uniform)  # (P', S, k, k)
    count = max(plant_count, s.K.shape[0], s.X.shape[0], s.U.shape[0])
    steps = periods.shape[0]
    K, X, U = (np.broadcast_to(a, (count, *a.shape[1:])) for a in (s.K, s.X, s.U))
    laws = max(len(s.K), len(s.X), len(s.U))  # 1 or P'': a law per plant, or one for all
    feedback = feedback_of([ControlLaw.regulator(K[i], X[i], U[i]) for i in range(laws)])

    def each(matrix: Array) -> Array:
        """A stack (P'' or 1, [S,] a, b) as one matrix per plant and period, (P'' S, a, b)."""
        stack = matrix if matrix.ndim == 4 else matrix[:, np.newaxis]
        shape = matrix.shape[-2:]
        return np.broadcast_to(stack, (count, steps, *shape)).reshape(count * steps, *shape)

    sampled = (each(exp[..., :n, :n]), each(exp[..., :n, n : n + m]), each(exp[..., :n, n + m :]))
    step, command = one_step_map(sampled, replace(feedback, gains=each(feedback.gains)), 0)
    return step.reshape(count, steps, *step.shape[1:]), command[::steps]


def _propagate(
    s: _Stacks, E: Array | None, grid: TimeGrid, w: Array, rho: Array
) -> tuple[Array, Array]:
    """The states (P, N + 1, n) of the sampled closed loop, exactly (ZOH by expm), and the
    inputs (P, N, m): ``x[k+1] = x[k] @ step_x + w[k] @ step_w + rho[k] @ step_rho``,
    the stepper's matrices (:func:`_loop_map`)."""
    n, _, q = s.dimensions
    count, plants = grid.num_samples, rho.shape[0]
    if grid.h is not None:
        periods, index = np.array([grid.h]), np.zeros(count, dtype=np.intp)
    else:
        periods, index = np.unique(grid.steps, return_inverse=True)
    step, command = _loop_map(s, E, periods, uniform=grid.h is not None)
    # acting on rows, (P'', S, rows, n): the state's, the reference's and rho's parts
    step_x, step_w, step_rho = step[:, :, :n], step[:, :, n : n + q], step[:, :, n + q :]
    # forcing plant-major (a matmul per plant), the propagation plant-last (see _propagate)
    x0 = np.ascontiguousarray(np.broadcast_to(s.x0, (plants, n)).T)
    if grid.h is not None:
        forcing = w[:, :count] @ step_w[:, 0] + rho @ step_rho[:, 0]
        x = propagate_uniform(
            plant_last(step_x[:, 0].transpose(0, 2, 1)), to_plant_last(forcing), x0
        )
    else:
        w_steps = w[:, :count, np.newaxis, :]  # (P_w, N, 1, q)
        forcing = (w_steps @ step_w[:, index])[:, :, 0]
        forcing = forcing + (rho[:, :, np.newaxis, :] @ step_rho[:, index])[:, :, 0]
        closed_steps = np.ascontiguousarray(step_x.transpose(1, 2, 3, 0))  # (S, b, a, P'')
        x = propagate_steps(closed_steps, index, to_plant_last(forcing), x0)
    x = to_plant_major(x)
    u = (
        x[:, :count] @ command[:, :n]
        + w[:, :count] @ command[:, n : n + q]
        + rho @ command[:, n + q :]
    )
    return x, u


def _run(request: _Request) -> TrajectoryBatch:
    """The simulator behind :func:`simulate` and :func:`simulate_batch`."""
    s = _stacks(request)
    _, m, q = s.dimensions
    grid = time_grid(request.h, request.num_samples, request.t)
    count = grid.num_samples
    w, E = _exogenous_values(request, grid, q)
    given = _given_exploration(request, count, m)
    named = {"A": s.A, "B": s.B, "D": s.D, "K": s.K, "X": s.X, "U": s.U, "x0": s.x0}
    named["exogenous"] = w
    if given is not None:
        named["exploration"] = given
    num_plants = request.num_plants
    if num_plants is not None:
        num_plants = positive_integer(num_plants, "num_plants")
    plants = _batch_size(named, num_plants)
    rho = _exploration(request, given, grid, m, plants)
    with np.errstate(over="ignore", invalid="ignore"):
        x, u = _propagate(s, E, grid, w, rho)
    check_finite_states(x, grid.t)
    w_out = None if q == 0 else np.broadcast_to(w, (plants, count + 1, q))
    for array in [grid.t, x, u, rho] + ([] if w_out is None else [w_out]):
        if array.flags.writeable:
            array.setflags(write=False)
    return TrajectoryBatch(t=grid.t, x=x, u=u, w=w_out, exploration=np.asarray(rho))


def _check_exploration(drawn: ArrayLike, plants: int, count: int, m: int) -> Array:
    rho = as_float_array(drawn, "exploration.sample")
    if rho.shape == (count, m):
        rho = rho[np.newaxis]
    if rho.shape not in ((plants, count, m), (1, count, m)):
        raise InputError(
            f"exploration.sample: expected shape {(count, m)} or {(plants, count, m)}, "
            f"got {rho.shape}"
        )
    return np.broadcast_to(rho, (plants, count, m))


def simulate(
    A: ArrayLike,
    B: ArrayLike,
    *,
    D: ArrayLike | None = None,
    exogenous: ExogenousSignal | ArrayLike | None = None,
    K: ArrayLike | None = None,
    X: ArrayLike | None = None,
    U: ArrayLike | None = None,
    exploration: Exploration | ArrayLike | None = None,
    x0: ArrayLike | None = None,
    h: float | None = None,
    num_samples: int | None = None,
    t: ArrayLike | None = None,
    seed: Seed = None,
    input_hold: int = 1,
) -> Trajectory:
    """Simulate ``x' = A x + B u + D w`` exactly under ``u = -K (x - X w) + U w + rho``.

    Each ``u[k]`` is held over ``[t[k], t[k+1])`` (zero-order hold) and the plant is
    propagated by the matrix exponential, so the samples are exact up to rounding for any
    sampling period. Give either ``h`` and ``num_samples`` (times ``k h`` from 0) or the
    sample times ``t`` (a non-uniform grid is allowed; a uniform one, up to the rounding of
    the times, uses one cached discretization).

    Parameters
    ----------
    A : array_like, shape (n, n)
        State matrix, 1/s.
    B : array_like, shape (n, m)
        Input matrix.
    D : array_like, shape (n, q), optional
        Exogenous input matrix; needs ``exogenous``.
    exogenous : ExogenousSignal or array_like, optional
        The signal ``w``: :func:`constant`, :func:`steps`, :func:`held` (held over each
        sample), :func:`exosystem` (``w' = E w`` inside each sample), or an array (N + 1, q)
        of held values at the sample times.
    K : array_like, shape (m, n), optional
        Feedback gain (default 0: open loop).
    X : array_like, shape (n, q), optional
        Steady-state map, ``x_ss = X w`` (default 0).
    U : array_like, shape (m, q), optional
        Feedforward, ``u_ss = U w`` (default 0).
    exploration : Exploration or array_like, optional
        ``rho``: :func:`uniform`, :func:`prbs`, :func:`sum_of_sines`, an array (N, m), or
        None (default: no exploration).
    x0 : array_like, shape (n,), optional
        Initial state (default 0).
    h : float, optional
        Sampling period, s (with ``num_samples``).
    num_samples : int, optional
        N, the number of samples (with ``h``).
    t : array_like, shape (N + 1,), optional
        Sample times, s, strictly increasing (instead of ``h`` and ``num_samples``).
    seed : int, numpy.random.Generator or None, optional
        Source of the exploration's randomness; the same integer reproduces the run,
        None draws fresh entropy.
    input_hold : int, optional
        The controller updates ``u`` (and a held ``w``) every ``input_hold`` samples and
        holds it in between, while the state is sampled every ``h`` (a controller at a
        fraction of the measurement rate). Needs ``h`` and ``num_samples``. Learners
        integrate such data to fourth order (see :mod:`selftune.data_equation`).

    Returns
    -------
    Trajectory
        ``t`` (N + 1,), ``x`` (N + 1, n), ``u`` (N, m) with the exploration included, and
        ``w`` (N + 1, q) (None without D): ``w(t[k])``, for a held signal the last row is
        ``w(t[N])``, unused by the learners.

    Raises
    ------
    InputError
        Naming the argument, if a shape is wrong, a value is not finite, the time grid is
        invalid, or the state overflows (an unstable closed loop over a long horizon).

    Examples
    --------
    >>> import numpy as np
    >>> data = simulate([[-1.0]], [[1.0]], x0=[1.0], h=0.01, num_samples=100)
    >>> bool(np.isclose(data.x[-1, 0], np.exp(-1.0), rtol=1e-12))
    True
    """
    hold = positive_integer(input_hold, "input_hold")
    request = _Request(
        A, B, D=D, exogenous=exogenous, K=K, X=X, U=U, exploration=exploration, x0=x0,
        h=h, num_samples=num_samples, t=t, seed=seed,
    )  # fmt: skip
    if hold > 1:
        return _simulate_held_inputs(request, hold)
    return _run(request).trajectory(0)


def _simulate_held_inputs(request: _Request, hold: int) -> Trajectory:
    """:func:`simulate` with the controller at 1/``hold`` of the sampling rate.

    The closed loop runs at the controller's period ``hold h``; the samples in between
    are then filled in exactly from the discretization over ``j h``, j = 1 .. hold - 1.
    """
    if request.t is not None or request.h is None or request.num_samples is None:
        raise InputError("input_hold: needs a uniform grid given by h and num_samples")
    period = positive_finite(request.h, "h")
    count = positive_integer(request.num_samples, "num_samples")
    if request.exploration is not None and not isinstance(request.exploration, Exploration):
        raise InputError("input_hold: give the exploration as a generator (uniform, prbs, ...)")
    exogenous = request.exogenous
    if exogenous is not None and not isinstance(exogenous, ExogenousSignal):
        raise InputError("input_hold: give the exogenous signal as a signal object (held, ...)")
    updates = -(-count // hold)
    coarse = _run(replace(request, h=hold * period, num_samples=updates)).trajectory(0)
    E = None if exogenous is None else exogenous.E
    return fill_held(coarse, (request.A, request.B, request.D, E), period, hold, count)


def simulate_batch(
    A: ArrayLike,
    B: ArrayLike,
    *,
    D: ArrayLike | None = None,
    exogenous: ExogenousSignal | ArrayLike | None = None,
    K: ArrayLike | None = None,
    X: ArrayLike | None = None,
    U: ArrayLike | None = None,
    exploration: Exploration | ArrayLike | None = None,
    x0: ArrayLike | None = None,
    h: float | None = None,
    num_samples: int | None = None,
    t: ArrayLike | None = None,
    seed: Seed = None,
    num_plants: int | None = None,
) -> TrajectoryBatch:
    """Simulate P plants at once, vectorized over the batch (one time loop for all).

    Takes the arguments of :func:`simulate`; each of ``A`` (P, n, n), ``B`` (P, n, m),
    ``D`` (P, n, q), ``K`` (P, m, n), ``X`` (P, n, q), ``U`` (P, m, q), ``x0`` (P, n), an
    exogenous signal with batched values (P, N + 1, q) and an exploration array
    (P, N, m) may be a batch, or unbatched to share it among all plants. An exploration
    generator draws an independent signal for each plant (so plant i does not see the
    same ``rho`` as a single run with the same seed). An exosystem's ``E`` is shared.

    Parameters
    ----------
    A : array_like, shape (n, n) or (P, n, n)
        State matrix, 1/s.
    B : array_like, shape (n, m) or (P, n, m)
        Input matrix.
    D : array_like, shape (n, q) or (P, n, q), optional
        Exogenous input matrix; needs ``exogenous``.
    exogenous : ExogenousSignal or array_like, optional
        The signal ``w`` (see :func:`simulate`); values may be batched, (P, N + 1, q).
    K : array_like, shape (m, n) or (P, m, n), optional
        Feedback gain (default 0: open loop).
    X : array_like, shape (n, q) or (P, n, q), optional
        Steady-state map, ``x_ss = X w`` (default 0).
    U : array_like, shape (m, q) or (P, m, q), optional
        Feedforward, ``u_ss = U w`` (default 0).
    exploration : Exploration or array_like, optional
        ``rho``: a generator (one draw per plant), or an array (N, m) or (P, N, m).
    x0 : array_like, shape (n,) or (P, n), optional
        Initial state (default 0).
    h : float, optional
        Sampling period, s (with ``num_samples``).
    num_samples : int, optional
        N, the number of samples (with ``h``).
    t : array_like, shape (N + 1,), optional
        Sample times, s, strictly increasing (instead of ``h`` and ``num_samples``).
    seed : int, numpy.random.Generator or None, optional
        Source of the exploration's randomness.
    num_plants : int, optional
        P when no argument is batched (e.g. one plant under P exploration draws).

    Returns
    -------
    TrajectoryBatch
        ``x`` (P, N + 1, n), ``u`` (P, N, m), ``w`` (P, N + 1, q) or None, ``exploration``
        (P, N, m), ``t`` (N + 1,); ``.trajectory(i)`` gives plant i's :class:`Trajectory`.

    Raises
    ------
    InputError
        As :func:`simulate`, and if the batch sizes differ between arguments.

    Examples
    --------
    >>> import numpy as np
    >>> A = -np.arange(1.0, 4.0).reshape(3, 1, 1)  # three scalar plants
    >>> batch = simulate_batch(A, [[1.0]], x0=[1.0], h=0.1, num_samples=10)
    >>> batch.x.shape
    (3, 11, 1)
    """
    return _run(
        _Request(
            A, B, D=D, exogenous=exogenous, K=K, X=X, U=U, exploration=exploration, x0=x0,
            h=h, num_samples=num_samples, t=t, seed=seed, batch=True, num_plants=num_plants,
        )
    )  # fmt: skip
