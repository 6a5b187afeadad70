"""``selftune learn``: the learned controller from a drive's log and a configuration."""

from __future__ import annotations

from typing import Any

from ..config import learn_log
from ..core import labels, matrix_block
from ._output import _check_json_target, _print_report, _write_json


def learn_command(data_path: str, config_path: str, json_path: str | None) -> int:
    """``selftune learn``: the learned controller from a CSV or NPZ log and a config.

    The data file's header gives n, m, q; the configuration is read and checked against
    them completely before the rows are loaded. The controller comes with its quality;
    data that do not support one give an error that says why.

    Parameters
    ----------
    data_path : str
        The CSV or NPZ log.
    config_path : str
        CONFIG.toml.
    json_path : str or None
        Where to write the JSON (``-``: standard output, without the report).
    """
    _check_json_target(json_path)
    learned = learn_log(data_path, config_path)
    data, config = learned.data, learned.config
    result: Any = learned.result
    law = result.law
    states, inputs = labels("x", data.n), labels("u", data.m)
    servo = " with integral action" if law.K_i is not None else ""
    lines = [
        f"learned from {data_path}: {data.num_samples} samples, {data.duration:.6g} s",
        f"{result.target} controller{servo} by {result.method} "
        f"({len(result.history)} policy-iteration steps)"
        if result.method == "adp"
        else f"{result.target} controller{servo} by identify-then-design",
        "",
        "the controller (K's columns: " + ", ".join(law.state) + "):",
        f"  {law.equations()}",
        *matrix_block("K", law.K, inputs, list(law.state[: law.K.shape[1]])),
    ]
    if law.K_i is not None:
        lines += matrix_block("K_i", law.K_i, inputs, labels("z", law.K_i.shape[1]))
    if config.regulation:
        exogenous = labels("w", data.q)
        lines += matrix_block("X  steady-state map, x_e = X w", law.X, states, exogenous)
        lines += matrix_block("U  feedforward map, u_e = U w", law.U, inputs, exogenous)
    lines += matrix_block("B  estimated input matrix", result.B, states, inputs)
    lines += ["", *result.quality.lines()]
    if json_path is not None:
        _write_json(json_path, _learn_document(result))
    _print_report(lines, json_path)
    return 0


def _learn_document(result: Any) -> dict[str, Any]:
    """The JSON of ``selftune learn``: the law, its quality, how it was learned."""
    law = result.law
    alignment = result.alignment
    return {
        "target": result.target,
        "method": result.method,
        "h": result.h,
        "input_delay": result.input_delay,
        "state": list(law.state),
        "control_law": law.document(),
        "K": law.K,
        "K_i": law.K_i,
        "X": law.X,
        "U": law.U,
        "P": result.P,
        "B": result.B,
        "quality": result.quality,
        "alignment": {
            "logged_input": alignment.logged_input,
            "shift": alignment.shift,
            "detected_shift": alignment.detected_shift,
            "residuals": {str(shift): value for shift, value in alignment.residuals.items()},
        },
        "iterations": len(result.history),
    }
