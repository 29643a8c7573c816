"""Fuzz the API against its own OpenAPI schema: every response is a documented one, and none is a 5xx.

The app runs in-process (ASGI) on a real runtime with the embedded simulated
node; only the endless event stream is left out (it is tested over the socket).
CI replays the same few generated cases every run (the ``ci`` profile derandomizes),
the stored cases below (requests that once gave a 500), and the stored examples of
tests/examples/hypothesis; the random search is the fuzz job (``.ci/fuzz``).

Each operation is a test of its own, on a mill of its own: a fresh runtime with the
embedded node, stepped rather than run. Its control loop is not started, so each
request's command runs at once (``ServiceRuntime.call`` without a loop), and after each
request the test ticks controller and node through ``MILL_S_PER_REQUEST`` of mill time
on a manual clock. What a request meets (the mill's state, what an earlier request
started) is a function of that operation's earlier requests only: not of how busy the
machine is, nor of which operations ran before on the same test worker. (Once, all
operations ran as one test on one runtime with its real 100 Hz loop: ~800 requests
that took over 120 s on a loaded machine, so that pytest-timeout cut the test
mid-example and Hypothesis reported FlakyStrategyDefinition.) The loop and its queue
(503 ``busy``) are tested on their own (tests/unit/service/test_loop_commands.py).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import schemathesis
from fastapi import FastAPI
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from schemathesis.checks import not_a_server_error
from schemathesis.specs.openapi.checks import (
    content_type_conformance,
    response_schema_conformance,
    status_code_conformance,
)

from millctl.config import load_config
from millctl.service import ServiceRuntime, create_app
from tests.support import examples
from tests.support.service import DEMO_RECIPE as DEMO_RECIPE_FILE
from tests.support.service import advance, stepped_runtime, write_config

DEMO_RECIPE = DEMO_RECIPE_FILE.read_text()
CHECKS = [not_a_server_error, status_code_conformance, content_type_conformance, response_schema_conformance]


MILL_S_PER_REQUEST = 0.02
"""Mill time the test steps the runtime through after each request (s): two ticks, about what a request took
on the real loop, so that what one request starts (an arm, a ramp, a furnace target) goes on under the next."""


OPERATIONS = (
    "GET /v1/status",
    "GET /v1/service",
    "GET /v1/envelope",
    "POST /v1/envelope/check",
    "GET /v1/events",
    "GET /v1/control",
    "POST /v1/control/take",
    "POST /v1/control/release",
    "POST /v1/arm",
    "POST /v1/disarm",
    "POST /v1/stop",
    "POST /v1/reset",
    "POST /v1/estop",
    "POST /v1/setpoints",
    "POST /v1/furnace",
    "GET /v1/recipe",
    "POST /v1/recipe/run",
    "GET /v1/recipe/unfinished",
    "POST /v1/recipe/unfinished/{run_id}/resume",
    "POST /v1/recipe/unfinished/{run_id}/abort",
    "POST /v1/recipe/check",
    "POST /v1/recipe/pause",
    "POST /v1/recipe/resume",
    "POST /v1/recipe/abort",
)
"""Every operation of the API but the endless event stream (``GET /v1/stream``, tested over the socket): one test
each (test_the_fuzzed_operations_are_every_operation_but_the_stream keeps this list whole)."""


@pytest.fixture(scope="module")
def runtime(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ServiceRuntime]:
    stepped = stepped_runtime(tmp_path_factory.mktemp("schema"))
    try:
        yield stepped
    finally:
        stepped.close()


@pytest.fixture(scope="module")
def api_schema(runtime: ServiceRuntime) -> schemathesis.BaseSchema:
    return schemathesis.openapi.from_asgi("/openapi.json", create_app(runtime))


@pytest.fixture(scope="module")
def lease_id(runtime: ServiceRuntime) -> str:
    """The fuzzer holds control, so that commands reach the controller (and its interlock)."""
    return runtime.leases.take("api:fuzz")[0].lease_id


@dataclass
class Mill:
    """A mill of one operation's own: its stepped runtime, the app serving it, and the lease the fuzzer holds."""

    runtime: ServiceRuntime
    app: FastAPI
    lease_id: str


