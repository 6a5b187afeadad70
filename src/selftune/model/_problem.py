"""The linear output regulation problem and its regulator equations (the model side).

The plant and the exosystem (paper eq. 6)::

    x' = A x + B u + D w,     w' = E w,     e = C x + F w

with ``x`` (n), ``u`` (m), ``w`` (q) and ``e`` (r). The regulator equations (eq. 7)::

    A X + B U + D = X E,      C X + F = 0

are solved through their Kronecker form. When their solution is not unique (m > r), the
optimal pair of Remark 2 minimizes ``Tr(X'QX + U'RU)`` subject to eq. 7. The feedback is
the LQR of ``(A, B, Q, R)`` from the continuous algebraic Riccati equation::

    A'P + P A - P B R^-1 B' P + Q = 0,      K = R^-1 B' P

and the overall control is ``u = -K x + (U + K X) w = -K (x - X w) + U w``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..core import (
    Array,
    as_matrix,
    check_positive_definite,
    check_stabilizable,
    format_eigenvalue,
    numerical_rank,
    regulator_equations,
    solve_regulator,
    unique_eigenvalues,
)
from ..errors import UnsolvableError

__all__ = ["RegulationProblem"]


@dataclass(frozen=True, init=False)
class RegulationProblem:
    """A linear output regulation problem ``x' = Ax + Bu + Dw, w' = Ew, e = Cx + Fw``.

    Parameters
    ----------
    A : array_like, shape (n, n)
    B : array_like, shape (n, m)
    C : array_like, shape (r, n)
    D : array_like, shape (n, q)
    E : array_like, shape (q, q)
    F : array_like, shape (r, q)

    Units are those of the plant; for the motor, x in A, u in V, t in s.

    Raises
    ------
    InputError
        If a matrix is not finite or its shape does not fit the others.
    """

    A: Array
    B: Array
    C: Array
    D: Array
    E: Array
    F: Array

    def __init__(
        self,
        A: ArrayLike,
        B: ArrayLike,
        C: ArrayLike,
        D: ArrayLike,
        E: ArrayLike,
        F: ArrayLike,
    ) -> None:
        for name, value in zip("ABCDEF", (A, B, C, D, E, F), strict=True):
            object.__setattr__(self, name, value)
        self._validate()

    def _validate(self) -> None:
        A = as_matrix(self.A, "A")
        n = A.shape[0]
        A = as_matrix(A, "A", (n, n))
        B = as_matrix(self.B, "B", (n, None))
        C = as_matrix(self.C, "C", (None, n))
        D = as_matrix(self.D, "D", (n, None))
        q = D.shape[1]
        E = as_matrix(self.E, "E", (q, q))
        F = as_matrix(self.F, "F", (C.shape[0], q))
        for name, matrix in zip("ABCDEF", (A, B, C, D, E, F), strict=True):
            matrix.setflags(write=False)
            object.__setattr__(self, name, matrix)

    @property
    def n(self) -> int:
        """State dimension."""
        return int(self.A.shape[0])

    @property
    def m(self) -> int:
        """Input dimension."""
        return int(self.B.shape[1])

    @property
    def q(self) -> int:
        """Exogenous-signal dimension."""
        return int(self.D.shape[1])

    @property
    def r(self) -> int:
        """Regulated-output dimension."""
        return int(self.C.shape[0])

    def check_solvable(self) -> None:
        """Raise :class:`UnsolvableError` unless the problem is solvable.

        Checks that ``(A, B)`` is stabilizable and that (Remark 1)
        ``rank [[A - lambda I, B], [C, 0]] = n + r`` at every eigenvalue ``lambda`` of E.
        """
        check_stabilizable(self.A, self.B)
        n, m, r = self.n, self.m, self.r
        lower = np.hstack([self.C, np.zeros((r, m))])
        for value in unique_eigenvalues(self.E) if self.q else []:
            upper = np.hstack([self.A - value * np.eye(n), self.B])
            rank = numerical_rank(np.vstack([upper, lower]))
            if rank < n + r:
                raise UnsolvableError(
                    "the regulator equations are not solvable: rank [[A - lambda I, B], [C, 0]]"
                    f" = {rank} < n + r = {n + r} at the eigenvalue lambda ="
                    f" {format_eigenvalue(value)} of E (Remark 1)"
                )

    def regulator_system(self) -> tuple[Array, Array]:
        """The regulator equations (eq. 7) in Kronecker form ``N z = c``.

        ``z = [vec(X); vec(U)]`` and the rows are ``[vec(AX + BU - XE); vec(CX)]``, so
        ``c = [-vec(D); -vec(F)]``.
        """
        return regulator_equations(self.A, self.B, self.C, self.D, self.E, self.F)

    def regulator_residuals(self, X: ArrayLike, U: ArrayLike) -> tuple[float, float]:
        """Frobenius norms of ``AX + BU + D - XE`` and ``CX + F``.

        Parameters
        ----------
        X : array_like, shape (n, q)
            Candidate steady-state map, ``x_ss = X w``.
        U : array_like, shape (m, q)
            Candidate feedforward, ``u_ss = U w``.
        """
        X = np.asarray(X, dtype=float)
        U = np.asarray(U, dtype=float)
        first = self.A @ X + self.B @ U + self.D - X @ self.E
        second = self.C @ X + self.F
        return float(np.linalg.norm(first)), float(np.linalg.norm(second))

    def solve_regulator_equations(
        self, Q: ArrayLike | None = None, R: ArrayLike | None = None
    ) -> tuple[Array, Array]:
        """Solve eq. 7 for ``(X, U)``; when not unique, the pair minimizing
        ``Tr(X'QX + U'RU)`` (Remark 2).

        Parameters
        ----------
        Q : array_like, shape (n, n), optional
            Weight on X (default identity); symmetric positive definite.
        R : array_like, shape (m, m), optional
            Weight on U (default identity); symmetric positive definite.

        Returns
        -------
        X : ndarray, shape (n, q)
        U : ndarray, shape (m, q)

        Raises
        ------
        UnsolvableError
            If the rank condition of Remark 1 fails (names the eigenvalue of E).
        """
        n, m = self.n, self.m
        Q = np.eye(n) if Q is None else check_positive_definite(as_matrix(Q, "Q", (n, n)), "Q")
        R = np.eye(m) if R is None else check_positive_definite(as_matrix(R, "R", (m, m)), "R")
        self.check_solvable()
        return solve_regulator((self.A, self.B, self.C, self.D, self.E, self.F), Q, R)
