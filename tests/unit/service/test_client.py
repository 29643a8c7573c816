"""The client's error mapping, and what a user sees with no service or no node."""

from __future__ import annotations

import asyncio
from pathlib import Path

import httpx
import pytest

from millctl.cli import main
from millctl.client import (
    AccessDenied,
    Client,
    ControlHeld,
    InterlockRefusal,
    NodeUnavailable,
    RequestInvalid,
    ServiceRefused,
    ServiceUnavailable,
    raise_for_error,
)
from millctl.config import load_config
from millctl.errors import ExitCode, MillctlError
from millctl.service import ServiceRuntime, create_app
from tests.support.service import write_config


def _response(status: int, body: dict[str, object]) -> httpx.Response:
    return httpx.Response(status, json=body)


@pytest.mark.parametrize(
    ("status", "code", "error", "exit_code"),
    [
        (409, "interlock_refused", InterlockRefusal, ExitCode.INTERLOCK),
        (409, "recipe_refused", InterlockRefusal, ExitCode.INTERLOCK),
        (409, "wrong_state", ServiceRefused, ExitCode.INTERLOCK),
        (423, "control_held", ControlHeld, ExitCode.INTERLOCK),
        (422, "invalid_request", RequestInvalid, ExitCode.INVALID_INPUT),
        (401, "unauthorized", AccessDenied, ExitCode.BUS),
        (503, "node_unreachable", NodeUnavailable, ExitCode.BUS),
    ],
)
def test_api_errors_map_to_exceptions_with_their_exit_codes(
    status: int, code: str, error: type[MillctlError], exit_code: ExitCode
) -> None:
    body: dict[str, object] = {"code": code, "message": "because", "field": "body.rotary_rpm", "holder": "api:tui",
            "refusals": [{"quantity": "omega_r", "value": 250.0, "limit": 190.0, "unit": "rpm", "reason": "r"}]}
    with pytest.raises(error) as raised:
        raise_for_error(_response(status, body), "service socket /x")
    assert raised.value.exit_code is exit_code
    if isinstance(raised.value, InterlockRefusal):
        assert raised.value.refusals[0].limit == 190.0
    if isinstance(raised.value, ControlHeld):
        assert raised.value.holder == "api:tui"
    if isinstance(raised.value, RequestInvalid):
        assert raised.value.field == "body.rotary_rpm"