@pytest.fixture
def mill(tmp_path: Path) -> Iterator[Mill]:
    runtime = stepped_runtime(tmp_path)
    try:
        yield Mill(runtime, create_app(runtime), runtime.leases.take("api:fuzz")[0].lease_id)
    finally:
        runtime.close()


@pytest.fixture(params=OPERATIONS)
def operation_schema(request: pytest.FixtureRequest, api_schema: schemathesis.BaseSchema, mill: Mill) -> Any:
    """The schema of one operation (the parameter, "METHOD /path"), served by its own mill.

    A schema of its own, not ``api_schema.include(...)``: schemathesis replaces a fixture's filters with the test's.
    """
    method, path = str(request.param).split(" ", 1)
    method = method.lower()
    raw = api_schema.raw_schema
    one = schemathesis.openapi.from_dict({**raw, "paths": {path: {method: raw["paths"][path][method]}}})
    one.app = mill.app
    one.location = api_schema.location
    return one


schema = schemathesis.pytest.from_fixture("operation_schema")
Case = schemathesis.Case[Any]
"""A generated request of any operation of the schema (schemathesis types its operation generically)."""


def check_case(case: Case, mill: Mill) -> None:
    # A valid lease, so that commands get past the lease check to the controller and its interlock
    # (but never to release: the fuzzer keeps control for the whole run).
    headers = {} if case.path == "/v1/control/release" else {"X-Millctl-Lease": mill.lease_id}
    case.call_and_validate(checks=CHECKS, headers=headers)
    advance(mill.runtime, MILL_S_PER_REQUEST)


@schema.parametrize()
@settings(max_examples=8, deadline=None, database=None, suppress_health_check=list(HealthCheck))
def test_every_response_is_documented_and_none_is_a_server_error(case: Case, mill: Mill) -> None:
    """CI: the same few examples every run (the ``ci`` profile derandomizes; tests/conftest.py).

    Without the stored database: schemathesis passes derandomize and the database in one call, which
    Hypothesis refuses. The API's stored cases are explicit (``STORED_CASES``).
    """
    check_case(case, mill)


@pytest.mark.fuzz
@schema.parametrize()
@settings(deadline=None, database=None, suppress_health_check=list(HealthCheck))
def test_random_search_every_response_is_documented_and_none_is_a_server_error(case: Case, mill: Mill) -> None:
    """The random search, in the opt-in fuzz job (``.ci/fuzz``): as many examples as the profile gives.

    What it finds goes into ``STORED_CASES`` (schemathesis reports the request), not the example
    database: CI does not run this test, so nothing would replay an entry kept under its key.
    """
    check_case(case, mill)


def test_the_fuzzed_operations_are_every_operation_but_the_stream(api_schema: schemathesis.BaseSchema) -> None:
    paths = api_schema.raw_schema["paths"]
    served = {f"{method.upper()} {path}" for path, methods in paths.items() for method in methods} - {"GET /v1/stream"}
    missing = sorted(served - set(OPERATIONS))
    assert not missing, f"add to OPERATIONS in {__file__}, so that they are fuzzed: {missing}"
    assert sorted(OPERATIONS) == sorted(served)


def test_every_route_is_versioned_and_documents_its_errors(tmp_path: Path) -> None:
    runtime = ServiceRuntime(load_config(write_config(tmp_path)), embed_node=False)
    try:
        spec = create_app(runtime).openapi()
    finally:
        runtime.close()
    assert spec["paths"]
    for path, operations in spec["paths"].items():
        assert path.startswith("/v1/"), path
        for method, operation in operations.items():
            assert "422" in operation["responses"], (method, path)
            if method == "post" and path not in ("/v1/envelope/check", "/v1/recipe/check"):  # read-only checks
                assert {"409", "423", "503"} <= set(operation["responses"]), (method, path)


# --- stored cases: requests that once gave a 500 -------------------------------------------------------------------

NUL_RECIPE_NAME = "a\x00b.toml"
"""A recipe's name (the client's file name) with a NUL byte: the service once opened it as a path (a 500,
"embedded null byte"). A stored example of the property test below (tests/examples/hypothesis)."""

