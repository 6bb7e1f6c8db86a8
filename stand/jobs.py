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
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from stand.errors import InputError, NotFoundError, RunAborted, StandError, StorageError
from stand.storage import RunRecord, Storage, new_id

log = logging.getLogger("stand.jobs")

#: Least time between two progress writes to the database, s.
PROGRESS_INTERVAL_S = 0.2
#: How long close() waits for the worker to finish the current run after a stop, s.
CLOSE_TIMEOUT_S = 10.0
#: Most samples one run may record (duration_s / period_s), checked before planning:
#: planning holds every command in memory (about 25 bytes a sample), so 10**8 samples
#: would take seconds and gigabytes before any limit check. Two million is 2000 s at 1 kHz.
MAX_RUN_SAMPLES = 2_000_000
#: How often an idle worker retries final states it could not write, s.
RETRY_MARKS_S = 1.0

#: Master timeouts for drives simulated in this process (``bus.master.Master`` options).
#: The simulated drives share the CPU with the master and the service (and, on a build
#: machine, with everything else); under load a 100 ms heartbeat or a 0.5 s PDO answer is
#: missed although no drive failed and no frame was lost. Real drives keep the defaults.
SIMULATED_MASTER_OPTIONS: dict[str, Any] = {"heartbeat_period_s": 1.0, "pdo_timeout_s": 5.0}

ProgressCallback = Callable[[float], None]
ChunkCallback = Callable[[Mapping[str, np.ndarray]], None]


@dataclass(frozen=True)
class RunPlan:
    """One checked run of a request: its kind, its profile, the request as stored, and
    what the runner needs to execute it (``payload``, not stored)."""

    kind: str
    profile: str
    request: dict[str, Any]
    payload: Any = None


@dataclass
class RunOutcome:
    """What a runner reports at the end of a run."""

    meta: dict[str, Any] = field(default_factory=dict)
    message: str = ""


class StandRunner(Protocol):
    """What the job manager needs from a stand (bus controller or simulation)."""

    def plan(self, request: Mapping[str, Any]) -> list[RunPlan]:
        """The runs of ``request``, checked against the profile and its limits; nothing moves."""
        ...

    def execute(self, run_id: str, plan: RunPlan, on_progress: ProgressCallback, on_chunk: ChunkCallback,
                stop: threading.Event) -> RunOutcome:
        """Run the experiment; return when done or when ``stop`` is set."""
        ...

    def quick_stop_all(self) -> dict[str, Any]:
        """CiA 402 quick stop to every drive at once."""
        ...

    def status(self) -> dict[str, Any]:
        """Nodes, NMT states, heartbeat ages, error counters."""
        ...

    def close(self) -> None:
        """Release the bus and threads."""
        ...


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


def _check_samples(experiment: Any) -> None:
    """Refuse a run of more than :data:`MAX_RUN_SAMPLES` samples before it is planned."""
    from stand.profiles import load_motor, load_stand

    period = experiment.period_s
    if period is None and experiment.stand:
        period = load_stand(experiment.stand).sample_period_s
    elif period is None and experiment.motor:
        period = load_motor(experiment.motor).sample_period_s
    if period is None:
        return  # plan() names the missing motor or stand
    samples = experiment.duration_s / period
    if not samples <= MAX_RUN_SAMPLES:
        raise InputError(f"overrides: duration_s {experiment.duration_s:g} s at period_s "
                         f"{period:g} s is {samples:.3g} samples a run, more than "
                         f"{MAX_RUN_SAMPLES}; shorten duration_s or lengthen period_s")


