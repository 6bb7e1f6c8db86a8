"""Runs as jobs on the one stand: a queue, one worker thread, samples persisted as they come.

The :class:`JobManager` takes run requests (plain JSON data), checks them against the
profile's limits *before* queuing (:class:`~stand.errors.LimitError`), and runs them one
after the other on a :class:`StandRunner` — the stand controller over the bus, or a
direct simulation. Every sample chunk the runner hands over is committed to
:class:`~stand.storage.Storage` at once, so a crash keeps the samples recorded so far.

Run states: ``queued`` → ``running`` → ``done`` | ``stopped`` (a stop request) | ``aborted``
(the stand aborted the run, or the service died during it) | ``failed`` (an error).

The worker outlives anything a job throws, storage errors included: a final state that
cannot be written (disk full) is kept and written again before the next job and every
:data:`RETRY_MARKS_S` while idle; until then :attr:`JobManager.fault` says which runs
wait for it.
"""

from __future__ import annotations

import contextlib
import logging
import queue
import threading
import time
from collections.abc import Mapping
from dataclasses import replace
from typing import Any

import numpy as np

from stand.errors import RunAborted, StandError, StorageError
from stand.runner import RunPlan, StandRunner
from stand.storage import RunRecord, Storage, new_id

log = logging.getLogger("stand.jobs")

#: Least time between two progress writes to the database, s.
PROGRESS_INTERVAL_S = 0.2
#: How long close() waits for the worker to finish the current run after a stop, s.
CLOSE_TIMEOUT_S = 10.0
#: How often an idle worker retries final states it could not write, s.
RETRY_MARKS_S = 1.0


