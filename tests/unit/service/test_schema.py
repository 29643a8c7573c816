"""Fuzz the API against its own OpenAPI schema: every response is a documented one, and none is a 5xx.

The app runs in-process (ASGI) on a real runtime with the embedded simulated
node; only the endless event stream is left out (it is tested over the socket).
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import schemathesis
from hypothesis import HealthCheck, settings
from schemathesis.checks import not_a_server_error
from schemathesis.specs.openapi.checks import (
    content_type_conformance,
    response_schema_conformance,
    status_code_conformance,
)

from millctl.config import load_config
from millctl.service import ServiceRuntime, create_app
from tests.support.service import write_config

CHECKS = [not_a_server_error, status_code_conformance, content_type_conformance, response_schema_conformance]


@pytest.fixture(scope="module")
def runtime(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ServiceRuntime]:
    directory: Path = tmp_path_factory.mktemp("schema")
    running = ServiceRuntime(load_config(write_config(directory)))
    running.start()
    try:
        deadline = time.monotonic() + 10.0
        while running.status()["state"] != "DISABLED" and time.monotonic() < deadline:
            time.sleep(0.05)
        yield running
    finally:
        running.shutdown("test over", bound_s=2.0)


@pytest.fixture(scope="module")
def api_schema(runtime: ServiceRuntime) -> object:
    return schemathesis.openapi.from_asgi("/openapi.json", create_app(runtime))


@pytest.fixture(scope="module")
def lease_id(runtime: ServiceRuntime) -> str:
    """The fuzzer holds control, so that commands reach the controller (and its interlock)."""
    return runtime.leases.take("api:fuzz")[0].lease_id


schema = schemathesis.pytest.from_fixture("api_schema").exclude(path="/v1/stream")
Case = schemathesis.Case[Any]
"""A generated request of any operation of the schema (schemathesis types its operation generically)."""


def check_case(case: Case, lease_id: str) -> None:
    # A valid lease, so that commands get past the lease check to the controller and its interlock
    # (but never to release: the fuzzer keeps control for the whole run).
    headers = {} if case.path == "/v1/control/release" else {"X-Millctl-Lease": lease_id}
    case.call_and_validate(checks=CHECKS, headers=headers)


@schema.parametrize()
@settings(max_examples=8, deadline=None, suppress_health_check=list(HealthCheck))
def test_every_response_is_documented_and_none_is_a_server_error(case: Case, lease_id: str) -> None:
    """CI: the same few examples every run (the ``ci`` profile derandomizes; tests/conftest.py)."""
    check_case(case, lease_id)


@pytest.mark.fuzz
@schema.parametrize()
@settings(deadline=None, suppress_health_check=list(HealthCheck))
def test_random_search_every_response_is_documented_and_none_is_a_server_error(
    case: Case, lease_id: str
) -> None:
    """The random search, in the opt-in fuzz job (``.ci/fuzz``): as many examples as the profile gives."""
    check_case(case, lease_id)


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
