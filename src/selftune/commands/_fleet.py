"""``selftune fleet``: every log of a fleet of drives learned on Dask, into one table."""

from __future__ import annotations

from collections.abc import Sequence
from contextlib import nullcontext
from pathlib import Path
from typing import Any


def fleet_command(
    logs: Sequence[str],
    config_path: str,
    out: str,
    scheduler: str | None = None,
    workers: int | None = None,
    serial: bool = False,
) -> int:
    """``selftune fleet``: learn every log (as ``selftune learn`` does) on a Dask cluster,
    streaming the rows into ``out``'s table, then summarize the fleet.

    Everything is checked before a log is learned: the extra ``fleet`` is installed, the
    configuration reads, LOGS name at least one log, ``out`` can take the output, the
    scheduler answers. A log that fails is its row's error, never the run's.

    Parameters
    ----------
    logs : sequence of str
        Logs, directories, globs or a manifest CSV (:func:`~selftune.fleet.find_jobs`).
    config_path : str
        CONFIG.toml (``selftune learn``'s).
    out : str
        The output directory: absent, empty, or an earlier fleet's (added to; the logs
        already in its table are skipped).
    scheduler : str, optional
        A running Dask scheduler's address; default: a local cluster.
    workers : int, optional
        The local cluster's worker processes (default: the machine's cores).
    serial : bool
        Learn here, one log after another, without a cluster.

    Returns
    -------
    int
        0.
    """
    from ..config import read_toml
    from ..core._atomic import check_output_directory
    from ..fleet import FLEET_OUTPUTS, find_jobs, fleet_client, require_extra, run_fleet
    from ..fleet._table import use_system_allocator

    use_system_allocator()  # before pyarrow is imported

    if serial:
        require_extra("pyarrow")
    else:
        require_extra()
    read_toml(config_path)  # an unreadable configuration is one error, not one per log
    jobs = find_jobs(logs, config_path)
    check_output_directory(out, FLEET_OUTPUTS, "selftune fleet output")
    engine: Any = nullcontext(None) if serial else fleet_client(scheduler, workers)
    with engine as client:
        run = run_fleet(jobs, out, client, progress=True)
    summary = run.summary
    where = "here, serially" if serial else f"on {run.workers_count} Dask workers"
    lines = [
        f"learned {run.logs_count - run.skipped_count} of {run.logs_count} logs {where} in "
        f"{run.seconds:.1f} s ({run.skipped_count} already in the table)",
        f"the table: {summary.logs_count} logs, {summary.learned_count} learned, "
        f"{summary.logs_count - summary.learned_count} refused or failed",
    ]
    lines += [f"  {r.cause}: {r.count} ({', '.join(r.drives[:5])})" for r in summary.refusals]
    lines.append(f"drives that stand out of their group: {len(summary.outliers)}")
    lines += [
        f"  {o.drive} ({o.group}): {o.parameter} {o.value:.4g} against {o.median:.4g}, z {o.z:+.1f}"
        for o in summary.outliers
    ]
    directory = Path(out)
    lines.append("wrote " + ", ".join(str(directory / name) for name in FLEET_OUTPUTS))
    print("\n".join(lines))
    return 0
