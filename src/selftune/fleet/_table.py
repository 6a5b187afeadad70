"""The fleet's table: ``results.parquet`` and ``results.csv``, a row per log.

The table grows by batches as the results come, each batch written atomically: the
Parquet file is rewritten into a temporary file beside it (the earlier rows streamed
over by batches of :data:`READ_ROWS`, the new batch added) and moved over it, then the
CSV is derived from it the same way. A run stopped at any moment leaves both complete
(the CSV at most one batch behind, and caught up by the next run); the rows already
there are what a rerun skips.

A run writes its rows in the order of (drive id, path) (:func:`~selftune.fleet.run_fleet`):
the table is one such sorted run of rows after a first run, and one more after each
rerun. :meth:`ResultsTable.merge` merges the runs into one, streaming, so that the table
depends neither on the order in which the workers finished nor on where a run was
stopped, and the memory it takes is a few batches' however long the table is.
"""

from __future__ import annotations

import csv
import heapq
import math
import os
import sys
from collections.abc import Iterator, Sequence
from itertools import islice
from pathlib import Path
from typing import Any

from ..core._atomic import atomic_path
from ..errors import DataFileError

__all__ = ["RESULT_COLUMNS", "ResultsTable", "use_system_allocator"]

#: The columns of the table, in order: name, type, unit and meaning.
RESULT_COLUMNS: tuple[tuple[str, str, str, str], ...] = (
    ("path", "string", "", "the log"),
    ("drive", "string", "", "the drive's id"),
    ("group", "string", "", "the drives it is compared with (same motor)"),
    ("verdict", "string", "", "learned, or the refusal's or failure's cause (its class)"),
    ("error", "string", "", "why not: the one line selftune learn prints (empty if learned)"),
    ("method", "string", "", "adp or identify (identify-then-design)"),
    ("target", "string", "", "continuous or digital"),
    ("K", "string", "V/A", "the feedback gain, JSON rows"),
    ("K_i", "string", "V/(A s)", "the integral gain, JSON rows (empty without)"),
    ("U", "string", "", "the feedforward map u_e = U w, JSON rows"),
    ("K_relative_se", "float64", "", "||K_se|| / ||K||"),
    ("K_i_relative_se", "float64", "", "||K_i_se|| / ||K_i||"),
    ("U_relative_se", "float64", "", "||U_se|| / ||U||"),
    ("R_s_ohm", "float64", "ohm", "identified stator resistance"),
    ("R_s_se_ohm", "float64", "ohm", "its standard error"),
    ("L_s_H", "float64", "H", "identified inductance"),
    ("L_s_se_H", "float64", "H", "its standard error"),
    ("phi_pm_Wb", "float64", "Wb", "identified magnet flux linkage"),
    ("phi_pm_se_Wb", "float64", "Wb", "its standard error"),
    ("dead_time_V", "float64", "V", "the inverter's dead-time voltage per phase"),
    ("dead_time_se_V", "float64", "V", "its standard error"),
    ("samples", "int64", "", "samples of the log used"),
    ("data_seconds", "float64", "s", "the log's duration"),
    ("learn_seconds", "float64", "s", "the time its learning took"),
)

_NAMES = tuple(name for name, *_ in RESULT_COLUMNS)

#: Rows read at once when the table is rewritten or converted, so that the memory those
#: take does not grow with the table.
READ_ROWS = 256


#: The environment variable that chooses Arrow's allocator, read when pyarrow is first
#: imported, and the allocator a fleet's client asks for.
ARROW_POOL = ("ARROW_DEFAULT_MEMORY_POOL", "system")


def use_system_allocator() -> None:
    """Have Arrow take its memory from the C library's allocator, unless pyarrow is
    already imported (then nothing changes) or the environment chooses one already.

    Arrow's default pool (mimalloc) kept memory that grew with the table: with a 10 ms
    stand-in for the learning that returns the rows of a real fleet, the client's peak
    was 231, 243 and 252 MiB at 250, 1,000 and 3,000 logs; with the C library's
    allocator, 222 and 226 MiB at 1,000 and 3,000 logs. Arrow's Parquet reader and writer
    take its process-wide default pool, which only this variable chooses.
    """
    if "pyarrow" not in sys.modules:
        os.environ.setdefault(*ARROW_POOL)


def _schema() -> Any:
    import pyarrow as pa

    kinds = {"string": pa.string(), "float64": pa.float64(), "int64": pa.int64()}
    return pa.schema([(name, kinds[kind]) for name, kind, *_ in RESULT_COLUMNS])


def _cell(value: Any) -> Any:
    """A table value (float NaN for a number not there, "" for text not there)."""
    return "" if value is None else value


def _csv_text(value: Any) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    return repr(value) if isinstance(value, float) else str(value)


