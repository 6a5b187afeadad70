"""The engine: one function mapped over many items, serially or on a Dask cluster.

:func:`map_unordered` yields ``(index, function(item))`` as the results come: in order
when run serially (no client), as the workers finish them on a cluster. It submits
lazily, keeping at most ``window`` items in flight, so that the client holds a bounded
number of items and results however many there are; every item is a seeded,
self-contained job, so a result does not depend on where or in which order it ran.
:func:`map_in_order` gives them back in the items' order holding a bounded number
(``ahead``) of those that come early; :func:`map_ordered` gives them all as a list.

:func:`fleet_client` starts a local cluster sized to the machine (a worker process per
core, one thread each) or connects to a running scheduler, and closes what it started.
Dask (``dask[distributed]``) is the optional extra ``fleet``; it is imported only here,
when a cluster is asked for (:func:`require_extra`).
"""

from __future__ import annotations

import importlib
import logging
import os
import sys
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from typing import Any, TypeVar

from tqdm import tqdm

from ..errors import InputError

__all__ = [
    "AHEAD_PER_WORKER",
    "CONNECT_SECONDS",
    "INSTALL_HINT",
    "fleet_client",
    "map_in_order",
    "map_ordered",
    "map_unordered",
    "progress_bar",
    "require_extra",
    "workers_count",
]

Item = TypeVar("Item")
Result = TypeVar("Result")

#: What to install for ``selftune fleet`` (dask.distributed and pyarrow).
INSTALL_HINT = "pip install 'selftune[fleet]'"

#: How long a connection to a running scheduler may take before it is refused, s.
CONNECT_SECONDS = 10.0

#: Freed memory a local worker keeps before returning it to the system, bytes (glibc's
#: ``MALLOC_TRIM_THRESHOLD_``). Dask sets 64 KiB, which made a log's learning take 45%
#: more CPU on a worker than in the client (0.85 s against 1.3 s on this machine): the
#: learner's numpy temporaries were mapped and unmapped over and over.
RETAINED_BYTES = 2**27

#: Results :func:`map_in_order` holds at most, per worker: enough that a log taking
#: about 30 times the others' time does not leave a worker idle.
AHEAD_PER_WORKER = 64

_TRIM = "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_"

#: Entries the scheduler's and the client's debugging logs of task transitions keep
#: (Dask's ``distributed.admin.low-level-log-length``; Dask keeps 1,000). The local
#: cluster's scheduler runs in the client's process, where Dask's logs filled up to
#: about 9 MiB over the first 2,500 logs, which looked like memory growing with them.
LOG_LENGTH = 100

_LOG_LENGTH = "distributed.admin.low-level-log-length"


def require_extra(*modules: str) -> None:
    """Raise one line naming the extra to install unless ``modules`` import.

    Parameters
    ----------
    *modules : str
        The modules needed (default: ``distributed`` and ``pyarrow``).

    Raises
    ------
    InputError
        ``"selftune fleet needs <module> (pip install 'selftune[fleet]')"``.
    """
    for module in modules or ("distributed", "pyarrow"):
        try:
            importlib.import_module(module)
        except ImportError:
            raise InputError(
                f"selftune fleet needs {module.partition('.')[0]}, which is not installed:"
                f" {INSTALL_HINT}"
            ) from None


def progress_bar(total: int | None, description: str, enabled: bool) -> tqdm[Any]:
    """A tqdm bar on stderr, shown only on a terminal and when ``enabled``; a context
    manager whose ``update(1)`` advances it.

    Parameters
    ----------
    total : int or None
        The number of steps (None: unknown).
    description : str
        The bar's title.
    enabled : bool
        Show it (only when stderr is a terminal).
    """
    return tqdm(
        total=total,
        desc=description,
        file=sys.stderr,
        leave=False,
        disable=None if enabled else True,
    )


def workers_count(client: Any) -> int:
    """The workers (threads) a client's cluster runs: at least 1.

    Parameters
    ----------
    client : distributed.Client or None
        The client (None: serial, 1).
    """
    if client is None:
        return 1
    threads = client.nthreads()
    return max(1, sum(threads.values()))


