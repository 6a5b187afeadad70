"""Fleets of drives: thousands of logs learned on a distributed engine.

- the engine (:mod:`._engine`): :func:`map_unordered`, :func:`map_in_order` and
  :func:`map_ordered` map one function over many items, serially or on a Dask cluster
  (:func:`fleet_client`: a local cluster sized to the machine, or a running scheduler),
  with a bounded number of items in flight; the bench's seeded studies run through it too;
- the jobs (:mod:`._jobs`): :func:`find_jobs` reads LOGS (files, directories, globs, a
  manifest CSV with per-drive overrides of the configuration); :func:`learn_row` is
  ``selftune learn`` on one log, as a row of the table, never raising;
- the table (:mod:`._table`): :class:`ResultsTable`, ``results.parquet`` and
  ``results.csv`` written atomically batch by batch (:data:`RESULT_COLUMNS`);
- the picture (:mod:`._summary`): :func:`summarize`, ``summary.md`` and the figure: the
  spread of the identified parameters, the drives whose robust z exceeds their group's
  :func:`outlier_threshold` (:data:`FALSE_ALARM_RATE` per group), the refusals by cause;
- :func:`run_fleet` (:mod:`._run`): all of it, as ``selftune fleet`` runs it.

Dask (``dask[distributed]``) and pyarrow are the optional extra ``fleet``
(``pip install 'selftune[fleet]'``), imported only when a fleet runs; the serial map
needs neither.
"""

from __future__ import annotations

from ._engine import (
    CONNECT_SECONDS,
    INSTALL_HINT,
    fleet_client,
    map_in_order,
    map_ordered,
    map_unordered,
    progress_bar,
    require_extra,
    workers_count,
)
from ._jobs import LOG_SUFFIXES, MANIFEST_COLUMNS, LogJob, find_jobs, learn_row, read_manifest
from ._run import FLEET_OUTPUTS, FleetRun, run_fleet
from ._summary import (
    FALSE_ALARM_RATE,
    MIN_GROUP,
    PARAMETERS,
    SUMMARY_COLUMNS,
    FleetSummary,
    Outlier,
    RefusalCause,
    outlier_threshold,
    robust_z,
    summarize,
    summary_markdown,
    write_figure,
)
from ._table import RESULT_COLUMNS, ResultsTable

__all__ = [
    "CONNECT_SECONDS",
    "FALSE_ALARM_RATE",
    "FLEET_OUTPUTS",
    "INSTALL_HINT",
    "LOG_SUFFIXES",
    "MANIFEST_COLUMNS",
    "MIN_GROUP",
    "PARAMETERS",
    "RESULT_COLUMNS",
    "SUMMARY_COLUMNS",
    "FleetRun",
    "FleetSummary",
    "LogJob",
    "Outlier",
    "RefusalCause",
    "ResultsTable",
    "find_jobs",
    "fleet_client",
    "learn_row",
    "map_in_order",
    "map_ordered",
    "map_unordered",
    "outlier_threshold",
    "progress_bar",
    "read_manifest",
    "require_extra",
    "robust_z",
    "run_fleet",
    "summarize",
    "summary_markdown",
    "workers_count",
    "write_figure",
]
