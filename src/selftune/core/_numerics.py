"""Numerical trouble said against the input: a computation that warns (an overflow, lost
precision) or fails in numpy or scipy on absurd input is an error naming the input, never
a result. Every command, and every log of a fleet, goes through these two."""

from __future__ import annotations

import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager

import numpy as np

from ..errors import InputError, SelftuneError
from ._validation import Array

__all__ = ["check_numerics", "numerics"]

_ADVICE = "check that the values are in SI units and of a realistic size"


def check_numerics(source: str, caught: Sequence[warnings.WarningMessage], *results: Array) -> None:
    """Raise if a computation warned (overflow, lost precision) or gave non-finite numbers.

    Extreme inputs (a weight of 1e300, an inductance of 1e-300) pass every check on their
    own but make the numerics meaningless; better an error than wrong numbers. Other
    warnings are dropped (the command line never shows warnings).

    Parameters
    ----------
    source : str
        The input, for the message.
    caught : sequence of warnings.WarningMessage
        The warnings :func:`numerics` recorded.
    *results : ndarray
        The results, each required finite.

    Raises
    ------
    SelftuneError
        ``"<source>: the solution is not numerically meaningful (...)"``.
    """
    numeric = [w for w in caught if issubclass(w.category, RuntimeWarning)]
    if numeric or not all(np.all(np.isfinite(result)) for result in results):
        reason = f" ({numeric[0].message})" if numeric else ""
        raise SelftuneError(
            f"{source}: the solution is not numerically meaningful{reason}; {_ADVICE}"
        )


@contextmanager
def numerics(source: str) -> Iterator[list[warnings.WarningMessage]]:
    """Record numerical warnings in the block; name ``source`` in any failure of it.

    A :class:`SelftuneError` gets ``source`` in front; numpy's and scipy's
    ``LinAlgError`` (an SVD that does not converge, a singular matrix) on absurd input
    becomes an :class:`InputError` naming ``source``.

    Parameters
    ----------
    source : str
        The input, for the messages.
    """
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RuntimeWarning)
        try:
            yield caught
        except SelftuneError as exc:
            raise exc.retold(f"{source}: {exc}") from None
        except (np.linalg.LinAlgError, FloatingPointError, OverflowError) as exc:
            raise InputError(f"{source}: the computation failed ({exc}); {_ADVICE}") from None
