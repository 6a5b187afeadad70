"""JSON documents of results, derived from the typed result objects (never hand-copied)."""

from __future__ import annotations

from typing import Any

from ..core import Array, finite_or_null, to_jsonable
from ..model import ModelBasedSolution
from ..tuning import TuningResult
from ._evaluate import TuningEvaluation

__all__ = ["history_document", "regulator_document"]


def history_document(result: TuningResult, evaluation: TuningEvaluation) -> list[dict[str, Any]]:
    """The per-iteration history of a self-tuning session, as JSON-ready rows: the fields
    of each :class:`~selftune.tuning.TuningIteration` and its evaluation against the
    optimum (``theta_error``, ``learned_cost``, ``true_cost``).

    Parameters
    ----------
    result : TuningResult
        The self-tuning result.
    evaluation : TuningEvaluation
        Its evaluation (:func:`~selftune.report.evaluate`).
    """
    rows = []
    for index, item in enumerate(result.history):
        row = to_jsonable(item)
        row["theta_error"] = float(evaluation.theta_error[index])
        row["learned_cost"] = float(evaluation.learned_cost[index])
        row["true_cost"] = float(evaluation.true_cost[index])
        rows.append(finite_or_null(row))
    return rows


def regulator_document(solution: ModelBasedSolution | TuningResult) -> dict[str, Array]:
    """``K``, ``P``, ``X``, ``U`` and ``theta`` of a learned or model-based regulator (JSON).

    Parameters
    ----------
    solution : ModelBasedSolution or TuningResult
        The regulator.
    """
    return {name: getattr(solution, name) for name in ("K", "P", "X", "U", "theta")}
