"""The HTTP service over a real uvicorn on loopback: access, validation, runs as jobs."""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import httpx
import numpy as np
import pytest

from stand.excitation import excitation
from stand.physics.effects import Effects
from stand.physics.parts import DriveParams, MotorParams, SensorParams
from stand.physics.plant import MotorPlant
from stand.physics.simulate import simulate_motor
from stand.runfile import format_run, parse_run
from tests.integration.test_api_support import Server, serve

MOTOR = "crouzet_82800502"
#: One no-load run of 1.5 s of stand time at 1 kHz: about half a second of wall time.
SHORT_RUN = {"profile": "seed000_no_load", "overrides": {"duration_s": 1.5}}


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    with serve(tmp_path_factory.mktemp("api")) as running:
        yield running


@pytest.fixture()
def client(server: Server) -> Iterator[httpx.Client]:
    with server.client() as c:
        yield c


def wait_final(client: httpx.Client, run_id: str, timeout_s: float = 60.0) -> dict:
    import time

    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        run = client.get(f"/runs/{run_id}").json()
        if run["state"] not in ("queued", "running"):
            return run
        time.sleep(0.05)
    raise AssertionError(f"run {run_id} still {run['state']} after {timeout_s} s")


def test_health_and_profiles(client: httpx.Client) -> None:
    health = client.get("/health")
    assert health.status_code == 200 and health.json()["status"] == "ok"
    profiles = client.get("/profiles").json()
    assert MOTOR in profiles["motors"]
    assert client.get("/openapi.json").json()["paths"].keys() >= {
        "/runs", "/runs/{run_id}", "/runs/{run_id}/samples", "/identify", "/torque-constant",
        "/efficiency", "/step-identify", "/diagnose", "/profiles", "/bus", "/stop", "/health"}


def test_mutating_routes_need_the_key(server: Server) -> None:
    with server.client(auth=False) as anonymous:
        assert anonymous.post("/runs", json=SHORT_RUN).status_code == 401
        assert anonymous.post("/stop").status_code == 401
        assert anonymous.post("/identify", json={"run": "x"}).status_code == 401
        wrong = anonymous.post("/runs", json=SHORT_RUN, headers={"Authorization": "Bearer nope"})
        assert wrong.status_code == 401
        assert anonymous.get("/runs").status_code == 200  # reading is open


def test_validation_names_the_field(client: httpx.Client) -> None:
    answer = client.post("/runs", json={"overrides": {}})
    assert answer.status_code == 422
    assert ["body", "profile"] in [e["loc"] for e in answer.json()["detail"]]
    answer = client.post("/runs", json={**SHORT_RUN, "overrides": {"duration_s": -1}})
    assert answer.status_code == 422
    assert ["body", "overrides", "duration_s"] in [e["loc"] for e in answer.json()["detail"]]
    answer = client.post("/efficiency", json={"run": "abc", "ratio": "eleven", "k_in": 1, "k_out": 1})
    assert answer.status_code == 422
    assert ["body", "ratio"] in [e["loc"] for e in answer.json()["detail"]]
    assert client.post("/identify", content=b"{not json").status_code == 422


def test_limits_are_enforced_before_anything_moves(client: httpx.Client) -> None:
    # The output motor's current limit is 3 A (crouzet_82800502): a 5 A load step exceeds it.
    before = len(client.get("/runs").json())
    answer = client.post("/runs", json={"profile": "seed000_efficiency",
                                        "overrides": {"load_current_A": 5.0}})
    assert answer.status_code == 422 and answer.json()["error"] == "limit"
    assert len(client.get("/runs").json()) == before, "a refused job must store no run"


def test_unknown_ids_are_404(client: httpx.Client) -> None:
    assert client.get("/runs/nope").status_code == 404
    assert client.get("/runs/nope/samples").status_code == 404
    assert client.get("/runs/nope/events").status_code == 404
    assert client.post("/identify", json={"run": "nope"}).status_code == 404
    assert client.get("/results/nope").status_code == 404
    assert client.post("/runs", json={**SHORT_RUN, "profile": "no_such_experiment"}).status_code == 404


def test_run_job_lifecycle_and_samples(client: httpx.Client) -> None:
    answer = client.post("/runs", json=SHORT_RUN)
    assert answer.status_code == 202
    run_id = answer.json()["id"]
    assert answer.headers["location"] == f"/runs/{run_id}"
    run = wait_final(client, run_id)
    assert run["state"] == "done" and run["progress"] == 1.0
    csv_text = client.get(f"/runs/{run_id}/samples").text
    recorded = parse_run(csv_text, "single", "samples")  # a valid CONTRACT §1 file
    assert len(recorded) == run["samples"] > 0
    as_json = client.get(f"/runs/{run_id}/samples", params={"format": "json"}).json()
    np.testing.assert_allclose(as_json["position_rad"], recorded["position_rad"], rtol=1e-8,
                               err_msg="CSV keeps 9 significant digits")
    assert run_id in [r["id"] for r in client.get("/runs").json()]


