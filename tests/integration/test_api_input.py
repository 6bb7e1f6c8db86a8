"""Bad input over HTTP against a real uvicorn: every answer a clear 4xx, never a 500.

NaN and Infinity in JSON bodies and form fields, unbounded run overrides, profile
paths, chunked bodies over the limit, an empty key, cross-origin and rebinding callers
in no-key mode, and deleting runs.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import numpy as np
import pytest

from stand.runfile import format_run
from stand.settings import Settings
from tests.integration.test_api_support import ROOT, Server, free_port, serve, wait_for

SHORT_RUN = {"profile": "seed000_no_load", "overrides": {"duration_s": 1.0}}


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    with serve(tmp_path_factory.mktemp("input"),
               extra_env={"STAND_UPLOAD_LIMIT_BYTES": str(2 * 1024 * 1024)}) as running:
        yield running


@pytest.fixture()
def client(server: Server) -> Iterator[httpx.Client]:
    with server.client() as c:
        yield c


def run_csv(samples: int = 500) -> str:
    t = np.arange(samples) * 1e-3
    return format_run({"time_s": t, "current_A": np.sin(40 * t), "position_rad": np.cos(9 * t)})


def locs(answer: httpx.Response) -> list[list[object]]:
    return [e["loc"] for e in answer.json()["detail"]]


@pytest.mark.parametrize("body", [
    b'{"run": "x", "no_load_current_A": NaN}',
    b'{"run": "x", "no_load_current_A": Infinity}',
    b'{"run": NaN}',
])
def test_non_finite_json_is_422(client: httpx.Client, body: bytes) -> None:
    answer = client.post("/identify", content=body, headers={"Content-Type": "application/json"})
    assert answer.status_code == 422, answer.text
    assert "NaN" not in answer.text and "Infinity" not in answer.text


def test_non_finite_overrides_and_form_fields_are_422(client: httpx.Client) -> None:
    answer = client.post("/runs", content=b'{"profile": "seed000_no_load", '
                                          b'"overrides": {"duration_s": NaN}}',
                         headers={"Content-Type": "application/json"})
    assert answer.status_code == 422 and ["body", "overrides", "duration_s"] in locs(answer)
    answer = client.post("/step-identify", files={"runs": (None, "x"),  # a multipart form
                                                  "known": (None, '{"R": NaN}')})
    assert answer.status_code == 422, answer.text
    assert ["body", "known", "R"] in locs(answer)


@pytest.mark.parametrize(("overrides", "field"), [
    ({"seed": -1}, "seed"),
    ({"period_s": 1e-9}, "period_s"),
    ({"period_s": 3.6e-5, "duration_s": 3600}, "period_s"),
    ({"repeats": 0}, "repeats"),
    ({"motor": "other"}, "motor"),
])
def test_overrides_are_typed_and_bounded(client: httpx.Client, overrides: dict, field: str) -> None:
    answer = client.post("/runs", json={"profile": "seed000_no_load", "overrides": overrides})
    assert answer.status_code == 422 and ["body", "overrides", field] in locs(answer)


def test_samples_per_run_are_capped_before_planning(client: httpx.Client) -> None:
    # Within each field's bounds, but 3600 s at 0.25 ms is 14.4 million samples.
    before = len(client.get("/runs").json())
    answer = client.post("/runs", json={"profile": "seed000_no_load",
                                        "overrides": {"period_s": 2.5e-4, "duration_s": 3600}})
    assert answer.status_code == 422 and "samples a run" in answer.json()["detail"]
    assert len(client.get("/runs").json()) == before


def test_profiles_by_name_only(client: httpx.Client, tmp_path: Path) -> None:
    secret = tmp_path / "secret.yaml"
    secret.write_text("db_password: hunter2\n")
    answers = [client.post("/runs", json={"profile": p}) for p in
               (str(secret), str(tmp_path / "missing.yaml"), "../experiments/seed000_no_load")]
    for answer in answers:
        assert answer.status_code == 422 and "hunter2" not in answer.text
    # An existing and a missing file answer alike (no oracle), apart from the echo.
    assert [e["msg"] for e in answers[0].json()["detail"]] == \
        [e["msg"] for e in answers[1].json()["detail"]]
    unknown = client.post("/runs", json={"profile": "no_such_experiment"})
    assert unknown.status_code == 404 and "seed000_no_load" in unknown.json()["detail"]


def test_chunked_upload_over_the_limit_is_413(client: httpx.Client) -> None:
    def chunks() -> Iterator[bytes]:
        yield b"--b\r\nContent-Disposition: form-data; name=\"file\"; filename=\"a.csv\"\r\n\r\n"
        for _ in range(64):
            yield b"0" * 65536  # 4 MB, past the 2 MB limit + 1 MB form overhead
        yield b"\r\n--b--\r\n"

    answer = client.post("/runs/upload", content=chunks(),
                         headers={"Content-Type": "multipart/form-data; boundary=b"})
    assert answer.status_code == 413, answer.text
    answer = client.post("/identify", content=chunks(),
                         headers={"Content-Type": "multipart/form-data; boundary=b"})
    assert answer.status_code == 413, answer.text


def test_delete_runs_and_refused_analyses_keep_no_upload(client: httpx.Client) -> None:
    stored = client.post("/runs/upload", files={"file": ("a.csv", run_csv())}).json()["id"]
    assert client.delete(f"/runs/{stored}", headers={"Authorization": ""}).status_code == 401
    assert client.delete(f"/runs/{stored}").status_code == 204
    assert client.get(f"/runs/{stored}").status_code == 404
    assert client.delete(f"/runs/{stored}").status_code == 404
    before = len(client.get("/runs", params={"limit": 1000}).json())
    refused = client.post("/efficiency", data={"ratio": "-1", "k_in": "1", "k_out": "1"},
                          files={"run": ("r.csv", run_csv())})
    assert refused.status_code == 422
    assert len(client.get("/runs", params={"limit": 1000}).json()) == before
    live = client.post("/runs", json={"profile": "seed000_no_load",
                                      "overrides": {"duration_s": 600.0}}).json()["id"]
    assert client.delete(f"/runs/{live}").status_code == 422
    client.post("/stop")


def test_deleting_a_stand_run_deletes_its_files(server: Server, client: httpx.Client) -> None:
    run = client.post("/runs", json=SHORT_RUN).json()["id"]
    wait_for(lambda: client.get(f"/runs/{run}").json()["state"] == "done", 60, "the short run")
    files = server.data_dir / "runs" / run
    assert any(files.iterdir())  # the run file (and trace) of the run on the stand
    assert client.delete(f"/runs/{run}").status_code == 204
    assert not files.exists()


def test_upload_retention(tmp_path: Path) -> None:
    with serve(tmp_path, extra_env={"STAND_UPLOAD_RETENTION_S": "0.5"}) as server, \
            server.client() as c:
        old = c.post("/runs/upload", files={"file": ("a.csv", run_csv())}).json()["id"]
        time.sleep(0.6)
        new = c.post("/runs/upload", files={"file": ("b.csv", run_csv())}).json()["id"]
        assert c.get(f"/runs/{old}").status_code == 404
        assert c.get(f"/runs/{new}").status_code == 200


def _serve_exit(env: dict[str, str], *args: str) -> subprocess.CompletedProcess[str]:
    base = {k: v for k, v in os.environ.items() if not k.startswith("STAND_")}
    return subprocess.run([sys.executable, "-m", "stand", "serve", *args], cwd=ROOT,
                          env={**base, "PYTHONPATH": str(ROOT), **env}, capture_output=True,
                          text=True, timeout=60)


def test_an_empty_key_is_no_key(tmp_path: Path) -> None:
    done = _serve_exit({"STAND_API_KEY": " ", "STAND_DATA_DIR": str(tmp_path)},
                       "--host", "0.0.0.0", "--port", str(free_port()))
    assert done.returncode == 2 and "beyond loopback without a key" in done.stderr
    assert Settings(api_key="").api_key is None


def test_no_key_mode_checks_host_and_origin(tmp_path: Path) -> None:
    with serve(tmp_path, api_key=None) as server, server.client() as c:
        port = server.base_url.rsplit(":", 1)[1]
        rebound = c.get("/runs", headers={"Host": f"evil.example:{port}"})
        assert rebound.status_code == 403 and "Host" in rebound.json()["detail"]
        assert c.post("/runs", json=SHORT_RUN,
                      headers={"Host": f"evil.example:{port}"}).status_code == 403
        for origin in ("http://evil.example", "null", f"http://127.0.0.1.evil.example:{port}"):
            crossed = c.post("/stop", headers={"Origin": origin})
            assert crossed.status_code == 403, origin
            form = c.post("/runs/upload", headers={"Origin": origin},
                          files={"file": ("a.csv", run_csv())})
            assert form.status_code == 403
        assert c.get("/health", headers={"Origin": "http://evil.example"}).status_code == 200
        assert c.post("/stop", headers={"Origin": f"http://localhost:{port}"}).status_code == 200
        assert c.get("/health", headers={"Host": f"localhost:{port}"}).status_code == 200
        assert c.get("/health", headers={"Host": f"[::1]:{port}"}).status_code == 200
