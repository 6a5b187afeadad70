"""TOML configuration files: the one home of reading them and of their error messages.

Every command that reads a configuration file goes through this module, so every bad
input gives the same kind of message: one line naming the file, the table and the key,
and what is wrong, raised as a :class:`~selftune.errors.DataFileError`::

    motor.toml: [cost] Q: must be symmetric positive definite (smallest eigenvalue -1)
    motor.toml: [motor] L_s: missing
    motor.toml: [motor] Ls: unknown key (known: R_s, L_s, phi_pm, p, J; did you mean L_s?)

:func:`read_toml` reads a file, :class:`ConfigFile` checks its top-level tables, and
:class:`ConfigTable` gives typed values of one table.
"""

from __future__ import annotations

import difflib
import math
import os
import tomllib
import warnings
from collections.abc import Iterable, Mapping
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from ..core import Array, check_positive_definite
from ..core._atomic import read_regular_file
from ..core._validation import LIMITS, check_entries, check_range
from ..errors import DataFileError, InputError, SelftuneDeprecationWarning

__all__ = ["ConfigFile", "ConfigTable", "read_toml"]


def one_line(text: str) -> str:
    return " ".join(text.split())


def _suggestion(word: str, known: Iterable[str], renamed: Mapping[str, str] | None = None) -> str:
    """``"; did you mean X?"`` for the known name (or the old name of a renamed one,
    ``{old: new}``) closest to ``word``, or nothing."""
    renamed = renamed or {}
    names = [*known, *renamed]
    close = difflib.get_close_matches(word, names, n=1, cutoff=0.6)
    if not close:
        lowered = {name.lower().replace("_", ""): name for name in names}
        match = lowered.get(word.lower().replace("_", ""))
        close = [match] if match else []
    if not close:
        return ""
    if close[0] in renamed:
        return f"; did you mean {renamed[close[0]]} (formerly {close[0]})?"
    return f"; did you mean {close[0]}?"


def _clip(text: str, limit: int = 40) -> str:
    """A key as written, shortened for a message."""
    return text if len(text) <= limit else text[:limit] + "..."


def _short(value: object, limit: int = 40) -> str:
    """``repr`` of a value, shortened for a message (an integer of 500 digits, say)."""
    text = repr(value)
    return text if len(text) <= limit else text[:limit] + "..."


def _type_name(value: object) -> str:
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, int | float):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, list):
        return "an array"
    if isinstance(value, dict):
        return "a table"
    return f"a {type(value).__name__}"