def test_event_stream_ends_with_the_run(client: httpx.Client) -> None:
    run_id = client.post("/runs", json=SHORT_RUN).json()["id"]
    events: list[tuple[str, dict]] = []
    with client.stream("GET", f"/runs/{run_id}/events") as stream:
        name = ""
        for line in stream.iter_lines():
            if line.startswith("event: "):
                name = line[7:]
            elif line.startswith("data: "):
                events.append((name, json.loads(line[6:])))
    assert events[-1][0] == "end" and events[-1][1]["state"] == "done"
    streamed = sum(len(data["columns"]["time_s"]) for name, data in events if name == "samples")
    assert streamed == client.get(f"/runs/{run_id}").json()["samples"]


def test_upload_limit_is_413(tmp_path: Path) -> None:
    with serve(tmp_path, extra_env={"STAND_UPLOAD_LIMIT_BYTES": "2000"}) as small:
        t = np.arange(200) * 1e-3
        text = format_run({"time_s": t, "current_A": np.sin(t), "position_rad": t})
        with small.client() as c:
            answer = c.post("/identify", files={"run": ("big.csv", text)})
            assert answer.status_code == 413
            answer = c.post("/runs/upload", files={"file": ("big.csv", text)})
            assert answer.status_code == 413
            # Far past the limit: refused from Content-Length, before the body is read.
            answer = c.post("/runs/upload", files={"file": ("huge.csv", "0," * (2 << 20))})
            assert answer.status_code == 413
            assert c.get("/runs").json() == [], "nothing refused may be stored"


def test_bad_upload_is_422_naming_row_and_column(client: httpx.Client) -> None:
    text = "time_s,current_A,position_rad\n" + "".join(f"{k},0.1,{k}\n" for k in range(30))
    text = text.replace("\n5,0.1,5\n", "\n5,abc,5\n")
    answer = client.post("/runs/upload", files={"file": ("bad.csv", text)}, data={"kind": "single"})
    assert answer.status_code == 422
    assert "row 7, column current_A" in answer.json()["detail"]


def test_stop_quick_stops_and_reports(client: httpx.Client) -> None:
    answer = client.post("/stop")
    assert answer.status_code == 200
    assert "drives" in answer.json()
    bus = client.get("/bus").json()
    assert {"nodes", "current_run", "queued_runs"} <= bus.keys()


def test_without_a_key_only_loopback(tmp_path: Path) -> None:
    import os
    import subprocess
    import sys

    from tests.integration.test_api_support import ROOT

    env = {k: v for k, v in os.environ.items() if not k.startswith("STAND_")}
    env.update(STAND_DATA_DIR=str(tmp_path), PYTHONPATH=str(ROOT))
    refused = subprocess.run([sys.executable, "-m", "stand", "serve", "--host", "0.0.0.0",
                              "--port", "0"], env=env, capture_output=True, text=True, timeout=60)
    assert refused.returncode == 2
    assert "STAND_API_KEY" in refused.stderr
    with serve(tmp_path / "open", api_key=None) as open_server, open_server.client() as c:
        assert "loopback only" in c.get("/health").json()["auth"]
        assert c.post("/stop").status_code == 200  # local callers may mutate without a key


def test_without_a_key_real_drives_never_start(tmp_path: Path) -> None:
    # No key and a hardware bus: starting a motor is refused before the bus is touched
    # (the service opens the bus only for a run, so no vcan0/can0 is needed here).
    env = {"STAND_BUS_INTERFACE": "socketcan", "STAND_BUS_CHANNEL": "can0"}
    with serve(tmp_path, api_key=None, extra_env=env) as open_server, \
            open_server.client() as c:
        answer = c.post("/runs", json=SHORT_RUN)
        assert answer.status_code == 401
        assert "STAND_API_KEY" in answer.json()["detail"]


# The CLI's ``effects`` and ``estimator`` options on /identify and /torque-constant: a
# current-mode run with Coulomb friction (simulated, 3 s at 2 ms) is uploaded; the options
# must reach the identification (the answer names the effects and the estimator asked
# for), and bad values must be refused with a 422 that names the field.

IDENT_MOTOR = MotorParams(R=1.0, L=1e-3, Kt=0.05, J=2e-5, D=4e-5)
#: Coulomb friction of 20 % of the drive torque (0.5 A · 0.05 N·m/A).
FRICTION_NM = 0.005
IDENT_PERIOD_S = 2e-3
IDENT_SAMPLES = 1500


