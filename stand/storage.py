"""Embedded storage of runs, their samples and every result (SQLite, WAL mode).

One database file holds three tables:

``runs``
    one row a run: its kind (CONTRACT §1 ``single`` | ``step`` | ``reducer``), where it
    came from (``job`` on the stand or ``upload``), the request that made it, its state
    and progress, column names and sample count.
``chunks``
    the samples, as float64 blocks appended as they arrive (one transaction a chunk),
    so a crash loses at most the chunk being written.
``results``
    every analysis result (identify, torque constant, ...) with its inputs.

Durability: WAL journal with ``synchronous=NORMAL`` — a committed chunk survives a crash
or SIGKILL of the process (it is in the WAL, replayed on the next open); an operating
system crash may lose the last transactions. :meth:`Storage.recover` marks runs left
``running`` or ``queued`` by a dead process as ``aborted``, keeping their samples; it
runs only under the data directory's lock (:class:`stand.datadir.DataDirLock`).

Faults: every SQLite error (disk full, I/O error) becomes a
:class:`~stand.errors.StorageError` and is kept in :attr:`Storage.fault` until the next
write succeeds, so the service can report degraded storage with its reason.
"""

from __future__ import annotations

import json
import sqlite3
import threading
import time
import uuid
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from stand.datadir import DataDirLock
from stand.errors import InputError, NotFoundError, StorageError
from stand.runfile import Run, RunKind, check_columns

#: Run states. ``queued`` and ``running`` are live; the others are final.
STATES: tuple[str, ...] = ("queued", "running", "done", "stopped", "aborted", "failed")
LIVE_STATES: tuple[str, ...] = ("queued", "running")
#: How long a connection waits for a lock held by another connection, s.
BUSY_TIMEOUT_S = 10.0

_SCHEMA = """
CREATE TABLE IF NOT EXISTS runs (
    id TEXT PRIMARY KEY,
    kind TEXT NOT NULL,
    origin TEXT NOT NULL,
    profile TEXT,
    request TEXT NOT NULL DEFAULT '{}',
    state TEXT NOT NULL,
    progress REAL NOT NULL DEFAULT 0,
    message TEXT NOT NULL DEFAULT '',
    columns TEXT NOT NULL DEFAULT '[]',
    samples INTEGER NOT NULL DEFAULT 0,
    meta TEXT NOT NULL DEFAULT '{}',
    created_s REAL NOT NULL,
    started_s REAL,
    finished_s REAL
);
CREATE TABLE IF NOT EXISTS chunks (
    run_id TEXT NOT NULL REFERENCES runs(id),
    seq INTEGER NOT NULL,
    rows INTEGER NOT NULL,
    data BLOB NOT NULL,
    PRIMARY KEY (run_id, seq)
);
CREATE TABLE IF NOT EXISTS results (
    id TEXT PRIMARY KEY,
    operation TEXT NOT NULL,
    inputs TEXT NOT NULL,
    result TEXT NOT NULL,
    created_s REAL NOT NULL
);
CREATE INDEX IF NOT EXISTS runs_created ON runs(created_s);
"""


@dataclass(frozen=True)
class RunRecord:
    """What the database knows about one run (no samples).

    Attributes
    ----------
    id : str
        Run id.
    kind : str
        ``single``, ``step`` or ``reducer`` (CONTRACT §1).
    origin : str
        ``job`` (recorded on the stand) or ``upload``.
    state : str
        One of :data:`STATES`.
    progress : float
        Fraction done, 0 to 1.
    columns : list of str
        Column names of the samples, each with its unit.
    samples : int
        Samples recorded so far.
    created_s, started_s, finished_s : float or None
        Unix times, s.
    """

    id: str
    kind: str
    origin: str
    profile: str | None
    state: str
    progress: float
    message: str
    columns: list[str]
    samples: int
    created_s: float
    started_s: float | None
    finished_s: float | None
    request: dict[str, Any] = field(default_factory=dict)
    meta: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class ResultRecord:
    """One stored analysis result with its inputs."""

    id: str
    operation: str
    inputs: dict[str, Any]
    result: dict[str, Any]
    created_s: float


def new_id() -> str:
    """A fresh random id (32 hex digits)."""
    return uuid.uuid4().hex


