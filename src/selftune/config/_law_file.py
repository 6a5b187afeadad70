"""A controller from a JSON result: :func:`load_control_law`.

Every selftune JSON that carries a controller names it ``control_law`` with every matrix
(:meth:`selftune.core.ControlLaw.document`): ``selftune tune --json``, ``selftune learn
--json``. :func:`load_control_law` reads it back; an online run's JSON
(``selftune tune --online --json``) gives its last switch's law, or the cold law if it
switched none. Every error is one line naming the file and the key.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from typing import Any

from ..core import ControlLaw
from ..core._atomic import read_regular_file
from ..errors import DataFileError, InputError

__all__ = ["load_control_law"]

#: The largest JSON file read, bytes (a result with its history is well under 10 MB).
_LIMIT = 64 << 20


def _law_document(document: Any) -> tuple[Any, str]:
    """The ``control_law`` mapping of a result and its key path."""
    if not isinstance(document, Mapping):
        raise InputError("expected a JSON object with a 'control_law'")
    online = document.get("online")
    if isinstance(online, Mapping) and isinstance(online.get("switches"), list):
        switches = [s for s in online["switches"] if isinstance(s, Mapping)]
        if switches:
            return switches[-1].get("control_law"), "online.switches[-1].control_law"
        cold = document.get("cold")
        if isinstance(cold, Mapping):
            return cold.get("control_law"), "cold.control_law"
    return document.get("control_law"), "control_law"


def load_control_law(path: str | os.PathLike[str]) -> ControlLaw:
    """The controller a JSON result names (see the module).

    Parameters
    ----------
    path : str or os.PathLike
        The JSON file.

    Raises
    ------
    DataFileError
        ``"<file>: <key>: <why>"``, if the file is not JSON, has no controller, or a
        matrix is missing or does not fit.
    """
    name = os.fspath(path)
    try:
        raw = read_regular_file(path, _LIMIT, "a JSON result")
        document = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DataFileError(f"{name}: not a JSON file ({exc})") from None
    except InputError as exc:
        raise DataFileError(str(exc)) from None
    try:
        law, key = _law_document(document)
    except InputError as exc:
        raise DataFileError(f"{name}: {exc}") from None
    if not isinstance(law, Mapping):
        raise DataFileError(f"{name}: {key}: missing (a selftune result names its controller so)")
    values: dict[str, Any] = {}
    for field in ("K", "X", "U", "history", "K_i", "C", "F", "h"):
        if field in ("K", "X", "U", "history") and field not in law:
            raise DataFileError(f"{name}: {key}.{field}: missing")
        values[field] = law.get(field)
    try:
        return ControlLaw(**values)
    except (InputError, TypeError, ValueError) as exc:
        raise DataFileError(f"{name}: {key}: {exc}") from None
