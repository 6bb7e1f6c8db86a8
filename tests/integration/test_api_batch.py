"""POST /batch on a real service: a job over stored runs, progress over SSE, stored rows."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

import stand
from tests.batch_runs import write_runs
from tests.integration.test_api_support import Server, serve


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    with serve(tmp_path_factory.mktemp("api-batch")) as running:
        yield running


def events(client: httpx.Client, url: str) -> list[tuple[str, dict]]:
    """The stream's events until ``end``."""
    found: list[tuple[str, dict]] = []
    name = ""
    with client.stream("GET", url) as stream:
        for line in stream.iter_lines():
            if line.startswith("event: "):
                name = line[len("event: "):]
            elif line.startswith("data: "):
                found.append((name, json.loads(line[len("data: "):])))
                if name == "end":
                    break
    return found


def test_a_batch_of_stored_runs_streams_progress_and_stores_its_rows(
        server: Server, tmp_path: Path) -> None:
    paths = write_runs(tmp_path, 4, "small_ironcore_19v")
    with server.client() as client:
        ids = []
        for path in paths:
            answer = client.post("/runs/upload", files={"file": (path.name, path.read_bytes())},
                                 data={"kind": "single"})
            assert answer.status_code == 201, answer.text
            ids.append(answer.json()["id"])
        started = client.post("/batch", json={"operation": "identify", "inputs": ids[:3] + [
            f"run:{ids[3]}"]})
        assert started.status_code == 202, started.text
        job = started.json()
        assert started.headers["Location"] == f"/batch/{job['id']}" and job["total"] == 4
        stream = events(client, job["links"]["events"])
        names = [n for n, _ in stream]
        assert names[-1] == "end" and set(names[:-1]) == {"progress"}
        done = [d["done"] for n, d in stream if n == "progress"]
        assert done == sorted(done) and done[-1] == 4
        end = stream[-1][1]
        assert end["state"] == "done" and end["errors"] == 0
        record = client.get(f"/results/{end['result_id']}").json()
        assert record["operation"] == "batch" and record["inputs"]["inputs"][0] == ids[0]
        rows = record["result"]["rows"]
        for path, row in zip(paths, rows, strict=True):
            # The upload parses the same CSV text as read_run: the same numbers, exactly.
            assert row["Kt_over_J"] == stand.identify(stand.read_run(path)).Kt_over_J
        assert client.get(f"/batch/{job['id']}").json()["summary"]["ok"] == 4


def test_batch_needs_the_key_and_names_what_is_wrong(server: Server) -> None:
    with server.client(auth=False) as anonymous:
        assert anonymous.post("/batch", json={"operation": "identify",
                                              "inputs": ["query:kind=single"]}).status_code == 401
    with server.client() as client:
        answer = client.post("/batch", json={"operation": "identify", "inputs": ["x"],
                                             "options": {"ratio": 11}})
        assert answer.status_code == 422 and "unknown option(s) ratio" in answer.json()["detail"]
        # The service reads stored runs only: a path is taken as a run id, and not found.
        answer = client.post("/batch", json={"operation": "identify", "inputs": ["/etc/passwd"]})
        assert answer.status_code == 404 and "no run '/etc/passwd'" in answer.json()["detail"]
        answer = client.post("/batch", json={"operation": "fit", "inputs": ["x"]})
        assert answer.status_code == 422
        assert client.get("/batch/nope").status_code == 404
