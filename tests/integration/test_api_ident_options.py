"""The CLI's ``effects`` and ``estimator`` options through the real HTTP service.

A current-mode run with Coulomb friction (simulated, 3 s at 2 ms) is uploaded; the
options must reach the identification (the answer names the effects and the estimator
asked for) and bad values must be refused with a 422 that names the field.
"""

from __future__ import annotations

from collections.abc import Iterator

import httpx
import pytest

from stand.excitation import excitation
from stand.physics.effects import Effects
from stand.physics.parts import DriveParams, MotorParams, SensorParams
from stand.physics.plant import MotorPlant
from stand.physics.simulate import simulate_motor
from stand.runfile import format_run
from tests.integration.test_api_support import Server, serve

MOTOR = MotorParams(R=1.0, L=1e-3, Kt=0.05, J=2e-5, D=4e-5)
#: Coulomb friction of 20 % of the drive torque (0.5 A · 0.05 N·m/A).
FRICTION_NM = 0.005
PERIOD_S = 2e-3
SAMPLES = 1500


def run_csv(seed: int, inertia: float = 0.0) -> str:
    """A reversing current-mode PRBS run with Coulomb friction, as CSV text."""
    motor = MotorParams(R=MOTOR.R, L=MOTOR.L, Kt=MOTOR.Kt, J=MOTOR.J + inertia, D=MOTOR.D)
    plant = MotorPlant(motor, DriveParams(mode="current", supply_V=48.0, current_limit_A=5.0),
                       SensorParams(encoder_lines=2000, current_noise_A=0.005),
                       Effects.from_mapping({"coulomb_friction": {"Tc": FRICTION_NM}}), seed=seed)
    command = excitation("prbs", SAMPLES, PERIOD_S, 0.0, 0.5, 20, seed=seed)
    run = simulate_motor(plant, "current", command, PERIOD_S)
    return format_run({c: run[c] for c in ("time_s", "current_A", "position_rad")})


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    with serve(tmp_path_factory.mktemp("api-ident")) as running:
        yield running


@pytest.fixture()
def client(server: Server) -> Iterator[httpx.Client]:
    with server.client() as c:
        yield c


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
    assert tc == pytest.approx(FRICTION_NM / MOTOR.Kt, rel=0.1)
    seed_model = client.post("/identify", json={"run": run, "effects": "none"}).json()
    assert seed_model["effects"] == [] and seed_model["estimator"] == "ls"
    # a multipart form carries the same options
    form = client.post("/identify", files={"run": ("f.csv", run_csv(1))},
                       data={"effects": "coulomb_friction", "estimator": "bc"})
    assert form.status_code == 200, form.text
    assert form.json()["estimator"] == "bc" and form.json()["effects"] == ["coulomb_friction"]


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
    assert body["Kt"] == pytest.approx(MOTOR.Kt, rel=0.02)
    low, high = body["Kt_ci95"]
    assert low < body["Kt"] < high
