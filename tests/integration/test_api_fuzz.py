"""Property-based fuzzing of the OpenAPI schema (schemathesis): no route answers 500.

Every operation in /openapi.json gets up to ``MAX_EXAMPLES`` generated requests, with
the key (so the handlers behind the auth check are reached) against a real uvicorn.
POST /stop and POST /runs run too: the stand is simulated and runs are short or refused.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest
import schemathesis
from hypothesis import HealthCheck, settings
from schemathesis.checks import not_a_server_error

from tests.integration.test_api_support import Server, serve

#: Generated requests per operation; bounded to keep the suite fast on 2 cores.
MAX_EXAMPLES = 15


@pytest.fixture(scope="module")
def fuzz_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    # Runs long enough to matter are refused by the duration bound of the request model,
    # but generated runs may still queue; the server is stopped at the end.
    with serve(tmp_path_factory.mktemp("fuzz")) as running:
        yield running


@pytest.fixture(scope="module")
def api_schema(fuzz_server: Server) -> schemathesis.BaseSchema:
    return schemathesis.openapi.from_url(f"{fuzz_server.base_url}/openapi.json")


schema = schemathesis.pytest.from_fixture("api_schema")


@schema.parametrize()
@settings(max_examples=MAX_EXAMPLES, deadline=None,
          suppress_health_check=list(HealthCheck))
def test_no_route_answers_500(case: schemathesis.Case, fuzz_server: Server) -> None:
    headers = {"Authorization": f"Bearer {fuzz_server.api_key}"}
    case.call_and_validate(headers=headers, checks=[not_a_server_error], timeout=60)
