"""Batches of runs: one operation over many runs, on Dask, with the answers of one machine.

::

    from stand.batch import run_batch

    result = run_batch("identify", ["archive/*.csv"], workers=2)
    result.write("results.parquet")
    print(result.fleets[0].pooled["Kt_over_J"])

:func:`run_batch` expands the inputs into items (:mod:`.inputs`), maps the operation of
the public API over them (:mod:`.operations`) in this process, on a LocalCluster of
processes or on an existing Dask cluster (:mod:`.engine`), keeps one row per item with
an ``error`` column (:mod:`.table`), and the fleet figures of each group
(:mod:`.pooled`). Every path gives the same rows: the same function runs on the same
item, and the pooled sums are added in item order.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from stand.batch.engine import ClusterError, ProgressCallback, dask_client, map_items
from stand.batch.inputs import Item, expand_inputs
from stand.batch.operations import OPERATIONS, Outcome, check_options, operation, run_item
from stand.batch.pooled import Fleet, fleets
from stand.batch.table import rows, write_table
from stand.jsonable import JsonResult

#: Error rows shown in a summary (the table has them all).
SUMMARY_ERRORS = 10


@dataclass(frozen=True)
class BatchResult(JsonResult):
    """The outcome of a batch.

    Attributes
    ----------
    operation : str
        The operation (``identify``, ...).
    items, errors : int
        Items in the batch, and items that failed (their ``error`` column says why).
    rows : list of dict
        One row per item (:mod:`stand.batch.table`).
    fleets : list of Fleet
        Fleet figures of each group (empty when the operation has no fleet field or
        pooling is ``none``).
    seconds : float
        Wall time of the batch, s.
    cpu_seconds : float
        CPU time the items took in their workers, summed, s.
    engine : str
        ``serial``, ``local:N`` (a LocalCluster of N processes) or the scheduler address.
    output : str
        Where the table was written ("" until :meth:`write`).
    fleets_output : str
        Where the fleet figures were written, if anywhere.
    """

    operation: str
    items: int
    errors: int
    rows: list[dict[str, Any]] = field(repr=False)
    fleets: list[Fleet]
    seconds: float
    cpu_seconds: float
    engine: str
    output: str = ""
    fleets_output: str = ""

    def write(self, path: str | Path) -> BatchResult:
        """Write the table to ``path`` (.csv or .parquet); returns the result with
        ``output`` set."""
        return replace(self, output=str(write_table(path, self.rows)))

    def to_json(self) -> dict[str, Any]:
        """The summary (not the rows): counts, the first errors, fleets, time, engine."""
        return {
            "operation": self.operation, "items": self.items, "errors": self.errors,
            "ok": self.items - self.errors, "output": self.output,
            "fleets_output": self.fleets_output,
            "first_errors": [{"item": r["item"], "input": r["input"], "error": r["error"]}
                             for r in self.rows if r["error"]][:SUMMARY_ERRORS],
            "fleets": [f.to_json() for f in self.fleets],
            "seconds": self.seconds, "engine": self.engine,
            "seconds_per_item": self.seconds / self.items if self.items else None,
            "cpu_seconds_per_item": self.cpu_seconds / self.items if self.items else None,
        }


def run_batch(operation_name: str, inputs: Sequence[str] | Sequence[Item],
              options: Mapping[str, Any] | None = None, *, workers: int = 2,
              scheduler: str | None = None, client: Any = None,
              database: str | Path | None = None, pool: str = "auto", chunk: int = 1,
              on_progress: ProgressCallback | None = None) -> BatchResult:
    """Run one operation over many runs.

    Parameters
    ----------
    operation_name : str
        ``identify``, ``torque-constant``, ``efficiency``, ``step-identify`` or ``diagnose``.
    inputs : sequence of str, or of Item
        Paths, globs, ``run:ID``, ``query:...``, ``FIRST,SECOND`` (:mod:`.inputs`), or
        items already expanded.
    options : mapping, optional
        The operation's options (:data:`~stand.batch.operations.OPERATIONS` defaults).
    workers : int
        Processes of the LocalCluster started for the batch; 0 runs every item in this
        process (the serial path).
    scheduler : str, optional
        Address of an existing Dask scheduler (``tcp://HOST:8786``); ``workers`` is then
        ignored.
    client : distributed.Client, optional
        An open client to use (neither started nor closed here).
    database : str or Path, optional
        The service's SQLite file, for stored runs.
    pool : str
        How items form fleets (:data:`~stand.batch.inputs.POOL_KEYS` or ``re:REGEX``).
    chunk : int
        Items per Dask task (:func:`~stand.batch.engine.map_items`); the rows do not
        depend on it.
    on_progress : callable, optional
        ``on_progress(done, total)`` after every item.

    Raises
    ------
    InputError
        Bad operation, options, inputs or pool key (before any item runs).
    ClusterError
        The cluster could not be reached.
    """
    op = operation(operation_name)
    checked = check_options(op, options or {})
    db = str(Path(database).resolve()) if database is not None else None
    items: list[Item] = [i for i in inputs if isinstance(i, Item)]
    if len(items) != len(inputs) or not items:
        items = expand_inputs([str(i) for i in inputs], op.runs_per_item,
                              database=Path(db) if db else None, pool=pool)
    start = time.perf_counter()
    args = (op.name, checked, db)
    if client is not None:
        outcomes, engine = _run(items, args, client, chunk, on_progress), "client"
    elif scheduler or workers > 0:
        with dask_client(scheduler, workers) as own:
            outcomes = _run(items, args, own, chunk, on_progress)
        engine = scheduler or f"local:{workers}"
    else:
        outcomes, engine = _run(items, args, None, chunk, on_progress), "serial"
    seconds = time.perf_counter() - start
    table = rows(items, outcomes)
    groups = [item.group for item in items]
    fleet = fleets(outcomes, groups, op.fleet_field) if op.fleet_field else []
    return BatchResult(op.name, len(items), sum(1 for o in outcomes if o.error), table, fleet,
                       seconds, sum(o.cpu_seconds for o in outcomes), engine)


def _lost(item: Item, exc: BaseException) -> Outcome:
    return Outcome(item.index, None, f"the cluster lost this item: {type(exc).__name__}: {exc}", 0.0)


def _run(items: list[Item], args: tuple[str, dict[str, Any], str | None], client: Any,
         chunk: int, on_progress: ProgressCallback | None) -> list[Outcome]:
    return map_items(run_item, items, *args, client=client, chunk=chunk, on_progress=on_progress,
                     on_lost=_lost)


__all__ = ["OPERATIONS", "BatchResult", "ClusterError", "Fleet", "Item", "dask_client", "expand_inputs",
           "map_items", "run_batch"]
