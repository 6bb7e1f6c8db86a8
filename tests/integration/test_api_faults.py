"""The service under faults, against real servers on loopback: a full disk, a second
server on the same data directory, and the job worker after a storage error.

The disk fills in two ways that work unprivileged: SQLite's own size cap
(``STAND_DB_MAX_BYTES``, SQLITE_FULL as on a full disk) and a file-size limit on the
server process (``RLIMIT_FSIZE``, EFBIG from the kernel on every file it writes).
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest

from stand.datadir import DataDirLock
from stand.errors import DataDirLocked, StandError, StorageError
from stand.jobs import JobManager
from stand.runfile import format_run
from stand.runner import RunOutcome, RunPlan
from stand.storage import Storage
from tests.integration.test_api_support import ROOT, free_port, serve, wait_for

#: How long a state change may take to show, s (generous: 2 shared cores under load).
WAIT_S = 60.0
LONG_RUN = {"profile": "seed000_no_load", "overrides": {"duration_s": 600.0}}


def final(client: httpx.Client, run_id: str) -> dict[str, Any]:
    def done() -> dict[str, Any] | None:
        run: dict[str, Any] = client.get(f"/runs/{run_id}").json()
        return run if run["state"] not in ("queued", "running") else None
    result: dict[str, Any] = wait_for(done, WAIT_S, f"run {run_id} to end")
    return result


# -- the job worker, in-process, on a real SQLite file that fills up ---------------------

class ChunkRunner:
    """A stand that hands over sample chunks until ``stop`` or an error, then fails
    with a message of ``message_bytes`` characters (room a full database lacks)."""

    def __init__(self, message_bytes: int = 0) -> None:
        self.message_bytes = message_bytes
        self.executed: list[str] = []

    def plan(self, request: Mapping[str, Any]) -> list[RunPlan]:
        return [RunPlan("single", "chunks", dict(request))]

    def execute(self, run_id: str, plan: RunPlan, on_progress: Any, on_chunk: Any,
                stop: threading.Event) -> RunOutcome:
        self.executed.append(run_id)
        t = np.arange(1000) * 1e-3
        for k in range(int(plan.request.get("chunks", 10**6))):
            if stop.is_set():
                break
            try:
                on_chunk({"time_s": t + k, "current_A": np.sin(t), "position_rad": t})
            except StorageError as exc:
                if self.message_bytes:
                    raise StandError("x" * self.message_bytes) from exc
                raise
        return RunOutcome()

    def quick_stop_all(self) -> dict[str, Any]:
        return {}

    def status(self) -> dict[str, Any]:
        return {}

    def close(self) -> None:
        pass


def test_worker_survives_a_failed_final_state(tmp_path: Path) -> None:
    # 256 KiB of database: a few chunks of samples fill it; the runner's 200 kB error
    # message cannot be stored as the run's final state either.
    storage = Storage(tmp_path / "db.sqlite3", max_bytes=256 * 1024)
    runner = ChunkRunner(message_bytes=200_000)
    jobs = JobManager(storage, runner)
    try:
        first = jobs.submit({})[0].id
        wait_for(lambda: jobs.fault, WAIT_S, "the failed final state to be pending")
        assert first in (jobs.fault or "")
        assert storage.get_run(first).state == "running"  # not stored: the disk is full
        assert storage.fault is not None and "full" in storage.fault
        # Room again (a lab deletes old runs): the pending state is written, the worker
        # takes the next job.
        storage._db.execute("PRAGMA max_page_count=100000")
        runner.message_bytes = 0
        wait_for(lambda: jobs.fault is None, WAIT_S, "the pending state to be stored")
        assert storage.get_run(first).state == "failed"
        second = jobs.submit({"chunks": 3})[0].id
        wait_for(lambda: storage.get_run(second).state == "done", WAIT_S, "the next job to run")
        assert storage.get_run(second).samples == 3000
        assert storage.fault is None
    finally:
        jobs.close()
        storage.close()


def test_a_submit_refused_by_storage_leaves_the_worker_running(tmp_path: Path) -> None:
    storage = Storage(tmp_path / "db.sqlite3")
    runner = ChunkRunner()
    jobs = JobManager(storage, runner)
    try:
        queued = jobs.submit({"chunks": 1})[0].id
        wait_for(lambda: storage.get_run(queued).state == "done", WAIT_S, "the first job")
        storage._db.execute("PRAGMA query_only=ON")  # every write now fails
        with pytest.raises(StorageError, match="readonly|read-only|query_only"):
            jobs.submit({"chunks": 1})  # create_run fails: a clear error, nothing queued
        storage._db.execute("PRAGMA query_only=OFF")
        after = jobs.submit({"chunks": 2})[0].id
        wait_for(lambda: storage.get_run(after).state == "done", WAIT_S, "the worker to take the next job")
        assert runner.executed[-1] == after
    finally:
        jobs.close()
        storage.close()


# -- a full disk under a real server ---------------------------------------------------

def upload_text(samples: int) -> str:
    t = np.arange(samples) * 1e-3
    return format_run({"time_s": t, "current_A": np.sin(7 * t), "position_rad": np.cos(3 * t)})


def assert_degraded(c: httpx.Client, reason: str) -> None:
    """/health names the storage fault; a new job is refused (503) or taken and ends
    ``failed``: the worker lives on, nothing stays queued."""
    health = c.get("/health").json()
    assert health["status"] == "degraded" and reason in health["storage"]["reason"]
    started = c.post("/runs", json=LONG_RUN)
    if started.status_code == 202:
        assert final(c, started.json()["id"])["state"] == "failed"
    else:
        assert started.status_code == 503


def test_database_full_degrades_and_recovers(tmp_path: Path) -> None:
    env = {"STAND_DB_MAX_BYTES": str(256 * 1024)}
    with serve(tmp_path, extra_env=env) as server, server.client() as c:
        assert c.get("/health").json()["status"] == "ok"
        run_id = c.post("/runs", json=LONG_RUN).json()["id"]
        failed = final(c, run_id)
        assert failed["state"] == "failed" and "full" in failed["message"]
        assert failed["samples"] > 0  # the samples before the disk filled are kept
        big = c.post("/runs/upload", files={"file": ("big.csv", upload_text(200_000))})
        assert big.status_code == 503 and big.json()["error"] == "storage"
        assert_degraded(c, "full")
        # Reading and analysing what is stored still works; deleting makes room.
        assert c.post("/identify", json={"run": run_id}).status_code == 200
        assert c.delete(f"/runs/{run_id}").status_code == 204
        small = c.post("/runs/upload", files={"file": ("small.csv", upload_text(2000))})
        assert small.status_code == 201
        assert c.get("/health").json()["status"] == "ok"


def test_file_size_limit_fails_writes_not_the_service(tmp_path: Path) -> None:
    # Every file of the server may grow to 4 MB: uploads of 30 000 samples (0.9 MB of
    # CSV, 0.7 MB stored) fill the database within a dozen.
    with serve(tmp_path, file_size_limit=4_000_000) as server, server.client() as c:
        text = upload_text(30_000)
        answers = []
        for _ in range(30):
            answers.append(c.post("/runs/upload", files={"file": ("u.csv", text)}))
            if answers[-1].status_code != 201:
                break
        assert answers[-1].status_code == 503 and answers[-1].json()["error"] == "storage"
        assert {a.status_code for a in answers[:-1]} == {201}
        health = c.get("/health").json()  # (a run on a full disk: the test above)
        assert health["status"] == "degraded" and "write failed" in health["storage"]["reason"]
        # A body the server cannot even spool to its temporary file: 503, not 400/500.
        spool = c.post("/runs/upload", files={"file": ("big.csv", upload_text(200_000))})
        assert spool.status_code == 503, spool.text
        stored = answers[0].json()["id"]
        assert c.get(f"/runs/{stored}/samples").text == text  # reading still works


# -- one owner per data directory ------------------------------------------------------

def test_second_server_refuses_and_names_the_owner(tmp_path: Path) -> None:
    with serve(tmp_path) as first, first.client() as c:
        run_id = c.post("/runs", json=LONG_RUN).json()["id"]
        seen = wait_for(lambda: c.get(f"/runs/{run_id}").json()["samples"], WAIT_S, "samples")
        env = {k: v for k, v in os.environ.items() if not k.startswith("STAND_")}
        env.update(STAND_DATA_DIR=str(tmp_path), STAND_API_KEY="other", PYTHONPATH=str(ROOT))
        second = subprocess.run(
            [sys.executable, "-m", "stand", "serve", "--port", str(free_port())],
            cwd=ROOT, env=env, capture_output=True, text=True, timeout=WAIT_S)
        assert second.returncode == 1
        assert f"PID {first.process.pid}" in second.stderr
        run = c.get(f"/runs/{run_id}").json()
        assert run["state"] == "running", "the second server touched the first one's run"
        wait_for(lambda: c.get(f"/runs/{run_id}").json()["samples"] > seen, WAIT_S, "more samples")
        assert c.post("/stop").json()["stopped_run"] == run_id


def test_lock_is_exclusive_and_recover_needs_it(tmp_path: Path) -> None:
    storage = Storage(tmp_path / "stand.sqlite3")
    lock = DataDirLock(tmp_path)
    with pytest.raises(StorageError, match="lock"):
        storage.recover(lock)
    with lock:
        assert (tmp_path / "stand.lock").read_text().strip() == str(os.getpid())
        with pytest.raises(DataDirLocked, match=f"PID {os.getpid()}"):
            DataDirLock(tmp_path).acquire()
        assert storage.recover(lock) == []
    with DataDirLock(tmp_path):  # released: free again
        pass
    storage.close()