class ResultsTable:
    """``results.parquet`` and ``results.csv`` in a directory (see the module).

    Parameters
    ----------
    directory : str or os.PathLike
        Where the two files are (the directory exists).
    """

    def __init__(self, directory: str | os.PathLike[str]) -> None:
        self.parquet = Path(directory) / "results.parquet"
        self.csv = Path(directory) / "results.csv"

    def _read(self, columns: Sequence[str] | None = None) -> Any:
        """The table (or some of its columns), checked to be a fleet's."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        try:
            schema = pq.read_schema(self.parquet)
        except (pa.ArrowException, OSError) as exc:
            reason = " ".join(str(exc).split())
            raise DataFileError(f"{self.parquet}: not a selftune fleet table ({reason})") from None
        if tuple(schema.names) != _NAMES:
            raise DataFileError(
                f"{self.parquet}: not a selftune fleet table of this version (its columns:"
                f" {', '.join(schema.names[:6])}...); choose a new directory"
            )
        return pq.read_table(self.parquet, columns=list(columns) if columns else None)

    def done(self) -> set[tuple[str, str]]:
        """The (path, drive) pairs already in the table (empty if there is none)."""
        if not self.parquet.exists():
            return set()
        table = self._read(["path", "drive"])
        return set(zip(table["path"].to_pylist(), table["drive"].to_pylist(), strict=True))

    def rows_count(self) -> int:
        """Rows in the table (0 if there is none)."""
        import pyarrow.parquet as pq

        return pq.ParquetFile(self.parquet).metadata.num_rows if self.parquet.exists() else 0

    def append(self, rows: Sequence[dict[str, Any]]) -> None:
        """Add ``rows`` (:func:`~selftune.fleet.learn_row`'s) to both files, atomically.

        Parameters
        ----------
        rows : sequence of dict
            The new rows; a column they lack is empty.
        """
        import pyarrow as pa

        schema = _schema()
        columns: dict[str, list[Any]] = {name: [] for name in _NAMES}
        for row in rows:
            for name, kind, *_ in RESULT_COLUMNS:
                value = row.get(name)
                if kind == "float64":
                    value = math.nan if value is None else float(value)
                elif kind == "string":
                    value = _cell(value)
                columns[name].append(value)
        batch = pa.Table.from_pydict(columns, schema=schema)
        self._rewrite(lambda writer: writer.write_table(batch))

    def _rewrite(self, add: Any, copy: bool = True) -> None:
        """The Parquet file rewritten (the earlier rows if ``copy``, then what
        ``add(writer)`` writes), then the CSV from it."""
        import pyarrow.parquet as pq

        schema = _schema()
        with atomic_path(self.parquet, ".parquet") as temporary:
            with pq.ParquetWriter(temporary, schema) as writer:
                if copy and self.parquet.exists():
                    for part in self._batches():
                        writer.write_batch(part)
                add(writer)
        self.write_csv()

    def _batches(self, columns: Sequence[str] | None = None) -> Iterator[Any]:
        """The table's record batches of :data:`READ_ROWS` rows (some columns only)."""
        import pyarrow.parquet as pq

        names = list(columns) if columns else None
        yield from pq.ParquetFile(self.parquet).iter_batches(batch_size=READ_ROWS, columns=names)

    def write_csv(self) -> None:
        """``results.csv`` from ``results.parquet`` (streamed by batches), atomically."""
        with (
            atomic_path(self.csv, ".csv") as temporary,
            temporary.open("w", encoding="utf-8", newline="") as stream,
        ):
            writer = csv.writer(stream)
            writer.writerow(_NAMES)
            if self.parquet.exists():
                for row in self._rows():
                    writer.writerow(_csv_text(row[name]) for name in _NAMES)

    def _rows(self, start: int = 0, stop: int | None = None) -> Iterator[dict[str, Any]]:
        """The rows ``start`` to ``stop`` (exclusive; None: to the end), streamed."""
        place = 0
        for part in self._batches():
            end = place + part.num_rows
            if end > start:
                low = max(start - place, 0)
                high = part.num_rows if stop is None else min(stop - place, part.num_rows)
                yield from part.slice(low, high - low).to_pylist()
            place = end
            if stop is not None and place >= stop:
                return

    def runs(self) -> list[int]:
        """Where each sorted run of rows begins: 0, then every row whose (drive id, path)
        falls below the row's before it (``[]`` if there is no table or no row)."""
        if not self.parquet.exists():
            return []
        starts: list[int] = []
        before: tuple[str, str] | None = None
        place = 0
        for part in self._batches(["drive", "path"]):
            for key in zip(part["drive"].to_pylist(), part["path"].to_pylist(), strict=True):
                if before is None or key < before:
                    starts.append(place)
                before = key
                place += 1
        return starts

    def merge(self) -> None:
        """Rewrite both files with the table's sorted runs of rows merged into one, by
        (drive id, path), streaming; nothing is rewritten when there is one run or none."""
        import pyarrow as pa

        starts = self.runs()
        if len(starts) < 2:
            return
        stops: list[int | None] = [*starts[1:], None]
        merged = heapq.merge(
            *(self._rows(start, stop) for start, stop in zip(starts, stops, strict=True)),
            key=lambda row: (row["drive"], row["path"]),
        )
        schema = _schema()

        def write(writer: Any) -> None:
            while batch := list(islice(merged, READ_ROWS)):
                writer.write_table(pa.Table.from_pylist(batch, schema=schema))

        self._rewrite(write, copy=False)

    def columns(self, names: Sequence[str]) -> dict[str, list[Any]]:
        """Some columns of the table as lists (empty lists if there is no table).

        Parameters
        ----------
        names : sequence of str
            The columns.
        """
        if not self.parquet.exists():
            return {name: [] for name in names}
        table = self._read(names)
        return {name: table[name].to_pylist() for name in names}
