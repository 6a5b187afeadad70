"""The fleet's table: ``results.parquet`` and ``results.csv``, a row per log.

The table grows by batches as the results come, each batch written atomically: the
Parquet file is rewritten into a temporary file beside it (the earlier rows streamed
over by row groups, the new batch added) and moved over it, then the CSV is derived from
it the same way. A run stopped at any moment leaves both complete (the CSV at most one
batch behind, and caught up by the next run); the rows already there are what a rerun
skips. At the end the rows are sorted by drive id and path, so that the table does not
depend on the order in which the workers finished.
"""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..core._atomic import atomic_path
from ..errors import DataFileError

__all__ = ["RESULT_COLUMNS", "ResultsTable"]

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

    def _rewrite(self, add: Any = None, table: Any = None) -> None:
        """The Parquet file rewritten (the earlier rows then ``add(writer)``'s, or
        ``table`` instead of all), then the CSV from it."""
        import pyarrow.parquet as pq

        schema = _schema()
        with atomic_path(self.parquet, ".parquet") as temporary:
            with pq.ParquetWriter(temporary, schema) as writer:
                if table is not None:
                    writer.write_table(table)
                else:
                    if self.parquet.exists():
                        for part in pq.ParquetFile(self.parquet).iter_batches():
                            writer.write_batch(part)
                    add(writer)
        self.write_csv()

    def write_csv(self) -> None:
        """``results.csv`` from ``results.parquet`` (streamed by batches), atomically."""
        import pyarrow.parquet as pq

        with (
            atomic_path(self.csv, ".csv") as temporary,
            temporary.open("w", encoding="utf-8", newline="") as stream,
        ):
            writer = csv.writer(stream)
            writer.writerow(_NAMES)
            if self.parquet.exists():
                for part in pq.ParquetFile(self.parquet).iter_batches():
                    for row in part.to_pylist():
                        writer.writerow(_csv_text(row[name]) for name in _NAMES)

    def sort(self) -> None:
        """Rewrite both files with the rows sorted by drive id and path."""
        if not self.parquet.exists():
            return
        table = self._read().sort_by([("drive", "ascending"), ("path", "ascending")])
        self._rewrite(table=table)

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
