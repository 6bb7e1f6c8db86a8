"""Property-based fuzzing that reaches the numbers: typed bodies, NaN and Infinity in
JSON and in form fields, real CSV uploads (whole and broken), and requests without or
with a wrong key. No answer may be a 500.

The schema-driven fuzz (``test_api_fuzz.py``) cannot get here: JSON from a schema never
holds NaN, and a random run id stops every analysis at a 404. Here the bodies are drawn
from the request models with the ids of runs really stored (simulated by ``stand
simulate``), so the methods run on the drawn numbers.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from api.routers.analysis import OPERATIONS
from stand.cli import main
from tests.integration.test_api_support import Server, serve

#: Drawn requests per operation and kind of body; bounded to keep the suite fast.
MAX_EXAMPLES = 6
FUZZ = settings(max_examples=MAX_EXAMPLES, deadline=None, derandomize=True,
                suppress_health_check=list(HealthCheck))

#: Stand runs simulated for the fuzz, by kind of run file: ``stand simulate`` arguments.
SIMULATE = {
    "single": ["crouzet_82800502", "--duration", "2", "--seed", "3"],
    "reducer": ["cycloidal_two_motor", "--duration", "2", "--seed", "3"],
    "step": ["crouzet_82800502", "--duration", "1", "--mode", "voltage", "--excitation",
             "step", "--step-time", "0.1", "--seed", "3"],
}

numbers = st.one_of(
    st.sampled_from([math.nan, math.inf, -math.inf]),  # what JSON from a schema never holds
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -1.0, 1e-300, 1e308, 3.0, 0.02, 11.0]),
    st.integers(-(10**20), 10**20),
)
junk = st.one_of(st.text(max_size=8), st.none(), st.booleans(), st.lists(numbers, max_size=2))


def non_finite(value: Any) -> bool:
    if isinstance(value, float):
        return not math.isfinite(value)
    if isinstance(value, dict):
        return any(non_finite(v) for v in value.values())
    if isinstance(value, list):
        return any(non_finite(v) for v in value)
    return False


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    with serve(tmp_path_factory.mktemp("fuzz-typed")) as running:
        yield running


@pytest.fixture(scope="module")
def csv_files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    folder = tmp_path_factory.mktemp("fuzz-runs")
    texts = {}
    for kind, args in SIMULATE.items():
        path = folder / f"{kind}.csv"
        assert main(["simulate", *args, "-o", str(path)]) == 0
        texts[kind] = Path(path).read_text()
    return texts


@pytest.fixture(scope="module")
def stored(server: Server, csv_files: dict[str, str]) -> dict[str, str]:
    ids = {}
    with server.client() as c:
        for kind, text in csv_files.items():
            answer = c.post("/runs/upload", data={"kind": kind}, files={"file": ("r.csv", text)})
            assert answer.status_code == 201, answer.text
            ids[kind] = answer.json()["id"]
    return ids


def run_count(c: httpx.Client) -> int:
    return len(c.get("/runs", params={"limit": 1000}).json())


def body_strategy(name: str, stored: dict[str, str]) -> st.SearchStrategy[dict[str, Any]]:
    """Bodies of operation ``name``: every field of its model, drawn typed or not."""
    op = OPERATIONS[name]
    fields: dict[str, st.SearchStrategy[Any]] = {}
    for field, info in op.model.model_fields.items():
        if field in op.run_fields:
            one = st.sampled_from([stored[op.run_fields[field]], stored["single"], "x" * 32])
            is_list = "list" in str(info.annotation)
            fields[field] = st.lists(one, min_size=1, max_size=2) if is_list else one
        elif field == "known":
            fields[field] = st.dictionaries(st.sampled_from(["R", "L", "K", "J", "Kf", "Q"]),
                                            numbers, max_size=2)
        elif field in ("method", "compensate"):
            fields[field] = st.sampled_from([info.default, "paper", "lm", True, "nope"])
        else:
            fields[field] = st.one_of(numbers, junk)
    required = {k: v for k, v in fields.items() if op.model.model_fields[k].is_required()}
    optional = {k: v for k, v in fields.items() if k not in required}
    return st.fixed_dictionaries(required, optional=optional)


@pytest.mark.parametrize("name", list(OPERATIONS))
def test_json_bodies_never_500(server: Server, stored: dict[str, str], name: str) -> None:
    with server.client() as c:
        @FUZZ
        @given(body=body_strategy(name, stored))
        def check(body: dict[str, Any]) -> None:
            text = json.dumps(body)  # NaN and Infinity as Python writes them
            answer = c.post(f"/{name}", content=text,
                            headers={"Content-Type": "application/json"})
            assert answer.status_code < 500, (body, answer.text)
            if non_finite(body):
                assert answer.status_code == 422, (body, answer.text)
                assert "NaN" not in answer.text and "Infinity" not in answer.text

        check()


def broken(text: str, how: str, where: float) -> str:
    """A run file broken in one way (CONTRACT §1 refusals), or whole."""
    lines = text.splitlines()
    row = 1 + int(where * (len(lines) - 2))
    cells = lines[row].split(",")
    if how == "cell":
        cells[int(where * len(cells)) % len(cells)] = "nan"
        lines[row] = ",".join(cells)
    elif how == "word":
        cells[0] = "abc"
        lines[row] = ",".join(cells)
    elif how == "time":
        lines[row] = lines[row - 1] if row > 1 else lines[row]
    elif how == "cut":
        return text[: int(where * len(text))]
    elif how == "header":
        lines[0] = lines[0].replace("time_s", "t")
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("name", list(OPERATIONS))
def test_form_uploads_never_500_and_refused_ones_leave_nothing(
        server: Server, csv_files: dict[str, str], name: str) -> None:
    op = OPERATIONS[name]
    with server.client() as c:
        @FUZZ
        @given(how=st.sampled_from(["whole", "whole", "cell", "word", "time", "cut", "header"]),
               where=st.floats(0.01, 0.99), values=st.lists(numbers, min_size=4, max_size=4))
        def check(how: str, where: float, values: list[float]) -> None:
            files = [(field, (f"{field}.csv", broken(csv_files[kind], how, where)))
                     for field, kind in op.run_fields.items()]
            plain = [f for f in op.model.model_fields if f not in op.run_fields
                     and f not in ("method", "compensate", "known")]
            data = {f: str(v) for f, v in zip(plain, values, strict=False)}
            before = run_count(c)
            answer = c.post(f"/{name}", data=data, files=files)
            assert answer.status_code < 500, (how, data, answer.text)
            if answer.status_code != 200:
                assert run_count(c) == before, "a refused analysis kept its uploads"

        check()


def test_run_overrides_never_500(server: Server) -> None:
    keys = ["repeats", "duration_s", "period_s", "added_inertia_kgm2", "load_current_A",
            "step_V", "step_time_s", "seed", "procedure", "motor"]
    with server.client() as c:
        @FUZZ
        @given(profile=st.sampled_from(["seed000_no_load", "seed000_efficiency", "nope",
                                        "../x", "/etc/passwd"]),
               overrides=st.dictionaries(st.sampled_from(keys), st.one_of(numbers, junk),
                                         max_size=3))
        def check(profile: str, overrides: dict[str, Any]) -> None:
            text = json.dumps({"profile": profile, "overrides": overrides})
            answer = c.post("/runs", content=text, headers={"Content-Type": "application/json"})
            assert answer.status_code in (202, 404, 422), (overrides, answer.text)
            if non_finite(overrides):
                assert answer.status_code == 422
            if answer.status_code == 202:
                c.post("/stop")  # a drawn run may be long: cancel it

        check()


def test_every_mutating_route_refuses_a_missing_or_wrong_key(server: Server) -> None:
    schema = httpx.get(f"{server.base_url}/openapi.json").json()
    routes = [(method.upper(), path.replace("{run_id}", "0" * 32))
              for path, item in schema["paths"].items() for method in item
              if method in ("post", "put", "patch", "delete")]
    assert len(routes) >= 9
    with server.client(auth=False) as c:
        before = run_count(c)
        for method, path in routes:
            for headers in ({}, {"Authorization": "Bearer wrong"}, {"Authorization": "Bearer"},
                            {"Authorization": f"Basic {server.api_key}"}):
                answer = c.request(method, path, headers=headers, json={})
                assert answer.status_code == 401, (method, path, headers, answer.text)
        assert run_count(c) == before
