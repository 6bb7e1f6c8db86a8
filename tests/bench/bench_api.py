"""Benchmark of the HTTP service and its storage; prints figures (not collected by pytest).

Run: ``python -m tests.bench.bench_api`` (about a minute on 2 cores).

1. Storage of samples: SQLite BLOB chunks (the choice) against appending CSV files,
   per-chunk write latency and the read-back time of a 100 000-sample run.
2. 50 concurrent POST /identify on stored 100 000-sample runs against a real uvicorn:
   errors, p50 / p99 / max latency, throughput.
3. 100 concurrent uploads (POST /runs/upload) of 100 000-sample runs while GET /health
   is polled: upload latencies and the /health latencies during the load (p50, p99, max).

``python -m tests.bench.bench_api uploads`` runs only the third (about two minutes).
"""

from __future__ import annotations

import asyncio
import statistics
import sys
import tempfile
import time
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any

import httpx
import numpy as np

from stand.physics.plant import MotorPlant
from stand.physics.simulate import simulate_motor
from stand.procedures import multisine
from stand.profiles import load_motor
from stand.runfile import format_run, read_run
from stand.storage import Storage
from tests.integration.test_api_support import serve

SAMPLES = 100_000
CHUNK = 250
REQUESTS = 50
COLUMNS = ("time_s", "current_A", "position_rad", "voltage_V", "velocity_rad_s")


def percentile(values: list[float], q: float) -> float:
    return float(np.percentile(np.asarray(values), q))


def bench_storage(workdir: Path) -> None:
    rng = np.random.default_rng(0)
    table = rng.standard_normal((SAMPLES, len(COLUMNS)))
    table[:, 0] = np.arange(SAMPLES) * 1e-3
    storage = Storage(workdir / "bench.sqlite3")
    run_id = storage.create_run("single", "job", columns=COLUMNS).id
    db_times = []
    for start in range(0, SAMPLES, CHUNK):
        block = table[start:start + CHUNK]
        t0 = time.perf_counter()
        storage.append_samples(run_id, {n: block[:, j] for j, n in enumerate(COLUMNS)})
        db_times.append(time.perf_counter() - t0)
    t0 = time.perf_counter()
    back = storage.samples(run_id)
    db_read = time.perf_counter() - t0
    assert np.array_equal(back["current_A"], table[:, 1])
    storage.close()
    db_size = (workdir / "bench.sqlite3").stat().st_size + sum(
        p.stat().st_size for p in workdir.glob("bench.sqlite3-*"))

    csv_path = workdir / "bench.csv"
    csv_times = []
    with open(csv_path, "w", encoding="utf-8") as out:
        out.write(",".join(COLUMNS) + "\n")
        for start in range(0, SAMPLES, CHUNK):
            block = table[start:start + CHUNK]
            t0 = time.perf_counter()
            text = format_run({n: block[:, j] for j, n in enumerate(COLUMNS)})
            out.write(text.split("\n", 1)[1])
            out.flush()
            csv_times.append(time.perf_counter() - t0)
    t0 = time.perf_counter()
    read_run(csv_path, "single")
    csv_read = time.perf_counter() - t0

    print(f"storage of {SAMPLES} samples x {len(COLUMNS)} columns in chunks of {CHUNK}:")
    print(f"  sqlite blob chunks (WAL, one transaction a chunk): write p50 "
          f"{1e3 * statistics.median(db_times):.3f} ms p99 {1e3 * percentile(db_times, 99):.3f} ms "
          f"a chunk; read all {1e3 * db_read:.1f} ms; {db_size / 1e6:.1f} MB (exact float64)")
    print(f"  csv append + flush:                               write p50 "
          f"{1e3 * statistics.median(csv_times):.3f} ms p99 {1e3 * percentile(csv_times, 99):.3f} ms "
          f"a chunk; read all (validated) {1e3 * csv_read:.1f} ms; "
          f"{csv_path.stat().st_size / 1e6:.1f} MB (9 digits)")


