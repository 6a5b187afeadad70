"""What every command shares: its ``--json`` target checked first, the JSON written
atomically, the report printed, and numerical trouble said against the input
(:mod:`selftune.core._numerics`)."""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from ..core import Array, finite_or_null, to_jsonable, write_json
from ..core._atomic import check_output_directory, check_output_file
from ..core._numerics import check_numerics as _check_numerics
from ..core._numerics import numerics as _numerics
from ..errors import SelftuneError

if TYPE_CHECKING:  # matplotlib is loaded only to draw
    from matplotlib.figure import Figure

#: The ``--json`` value that writes the JSON to standard output.
STANDARD_OUTPUT = "-"


def _check_json_target(path: str | None) -> None:
    """Refuse, before anything is computed, a ``--json`` file that cannot be written."""
    if path is not None and path != STANDARD_OUTPUT:
        check_output_file(path)


def _check_report_target(directory: str | None) -> None:
    """Refuse, before anything is computed, a ``--report`` directory that cannot receive
    a learned controller's report (:data:`selftune.report.LEARN_REPORT_NAMES`)."""
    if directory is not None:
        from ..report import LEARN_REPORT_NAMES

        check_output_directory(directory, LEARN_REPORT_NAMES, "learn report")


def _write_report(
    result: Any,
    title: str,
    lines: Sequence[str],
    directory: str | None,
    step: tuple[Array, Array] | None = None,
    schedule: Figure | None = None,
) -> None:
    """Write the report of a learned controller (with its evidence) into ``directory``
    (``step``: the reference before and after its step response's step; ``schedule``: the
    speed schedule's figure, when the law is scheduled)."""
    if directory is not None:
        from ..report import write_learn_report

        write_learn_report(result, title, lines, directory, step, schedule)


def _say_report_written(
    directory: str | None, json_path: str | None, scheduled: bool = False
) -> None:
    """Say where the report went (not when the JSON goes to standard output), with the
    schedule's figure if ``scheduled``."""
    if directory is not None and json_path != STANDARD_OUTPUT:
        from ..report import report_files

        print(f"wrote {directory}/ ({', '.join(report_files(scheduled))})")


def _write_json(path: str, data: dict[str, Any]) -> None:
    """Write ``data`` to ``path`` atomically (``-``: to stdout); a failure names ``path``."""
    if path == STANDARD_OUTPUT:
        sys.stdout.write(json.dumps(finite_or_null(to_jsonable(data)), indent=2) + "\n")
        return
    try:
        write_json(path, data)
    except OSError as exc:
        raise SelftuneError(f"{path}: cannot write the file ({exc.strerror or exc})") from None


def _print_report(lines: Sequence[str], json_path: str | None) -> None:
    """The report on stdout (not when the JSON goes there), and where the JSON went."""
    if json_path == STANDARD_OUTPUT:
        return
    print("\n".join(lines))
    if json_path is not None:
        print(f"\nwrote {json_path}")


__all__ = [
    "STANDARD_OUTPUT",
    "_check_json_target",
    "_check_numerics",
    "_numerics",
    "_print_report",
    "_write_json",
]
