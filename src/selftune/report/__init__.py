"""Results meet the truth: evaluation against the model, the paper's reproduction, figures.

- :func:`evaluate`, :func:`closed_loop_response`: a self-tuning result against the
  model-based optimum (:mod:`._evaluate`);
- :func:`reproduce`, :func:`report`, :func:`write_outputs`: the paper's Section V
  (:mod:`._reproduce`), with Figs. 1-5 (:mod:`._figures`);
- :func:`regulator_document`, :func:`history_document`: JSON derived from the results;
- :func:`evaluate_digital` (:mod:`._digital_evaluation`): a digital result against the
  optimum of the same sampled loop, with the excess cost of its feedback;
- :func:`steady_torque_error` (:mod:`._drive_check`): a controller's steady torque on the
  simulated drive; :func:`tune_lines`, :func:`tune_document` (:mod:`._tune_report`): what
  ``selftune tune`` prints and writes;
- :func:`firmware`, :func:`write_firmware` (:mod:`._firmware`): a law as C99 firmware
  with its voltage limit and anti-windup (``selftune export``);
- :func:`write_learn_report` (:mod:`._html_report`, figures :mod:`._learn_figures`): a
  learned controller's report, one HTML page and its figures (``--report DIR``);
- :func:`figure_schedule` (:mod:`._schedule_figure`): a speed schedule's gains,
  bandwidth and excess cost against speed, with the single-speed controller's;
- :func:`evaluate_ramp`, :func:`ramp_lines`, :func:`ramp_document` (:mod:`._ramp_report`):
  a motor commissioned over a speed ramp and its schedule against the true motor's
  pointwise optimum, and what ``selftune tune`` prints and writes of it;
- :func:`evaluate_current_schedule`, :func:`current_lines`, :func:`current_document`
  (:mod:`._saturation_report`): a saturating motor's current schedule against the true
  pointwise optimum, and what ``selftune tune`` prints and writes of it.
"""

from __future__ import annotations

from ._digital_evaluation import (
    digital_step_cost,
    evaluate_digital,
    feedback_excess_cost,
    step_cost,
    true_motor,
)
from ._documents import history_document, regulator_document
from ._drive_check import STEADY_SECONDS, steady_torque_error
from ._evaluate import (
    TuningEvaluation,
    closed_loop_response,
    evaluate,
    feedback_value,
    steady_state,
)
from ._firmware import ANTI_WINDUP, FIRMWARE_FILES, Firmware, firmware, write_firmware
from ._html_report import (
    LEARN_REPORT_FILES,
    LEARN_REPORT_NAMES,
    SCHEDULE_FILES,
    report_files,
    verdict_sentence,
    write_learn_report,
)
from ._interior_report import (
    InteriorEvaluation,
    evaluate_interior,
    interior_document,
    interior_lines,
)
from ._learn_figures import FIGURE_STEMS, LearnFigureData, learn_figure_data, learn_figures
from ._online_report import (
    ONLINE_REPORT_FILES,
    TIMELINE_POINTS,
    OnlineEvaluation,
    error_bars,
    evaluate_online,
    online_document,
    online_lines,
    online_summary,
    steps_detected,
    write_online_report,
)
from ._ramp_report import RampEvaluation, evaluate_ramp, ramp_document, ramp_lines
from ._reproduce import (
    ALGORITHM_LABELS,
    Reproduction,
    report,
    reproduce,
    results_document,
    write_outputs,
)
from ._saturation_report import (
    CurrentEvaluation,
    current_document,
    current_lines,
    evaluate_current_schedule,
)
from ._schedule_figure import figure_schedule
from ._tune_report import (
    HOT_RESISTANCE,
    TorqueCheck,
    drive_text,
    torque_check,
    tune_document,
    tune_lines,
    tuned_pi,
)

__all__ = [
    "ALGORITHM_LABELS",
    "ANTI_WINDUP",
    "FIGURE_STEMS",
    "FIRMWARE_FILES",
    "HOT_RESISTANCE",
    "LEARN_REPORT_FILES",
    "LEARN_REPORT_NAMES",
    "ONLINE_REPORT_FILES",
    "SCHEDULE_FILES",
    "STEADY_SECONDS",
    "TIMELINE_POINTS",
    "CurrentEvaluation",
    "Firmware",
    "InteriorEvaluation",
    "LearnFigureData",
    "OnlineEvaluation",
    "RampEvaluation",
    "Reproduction",
    "TorqueCheck",
    "TuningEvaluation",
    "closed_loop_response",
    "current_document",
    "current_lines",
    "digital_step_cost",
    "drive_text",
    "error_bars",
    "evaluate",
    "evaluate_current_schedule",
    "evaluate_digital",
    "evaluate_interior",
    "evaluate_online",
    "evaluate_ramp",
    "feedback_excess_cost",
    "feedback_value",
    "figure_schedule",
    "firmware",
    "history_document",
    "interior_document",
    "interior_lines",
    "learn_figure_data",
    "learn_figures",
    "online_document",
    "online_lines",
    "online_summary",
    "ramp_document",
    "ramp_lines",
    "regulator_document",
    "report",
    "report_files",
    "reproduce",
    "results_document",
    "steady_state",
    "steady_torque_error",
    "step_cost",
    "steps_detected",
    "torque_check",
    "true_motor",
    "tune_document",
    "tune_lines",
    "tuned_pi",
    "verdict_sentence",
    "write_firmware",
    "write_learn_report",
    "write_online_report",
    "write_outputs",
]