def run_csv(seed: int, inertia: float = 0.0) -> str:
    """A reversing current-mode PRBS run with Coulomb friction, as CSV text."""
    motor = replace(IDENT_MOTOR, J=IDENT_MOTOR.J + inertia)
    plant = MotorPlant(motor, DriveParams(mode="current", supply_V=48.0, current_limit_A=5.0),
                       SensorParams(encoder_lines=2000, current_noise_A=0.005),
                       Effects.from_mapping({"coulomb_friction": {"Tc": FRICTION_NM}}), seed=seed)
    command = excitation("prbs", IDENT_SAMPLES, IDENT_PERIOD_S, 0.0, 0.5, 20, seed=seed)
    run = simulate_motor(plant, "current", command, IDENT_PERIOD_S)
    return format_run({c: run[c] for c in ("time_s", "current_A", "position_rad")})


def upload(client: httpx.Client, text: str, name: str) -> str:
    answer = client.post("/runs/upload", files={"file": (name, text)}, data={"kind": "single"})
    assert answer.status_code == 201, answer.text
    return str(answer.json()["id"])


def test_identify_takes_effects_and_estimator(client: httpx.Client) -> None:
    run = upload(client, run_csv(1), "friction.csv")
    forced = client.post("/identify", json={"run": run, "effects": "coulomb_friction",
                                            "estimator": "ls"})
    assert forced.status_code == 200, forced.text
    body = forced.json()
    assert body["effects"] == ["coulomb_friction"] and body["estimator"] == "ls"
    assert body["inputs"]["effects"] == "coulomb_friction"
    # the friction found is the one simulated (Tc/Kt = 0.1 A), within 10 %
    tc = body["effect_params"]["coulomb_friction"]["Tc_over_Kt_A"]
    assert tc == pytest.approx(FRICTION_NM / IDENT_MOTOR.Kt, rel=0.1)
    seed_model = client.post("/identify", json={"run": run, "effects": "none"}).json()
    assert seed_model["effects"] == [] and seed_model["estimator"] == "ls"
    # a multipart form carries the same options
    form = client.post("/identify", files={"run": ("f.csv", run_csv(1))},
                       data={"effects": "coulomb_friction", "estimator": "bc"})
    assert form.status_code == 200, form.text
    assert form.json()["estimator"] == "bc" and form.json()["effects"] == ["coulomb_friction"]


def test_identify_takes_the_drive_supply_by_motor_profile(client: httpx.Client) -> None:
    run = upload(client, run_csv(3), "supply.csv")
    plain = client.post("/identify", json={"run": run, "effects": "coulomb_friction"})
    told = client.post("/identify", json={"run": run, "effects": "coulomb_friction",
                                          "motor": MOTOR})
    assert told.status_code == 200, told.text
    assert told.json()["inputs"]["motor"] == MOTOR
    # a current-mode run has no speed loop to refine: the supply changes nothing
    assert told.json()["Kt_over_J"] == plain.json()["Kt_over_J"]
    unknown = client.post("/identify", json={"run": run, "motor": "no_such_motor"})
    assert unknown.status_code == 404 and "no_such_motor" in unknown.text
    for route, body in (("/identify", {"run": run}),
                        ("/torque-constant", {"no_load": [run], "loaded": [run],
                                              "added_inertia": 1e-5})):
        path = client.post(route, json={**body, "motor": "../profiles/x.yaml"})
        assert path.status_code == 422, path.text
        assert ["body", "motor"] in [e["loc"] for e in path.json()["detail"]]


@pytest.mark.parametrize(("field", "value", "expected"), [
    ("effects", "friction", "coulomb_friction"),
    ("effects", "", "expected 'auto', 'none'"),
    ("estimator", "ols", "'auto', 'iv', 'bc' or 'ls'"),
])
def test_bad_options_are_422_naming_the_field(client: httpx.Client, field: str, value: str,
                                              expected: str) -> None:
    run = upload(client, run_csv(2), "bad-options.csv")
    for route, body in (("/identify", {"run": run}),
                        ("/torque-constant", {"no_load": [run], "loaded": [run],
                                              "added_inertia": 1e-5})):
        answer = client.post(route, json={**body, field: value})
        assert answer.status_code == 422, answer.text
        errors = [e for e in answer.json()["detail"] if e["loc"] == ["body", field]]
        assert errors, answer.text
        assert expected in errors[0]["msg"]


def test_torque_constant_takes_effects_and_estimator(client: httpx.Client) -> None:
    added = 2e-5
    free = [upload(client, run_csv(10 + k), f"free{k}.csv") for k in range(3)]
    loaded = [upload(client, run_csv(20 + k, added), f"loaded{k}.csv") for k in range(3)]
    answer = client.post("/torque-constant", json={
        "no_load": free, "loaded": loaded, "added_inertia": added,
        "effects": "coulomb_friction", "estimator": "ls"})
    assert answer.status_code == 200, answer.text
    body = answer.json()
    assert body["effects"] == ["coulomb_friction"]
    assert body["Kt"] == pytest.approx(IDENT_MOTOR.Kt, rel=0.02)
    low, high = body["Kt_ci95"]
    assert low < body["Kt"] < high