class ControllerRunner:
    """The stand run by :class:`stand.controller.StandController` over the bus.

    A request names an experiment profile (``profiles/experiments``) and ``overrides``
    of its fields (``procedure``, ``repeats``, ``duration_s``, ``seed``, ...; never the
    motor or stand, whose profiles hold the limits); it becomes one job per
    run of the experiment (the torque-constant experiment: no-load and added-inertia
    runs, alternately). Run files and CAN traces go to ``runs_dir/<run id>/``.

    Parameters
    ----------
    bus_factory : callable
        ``bus_factory(profile, seed)`` opens the stand's bus (a ``StandBus``), with the
        drives of the motor or stand ``profile`` simulated when the bus is virtual.
    runs_dir : path
        Where run files and traces are written.
    time_mode : {'lockstep', 'realtime'}
        SYNC timing (lockstep for simulated drives).
    """

    def __init__(self, bus_factory: Callable[[str, int | None], Any], runs_dir: str | Path,
                 time_mode: str = "lockstep") -> None:
        self.bus_factory = bus_factory
        self.runs_dir = Path(runs_dir)
        self.time_mode = time_mode
        self._lock = threading.Lock()
        self._bus: Any = None
        self._bus_key: tuple[str, int | None] | None = None

    def plan(self, request: Mapping[str, Any]) -> list[RunPlan]:
        """The runs of ``request``; ``profile`` is a shipped experiment's *name*.

        Requests come from the network: a path would read any YAML file on this machine
        and tell the caller whether it exists, so only the names of the shipped experiment profiles count.
        """
        from pydantic import ValidationError

        from stand.controller import ExperimentProfile, load_experiment, plan
        from stand.profiles import describe, list_profiles

        name = str(request.get("profile"))
        known = list_profiles().get("experiments", [])
        if name not in known:
            raise NotFoundError(f"profile: no experiment profile of that name; known: "
                                f"{', '.join(known)}")
        experiment = load_experiment(name)
        overrides = dict(request.get("overrides") or {})
        for key in ("name", "motor", "stand"):
            if key in overrides:
                raise InputError(f"overrides.{key}: cannot be changed by a request; choose another "
                                 "of the shipped experiment profiles")
        try:
            experiment = ExperimentProfile(**{**experiment.model_dump(), **overrides})
        except ValidationError as exc:
            raise InputError(describe(exc, "overrides.", echo=False)) from exc
        _check_samples(experiment)
        runs = plan(experiment)  # LimitError before anything moves
        target = str(experiment.stand or experiment.motor)
        return [RunPlan(proc.kind, experiment.name,
                        {"profile": name, "overrides": overrides, "procedure": proc.name,
                         "run": k + 1, "runs": len(runs), "description": proc.description},
                        payload=(proc, drives, target, experiment.seed))
                for k, (proc, drives) in enumerate(runs)]

    def _open(self, profile: str, seed: int | None) -> Any:
        with self._lock:
            if self._bus is not None and self._bus_key == (profile, seed):
                return self._bus
            old, self._bus, self._bus_key = self._bus, None, None
        if old is not None:
            old.close()
        bus = self.bus_factory(profile, seed)
        with self._lock:
            self._bus, self._bus_key = bus, (profile, seed)
        return bus

    def execute(self, run_id: str, plan: RunPlan, on_progress: ProgressCallback,
                on_chunk: ChunkCallback, stop: threading.Event) -> RunOutcome:
        from stand.controller import StandController

        procedure, drives, target, seed = plan.payload
        bus = self._open(target, seed)
        controller = StandController(bus, self.time_mode, on_chunk=on_chunk, stop=stop)
        record = controller.run_procedure(procedure, drives, self.runs_dir / run_id,
                                          lambda k, n: on_progress(k / n))
        meta = {"path": record.path, "trace_path": record.trace_path,
                "expected_samples": record.expected_samples, "period_s": record.period_s,
                "complete": record.complete, "lost": record.lost, "late": record.late,
                "duplicates": record.duplicates, "wall_time_s": record.wall_time_s,
                "stand_time_s": record.stand_time_s, "aborted": record.aborted}
        return RunOutcome(meta, record.aborted or "")

    def quick_stop_all(self) -> dict[str, Any]:
        with self._lock:
            bus = self._bus
        if bus is None:
            return {"sent": False, "reason": "no bus open: no drive has been set up yet"}
        bus.quick_stop_all()
        return {"sent": True, "nodes": [n["node_id"] for n in bus.status().get("nodes", [])]}

    def status(self) -> dict[str, Any]:
        with self._lock:
            bus, key = self._bus, self._bus_key
        if bus is None:
            return {"bus": "closed (opens with the first run)", "nodes": []}
        return {**bus.status(), "profile": key[0] if key else None}

    def close(self) -> None:
        with self._lock:
            bus, self._bus, self._bus_key = self._bus, None, None
        if bus is not None:
            bus.close()
