"""The result type every regulator shares, learned or model-based, so they compare directly."""

from __future__ import annotations

from dataclasses import dataclass

from ._validation import Array
from ._vectorize import pack_theta

__all__ = ["RegulatorSolution"]


@dataclass(frozen=True)
class RegulatorSolution:
    """An output regulator ``u = -K (x - X w) + U w`` with its value matrix.

    The result type the model-based optimum (:class:`ModelBasedSolution`) and the
    learners (:class:`selftune.learn.LearnedSolution`) share, so they compare directly.

    Attributes
    ----------
    K : ndarray, shape (m, n)
        Feedback gain.
    P : ndarray, shape (n, n)
        Value matrix: the cost from ``xbar(0)`` is ``xbar(0)' P xbar(0)``.
    X : ndarray, shape (n, q)
        Steady-state map ``x_ss = X w``.
    U : ndarray, shape (m, q)
        Feedforward map ``u_ss = U w``.
    exogenous_block : ndarray, shape (q, n)
        ``M = (D + A X - X E)' P``; ``(D + A X)' P`` when E = 0 (the paper).
    """

    K: Array
    P: Array
    X: Array
    U: Array
    exogenous_block: Array

    @property
    def L(self) -> Array:
        """Gain on w of the overall control ``u = -K x + L w``, ``L = U + K X``."""
        return self.U + self.K @ self.X

    @property
    def theta(self) -> Array:
        """Theta = [vecs(P); vec(K); vec(M)], the unknowns of the data equation."""
        return pack_theta(self.P, self.K, self.exogenous_block)
