"""Batches as jobs of the service: checked when submitted, run in a thread, kept in storage.

:meth:`BatchJobs.submit` checks the operation, its options and the inputs (stored runs
only: ``ID``, ``run:ID``, ``query:...`` or ``FIRST,SECOND`` pairs of them; the service
never reads a path a caller names) before anything runs, so a bad request fails at once.
The batch then runs in its own thread — in the service's process (``workers=0``) or on a
LocalCluster of ``workers`` processes — updating its progress, and its rows and fleets
are stored as one result (operation ``batch``) when it ends.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from stand.batch.inputs import QUERY_PREFIX, RUN_PREFIX, expand_inputs
from stand.batch.operations import check_options, operation
from stand.errors import NotFoundError, StandError
from stand.storage import Storage, new_id

log = logging.getLogger("stand.batch")

#: Batch job states; ``queued`` and ``running`` are live.
BATCH_STATES = ("queued", "running", "done", "failed")


@dataclass
class BatchJob:
    """What the service knows of one batch.

    Attributes
    ----------
    id : str
        Job id.
    request : dict
        The request as given (operation, inputs, options, pool, workers).
    state : str
        One of :data:`BATCH_STATES`.
    done, total, errors : int
        Items finished, items in the batch, items that failed so far.
    message : str
        Why the batch failed, if it did.
    result_id : str or None
        The id of the stored result once done.
    summary : dict or None
        The batch's summary (:meth:`stand.batch.BatchResult.to_json`) once done.
    """

    id: str
    request: dict[str, Any]
    state: str = "queued"
    done: int = 0
    total: int = 0
    errors: int = 0
    message: str = ""
    result_id: str | None = None
    summary: dict[str, Any] | None = None
    created_s: float = field(default_factory=time.time)


def stored_inputs(inputs: Sequence[str]) -> list[str]:
    """Inputs naming stored runs only: a bare id becomes ``run:ID``, on each side of a pair."""
    out = []
    for text in inputs:
        sides = [s.strip() for s in text.split(",")]
        out.append(",".join(s if s.startswith((RUN_PREFIX, QUERY_PREFIX)) else RUN_PREFIX + s
                            for s in sides))
    return out


class BatchJobs:
    """The service's batch jobs (held in memory; their results in ``storage``).

    Parameters
    ----------
    storage : Storage
        Where the results go, and whose runs the batches read.
    database : Path
        The SQLite file of ``storage``, opened by the workers.
    """

    def __init__(self, storage: Storage, database: Path) -> None:
        self.storage = storage
        self.database = Path(database)
        self._jobs: dict[str, BatchJob] = {}
        self._lock = threading.Lock()

    def submit(self, operation_name: str, inputs: Sequence[str], options: Mapping[str, Any],
               pool: str = "auto", workers: int = 0) -> BatchJob:
        """Check the request, start the batch in a thread and return its job (``queued``)."""
        op = operation(operation_name)
        checked = check_options(op, options)
        items = expand_inputs(stored_inputs(inputs), op.runs_per_item, database=self.database,
                              pool=pool)
        job = BatchJob(new_id(), {"operation": op.name, "inputs": list(inputs),
                                  "options": dict(options), "pool": pool, "workers": workers},
                       total=len(items))
        with self._lock:
            self._jobs[job.id] = job
        threading.Thread(target=self._work, args=(job, items, checked, workers),
                         name=f"stand-batch-{job.id[:8]}", daemon=True).start()
        return job

    def get(self, job_id: str) -> BatchJob:
        """The job ``job_id``; :class:`NotFoundError` if unknown."""
        with self._lock:
            job = self._jobs.get(job_id)
        if job is None:
            raise NotFoundError(f"no batch {job_id!r}: batches are known from their start until the "
                                "service stops")
        return job

    def _work(self, job: BatchJob, items: list[Any], options: dict[str, Any], workers: int) -> None:
        from stand.batch import run_batch

        def progress(done: int, total: int) -> None:
            job.done = done

        job.state = "running"
        try:
            result = run_batch(job.request["operation"], items, options, workers=workers,
                               database=self.database, on_progress=progress)
            job.errors = result.errors
            summary = result.to_json()
            job.result_id = self.storage.add_result(
                "batch", job.request, {**summary, "rows": result.rows})
            job.summary = summary
            job.state = "done"
        except StandError as exc:
            job.message, job.state = str(exc), "failed"
        except Exception as exc:  # noqa: BLE001 - a batch thread must end in a final state
            log.exception("batch %s failed", job.id)
            job.message, job.state = f"{type(exc).__name__}: {exc}", "failed"
