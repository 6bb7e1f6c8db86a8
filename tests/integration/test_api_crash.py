"""Crash safety: SIGKILL the server mid-run, restart it on the same data directory.

Earlier runs and results must be intact; the interrupted run must be ``aborted`` with
the samples it had recorded (every chunk is committed as it arrives, WAL mode).
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from stand.runfile import parse_run
from tests.integration.test_api_support import serve, start, stop, wait_for

#: Stand time of the run that gets killed: far longer than the test waits, s.
LONG_RUN_S = 600.0
WAIT_S = 60.0
#: Time the helper processes of a crashed service may take to end: the parsing worker
#: looks for the service every api.uploads.SERVICE_WATCH_S, and a loaded machine is slow, s.
HELPERS_END_S = 10.0


def test_sigkill_mid_run_keeps_everything(tmp_path: Path) -> None:
    server = start(tmp_path)
    try:
        with server.client() as c:
            first = c.post("/runs", json={"profile": "seed000_no_load",
                                          "overrides": {"duration_s": 1.0}}).json()["id"]
            deadline = time.monotonic() + WAIT_S
            while c.get(f"/runs/{first}").json()["state"] != "done":
                assert time.monotonic() < deadline
                time.sleep(0.05)
            before_csv = c.get(f"/runs/{first}/samples").text
            result = c.post("/identify", json={"run": first}).json()
            long_id = c.post("/runs", json={"profile": "seed000_no_load",
                                            "overrides": {"duration_s": LONG_RUN_S}}).json()["id"]
            while (seen := c.get(f"/runs/{long_id}").json())["samples"] < 2000:
                assert time.monotonic() < deadline, "the long run recorded nothing"
                time.sleep(0.05)
            # An upload starts the parsing worker (through a forkserver).
            assert c.post("/runs/upload", files={"file": ("up.csv", before_csv)}).status_code == 201
            assert server.helpers(), "the upload started no parsing worker"
        server.kill()
        assert server.process.returncode == -9
        # Nobody tells the service's helper processes that it is gone: they must notice.
        wait_for(lambda: not server.helpers(), HELPERS_END_S, "the crashed service's helper "
                 "processes (upload parser, forkserver, resource tracker) ending")
    finally:
        stop(server)

    with serve(tmp_path) as again, again.client() as c:
        assert c.get(f"/runs/{first}/samples").text == before_csv
        assert c.get(f"/results/{result['result_id']}").json()["result"]["Kt_over_J"] == \
            pytest.approx(result["Kt_over_J"], rel=0, abs=0)
        killed = c.get(f"/runs/{long_id}").json()
        assert killed["state"] == "aborted"
        assert killed["samples"] >= seen["samples"], "committed chunks were lost"
        assert killed["samples"] < LONG_RUN_S * 1000
        kept = parse_run(c.get(f"/runs/{long_id}/samples").text, "single", "kept samples")
        assert len(kept) == killed["samples"]
        # The service works on after the restart.
        assert c.post("/identify", json={"run": long_id}).status_code == 200
