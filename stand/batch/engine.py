"""Mapping a function over items, in this process or on a Dask cluster.

Three ways, the same answers:

- ``workers=0``: in this process, one item after the other (the serial path);
- a :class:`distributed.LocalCluster` of ``workers`` processes, one thread each, started
  for the batch and closed after it (the default of the command line);
- ``scheduler=ADDRESS`` (or an open ``client``): an existing cluster, e.g. one started
  with dask-jobqueue on a batch system or on Kubernetes.

Each task carries one item (a few refs and options, not the samples): the workers read
the runs themselves, so the scheduler moves bytes, not arrays. Outcomes come back in
completion order for the progress callback and are returned in item order.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any, TypeVar

from stand.errors import InputError, StandError

T = TypeVar("T")
#: ``on_progress(done, total)`` after every finished item.
ProgressCallback = Callable[[int, int], None]

#: How long connecting to an existing scheduler may take, s.
CONNECT_TIMEOUT_S = 30.0


class ClusterError(StandError, ConnectionError):
    """The Dask cluster could not be reached or started."""


@contextmanager
def dask_client(scheduler: str | None = None, workers: int = 2) -> Iterator[Any]:
    """A :class:`distributed.Client` on ``scheduler``, or on a LocalCluster of
    ``workers`` processes started here (and closed on exit)."""
    try:
        from distributed import Client, LocalCluster
    except ImportError as exc:  # pragma: no cover - a dependency of the package
        raise ClusterError("Dask is not installed: pip install 'dask[distributed]'") from exc
    if scheduler:
        try:
            client = Client(scheduler, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError) as exc:
            raise ClusterError(f"--scheduler {scheduler!r}: cannot reach the Dask scheduler "
                               f"({exc}); start one with 'dask scheduler' or check the "
                               "address (tcp://HOST:8786)") from exc
        with client:
            yield client
        return
    if workers < 1:
        raise InputError(f"workers must be >= 1 for a local cluster, got {workers}")
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                           host="127.0.0.1", dashboard_address=None,
                           scheduler_kwargs={"dashboard": False}, silence_logs=logging.WARNING)
    with cluster, Client(cluster) as client:
        yield client


def map_items(func: Callable[..., T], items: Sequence[Any], *args: Any, client: Any = None,
              chunk: int = 1, on_progress: ProgressCallback | None = None,
              on_lost: Callable[[Any, BaseException], T] | None = None) -> list[T]:
    """``[func(item, *args) for item in items]``, on ``client``'s cluster or here.

    Parameters
    ----------
    func : callable
        Importable by name in the workers (a module-level function).
    items : sequence
        One task per item.
    *args
        Passed to every call after the item (small: they travel with every task).
    client : distributed.Client or None
        The cluster; ``None`` runs every call in this process, in order.
    chunk : int
        Items per task on a cluster: a task costs the scheduler and the worker about a
        millisecond or more (much more on a loaded machine), so items that take tens of
        milliseconds go faster several to a task.
    on_progress : callable, optional
        ``on_progress(done, total)`` after every finished item.
    on_lost : callable, optional
        ``on_lost(item, exc)`` gives the result of a task the cluster lost (a worker that
        died, a result that could not be sent back); without it the error is raised.

    Returns
    -------
    list
        Results in item order.
    """
    total = len(items)
    results: list[Any] = [None] * total
    if client is None:
        for k, item in enumerate(items):
            results[k] = func(item, *args)
            if on_progress:
                on_progress(k + 1, total)
        return results
    from distributed import as_completed

    if chunk < 1:
        raise InputError(f"chunk must be >= 1 item per task, got {chunk}")
    starts = range(0, total, chunk)
    groups = [list(items[k:k + chunk]) for k in starts]
    futures = client.map(apply_chunk, [func] * len(groups), groups,
                         *[[a] * len(groups) for a in args], pure=False)
    position = {f.key: k for k, f in zip(starts, futures, strict=True)}
    done = 0
    for future in as_completed(futures):
        k = position[future.key]
        group = items[k:k + chunk]
        try:
            results[k:k + len(group)] = future.result()
        except Exception as exc:
            if on_lost is None:
                raise
            results[k:k + len(group)] = [on_lost(item, exc) for item in group]
        future.release()
        done += len(group)
        if on_progress:
            on_progress(done, total)
    return results


def apply_chunk(func: Callable[..., T], group: list[Any], *args: Any) -> list[T]:
    """``[func(item, *args) for item in group]``: one task of :func:`map_items`."""
    return [func(item, *args) for item in group]