def map_unordered(
    function: Callable[[Item], Result],
    items: Iterable[Item],
    client: Any = None,
    window: int | None = None,
    ahead: int | None = None,
) -> Iterator[tuple[int, Result]]:
    """``(index, function(item))`` for every item, as the results come.

    Parameters
    ----------
    function : callable
        One item's job: a module-level function or a picklable closure (cloudpickle).
    items : iterable
        The items, read lazily.
    client : distributed.Client, optional
        Run on its cluster; None (default): here, one after another, in order.
    window : int, optional
        Items in flight on the cluster at most (default: four per worker).
    ahead : int, optional
        Submit no item more than ``ahead`` places after the oldest one not yet given
        back (default: no such bound). It bounds how many results a caller who puts
        them back in order must hold (:func:`map_in_order`), at the price of idle
        workers behind an item that takes ``ahead`` items' time.

    Yields
    ------
    (int, result)
        The item's place in ``items`` and its result. A job that raises raises here.
    """
    numbered = enumerate(items)
    if client is None:
        for index, item in numbered:
            yield index, function(item)
        return
    distributed: Any = importlib.import_module("distributed")
    limit = window or 4 * workers_count(client)
    places: dict[str, int] = {}
    running = distributed.as_completed()
    waiting: tuple[int, Item] | None = None  # read from items, not yet submitted

    def fill() -> None:
        """Submit items while fewer than ``limit`` run and ``ahead`` allows."""
        nonlocal waiting
        while len(places) < limit:
            if waiting is None:
                waiting = next(numbered, None)
                if waiting is None:
                    return
            oldest = min(places.values(), default=waiting[0])
            if ahead is not None and waiting[0] >= oldest + ahead:
                return
            future = client.submit(function, waiting[1], pure=False)
            places[future.key] = waiting[0]
            running.add(future)
            waiting = None

    fill()
    for future in running:
        index = places.pop(future.key)
        result = future.result()
        future.release()
        fill()
        yield index, result


def map_in_order(
    function: Callable[[Item], Result],
    items: Iterable[Item],
    client: Any = None,
    ahead: int | None = None,
) -> Iterator[Result]:
    """``function(item)`` for every item, in the items' order, holding few results.

    On a cluster the results that come before their turn wait here; no item is
    submitted more than ``ahead`` places after the oldest one not yet given back
    (:func:`map_unordered`), so at most ``ahead`` results wait, however many items there
    are.

    Parameters
    ----------
    function : callable
        One item's job (see :func:`map_unordered`).
    items : iterable
        The items, read lazily.
    client : distributed.Client, optional
        Run on its cluster; None (default): here, one after another.
    ahead : int, optional
        The most results held (default: :data:`AHEAD_PER_WORKER` per worker).

    Yields
    ------
    result
        ``function(item)``, in the items' order.
    """
    ahead = ahead or AHEAD_PER_WORKER * workers_count(client)
    held: dict[int, Result] = {}
    following = 0
    for index, result in map_unordered(function, items, client, ahead=ahead):
        held[index] = result
        while following in held:
            yield held.pop(following)
            following += 1


def map_ordered(
    function: Callable[[Item], Result],
    items: Iterable[Item],
    client: Any = None,
    progress: tuple[str, bool] = ("", False),
) -> list[Result]:
    """``[function(item) for item in items]``, on a cluster if ``client`` is given.

    Parameters
    ----------
    function : callable
        One item's job (see :func:`map_unordered`).
    items : iterable
        The items.
    client : distributed.Client, optional
        Run on its cluster; None (default): here, in order.
    progress : (str, bool)
        A progress bar's title, and whether to show it (on a terminal only).

    Returns
    -------
    list
        The results in the items' order.
    """
    items = list(items)
    results: list[Any] = [None] * len(items)
    with progress_bar(len(items), *progress) as bar:
        for index, result in map_unordered(function, items, client):
            results[index] = result
            bar.update(1)
    return results


@contextmanager
def fleet_client(scheduler: str | None = None, workers: int | None = None) -> Iterator[Any]:
    """A Dask client: on a local cluster started here (and closed after), or on the
    running scheduler at ``scheduler``.

    Parameters
    ----------
    scheduler : str, optional
        The address of a running scheduler (``tcp://host:8786``); None: a local cluster.
    workers : int, optional
        The local cluster's worker processes (default: the machine's cores), one thread
        each.

    Raises
    ------
    InputError
        Without the extra ``fleet`` (:func:`require_extra`), or when the scheduler cannot
        be reached within :data:`CONNECT_SECONDS` (one line, no hang).
    """
    require_extra("distributed")
    distributed: Any = importlib.import_module("distributed")
    dask: Any = importlib.import_module("dask")
    if scheduler is not None:
        try:
            with dask.config.set({_LOG_LENGTH: LOG_LENGTH}):
                client = distributed.Client(scheduler, timeout=CONNECT_SECONDS)
        except (OSError, TimeoutError, ValueError, TypeError) as exc:
            reason = " ".join(str(exc).split()) or type(exc).__name__
            raise InputError(f"--scheduler {scheduler}: cannot connect ({reason})") from None
        try:
            yield client
        finally:
            client.close()
        return
    count = workers or os.cpu_count() or 1
    with dask.config.set({_TRIM: RETAINED_BYTES, _LOG_LENGTH: LOG_LENGTH}):
        cluster = distributed.LocalCluster(
            n_workers=count,
            threads_per_worker=1,
            processes=True,
            dashboard_address=":0",
            silence_logs=logging.CRITICAL,
        )
    try:
        with dask.config.set({_LOG_LENGTH: LOG_LENGTH}):
            client = distributed.Client(cluster)
        try:
            yield client
        finally:
            client.close()
    finally:
        cluster.close()