def long_run_csv() -> str:
    profile = load_motor("crouzet_82800502")
    dt = 1e-3
    limit = profile.limits.speed_rad_s
    command = multisine(SAMPLES, dt, 0.5 * limit, 0.25 * limit, 10.0, seed=1)
    plant = MotorPlant(profile.motor_params(), profile.drive_params("speed"),
                       profile.sensor_params(), profile.effect_set(), seed=1)
    return format_run(simulate_motor(plant, "speed", command, dt).columns)


async def timed_concurrently(count: int, send: Callable[[int], Awaitable[httpx.Response]],
                             expected: int) -> tuple[list[float], int, float]:
    """``send(k)`` for k < ``count`` all at once: latencies (s), answers other than
    ``expected``, wall time (s)."""
    latencies: list[float] = []
    errors = 0

    async def one(k: int) -> None:
        nonlocal errors
        t0 = time.perf_counter()
        answer = await send(k)
        latencies.append(time.perf_counter() - t0)
        if answer.status_code != expected:
            errors += 1
            print(f"  request {k}: {answer.status_code} {answer.text[:200]}", file=sys.stderr)

    t0 = time.perf_counter()
    await asyncio.gather(*(one(k) for k in range(count)))
    return latencies, errors, time.perf_counter() - t0


async def fire(base_url: str, headers: dict[str, str], run_ids: list[str]) -> tuple[list[float], int, float]:
    async with httpx.AsyncClient(base_url=base_url, headers=headers, timeout=600) as client:
        return await timed_concurrently(
            REQUESTS, lambda k: client.post("/identify", json={"run": run_ids[k % len(run_ids)]}),
            200)


def bench_identify(workdir: Path) -> None:
    t0 = time.perf_counter()
    text = long_run_csv()
    print(f"simulated a {SAMPLES}-sample run in {time.perf_counter() - t0:.1f} s "
          f"({len(text) / 1e6:.1f} MB of CSV)")
    with serve(workdir / "server") as server, server.client() as client:
        run_ids = []
        for _ in range(5):
            answer = client.post("/runs/upload", files={"file": ("long.csv", text)})
            answer.raise_for_status()
            run_ids.append(answer.json()["id"])
        latencies, errors, wall = asyncio.run(
            fire(server.base_url, {"Authorization": f"Bearer {server.api_key}"}, run_ids))
    print(f"{REQUESTS} concurrent POST /identify on stored {SAMPLES}-sample runs "
          f"(5 distinct runs), one uvicorn worker, 2 shared cores:")
    print(f"  errors {errors}; latency p50 {percentile(latencies, 50):.2f} s, "
          f"p99 {percentile(latencies, 99):.2f} s, max {max(latencies):.2f} s; "
          f"all done in {wall:.2f} s ({REQUESTS / wall:.1f} requests/s)")


UPLOADS = 100
#: Time between two GET /health polls during the upload load, s.
HEALTH_POLL_S = 0.05


def _watch_health(base_url: str, stop: Any, out: Any) -> None:
    """GET /health every HEALTH_POLL_S until ``stop`` is set; send the latencies, s.

    Runs in its own process: in the uploading process the client's own work (100
    uploads on one event loop) would add to the latencies it measures.
    """
    latencies: list[float] = []
    with httpx.Client(base_url=base_url, timeout=900) as watcher:
        while not stop.is_set():
            t0 = time.perf_counter()
            watcher.get("/health").raise_for_status()
            latencies.append(time.perf_counter() - t0)
            time.sleep(HEALTH_POLL_S)
    out.send(latencies)


async def _upload_all(base_url: str, headers: dict[str, str], text: str,
                      ) -> tuple[list[float], int, float]:
    body, content_type = _multipart(text)
    limits = httpx.Limits(max_connections=UPLOADS + 5)
    async with httpx.AsyncClient(base_url=base_url, headers=headers, timeout=900,
                                 limits=limits) as client:
        return await timed_concurrently(
            UPLOADS, lambda k: client.post("/runs/upload", content=body,
                                           headers={"Content-Type": content_type}), 201)


