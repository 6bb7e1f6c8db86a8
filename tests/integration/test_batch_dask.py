"""Batches on a real Dask LocalCluster of two worker processes: the serial path's answers.

One cluster for the module (it starts in a few seconds); each test maps real run files
over it and compares every row and every fleet figure with the serial path. The
tolerance is 1e-12 relative: the same function runs on the same bytes in both paths, so
only a different BLAS thread count in the workers could change a last bit or two.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from stand.batch import BatchResult, dask_client, engine, run_batch
from stand.cli import main
from tests.batch_runs import write_bad, write_runs

RTOL = 1e-12


@pytest.fixture(scope="module")
def client() -> Iterator[Any]:
    with dask_client(workers=2) as c:
        assert len(c.scheduler_info()["workers"]) == 2
        yield c


@pytest.fixture(scope="module")
def hundred(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """99 good runs of one motor and one bad file, item 50 in sorted order (after run_049)."""
    folder = tmp_path_factory.mktemp("hundred")
    write_runs(folder, 99)
    write_bad(folder / "run_049_bad.csv")
    return folder


def assert_same(a: Any, b: Any, where: str) -> None:
    """Equal strings, ints and structure; floats to RTOL (JSON text compared parsed)."""
    if isinstance(a, str) and a.startswith(("[", "{")) and isinstance(b, str):
        a, b = json.loads(a), json.loads(b)
    if isinstance(a, float) and isinstance(b, float):
        assert math.isclose(a, b, rel_tol=RTOL, abs_tol=0.0) or a == b, (where, a, b)
    elif isinstance(a, dict):
        assert a.keys() == b.keys(), where
        for k in a:
            assert_same(a[k], b[k], f"{where}.{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), where
        for k, (x, y) in enumerate(zip(a, b, strict=True)):
            assert_same(x, y, f"{where}[{k}]")
    else:
        assert a == b, (where, a, b)


def assert_same_batch(parallel: BatchResult, serial: BatchResult) -> None:
    assert (parallel.items, parallel.errors) == (serial.items, serial.errors)
    for p, s in zip(parallel.rows, serial.rows, strict=True):
        p, s = dict(p), dict(s)
        for timing in ("seconds", "cpu_seconds"):  # the columns that may differ
            p.pop(timing), s.pop(timing)
        assert_same(p, s, f"row {p['item']}")
    assert_same([f.to_json() for f in parallel.fleets], [f.to_json() for f in serial.fleets],
                "fleets")


def test_a_hundred_items_on_two_workers_equal_the_serial_path(client: Any, hundred: Path) -> None:
    done: list[int] = []
    parallel = run_batch("identify", [str(hundred / "*.csv")], client=client, chunk=7,
                         on_progress=lambda k, n: done.append(k))
    serial = run_batch("identify", [str(hundred / "*.csv")], workers=0)
    assert done[-1] == 100 and sorted(done) == done  # 14 tasks of 7 items and one of 2
    assert len(done) == 15
    assert (parallel.items, parallel.errors) == (100, 1)
    bad = [r for r in parallel.rows if r["error"]]
    assert [r["item"] for r in bad] == [50] and bad[0]["input"].endswith("run_049_bad.csv")
    assert "row 2, column position_rad" in bad[0]["error"]
    assert all(isinstance(r["Kt_over_J"], float) for r in parallel.rows if not r["error"])
    assert_same_batch(parallel, serial)
    fleet = parallel.fleets[0]
    assert (fleet.runs, fleet.errors) == (99, 1) and fleet.pooled["runs"] == 99


def test_diagnosis_pairs_equal_the_serial_path(client: Any, tmp_path: Path) -> None:
    write_runs(tmp_path / "train", 2, "small_ironcore_19v", seed0=1, duration_s=1.0)
    write_runs(tmp_path / "holdout", 2, "small_ironcore_19v", seed0=3, duration_s=1.0)
    pair = f"{tmp_path}/train/*.csv,{tmp_path}/holdout/*.csv"
    parallel = run_batch("diagnose", [pair], client=client)
    serial = run_batch("diagnose", [pair], workers=0)
    assert parallel.errors == 0 and [r["verdict"] for r in parallel.rows] == ["none", "none"]
    assert_same_batch(parallel, serial)


def test_the_command_on_an_existing_scheduler(client: Any, hundred: Path, tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str],
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    out = tmp_path / "r.parquet"
    code = main(["batch", "identify", str(hundred / "run_00*.csv"), "-o", str(out),
                 "--scheduler", client.scheduler.address, "--json", "--no-progress"])
    summary = json.loads(capsys.readouterr().out)
    assert code == 0 and summary["engine"] == client.scheduler.address
    assert (summary["items"], summary["errors"]) == (10, 0) and out.exists()
    monkeypatch.setattr(engine, "CONNECT_TIMEOUT_S", 1.0)  # nothing listens on port 9
    assert main(["batch", "identify", str(hundred / "run_00*.csv"), "-o", str(out),
                 "--scheduler", "tcp://127.0.0.1:9", "--no-progress"]) == 1
    assert "cannot reach the Dask scheduler" in capsys.readouterr().err
