"""Results meet the truth: evaluation against the model, the paper's reproduction, figures.

- :func:`evaluate`, :func:`closed_loop_response`: a self-tuning result against the
  model-based optimum (:mod:`._evaluate`);
- :func:`reproduce`, :func:`report`, :func:`write_outputs`: the paper's Section V
  (:mod:`._reproduce`), with Figs. 1-5 (:mod:`._figures`);
- :func:`regulator_document`, :func:`history_document`: JSON derived from the results.
"""

from __future__ import annotations

from ._documents import history_document, regulator_document
from ._evaluate import TuningEvaluation, closed_loop_response, evaluate, policy_true_cost
from ._reproduce import (
    ALGORITHMS,
    Reproduction,
    report,
    reproduce,
    results_document,
    write_outputs,
)

__all__ = [
    "ALGORITHMS",
    "Reproduction",
    "TuningEvaluation",
    "closed_loop_response",
    "evaluate",
    "history_document",
    "policy_true_cost",
    "regulator_document",
    "report",
    "reproduce",
    "results_document",
    "write_outputs",
]