class JobManager:
    """Queue of run jobs on one stand, executed by one worker thread.

    Parameters
    ----------
    storage : Storage
        Where runs and samples go.
    runner : StandRunner
        The stand.
    """

    def __init__(self, storage: Storage, runner: StandRunner) -> None:
        self.storage = storage
        self.runner = runner
        self._queue: queue.Queue[str | None] = queue.Queue()
        self._plans: dict[str, RunPlan] = {}
        self._lock = threading.Lock()
        self._current: str | None = None
        self._stop = threading.Event()
        self._cancelled: set[str] = set()
        self._closing = False
        #: Final states not yet written (run id to update_run fields), oldest first.
        self._unmarked: dict[str, dict[str, Any]] = {}
        self._worker = threading.Thread(target=self._work, name="stand-jobs", daemon=True)
        self._worker.start()

    # -- requests ---------------------------------------------------------------------

    def submit(self, request: Mapping[str, Any]) -> list[RunRecord]:
        """Check ``request`` and queue its runs; returns them (state ``queued``)."""
        plans = self.runner.plan(request)
        job = new_id()
        records: list[RunRecord] = []
        try:
            for plan in plans:
                records.append(self.storage.create_run(plan.kind, "job", profile=plan.profile,
                                                       request={**plan.request, "job": job}))
        except StorageError as exc:
            for record in records:  # never queued: they must not stay "queued"
                self._mark(record.id, state="failed", message=f"not queued: {exc}")
            raise
        plans = [replace(plan, request={**plan.request, "job": job}) for plan in plans]
        with self._lock:
            for record, plan in zip(records, plans, strict=True):
                self._plans[record.id] = plan
        for record in records:
            self._queue.put(record.id)
        return records

    def stop_all(self) -> dict[str, Any]:
        """Quick stop every drive now, stop the current run, cancel the queued ones."""
        started = time.monotonic()
        with self._lock:
            current = self._current
            self._stop.set()
            cancelled = [run_id for run_id in self._plans
                         if run_id != current and run_id not in self._cancelled]
            self._cancelled.update(cancelled)
        drives = self.runner.quick_stop_all()
        for run_id in cancelled:
            self._mark(run_id, state="stopped", message="cancelled by a stop request")
        return {"stopped_run": current, "cancelled_runs": cancelled, "drives": drives,
                "wall_time_s": time.monotonic() - started}

    def status(self) -> dict[str, Any]:
        """The stand's status plus the current run and the queue length."""
        with self._lock:
            current = self._current
            queued = sum(1 for i in self._plans if i != current and i not in self._cancelled)
        return {**self.runner.status(), "current_run": current, "queued_runs": queued}

    @property
    def fault(self) -> str | None:
        """Why some runs' final states are not yet stored, or None."""
        with self._lock:
            waiting = list(self._unmarked)
        if not waiting:
            return None
        return (f"{len(waiting)} run(s) ended but their final state could not be stored yet "
                f"({', '.join(waiting[:5])}); retried every {RETRY_MARKS_S:g} s")

    def close(self) -> None:
        """Stop the current run, let the worker end, close the runner."""
        with self._lock:
            self._closing = True
            self._stop.set()
        self._queue.put(None)
        self._worker.join(CLOSE_TIMEOUT_S)
        self.runner.close()

    # -- worker -----------------------------------------------------------------------

    def _mark(self, run_id: str, **fields: Any) -> bool:
        """Write a run's final state; on a storage error keep it for a retry."""
        try:
            self.storage.update_run(run_id, **fields)
        except StorageError as exc:
            log.error("run %s: could not store state %s: %s", run_id, fields.get("state"), exc)
            with self._lock:
                self._unmarked[run_id] = {**self._unmarked.get(run_id, {}), **fields}
            return False
        with self._lock:
            self._unmarked.pop(run_id, None)
        return True

    def _retry_marks(self) -> None:
        with self._lock:
            waiting = list(self._unmarked.items())
        for run_id, fields in waiting:
            if not self._mark(run_id, **fields):
                return  # the storage still fails; next time

    def _work(self) -> None:
        while True:
            try:
                run_id = self._queue.get(timeout=RETRY_MARKS_S)
            except queue.Empty:
                self._retry_marks()
                continue
            if run_id is None:
                return
            self._retry_marks()
            with self._lock:
                plan = self._plans.get(run_id)
                if plan is None or run_id in self._cancelled:
                    self._plans.pop(run_id, None)
                    continue
                self._current = run_id
                self._stop.clear()
            try:
                self._execute(run_id, plan)
            except Exception:  # the worker outlives any job; the queue goes on
                log.exception("run %s: the job failed outside its own error handling", run_id)
                self._mark(run_id, state="failed", message="internal error; see the service log")
            finally:
                with self._lock:
                    self._current = None
                    self._plans.pop(run_id, None)

    def _cancel_job(self, job: Any, reason: str) -> None:
        """Cancel the queued runs of ``job`` (marked ``aborted`` with ``reason``)."""
        with self._lock:
            ids = [i for i, p in self._plans.items() if p.request.get("job") == job
                   and i != self._current and i not in self._cancelled]
            self._cancelled.update(ids)
        for run_id in ids:
            self._mark(run_id, state="aborted", message=reason)

    def _execute(self, run_id: str, plan: RunPlan) -> None:
        storage = self.storage
        try:
            storage.update_run(run_id, state="running")
        except StorageError as exc:  # nothing could be recorded: nothing moves
            self._mark(run_id, state="failed", message=f"not started: {exc}")
            return
        last = [0.0]

        def on_progress(fraction: float) -> None:
            now = time.monotonic()
            if now - last[0] >= PROGRESS_INTERVAL_S:
                last[0] = now
                # Progress is a hint for watchers; samples (on_chunk) carry the run. A
                # failed progress write must not stop the drive mid-run.
                with contextlib.suppress(StorageError):
                    storage.update_run(run_id, progress=fraction)

        def on_chunk(columns: Mapping[str, np.ndarray]) -> None:
            storage.append_samples(run_id, columns)

        try:
            outcome = self.runner.execute(run_id, plan, on_progress, on_chunk, self._stop)
        except RunAborted as exc:
            self._mark(run_id, state="aborted", message=str(exc))
            self._cancel_job(plan.request.get("job"), f"an earlier run of this job aborted: {exc}")
        except StorageError as exc:
            self._mark(run_id, state="failed", message=str(exc))
            self._cancel_job(plan.request.get("job"), f"an earlier run of this job failed: {exc}")
        except StandError as exc:
            self._mark(run_id, state="failed", message=str(exc))
        except Exception as exc:  # a bug in a runner must not kill the worker
            log.exception("run %s failed", run_id)
            self._mark(run_id, state="failed", message=f"{type(exc).__name__}: {exc}")
        else:
            if self._closing:
                self._mark(run_id, state="aborted", meta=outcome.meta,
                           message="the service shut down during the run; samples so far are kept")
            elif self._stop.is_set():
                self._mark(run_id, state="stopped", meta=outcome.meta,
                           message=outcome.message or "stopped by a stop request (quick stop)")
            else:
                self._mark(run_id, state="done", progress=1.0, meta=outcome.meta,
                           message=outcome.message)