def test_no_service_names_the_socket_and_suggests_serve(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    missing = tmp_path / "nobody.sock"
    with Client(missing) as client, pytest.raises(ServiceUnavailable) as raised:
        client.status()
    assert str(missing) in str(raised.value) and "millctl serve" in str(raised.value)
    assert main(["status", "--socket", str(missing)]) == ExitCode.BUS
    assert "millctl serve" in capsys.readouterr().err


async def test_commands_without_a_node_are_503(tmp_path: Path) -> None:
    runtime = ServiceRuntime(load_config(write_config(tmp_path)), embed_node=False)
    runtime.start()
    try:
        transport = httpx.ASGITransport(app=create_app(runtime))
        async with httpx.AsyncClient(transport=transport, base_url="http://millctl") as http:
            taken = await http.post("/v1/control/take", headers={"X-Millctl-Client": "t"})
            await asyncio.sleep(0.05)  # a few loop ticks (the loop keeps running): still no node on this channel
            response = await http.post("/v1/arm", headers={"X-Millctl-Lease": taken.json()["lease_id"]})
            assert response.status_code == 503
            assert response.json()["code"] == "node_unreachable"
            assert (await http.post("/v1/estop")).status_code == 200  # E-stop is always accepted
    finally:
        runtime.shutdown("test over", bound_s=0.5)


ANSWERS = {
    "/v1/setpoints": {"accepted": True, "message": "setpoints", "state": "RUNNING", "duration_s": 4.5},
    "/v1/control/take": {"lease_id": "L1", "holder": "api:t@h", "expires_in_s": 30.0, "ttl_s": 30.0},
    "/v1/control/release": {"held": False, "holder": None, "expires_in_s": None, "expired": False},
}


def _mock(seen: list[httpx.Request]) -> httpx.MockTransport:
    def answer(request: httpx.Request) -> httpx.Response:
        seen.append(request)
        return httpx.Response(200, json=ANSWERS[request.url.path])

    return httpx.MockTransport(answer)


async def test_both_clients_are_one_table_over_two_transports(tmp_path: Path) -> None:
    from millctl.api import CommandOut, ControllerState
    from millctl.client import AsyncClient, Operation, Operations

    table = {name: op for name, op in vars(Operations).items() if isinstance(op, Operation)}
    assert {"status", "set_speeds", "recipe_run", "take_control", "estop"} <= set(table)
    assert all(getattr(Client, n) is op and getattr(AsyncClient, n) is op for n, op in table.items())

    seen_sync: list[httpx.Request] = []
    seen_async: list[httpx.Request] = []
    with Client(tmp_path / "s.sock") as sync:
        sync._http = httpx.Client(base_url=sync.base_url, transport=_mock(seen_sync))
        sync.take_control()
        assert sync.lease_id == "L1"
        result = sync.set_speeds(180.0, 800.0, linear=True)
        sync.release_control()
        assert sync.lease_id is None
    async with AsyncClient(tmp_path / "s.sock") as asynchronous:
        asynchronous._http = httpx.AsyncClient(base_url=asynchronous.base_url, transport=_mock(seen_async))
        await asynchronous.take_control()
        awaited = await asynchronous.set_speeds(180.0, 800.0, linear=True)
    assert isinstance(result, CommandOut) and result == awaited and result.state is ControllerState.RUNNING
    assert [(r.method, r.url.path, r.content) for r in seen_sync[:2]] == \
        [(r.method, r.url.path, r.content) for r in seen_async]
    assert seen_sync[1].headers["X-Millctl-Lease"] == "L1"


async def test_the_stream_resumes_after_the_last_event_id(tmp_path: Path) -> None:
    from millctl.api import EventOut
    from millctl.client import AsyncClient

    runtime = ServiceRuntime(load_config(write_config(tmp_path)), embed_node=False)
    try:
        for i in range(5):
            runtime.journal.add("service", "test", f"event {i}")
        async with AsyncClient(tmp_path / "s.sock") as client:
            client._http = httpx.AsyncClient(base_url=client.base_url,
                                             transport=httpx.ASGITransport(app=create_app(runtime)))
            client.last_event_id = 2  # seen up to 2, then the connection dropped
            got = [item async for item in client.stream(count=3)]
        assert [e.seq for e in got if isinstance(e, EventOut)] == [3, 4, 5]
        assert client.last_event_id == 5
    finally:
        runtime.close()


async def test_an_idle_connection_is_let_go_by_the_client_before_the_service_closes_it(tmp_path: Path) -> None:
    """uvicorn's default keep-alive (5 s) equals httpx's: a request sent as the service closed the idle connection
    met "Connection reset by peer" (vcan tier, a status read 5.7 s after the last). The service now outlives the
    client by far, and both clients use the client's expiry."""
    from millctl.client import CLIENT_KEEP_ALIVE_S, AsyncClient
    from millctl.service.server import SERVICE_KEEP_ALIVE_S, server_config

    runtime = ServiceRuntime(load_config(write_config(tmp_path)), embed_node=False)
    assert server_config(create_app(runtime)).timeout_keep_alive == SERVICE_KEEP_ALIVE_S
    assert SERVICE_KEEP_ALIVE_S >= 10 * CLIENT_KEEP_ALIVE_S
    with Client(tmp_path / "s.sock") as sync:
        assert sync._http._transport._pool._keepalive_expiry == CLIENT_KEEP_ALIVE_S  # type: ignore[attr-defined]
    async with AsyncClient(tmp_path / "s.sock") as asynchronous:
        pool = asynchronous._http._transport._pool  # type: ignore[attr-defined]
        assert pool._keepalive_expiry == CLIENT_KEEP_ALIVE_S


def _broken(error: type[httpx.TransportError]) -> httpx.MockTransport:
    def answer(request: httpx.Request) -> httpx.Response:
        raise error("[Errno 104] Connection reset by peer", request=request)

    return httpx.MockTransport(answer)


@pytest.mark.parametrize("error", [httpx.ReadError, httpx.WriteError])
async def test_a_connection_broken_mid_request_says_the_outcome_is_unknown(
    tmp_path: Path, error: type[httpx.TransportError]
) -> None:
    from millctl.client import AsyncClient

    with Client(tmp_path / "s.sock") as sync, pytest.raises(ServiceUnavailable) as raised:
        sync._http = httpx.Client(base_url=sync.base_url, transport=_broken(error))
        sync.stop()
    message = str(raised.value)
    assert "POST /v1/stop" in message and "Connection reset by peer" in message and "unknown" in message
    assert str(tmp_path / "s.sock") in message
    async with AsyncClient(tmp_path / "s.sock") as asynchronous:
        asynchronous._http = httpx.AsyncClient(base_url=asynchronous.base_url, transport=_broken(error))
        with pytest.raises(ServiceUnavailable, match=r"GET /v1/status .*unknown"):
            await asynchronous.status()
