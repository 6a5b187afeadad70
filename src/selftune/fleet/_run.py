"""A fleet's run: every log learned on the engine, the table written as the rows come,
then the summary and the figure (:func:`run_fleet`)."""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..core import write_text
from ..core._atomic import check_output_directory
from ._engine import map_in_order, progress_bar, require_extra, workers_count
from ._jobs import LogJob, learn_row
from ._summary import SUMMARY_COLUMNS, FleetSummary, summarize, summary_markdown, write_figure
from ._table import ResultsTable, use_system_allocator

__all__ = ["FLEET_OUTPUTS", "FleetRun", "run_fleet"]

#: The files of a fleet's output directory.
FLEET_OUTPUTS = ("results.parquet", "results.csv", "summary.md", "fleet.png", "fleet.svg")

_WHAT = "selftune fleet output"

#: The most rows held before they are written, and the longest time between two writes,
#: s. Each write rewrites the whole table (atomically), so writing by time keeps that
#: work in proportion to the run's length, not to the square of the logs' number; a run
#: stopped loses at most that much of its work.
BATCH_ROWS = 1024
WRITE_SECONDS = 10.0


@dataclass(frozen=True)
class FleetRun:
    """What a fleet's run did.

    Attributes
    ----------
    logs_count : int
        The logs given.
    skipped_count : int
        Those already in the table (an earlier run's), not learned again.
    rows_count : int
        Rows of the table now.
    seconds : float
        The run's wall time, s.
    workers_count : int
        Workers it ran on (1: serially, here).
    summary : FleetSummary
        The summary of the whole table.
    """

    logs_count: int
    skipped_count: int
    rows_count: int
    seconds: float
    workers_count: int
    summary: FleetSummary


def run_fleet(
    jobs: Sequence[LogJob],
    out: str | os.PathLike[str],
    client: Any = None,
    batch: int | None = None,
    progress: bool = False,
) -> FleetRun:
    """Learn every log not yet in ``out``'s table, then summarize the table.

    The logs are learned in the order of (drive id, path), and their rows written in
    that order as they come (a bounded number held back until their turn), then merged
    with the rows of earlier runs (:meth:`ResultsTable.merge`): the client's memory does
    not grow with the logs' number but for the jobs and the summary's columns.

    ``out`` must be absent (created), empty, or a fleet's earlier output: its table is
    added to (the logs whose (path, drive id) it holds are skipped), the summary and the
    figure are rewritten.

    Parameters
    ----------
    jobs : sequence of LogJob
        The logs (:func:`~selftune.fleet.find_jobs`).
    out : str or os.PathLike
        The output directory.
    client : distributed.Client, optional
        Learn on its cluster; None: here, one log after another.
    batch : int, optional
        Rows written at most at once (default :data:`BATCH_ROWS`); rows are also written
        whenever :data:`WRITE_SECONDS` have passed since the last write, and at the end.
    progress : bool
        Show a progress bar on stderr (on a terminal only).

    Raises
    ------
    InputError
        If ``out`` cannot take a fleet's output, or the extra ``fleet`` is not installed.
    """
    use_system_allocator()
    require_extra("pyarrow")
    started = time.perf_counter()
    check_output_directory(out, FLEET_OUTPUTS, _WHAT)
    Path(out).mkdir(parents=True, exist_ok=True)
    table = ResultsTable(out)
    done = table.done()
    todo = sorted(
        (job for job in jobs if (job.path, job.drive) not in done),
        key=lambda job: (job.drive, job.path),
    )
    workers = workers_count(client)
    size = batch or BATCH_ROWS
    pending: list[dict[str, Any]] = []
    written = time.monotonic()
    with progress_bar(len(todo), "fleet", progress) as bar:
        for row in map_in_order(learn_row, todo, client):
            pending.append(row)
            bar.update(1)
            if len(pending) >= size or time.monotonic() - written >= WRITE_SECONDS:
                table.append(pending)
                pending = []
                written = time.monotonic()
    if pending:
        table.append(pending)
    table.merge()
    if not table.parquet.exists():  # every log was skipped and there was no table
        table.append([])
    summary = summarize(table.columns(list(SUMMARY_COLUMNS)))
    write_text(Path(out) / "summary.md", summary_markdown(summary))
    write_figure(summary, Path(out) / "fleet")
    return FleetRun(
        logs_count=len(jobs),
        skipped_count=len(jobs) - len(todo),
        rows_count=summary.logs_count,
        seconds=time.perf_counter() - started,
        workers_count=workers,
        summary=summary,
    )
