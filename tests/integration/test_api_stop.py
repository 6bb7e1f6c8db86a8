"""POST /stop: CiA 402 quick stop reaches every drive within 100 ms of stand time, mid-run.

The app runs in-process (TestClient) so the test can read the simulated drive nodes:
each records the SYNC count at which its state machine entered QUICK STOP ACTIVE.
"""

from __future__ import annotations

import itertools
import time
from pathlib import Path
from typing import Any

from fastapi.testclient import TestClient

from api.app import create_app, default_runner
from stand.runner import StandRunner
from stand.settings import Settings

#: The requirement: every drive in quick stop within this much stand time of the request, s.
QUICK_STOP_WITHIN_S = 0.100
WAIT_S = 60.0
_channels = itertools.count()


class RecordingRunner:
    """The real stand runner; notes each node's SYNC count when a stop request arrives."""

    def __init__(self, runner: Any) -> None:
        self.runner = runner
        self.syncs_at_request: dict[int, int] = {}

    def __getattr__(self, name: str) -> Any:
        return getattr(self.runner, name)

    def nodes(self) -> list[Any]:
        return list(self.runner._bus.sim.nodes)

    def quick_stop_all(self) -> dict[str, Any]:
        self.syncs_at_request = {node.id: node.syncs for node in self.nodes()}
        return dict(self.runner.quick_stop_all())


def test_stop_quick_stops_every_drive_mid_run(tmp_path: Path) -> None:
    settings = Settings(data_dir=tmp_path, bus_channel=f"api-stop-{next(_channels)}",
                        api_key="k")
    recorder: list[RecordingRunner] = []

    def factory(s: Settings) -> StandRunner:
        recorder.append(RecordingRunner(default_runner(s)))
        return recorder[0]  # type: ignore[return-value]

    with TestClient(create_app(settings, factory), base_url="http://127.0.0.1") as client:
        client.headers["Authorization"] = "Bearer k"
        # Two drives: the efficiency run of the reducer stand, long enough to be mid-run.
        run_id = client.post("/runs", json={"profile": "seed000_efficiency",
                                            "overrides": {"duration_s": 300.0}}).json()["id"]
        deadline = time.monotonic() + WAIT_S
        while client.get(f"/runs/{run_id}").json()["samples"] < 1000:
            assert time.monotonic() < deadline, "the run recorded nothing"
            time.sleep(0.02)
        answer = client.post("/stop")
        assert answer.status_code == 200, answer.text
        assert answer.json()["stopped_run"] == run_id
        runner = recorder[0]
        period_s = runner.runner._bus.master.period_s
        for node in runner.nodes():
            assert node.quick_stop_at is not None, f"node {node.id} never entered quick stop"
            lag_s = (node.quick_stop_at[1] - runner.syncs_at_request[node.id]) * period_s
            assert 0 <= lag_s <= QUICK_STOP_WITHIN_S, f"node {node.id}: quick stop after {lag_s} s"
        while (run := client.get(f"/runs/{run_id}").json())["state"] == "running":
            assert time.monotonic() < deadline
            time.sleep(0.02)
        assert run["state"] == "stopped"
        assert 1000 <= run["samples"] < 300_000, "samples so far are kept, the run ended early"
