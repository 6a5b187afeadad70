"""The digital control law a drive runs: the one description every part of selftune shares.

A controller computed at sample k from the measured state ``x_k`` and the reference
``w_k`` (held over the sample) is::

    u_k = U w_k - K [x_k - X w_k; u_(k-d) - U w_k; ...; u_(k-1) - U w_k] - K_i z_k
    z_(k+1) = z_k + h (C x_k + F w_k)

- ``K`` (m x (n + d m)) feeds back the state deviation and, with ``history = d > 0``, the
  deviations of the d voltages computed before (the optimal digital controller of a drive
  with a computation delay of d samples does); its columns are named by :attr:`state`;
- ``K_i`` (m x r), optional, is integral action on the regulated error ``e = C x + F w``
  (the integrator ``z`` starts at 0);
- ``X`` (n x q) and ``U`` (m x q) are the steady-state maps: ``x_e = X w``, ``u_e = U w``.

The voltage computed at sample k is applied when the drive applies it (at once, or d
samples later): that is a property of the drive, not of the law. A continuous-time
regulator ``u = -K (x - X w) + U w`` is the law with ``history = 0`` and no ``K_i``.
Learned controllers (:mod:`selftune.learn`), model-based ones (:mod:`selftune.model`),
drives (:mod:`selftune.sim`) and reports all use this one type.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError
from ._validation import Array, as_matrix, positive_finite, positive_integer

__all__ = ["ControlLaw", "WithLaw", "cost_document", "state_names"]


def state_names(n: int, m: int, history: int, r: int = 0) -> tuple[str, ...]:
    """Names of the columns of ``[K, K_i]`` in order: ``x1..xn``, then ``u1[k-d]..um[k-1]``,
    then ``z1..zr`` (the integrator states).

    Parameters
    ----------
    n : int
        State dimension.
    m : int
        Input dimension.
    history : int
        d, the number of past inputs fed back.
    r : int
        Number of integrator states (0 without integral action).

    Returns
    -------
    tuple of str
    """
    names = [f"x{i + 1}" for i in range(n)]
    for lag in range(history, 0, -1):
        names += [f"u{i + 1}[k-{lag}]" for i in range(m)]
    names += [f"z{i + 1}" for i in range(r)]
    return tuple(names)


@dataclass(frozen=True, init=False)
class ControlLaw:
    """A digital state-feedback law with feedforward, delayed-input feedback and integral
    action (see the module docstring for the equations).

    Parameters
    ----------
    K : array_like, shape (m, n + history m)
        Feedback gain on ``[x_k - X w_k; u_(k-history) - U w_k; ...; u_(k-1) - U w_k]``.
    X : array_like, shape (n, q)
        Steady-state map of the state.
    U : array_like, shape (m, q)
        Feedforward map of the input.
    history : int
        d: how many previously computed inputs ``K`` feeds back (0, 1, 2, ...).
    K_i : array_like, shape (m, r), optional
        Integral gain on ``z``, the integral of ``e = C x + F w``; needs C, F and h.
    C : array_like, shape (r, n), optional
        Regulated output (with ``K_i``).
    F : array_like, shape (r, q), optional
        Regulated output's reference part (with ``K_i``).
    h : float, optional
        Sampling period of the integrator, s (with ``K_i``).

    Attributes
    ----------
    n, m, q, r : int
        Dimensions of x, u, w and e (r = 0 without integral action).
    state : tuple of str
        The names of the columns of ``[K, K_i]``, see :func:`state_names`.

    Raises
    ------
    InputError
        Naming the matrix, if a shape does not fit or a value is not finite.
    """

    K: Array
    X: Array
    U: Array
    history: int = 0
    K_i: Array | None = None
    C: Array | None = None
    F: Array | None = None
    h: float | None = None
    n: int = field(init=False)
    m: int = field(init=False)
    q: int = field(init=False)
    r: int = field(init=False)

    def __init__(
        self,
        K: ArrayLike,
        X: ArrayLike,
        U: ArrayLike,
        history: int = 0,
        K_i: ArrayLike | None = None,
        C: ArrayLike | None = None,
        F: ArrayLike | None = None,
        h: float | None = None,
    ) -> None:
        history = positive_integer(history, "history", minimum=0)
        U_ = as_matrix(U, "U")
        m, q = U_.shape
        K_ = as_matrix(K, "K", (m, None))
        n = K_.shape[1] - history * m
        if n < 1:
            raise InputError(
                f"K: has {K_.shape[1]} columns, too few for {history} past inputs of {m}"
            )
        X_ = as_matrix(X, "X", (n, q))
        values: dict[str, object] = {"K": K_, "X": X_, "U": U_, "history": history}
        r = 0
        if K_i is not None:
            if C is None or F is None or h is None:
                raise InputError("K_i: integral action needs C, F and the sampling period h")
            K_i_ = as_matrix(K_i, "K_i", (m, None))
            r = K_i_.shape[1]
            values.update(
                K_i=K_i_,
                C=as_matrix(C, "C", (r, n)),
                F=as_matrix(F, "F", (r, q)),
                h=positive_finite(h, "h"),
            )
        else:
            values.update(
                K_i=None, C=None, F=None, h=None if h is None else positive_finite(h, "h")
            )
        values.update(n=n, m=m, q=q, r=r)
        for name, value in values.items():
            if isinstance(value, np.ndarray):
                value.setflags(write=False)
            object.__setattr__(self, name, value)

    @property
    def state(self) -> tuple[str, ...]:
        """The names of the columns of ``[K, K_i]`` in order."""
        return state_names(self.n, self.m, self.history, self.r)

    @property
    def K_x(self) -> Array:
        """The part of K on the state deviation, shape (m, n)."""
        return self.K[:, : self.n]

    @classmethod
    def regulator(cls, K: ArrayLike, X: ArrayLike, U: ArrayLike) -> ControlLaw:
        """The law ``u = -K (x - X w) + U w`` (no history, no integral action).

        Parameters
        ----------
        K : array_like, shape (m, n)
            Feedback gain.
        X : array_like, shape (n, q)
            Steady-state map.
        U : array_like, shape (m, q)
            Feedforward map.

        Returns
        -------
        ControlLaw
        """
        return cls(K, X, U)

    def command(self, x: Array, w: Array, past: Array, z: Array | None = None) -> Array:
        """The input computed from the state, the reference and the past inputs.

        Parameters
        ----------
        x : ndarray, shape (..., n)
            The measured state(s).
        w : ndarray, shape (..., q)
            The reference(s).
        past : ndarray, shape (..., history, m)
            The inputs computed at ``k - history .. k - 1``, oldest first.
        z : ndarray, shape (..., r), optional
            The integrator state (with ``K_i``).

        Returns
        -------
        ndarray, shape (..., m)
        """
        steady = w @ self.U.T
        deviation = [x - w @ self.X.T]
        for lag in range(self.history):
            deviation.append(past[..., lag, :] - steady)
        u = steady - np.concatenate(deviation, axis=-1) @ self.K.T
        if self.K_i is not None and z is not None:
            u = u - z @ self.K_i.T
        return np.asarray(u, dtype=float)

    def bumpless_integrator(self, x: Array, w: Array, past: Array, command: Array) -> Array:
        """The integrator state with which this law computes ``command`` from ``x``, ``w``
        and ``past`` (least squares where ``K_i`` has fewer rows than columns): switched
        in with it, the law continues the voltage the drive was applying (a bumpless
        switch).

        Parameters
        ----------
        x : ndarray, shape (n,)
            The measured state at the switch.
        w : ndarray, shape (q,)
            The reference.
        past : ndarray, shape (history, m)
            The inputs computed before, oldest first.
        command : ndarray, shape (m,)
            The input the old law computes at the switch.

        Raises
        ------
        InputError
            If the law has no integral action.
        """
        if self.K_i is None:
            raise InputError("law: a bumpless switch sets the integrator; this law has none")
        without = self.command(x, w, past)
        solution, *_ = np.linalg.lstsq(self.K_i, without - command, rcond=None)
        return np.asarray(solution, dtype=float)

    def scaled_reference(self, scales: ArrayLike) -> ControlLaw:
        """The same feedback with each reference channel scaled: the columns of ``X``,
        ``U`` and ``F`` multiplied by ``scales`` (the law fed ``scales * w`` for ``w``).

        A torque reference's current for a magnet flux that changed by a factor ``c`` is
        this law with the torque channel scaled by ``1 / c``: the steady state and the
        feedforward of a channel that does not drive the plant are linear in its ``F``
        column, and ``K``, ``K_i`` (so the loop and its cost) stay as they are.

        Parameters
        ----------
        scales : array_like, shape (q,)
            The factor on each channel of ``w``.

        Raises
        ------
        InputError
            If ``scales`` does not have q finite entries.
        """
        factors = np.asarray(scales, dtype=float)
        if factors.shape != (self.q,) or not np.all(np.isfinite(factors)):
            raise InputError(f"scales: needs {self.q} finite factors, got {factors!r}")
        return ControlLaw(
            self.K, self.X * factors, self.U * factors, self.history, self.K_i, self.C,
            None if self.F is None else self.F * factors, self.h,
        )  # fmt: skip

    def document(self) -> dict[str, object]:
        """The law as a drive engineer puts it on a drive: its equations in words and
        symbols, the names of K's columns, and every matrix they name (SI units: V/A on
        currents, V/V on past voltages, V/(A s) on the integrator, s for h)."""
        document: dict[str, object] = {
            "equations": self.equations(),
            "state": list(self.state),
            "K": self.K,
            "X": self.X,
            "U": self.U,
            "history": self.history,
        }
        if self.K_i is not None:
            document.update({"K_i": self.K_i, "C": self.C, "F": self.F, "h": self.h})
        return document

    def equations(self) -> str:
        """The law in words and symbols, for a report or a JSON document."""
        blocks = ["xbar_k"] + [f"ubar_(k-{lag})" for lag in range(self.history, 0, -1)]
        text = f"u_k = U w_k - K [{'; '.join(blocks)}]"
        if self.K_i is not None:
            text += " - K_i z_k, z_(k+1) = z_k + h e_k, e_k = C x_k + F w_k"
        text += "; xbar_k = x_k - X w_k"
        if self.history:
            text += ", ubar_(k-j) = u_(k-j) - U w_k (the input computed j samples before)"
        return text


def cost_document(Q: Array, R: Array, Q_i: Array | None) -> dict[str, Array | None]:
    """The whole cost a controller optimized, for its JSON: ``Q``, ``R`` and ``Q_i`` (null
    without integral action), so that the optimum can be recomputed from the file.

    Parameters
    ----------
    Q, R : ndarray
        The state and input weights.
    Q_i : ndarray or None
        The weight of the integrated error.
    """
    return {"Q": Q, "R": R, "Q_i": Q_i}


class WithLaw:
    """A result that carries a :class:`ControlLaw` as ``law``: its gains read off it.

    Mixed into every result type with a law (learned, model-based, self-tuned), so that
    ``result.K`` means the same everywhere: the law's.
    """

    law: ControlLaw

    @property
    def K(self) -> Array:
        """Feedback gain over ``[xbar_k; ubar_(k-d); ...; ubar_(k-1)]``, shape (m, n + d m)."""
        return self.law.K

    @property
    def X(self) -> Array:
        """Steady-state map of the state, ``x_e = X w``, shape (n, q)."""
        return self.law.X

    @property
    def U(self) -> Array:
        """Feedforward map of the input, ``u_e = U w``, shape (m, q)."""
        return self.law.U

    @property
    def K_i(self) -> Array | None:
        """Integral gain on the integrator z, shape (m, r); None without integral action."""
        return self.law.K_i

    @property
    def L(self) -> Array:
        """Gain on w of the overall control ``u = -K x + L w``, ``L = U + K X`` (K's part
        on the state)."""
        return self.law.U + self.law.K_x @ self.law.X

    @property
    def state(self) -> tuple[str, ...]:
        """The names of the columns of ``[K, K_i]`` in order."""
        return self.law.state