STORED_CASES: dict[str, tuple[str, str, dict[str, Any]]] = {
    # id: (method, path, the case's parts): each once reached the service unrefused
    "recipe-run-nul-name": ("POST", "/v1/recipe/run", {"body": {"name": NUL_RECIPE_NAME, "text": DEMO_RECIPE}}),
    "recipe-run-nul-text": ("POST", "/v1/recipe/run", {"body": {"name": "r.toml", "text": "a = \x00"}}),
    "recipe-check-nul-name": ("POST", "/v1/recipe/check", {"body": {"name": NUL_RECIPE_NAME, "text": DEMO_RECIPE}}),
    "resume-nul-run-id": (
        "POST",
        "/v1/recipe/unfinished/{run_id}/resume",
        {"path_parameters": {"run_id": "2026\x00"}, "body": {"confirm": False}},
    ),
}


@pytest.mark.parametrize("stored", STORED_CASES, ids=str)
def test_a_stored_case_gets_a_documented_4xx_and_no_server_error(
    api_schema: schemathesis.BaseSchema, lease_id: str, stored: str
) -> None:
    """Explicit cases: replayed every run, whatever the random search draws (they survive an edit of the test)."""
    method, path, parts = STORED_CASES[stored]
    case = api_schema[path][method].Case(**parts)
    response = case.call(headers={"X-Millctl-Lease": lease_id})
    case.validate_response(response, checks=CHECKS)
    assert response.status_code == 422, (stored, response.status_code, response.text)


def check_recipe_named(api_schema: schemathesis.BaseSchema, name: str) -> tuple[int, dict[str, Any]]:
    """Pre-flight the demo recipe sent under ``name``: its status code and body (a documented response)."""
    case = api_schema["/v1/recipe/check"]["POST"].Case(body={"name": name, "text": DEMO_RECIPE})
    response = case.call()
    case.validate_response(response, checks=CHECKS)
    return response.status_code, response.json()


@settings(max_examples=20, deadline=None)
@given(name=st.text(max_size=300))
def test_any_recipe_name_is_checked_or_refused_as_the_name_never_a_server_error(
    api_schema: schemathesis.BaseSchema, name: str
) -> None:
    """A client names the recipe it sends (its file name): any text gets the recipe's check or a 422 for the name.

    The name with a NUL byte that once gave a 500 is a stored example (tests/examples/hypothesis), replayed
    before the generated names in every CI run (test_the_stored_nul_byte_name_is_replayed_every_run).
    """
    status, body = check_recipe_named(api_schema, name)
    valid = 1 <= len(name) <= 255 and not any(ord(c) < 0x20 or ord(c) == 0x7F for c in name)
    if valid:
        assert status == 200 and body["source"] == name, (name, status, body)
    else:
        assert status == 422 and body["field"] == "body.name", (name, status, body)


def test_the_stored_nul_byte_name_is_replayed_every_run(
    api_schema: schemathesis.BaseSchema, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The ``ci`` profile replays the committed example database: the NUL-byte name is sent, though the
    derandomized search alone would never draw that exact name."""
    test = test_any_recipe_name_is_checked_or_refused_as_the_name_never_a_server_error
    stored = examples.stored_choices(examples.inner_test(test))
    assert (NUL_RECIPE_NAME,) in stored, f"the NUL-byte name is not stored in {examples.EXAMPLES_DIR}: {stored}"
    if settings.get_current_profile_name() != "ci":
        pytest.skip(f"the stored examples are replayed by the ci profile, not {settings.get_current_profile_name()!r}")
    sent: list[str] = []
    check = check_recipe_named

    def spy(schema: schemathesis.BaseSchema, name: str) -> tuple[int, dict[str, Any]]:
        sent.append(name)
        return check(schema, name)

    monkeypatch.setattr(f"{__name__}.check_recipe_named", spy)
    test(api_schema)
    assert sent[0] == NUL_RECIPE_NAME, sent[:3]  # replayed first, before anything generated
    assert sent.count(NUL_RECIPE_NAME) == 1, sent