def read_toml(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read a TOML file into a dictionary.

    Parameters
    ----------
    path : str or path-like
        The file to read.

    Returns
    -------
    dict
        The parsed document (tables are dicts).

    Raises
    ------
    DataFileError
        If the file cannot be read, is not a regular file (a FIFO, a device or a directory
        is refused before it is opened for reading), is larger than 1 MiB, is not UTF-8
        text (a byte-order mark is allowed), or is not valid TOML; the message names the
        file.
    """
    name = os.fspath(path)
    raw = read_regular_file(path, LIMITS["toml_bytes"], "a configuration file")
    try:
        text = raw.decode("utf-8").removeprefix("\ufeff")
    except UnicodeDecodeError as exc:
        raise DataFileError(
            f"{name}: not a TOML file (not UTF-8 text at byte {exc.start})"
        ) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise DataFileError(one_line(f"{name}: not a valid TOML file ({exc})")) from None
    except RecursionError:
        raise DataFileError(f"{name}: not a valid TOML file (nested too deeply)") from None


class ConfigTable:
    """One table of a configuration file, with typed getters whose errors name the key.

    Every getter raises :class:`DataFileError` with a one-line message
    ``"<file>: [<table>] <key>: <what is wrong>"``.

    Parameters
    ----------
    file : str
        The file name used in messages.
    name : str
        The table's key path, e.g. ``"motor"`` (shown as ``[motor]``).
    data : mapping
        The table's content as parsed by :func:`read_toml`.
    known_keys : iterable of str, optional
        If given, any other key is an error (catches typos such as ``Ls`` for ``L_s``).
    renamed : mapping of str to str, optional
        ``{old: new}``: keys renamed since the format had them (:data:`RENAMED_KEYS`),
        read under the new name with a deprecation warning; messages name the key as the
        file writes it. Both names at once are an error.

    Examples
    --------
    >>> table = ConfigTable("motor.toml", "motor", {"L_s": 0.06}, known_keys=["L_s", "J"])
    >>> table.positive("L_s")
    0.06
    >>> "J" in table
    False
    """

    def __init__(
        self,
        file: str,
        name: str,
        data: Mapping[str, Any],
        known_keys: Iterable[str] | None = None,
        renamed: Mapping[str, str] | None = None,
    ) -> None:
        self.file = file
        self.name = name
        self.renamed: Mapping[str, str] = MappingProxyType(dict(renamed or {}))
        content, written = dict(data), dict[str, str]()
        self.written: Mapping[str, str] = MappingProxyType(written)  # {new: old} as written
        for old, new in (renamed or {}).items():
            if old not in content:
                continue
            if new in content:
                raise self.error(old, f"the old name of {new}, which is set too: keep only {new}")
            content[new], written[new] = content.pop(old), old
            warnings.warn(
                f"{file}: [{name}] {old} is deprecated: call it {new} (same value)",
                SelftuneDeprecationWarning,
                stacklevel=2,
            )
        self.data: Mapping[str, Any] = MappingProxyType(content)
        if known_keys is not None:
            self.check_keys(known_keys)

    def __contains__(self, key: object) -> bool:
        return key in self.data

    def error(self, key: str | None, message: str) -> DataFileError:
        """A :class:`DataFileError` about ``key`` (or the whole table if None).

        Parameters
        ----------
        key : str or None
            The key the message is about; None for the whole table.
        message : str
            What is wrong.
        """
        if key is not None:
            key = self.written.get(key, key)
        where = f"[{self.name}]" if key is None else f"[{self.name}] {_clip(key)}"
        return DataFileError(one_line(f"{self.file}: {where}: {message}"))

    def check_keys(self, known_keys: Iterable[str]) -> None:
        """Raise :class:`DataFileError` for the first key not in ``known_keys``.

        Parameters
        ----------
        known_keys : iterable of str
            The keys allowed in this table.
        """
        known = list(known_keys)
        for key in self.data:
            if key not in known:
                listing = ", ".join(known) if known else "none"
                hint = _suggestion(key, known, self.renamed)
                raise self.error(key, f"unknown key (known: {listing}{hint})")

    def _get(self, key: str, default: object) -> object:
        if key in self.data:
            return self.data[key]
        if default is None:
            raise self.error(key, "missing")
        return default

    def number(self, key: str, default: float | None = None) -> float:
        """A finite number; required unless ``default`` is given.

        Parameters
        ----------
        key : str
            The key in this table.
        default : float, optional
            Returned if the key is absent; without it the key is required.
        """
        value = self._get(key, default)
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.error(key, f"must be a number, got {_type_name(value)}")
        try:
            number = float(value)
        except OverflowError:
            number = math.inf
        if not math.isfinite(number):
            raise self.error(key, f"must be finite, got {_short(value)}")
        return number

    def ranged(self, key: str, default: float | None = None, limits: str | None = None) -> float:
        """A number within its plausible range (:data:`~selftune.core._validation.
        PLAUSIBLE_RANGES`); required unless ``default`` is given.

        Parameters
        ----------
        key : str
            The key in this table.
        default : float, optional
            Returned if the key is absent; without it the key is required.
        limits : str, optional
            The entry of the ranges (default: ``key``).
        """
        number = self.number(key, default)
        try:
            return check_range(number, key, limits)
        except InputError as exc:
            raise self.error(key, str(exc).removeprefix(f"{key}: ")) from None

    def positive(self, key: str, default: float | None = None) -> float:
        """A finite, strictly positive number; required unless ``default`` is given.

        Parameters
        ----------
        key : str
            The key in this table.
        default : float, optional
            Returned if the key is absent; without it the key is required.
        """
        number = self.number(key, default)
        if number <= 0.0:
            raise self.error(key, f"must be positive, got {_short(self.data.get(key, default))}")
        return number

    def positive_integer(
        self, key: str, default: int | None = None, maximum: int | None = None
    ) -> int:
        """A whole number >= 1 (``2`` or ``2.0``); required unless ``default`` is given.

        Parameters
        ----------
        key : str
            The key in this table.
        default : int, optional
            Returned if the key is absent; without it the key is required.
        maximum : int, optional
            The largest value allowed (default: none).
        """
        number = self.positive(key, None if default is None else float(default))
        if not number.is_integer():
            raise self.error(key, f"must be a whole number, got {_short(self.data.get(key))}")
        if maximum is not None and number > maximum:
            raise self.error(key, f"must be at most {maximum}, got {_short(self.data.get(key))}")
        return int(number)

    def flag(self, key: str, default: bool) -> bool:
        """``true`` or ``false``; ``default`` if the key is absent.

        Parameters
        ----------
        key : str
            The key in this table.
        default : bool
            Returned if the key is absent.
        """
        value = self.data.get(key, default)
        if not isinstance(value, bool):
            raise self.error(key, f"must be true or false, got {_type_name(value)}")
        return value

    def choice(self, key: str, allowed: tuple[str, ...], default: str) -> str:
        """One of the strings ``allowed``; ``default`` if the key is absent.

        Parameters
        ----------
        key : str
            The key in this table.
        allowed : tuple of str
            The accepted values.
        default : str
            Returned if the key is absent.
        """
        value = self.data.get(key, default)
        if not isinstance(value, str) or value not in allowed:
            listing = ", ".join(f'"{option}"' for option in allowed)
            shown = _short(value) if isinstance(value, str) else _type_name(value)
            raise self.error(key, f"must be one of {listing}, got {shown}")
        return value

    def vector(self, key: str) -> Array:
        """A finite, non-empty list of numbers, e.g. ``[-4.0, 0.0, 4.0]`` (required).

        Parameters
        ----------
        key : str
            The key in this table.
        """
        value = self._get(key, None)
        if not isinstance(value, list) or not value:
            raise self.error(key, f"must be a list of numbers, got {_type_name(value)}")
        return self.matrix(key, (1, len(value)), None, rows=[value])[0]

    def matrix(
        self,
        key: str,
        shape: tuple[int | None, int | None],
        default: Array | None = None,
        rows: list[object] | None = None,
    ) -> Array:
        """A finite matrix written as an array of rows, e.g. ``[[1.0, 0.0], [0.0, 1.0]]``.

        Parameters
        ----------
        key : str
            The key in this table.
        shape : (rows, columns)
            The expected shape; None for a free dimension.
        default : ndarray, optional
            Returned (copied) if the key is absent; without it the key is required.
        rows : list, optional
            The rows to check instead of the key's value (:meth:`vector`'s one row).
        """
        if key not in self.data and default is not None:
            return np.array(default, dtype=float)
        value = self._get(key, None) if rows is None else rows
        expected = "x".join("n" if size is None else str(size) for size in shape)
        if not isinstance(value, list) or not all(isinstance(row, list) for row in value):
            raise self.error(
                key, f"must be a {expected} matrix (an array of rows), got {_type_name(value)}"
            )
        for row in value:
            for entry in row:
                if isinstance(entry, bool) or not isinstance(entry, int | float):
                    raise self.error(key, f"entries must be numbers, found {_type_name(entry)}")
        lengths = {len(row) for row in value}
        if len(lengths) > 1:
            raise self.error(key, "rows have different lengths")
        columns = lengths.pop() if lengths else 0
        if any(
            size is not None and size != actual
            for size, actual in zip(shape, (len(value), columns), strict=True)
        ):
            raise self.error(key, f"must be a {expected} matrix, got {len(value)}x{columns}")
        try:
            matrix = np.array(value, dtype=float).reshape(len(value), columns)
        except OverflowError:
            raise self.error(key, "contains NaN or infinite values") from None
        if not np.all(np.isfinite(matrix)):
            raise self.error(key, "contains NaN or infinite values")
        try:
            return check_entries(matrix, key, floor=True)
        except InputError as exc:
            raise self.error(key, str(exc).removeprefix(f"{key}: ")) from None

    def positive_definite(self, key: str, size: int, default: Array | None = None) -> Array:
        """A ``size x size`` symmetric positive definite matrix (a weight of the cost).

        Parameters
        ----------
        key : str
            The key in this table.
        size : int
            Number of rows and columns.
        default : ndarray, shape (size, size), optional
            Returned (copied) if the key is absent; without it the key is required.
        """
        matrix = self.matrix(key, (size, size), default)
        try:
            return check_positive_definite(matrix, "matrix")
        except InputError as exc:
            reason = str(exc).removeprefix("matrix: ")
            if "must be symmetric" == reason:
                reason = "must be symmetric positive definite (it is not symmetric)"
            raise self.error(key, reason) from None


#: Keys renamed since a file format first had them: ``{table: {old: new}}``. The old name
#: is read as the new one, with a :class:`~selftune.errors.SelftuneDeprecationWarning`.
RENAMED_KEYS: Mapping[str, Mapping[str, str]] = MappingProxyType(
    {"learning": MappingProxyType({"sampling": "h"})}
)


class ConfigFile:
    """A parsed configuration file whose top level holds only known tables.

    A key renamed since the format first had it (:data:`RENAMED_KEYS`) is read under its
    new name (:class:`ConfigTable`).

    Parameters
    ----------
    path : str or path-like
        The file to read (see :func:`read_toml`).
    tables : mapping of str to tuple of str
        The allowed tables and, for each, its allowed keys; an empty tuple means the
        table's keys are checked later, by whoever reads it.
    overrides : mapping of str to mapping, optional
        ``{table: {key: value}}`` set over the file's values (checked as the file's are).
    overridden_by : str, optional
        Where the overrides come from, named after the file in every message (e.g.
        ``"manifest.csv row 3"``).

    Raises
    ------
    DataFileError
        If the file cannot be read or parsed, or holds an unknown table or a top-level
        value that is not a table.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        tables: Mapping[str, tuple[str, ...]],
        overrides: Mapping[str, Mapping[str, Any]] | None = None,
        overridden_by: str = "",
    ) -> None:
        self.path = Path(path)
        self.file = os.fspath(path)
        self.tables = dict(tables)
        self.data = read_toml(path)
        if overrides:
            self.file = f"{self.file} with {overridden_by or 'overrides'}"
            for name, values in overrides.items():
                table = self.data.setdefault(name, {})
                if isinstance(table, dict):  # anything else is refused below
                    table.update(values)
        for key, value in self.data.items():
            known = ", ".join(f"[{name}]" for name in self.tables)
            if key not in self.tables and not isinstance(value, dict):
                raise DataFileError(
                    one_line(
                        f"{self.file}: {_clip(key)}: a key outside any table (tables: {known})"
                    )
                )
            if key not in self.tables:
                hint = _suggestion(key, self.tables)
                if hint:
                    hint = hint.replace("mean ", "mean [").replace("?", "]?")
                raise DataFileError(
                    one_line(f"{self.file}: {_clip(key)}: unknown table (known: {known}{hint})")
                )
            if not isinstance(value, dict):
                raise DataFileError(
                    f"{self.file}: {key}: must be a table [{key}], got {_type_name(value)}"
                )

    def __contains__(self, name: object) -> bool:
        return name in self.data

    def table(self, name: str, required: bool = False) -> ConfigTable:
        """The table ``name`` with its keys checked; an absent optional table is empty.

        Parameters
        ----------
        name : str
            The table's name, one of the allowed tables.
        required : bool, optional
            Whether an absent table is an error (default False: an empty table).

        Raises
        ------
        DataFileError
            If the table is required and absent, or holds an unknown key.
        """
        if name not in self.data and required:
            raise DataFileError(f"{self.file}: [{name}]: missing table")
        known = self.tables[name]
        data = self.data.get(name, {})
        return ConfigTable(self.file, name, data, known or None, RENAMED_KEYS.get(name))