class Storage:
    """Thread-safe access to the SQLite database at ``path`` (created if missing).

    One connection is shared by all threads behind a lock; every write is one
    transaction.

    Parameters
    ----------
    path : path
        The database file (``":memory:"`` for a throw-away one).
    max_bytes : int, optional
        Largest size the database may grow to, bytes (SQLite ``max_page_count``); a
        write past it fails as on a full disk, so the data directory's disk never fills.

    Attributes
    ----------
    fault : str or None
        Why the last write failed (disk full, I/O error), or None once a write succeeded.
    """

    def __init__(self, path: str | Path, max_bytes: int | None = None) -> None:
        self.path = Path(path)
        self.fault: str | None = None
        if str(path) != ":memory:":
            self.path.parent.mkdir(parents=True, exist_ok=True)
        self._lock = threading.RLock()
        with self._guard("open"):
            self._db = sqlite3.connect(str(path), timeout=BUSY_TIMEOUT_S,
                                       check_same_thread=False, isolation_level=None)
            self._db.row_factory = sqlite3.Row
            self._db.execute("PRAGMA journal_mode=WAL")
            self._db.execute("PRAGMA synchronous=NORMAL")
            self._db.execute("PRAGMA foreign_keys=ON")
            self._db.executescript(_SCHEMA)
            if max_bytes is not None:
                page = int(self._db.execute("PRAGMA page_size").fetchone()[0])
                self._db.execute(f"PRAGMA max_page_count={max(1, int(max_bytes) // page)}")

    def close(self) -> None:
        """Close the connection (checkpoints the WAL)."""
        with self._lock, self._guard("close"):
            self._db.close()

    @contextmanager
    def _guard(self, action: str) -> Iterator[None]:
        """Turn SQLite errors into :class:`StorageError` and remember the fault."""
        try:
            yield
        except sqlite3.Error as exc:
            self.fault = f"{action} failed on {self.path}: {exc}"
            raise StorageError(f"storage: {self.fault}; free disk space or check the "
                               "database file") from exc

    @contextmanager
    def _transaction(self) -> Iterator[sqlite3.Connection]:
        with self._lock, self._guard("write"):
            self._db.execute("BEGIN IMMEDIATE")
            try:
                yield self._db
            except BaseException:
                # SQLite may already have rolled back itself (SQLITE_FULL, SQLITE_IOERR).
                if self._db.in_transaction:
                    self._db.execute("ROLLBACK")
                raise
            self._db.execute("COMMIT")
        self.fault = None

    def _query(self, sql: str, params: Sequence[Any] = ()) -> list[sqlite3.Row]:
        with self._lock, self._guard("read"):
            return self._db.execute(sql, params).fetchall()

    # -- runs -----------------------------------------------------------------------

    def recover(self, lock: DataDirLock) -> list[str]:
        """Mark runs a dead process left ``queued`` or ``running`` as ``aborted``.

        Call once at start-up, before any run starts, holding the data directory's
        ``lock``: without it the live runs of another service would be marked. Returns
        the ids marked.
        """
        if not lock.held:
            raise StorageError(f"recover() needs the lock of the data directory "
                               f"{lock.data_dir} held by this process; another service may "
                               "own its runs")
        with self._transaction() as db:
            rows = db.execute("SELECT id FROM runs WHERE state IN ('queued', 'running')").fetchall()
            ids = [row["id"] for row in rows]
            db.execute(
                "UPDATE runs SET state='aborted', finished_s=?, message=? "
                "WHERE state IN ('queued', 'running')",
                (time.time(), "the service stopped during the run; samples so far are kept"),
            )
        return ids

    def create_run(self, kind: str, origin: str, *, profile: str | None = None,
                   request: Mapping[str, Any] | None = None, state: str = "queued",
                   columns: Sequence[str] = ()) -> RunRecord:
        """Insert a new run and return its record."""
        if kind not in ("single", "step", "reducer"):
            raise InputError(f"kind must be 'single', 'step' or 'reducer', not {kind!r}")
        run_id = new_id()
        with self._transaction() as db:
            db.execute(
                "INSERT INTO runs (id, kind, origin, profile, request, state, columns, created_s) "
                "VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                (run_id, kind, origin, profile, json.dumps(dict(request or {})), state,
                 json.dumps(list(columns)), time.time()),
            )
        return self.get_run(run_id)

    def store_run(self, run: Run, kind: RunKind, origin: str = "upload",
                  request: Mapping[str, Any] | None = None) -> RunRecord:
        """Store a complete run (an upload) in one transaction; state ``done``."""
        names = list(run.columns)
        run_id = new_id()
        block = np.column_stack([run.columns[n] for n in names]).astype("<f8")
        now = time.time()
        with self._transaction() as db:
            db.execute(
                "INSERT INTO runs (id, kind, origin, request, state, progress, columns, samples, "
                "created_s, started_s, finished_s) VALUES (?, ?, ?, ?, 'done', 1, ?, ?, ?, ?, ?)",
                (run_id, kind, origin, json.dumps(dict(request or {})), json.dumps(names),
                 len(block), now, now, now),
            )
            db.execute("INSERT INTO chunks (run_id, seq, rows, data) VALUES (?, 0, ?, ?)",
                       (run_id, len(block), block.tobytes()))
        return self.get_run(run_id)

    def append_samples(self, run_id: str, columns: Mapping[str, np.ndarray]) -> int:
        """Append one chunk of samples (same column names every time); returns the total.

        The first chunk fixes the column order; later chunks must have the same columns.
        """
        with self._transaction() as db:
            row = db.execute("SELECT columns, samples FROM runs WHERE id=?", (run_id,)).fetchone()
            if row is None:
                raise NotFoundError(f"no run {run_id!r}")
            names = json.loads(row["columns"]) or list(columns)
            if set(names) != set(columns):
                raise InputError(f"run {run_id}: chunk columns {sorted(columns)} differ from "
                                 f"the run's {sorted(names)}")
            block = np.column_stack([np.asarray(columns[n], dtype="<f8").reshape(-1)
                                     for n in names])
            seq = db.execute("SELECT COALESCE(MAX(seq) + 1, 0) FROM chunks WHERE run_id=?",
                             (run_id,)).fetchone()[0]
            db.execute("INSERT INTO chunks (run_id, seq, rows, data) VALUES (?, ?, ?, ?)",
                       (run_id, seq, len(block), block.tobytes()))
            total = int(row["samples"]) + len(block)
            db.execute("UPDATE runs SET columns=?, samples=? WHERE id=?",
                       (json.dumps(names), total, run_id))
        return total

    def update_run(self, run_id: str, *, state: str | None = None, progress: float | None = None,
                   message: str | None = None, meta: Mapping[str, Any] | None = None) -> None:
        """Change a run's state, progress, message or meta (merged)."""
        if state is not None and state not in STATES:
            raise InputError(f"state must be one of {', '.join(STATES)}, not {state!r}")
        with self._transaction() as db:
            row = db.execute("SELECT meta FROM runs WHERE id=?", (run_id,)).fetchone()
            if row is None:
                raise NotFoundError(f"no run {run_id!r}")
            now = time.time()
            if state == "running":
                db.execute("UPDATE runs SET started_s=COALESCE(started_s, ?) WHERE id=?",
                           (now, run_id))
            elif state is not None and state not in LIVE_STATES:
                db.execute("UPDATE runs SET finished_s=? WHERE id=?", (now, run_id))
            if state is not None:
                db.execute("UPDATE runs SET state=? WHERE id=?", (state, run_id))
            if progress is not None:
                db.execute("UPDATE runs SET progress=? WHERE id=?",
                           (min(max(float(progress), 0.0), 1.0), run_id))
            if message is not None:
                db.execute("UPDATE runs SET message=? WHERE id=?", (message, run_id))
            if meta:
                merged = {**json.loads(row["meta"]), **meta}
                db.execute("UPDATE runs SET meta=? WHERE id=?", (json.dumps(merged), run_id))

    def get_run(self, run_id: str) -> RunRecord:
        """The record of run ``run_id``; :class:`NotFoundError` if unknown."""
        rows = self._query("SELECT * FROM runs WHERE id=?", (run_id,))
        if not rows:
            raise NotFoundError(f"no run {run_id!r}; the list of stored runs gives their ids")
        return _record(rows[0])

    def list_runs(self, limit: int = 100, offset: int = 0, state: str | None = None) -> list[RunRecord]:
        """Runs, newest first."""
        query, params = "SELECT * FROM runs", []
        if state is not None:
            query += " WHERE state=?"
            params.append(state)
        query += " ORDER BY created_s DESC LIMIT ? OFFSET ?"
        return [_record(row) for row in self._query(query, (*params, limit, offset))]

    def samples(self, run_id: str, start: int = 0) -> dict[str, np.ndarray]:
        """The samples of a run from sample index ``start`` on, column name to array."""
        record = self.get_run(run_id)
        rows = self._query("SELECT rows, data FROM chunks WHERE run_id=? ORDER BY seq", (run_id,))
        width = len(record.columns)
        blocks, seen = [], 0
        for row in rows:
            if seen + row["rows"] > start:
                block = np.frombuffer(row["data"], dtype="<f8").reshape(row["rows"], width)
                blocks.append(block[max(start - seen, 0):])
            seen += row["rows"]
        table = np.concatenate(blocks) if blocks else np.empty((0, width))
        return {name: table[:, j].copy() for j, name in enumerate(record.columns)}

    def load_run(self, run_id: str, kind: RunKind | None = None) -> Run:
        """A stored run as a validated :class:`Run` of ``kind`` (default: its own kind)."""
        record = self.get_run(run_id)
        return check_columns(self.samples(run_id), kind or record.kind,  # type: ignore[arg-type]
                             f"run {run_id}")

    def delete_run(self, run_id: str) -> None:
        """Delete a finished run and its samples (results that used it keep their inputs).

        A ``queued`` or ``running`` run is refused (:class:`InputError`): stop it first.
        """
        with self._transaction() as db:
            row = db.execute("SELECT state FROM runs WHERE id=?", (run_id,)).fetchone()
            if row is None:
                raise NotFoundError(f"no run {run_id!r}; the list of stored runs gives their ids")
            if row["state"] in LIVE_STATES:
                raise InputError(f"run {run_id} is {row['state']}; stop it first, then it can "
                                 "be deleted")
            db.execute("DELETE FROM chunks WHERE run_id=?", (run_id,))
            db.execute("DELETE FROM runs WHERE id=?", (run_id,))

    def prune_uploads(self, older_than_s: float) -> int:
        """Delete uploaded runs created more than ``older_than_s`` seconds ago; returns
        how many went. Runs recorded on the stand are never pruned."""
        cutoff = time.time() - older_than_s
        with self._transaction() as db:
            old = "SELECT id FROM runs WHERE origin='upload' AND created_s < ?"
            db.execute(f"DELETE FROM chunks WHERE run_id IN ({old})", (cutoff,))
            return int(db.execute("DELETE FROM runs WHERE origin='upload' AND created_s < ?",
                                  (cutoff,)).rowcount)

    # -- results --------------------------------------------------------------------

    def add_result(self, operation: str, inputs: Mapping[str, Any], result: Mapping[str, Any]) -> str:
        """Store one analysis result with its inputs (JSON data); returns its id."""
        result_id = new_id()
        with self._transaction() as db:
            db.execute("INSERT INTO results (id, operation, inputs, result, created_s) "
                       "VALUES (?, ?, ?, ?, ?)",
                       (result_id, operation, json.dumps(dict(inputs)), json.dumps(dict(result)),
                        time.time()))
        return result_id

    def get_result(self, result_id: str) -> ResultRecord:
        """One stored result; :class:`NotFoundError` if unknown."""
        rows = self._query("SELECT * FROM results WHERE id=?", (result_id,))
        if not rows:
            raise NotFoundError(f"no result {result_id!r}")
        return _result(rows[0])

    def list_results(self, limit: int = 100, offset: int = 0) -> list[ResultRecord]:
        """Stored results, newest first."""
        rows = self._query("SELECT * FROM results ORDER BY created_s DESC LIMIT ? OFFSET ?",
                           (limit, offset))
        return [_result(row) for row in rows]


def _record(row: sqlite3.Row) -> RunRecord:
    return RunRecord(
        id=row["id"], kind=row["kind"], origin=row["origin"], profile=row["profile"],
        state=row["state"], progress=row["progress"], message=row["message"],
        columns=json.loads(row["columns"]), samples=row["samples"], created_s=row["created_s"],
        started_s=row["started_s"], finished_s=row["finished_s"],
        request=json.loads(row["request"]), meta=json.loads(row["meta"]),
    )


def _result(row: sqlite3.Row) -> ResultRecord:
    return ResultRecord(id=row["id"], operation=row["operation"], inputs=json.loads(row["inputs"]),
                        result=json.loads(row["result"]), created_s=row["created_s"])