def _multipart(text: str) -> tuple[bytes, str]:
    """The upload's form encoded once (the client then only sends bytes)."""
    request = httpx.Request("POST", "http://localhost/", files={"file": ("run.csv", text)})
    return request.read(), request.headers["Content-Type"]


def bench_uploads(workdir: Path) -> None:
    import multiprocessing

    text = long_run_csv()
    with serve(workdir / "uploads") as server:
        stop = multiprocessing.Event()
        receive, send = multiprocessing.Pipe(duplex=False)
        watcher = multiprocessing.Process(target=_watch_health, args=(server.base_url, stop, send))
        watcher.start()
        uploads, errors, wall = asyncio.run(_upload_all(
            server.base_url, {"Authorization": f"Bearer {server.api_key}"}, text))
        stop.set()
        health = receive.recv()
        watcher.join()
    print(f"{UPLOADS} concurrent POST /runs/upload of {SAMPLES}-sample runs "
          f"({len(text) / 1e6:.1f} MB of CSV each), one uvicorn worker, 2 shared cores:")
    print(f"  errors {errors}; upload latency p50 {percentile(uploads, 50):.2f} s, "
          f"p99 {percentile(uploads, 99):.2f} s; all done in {wall:.1f} s")
    print(f"  GET /health during the load from another process ({len(health)} polls): p50 "
          f"{1e3 * percentile(health, 50):.1f} ms, p99 {1e3 * percentile(health, 99):.1f} ms, "
          f"max {1e3 * max(health):.1f} ms")


def bench_stop(workdir: Path, repeats: int = 5) -> None:
    """POST /stop mid-run on the two-drive stand: stand time until every node is in quick stop."""
    from fastapi.testclient import TestClient

    from api.app import create_app, default_runner
    from stand.settings import Settings
    from tests.integration.test_api_stop import RecordingRunner

    lags_ms: list[float] = []
    walls_ms: list[float] = []
    for k in range(repeats):
        recorder: list[RecordingRunner] = []

        def factory(s: Settings, recorder: list[RecordingRunner] = recorder) -> RecordingRunner:
            recorder.append(RecordingRunner(default_runner(s)))
            return recorder[0]

        settings = Settings(data_dir=workdir / f"stop{k}", bus_channel=f"bench-stop-{k}")
        with TestClient(create_app(settings, factory), base_url="http://127.0.0.1") as client:  # type: ignore[arg-type]
            run_id = client.post("/runs", json={"profile": "seed000_efficiency",
                                                "overrides": {"duration_s": 300.0}}).json()["id"]
            while client.get(f"/runs/{run_id}").json()["samples"] < 1000:
                time.sleep(0.02)
            t0 = time.perf_counter()
            client.post("/stop").raise_for_status()
            walls_ms.append(1e3 * (time.perf_counter() - t0))
            period = recorder[0].runner._bus.master.period_s
            for node in recorder[0].nodes():
                if node.quick_stop_at is None:
                    print(f"  repeat {k}: node {node.id} never entered quick stop "
                          f"(state {node.sm.state}, syncs {node.syncs})", file=sys.stderr)
                    continue
                lags_ms.append(1e3 * period * (node.quick_stop_at[1]
                                               - recorder[0].syncs_at_request[node.id]))
    print(f"POST /stop mid-run, 2 drives, {repeats} times: stand time from the request to "
          f"QUICK STOP ACTIVE max {max(lags_ms):.1f} ms (p50 {statistics.median(lags_ms):.1f} ms); "
          f"HTTP round trip p50 {statistics.median(walls_ms):.1f} ms")


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        if sys.argv[1:] == ["uploads"]:
            bench_uploads(Path(tmp))
            return
        bench_storage(Path(tmp))
        bench_stop(Path(tmp))
        bench_identify(Path(tmp))
        bench_uploads(Path(tmp))


if __name__ == "__main__":
    main()
