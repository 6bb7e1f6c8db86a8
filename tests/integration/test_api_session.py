"""A whole lab session over HTTP against a real uvicorn: runs on the (simulated) stand over
the virtual CAN bus, then every analysis by stored run id, as a lab script would do it.

Reference values are the simulated stand's own profile parameters (crouzet_82800502:
Kt 0.0527 N·m/A; cycloidal_two_motor: efficiency 0.80), so the checks can fail.
"""

from __future__ import annotations

import time
from collections.abc import Iterator

import httpx
import pytest

from stand.physics.effects import VERDICT_WORDS
from stand.procedures import SEED_ADDED_INERTIA_KGM2
from stand.profiles import load_motor, load_stand
from tests.integration.test_api_support import Server, serve

#: Wall-time bound of one job on 2 shared cores, s.
JOB_TIMEOUT_S = 120.0


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[httpx.Client]:
    server: Server
    with serve(tmp_path_factory.mktemp("session")) as server, server.client() as c:
        yield c


def finish(client: httpx.Client, run_ids: list[str]) -> list[dict]:
    runs = []
    for run_id in run_ids:
        deadline = time.monotonic() + JOB_TIMEOUT_S
        while (run := client.get(f"/runs/{run_id}").json())["state"] in ("queued", "running"):
            assert time.monotonic() < deadline, f"run {run_id} not done in {JOB_TIMEOUT_S} s"
            time.sleep(0.1)
        assert run["state"] == "done", run
        assert run["meta"]["complete"], f"samples lost on the bus: {run['meta']}"
        runs.append(run)
    return runs


def start(client: httpx.Client, profile: str, **overrides: float) -> list[str]:
    answer = client.post("/runs", json={"profile": profile, "overrides": overrides})
    assert answer.status_code == 202, answer.text
    return list(answer.json()["runs"])


def test_lab_session(client: httpx.Client) -> None:
    motor = load_motor("crouzet_82800502")
    stand = load_stand("cycloidal_two_motor")

    # 1. No-load and added-inertia runs, 2 repeats of 3 s at 1 kHz (seed 000 §4.2).
    runs = finish(client, start(client, "seed000_torque_constant", repeats=2, duration_s=3.0))
    no_load = [r["id"] for r in runs if r["request"]["procedure"].startswith("no_load")]
    loaded = [r["id"] for r in runs if r["request"]["procedure"].startswith("added_inertia")]
    assert len(no_load) == len(loaded) == 2
    assert all(r["samples"] == 3000 for r in runs)

    # 2. One run identified alone (CONTRACT §2 identify fields).
    ident = client.post("/identify", json={"run": no_load[0]})
    assert ident.status_code == 200, ident.text
    assert {"A", "B", "Kt_over_J", "D_over_J", "C_over_J", "fit_percent", "condition_number",
            "samples"} <= ident.json().keys()

    # 3. Torque constant from the stored runs.
    answer = client.post("/torque-constant", json={
        "no_load": no_load, "loaded": loaded, "added_inertia": SEED_ADDED_INERTIA_KGM2})
    assert answer.status_code == 200, answer.text
    kt = answer.json()
    assert {"Kt", "Kt_std", "J", "D", "C", "repeats", "no_load_current_A"} <= kt.keys()
    # 3 % : two 3 s repeats with 10 mA current noise and 2500-line quantization; the
    # ident helper's own tests bound the estimator, this bounds the HTTP path around it.
    assert kt["Kt"] == pytest.approx(motor.motor.Kt, rel=0.03)

    # 4. Efficiency run on the two-motor stand, then the efficiency (seed 000 eq. 18).
    (eff_run,) = finish(client, start(client, "seed000_efficiency"))
    assert eff_run["kind"] == "reducer"
    answer = client.post("/efficiency", json={"run": eff_run["id"], "ratio": stand.reducer.ratio,
                                              "k_in": motor.motor.Kt, "k_out": motor.motor.Kt})
    assert answer.status_code == 200, answer.text
    eff = answer.json()
    assert {"efficiency", "efficiency_std", "delta_i_in_A", "delta_i_out_A"} <= eff.keys()
    # 3 % : the load steps last 1 s each and the currents carry 10 mA noise.
    assert eff["efficiency"] == pytest.approx(stand.reducer.efficiency, rel=0.03)

    # 5. Diagnosis: train on one no-load run, hold out the other.
    answer = client.post("/diagnose", json={"train": no_load[0], "holdout": no_load[1],
                                            "motor": "crouzet_82800502"})
    assert answer.status_code in (200, 422), answer.text  # 422: data the method refuses
    if answer.status_code == 200:
        diag = answer.json()
        assert {"gap_percent", "where", "effects", "verdict"} <= diag.keys()
        assert all(name in VERDICT_WORDS for name in diag["verdict"].split("+"))

    # 6. Voltage step (seed 001) and the step identification.
    (step_run,) = finish(client, start(client, "seed001_voltage_step", duration_s=3.0))
    answer = client.post("/step-identify", json={"runs": [step_run["id"]]})
    assert answer.status_code == 200, answer.text
    assert {"transfer_function", "params", "identifiable", "fit_percent"} <= answer.json().keys()
    assert answer.json()["transfer_function"]["den"][0] == 1

    # 7. Every result is stored with its inputs.
    results = client.get("/results").json()
    operations = {r["operation"] for r in results}
    assert {"identify", "torque-constant", "efficiency", "step-identify"} <= operations
    stored = client.get(f"/results/{kt['result_id']}").json()
    assert stored["inputs"]["no_load"] == no_load and stored["result"]["Kt"] == kt["Kt"]


def test_upload_and_analyse_in_one_request(client: httpx.Client) -> None:
    runs = finish(client, start(client, "seed000_no_load", duration_s=2.0))
    csv_text = client.get(f"/runs/{runs[0]['id']}/samples").text
    by_file = client.post("/identify", files={"run": ("no_load.csv", csv_text)},
                          data={"method": "default"})
    by_id = client.post("/identify", json={"run": runs[0]["id"]})
    assert by_file.status_code == by_id.status_code == 200, by_file.text
    # The CSV keeps 9 significant digits: the same estimate to far better than 1e-6.
    assert by_file.json()["Kt_over_J"] == pytest.approx(by_id.json()["Kt_over_J"], rel=1e-6)
    upload_id = by_file.json()["inputs"]["run"]
    assert client.get(f"/runs/{upload_id}").json()["origin"] == "upload"
