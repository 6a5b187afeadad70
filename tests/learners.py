"""The tests' shorthand for the continuous regulator and servo learners: the problem's
parts as arguments (the learners themselves take the data, the problem, K0 and the
options)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

from numpy.typing import ArrayLike

from selftune.learn import (
    LearnedController,
    LearningOptions,
    LearningProblem,
    Trajectory,
    learn_regulator,
    learn_servo,
)


def regulator(
    data: Trajectory | Sequence[Trajectory],
    C: ArrayLike,
    E: ArrayLike,
    F: ArrayLike,
    Q: ArrayLike,
    R: ArrayLike,
    K0: ArrayLike,
    *,
    interval: int = 10,
    formulation: Literal["auto", "customized", "general"] = "auto",
) -> LearnedController:
    """:func:`learn_regulator` of ``LearningProblem(Q, R, C=C, E=E, F=F)``."""
    problem = LearningProblem(Q, R, C=C, E=E, F=F)
    options = LearningOptions(interval=interval)
    return learn_regulator(data, problem, K0, options, formulation=formulation)


def servo(
    data: Trajectory | Sequence[Trajectory],
    output: tuple[ArrayLike, ArrayLike, ArrayLike],
    weights: tuple[ArrayLike, ArrayLike, ArrayLike],
    K0: ArrayLike,
    *,
    interval: int = 10,
    discounts: Sequence[float] | None = None,
) -> LearnedController:
    """:func:`learn_servo` of the problem ``(C, E, F)`` with the weights ``(Q, R, Q_i)``."""
    (C, E, F), (Q, R, Q_i) = output, weights
    problem = LearningProblem(Q, R, C=C, E=E, F=F, integral_action=True, integral_weight=Q_i)
    return learn_servo(data, problem, K0, LearningOptions(interval=interval), discounts=discounts)
