"""A command's parts are checked whole by the API too (SAFETY requirement 20): a heating rate with no furnace
target to heat to is a 422 naming the value and why, before the controller sees anything."""

from __future__ import annotations

from collections.abc import AsyncIterator
from pathlib import Path

import httpx
import pytest

from millctl.cli.failures import with_flags
from millctl.config import load_config
from millctl.service import ServiceRuntime, create_app
from tests.support.service import write_config

WHY = (
    "heating rate 5.0 °C/min given without a furnace target (body.temp_c): there is nothing to heat to, and the "
    "rate would be ignored; give the target with it, or leave the rate out"
)


@pytest.fixture
async def api(tmp_path: Path) -> AsyncIterator[tuple[httpx.AsyncClient, dict[str, str]]]:
    runtime = ServiceRuntime(load_config(write_config(tmp_path)), embed_node=False)
    try:
        transport = httpx.ASGITransport(app=create_app(runtime))
        async with httpx.AsyncClient(transport=transport, base_url="http://millctl") as http:
            lease = (await http.post("/v1/control/take")).json()["lease_id"]
            yield http, {"X-Millctl-Lease": lease}
    finally:
        runtime.close()


@pytest.mark.parametrize(
    ("path", "body"),
    [
        ("/v1/setpoints", {"rotary_rpm": 20.0, "vibration_rpm": 200.0, "rate_c_per_min": 5.0}),
        ("/v1/setpoints", {"rotary_rpm": 20.0, "vibration_rpm": 200.0, "temp_c": None, "rate_c_per_min": 5.0}),
        ("/v1/furnace", {"temp_c": None, "rate_c_per_min": 5.0}),
    ],
)
async def test_a_heating_rate_without_a_furnace_target_is_422_and_nothing_is_applied(
    api: tuple[httpx.AsyncClient, dict[str, str]], path: str, body: dict[str, object]
) -> None:
    http, lease = api
    events_before = (await http.get("/v1/events")).json()
    response = await http.post(path, headers=lease, json=body)
    assert response.status_code == 422, response.text
    error = response.json()
    assert (error["code"], error["field"]) == ("invalid_request", "body.rate_c_per_min")
    assert error["message"] == f"body.rate_c_per_min: Value error, {WHY}"
    assert with_flags(error["message"]).startswith("--heat-rate: Value error, heating rate 5.0 °C/min given "
                                                   "without a furnace target (--temp-c)")  # what the CLI prints
    status = (await http.get("/v1/status")).json()
    assert (status["target_rotary_rpm"], status["furnace_target_c"]) == (0.0, None)
    assert (await http.get("/v1/events")).json() == events_before  # not even a refusal reached the controller
