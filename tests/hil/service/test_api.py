"""The service's API over a real Unix socket, with the embedded simulated node, through millctl.Client."""

from __future__ import annotations

import asyncio
import json
import os
import shutil
import signal
import stat
import subprocess
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from millctl.api import ControllerState, EventKind, EventOut, RunState, StatusOut
from millctl.api.models import CommandOut
from millctl.cli import main
from millctl.client import AsyncClient, Client, ControlHeld, InterlockRefusal, RequestInvalid, ServiceRefused
from millctl.errors import ExitCode, InterlockError, InvalidInputError
from millctl.records import read_records
from millctl.service.app import SETTLE_S
from tests.support.pace import stretched
from tests.support.service import DEMO_RECIPE as DEMO
from tests.support.service import Service, wait_for

SYSTEM_PYTHON = "/usr/bin/python3"
PROBE = (
    "import socket,sys\n"
    "s=socket.socket(socket.AF_UNIX)\n"
    "try:\n s.connect(sys.argv[1]); s.sendall(b'GET /v1/status HTTP/1.0\\r\\n\\r\\n')\n"
    " print('answered', s.recv(64))\n"
    "except PermissionError as e: print('refused', e)\n"
)
"""A raw client (no millctl needed, so another user can run it from the system Python)."""


def settles(command: Callable[[], CommandOut], client: Client, state: ControllerState) -> CommandOut:
    """Send ``command``; its answer reports ``state``, where the command leads once the node confirms it.

    The service waits up to SETTLE_S for that state before it answers (millctl/service/app.py), then
    reports the state as it is. On a machine loaded past that bound the answer may still show the state
    before: accepted only when the answer really took SETTLE_S, and then the state must follow.
    """
    asked = time.monotonic()
    answer = command()
    waited_s = time.monotonic() - asked
    if answer.state is not state:
        assert waited_s >= SETTLE_S, f"answered {answer.state} after {waited_s:.2f} s, not {state}, within {SETTLE_S} s"
        wait_for(lambda: client.status().state is state, 30.0, f"{state} after a slow answer")
    return answer


def test_status_and_service_show_the_config_law_and_margin(service: Service) -> None:
    with service.client() as client:
        status = client.status()
        info = client.service()
        envelope = client.envelope(points=5)
    assert status.state is ControllerState.DISABLED
    assert status.node_state == "DISABLED"
    assert info.config_path == str(service.config)
    assert info.embedded_node is True
    assert (info.law, info.margin) == (status.law, status.margin)
    assert len(envelope.points) == 5
    assert envelope.points[0].vibration_rpm == 0.0


def test_arm_set_refuse_stop_and_the_records_explain_it(service: Service) -> None:
    with service.client("operator") as client, client.control():
        settles(client.arm, client, ControllerState.ARMED)  # the answer reports the state after the command
        accepted = settles(lambda: client.set_speeds(180.0, 800.0), client, ControllerState.RUNNING)
        assert accepted.duration_s is not None and accepted.duration_s > 0.0
        with pytest.raises(InterlockRefusal) as refused:
            client.set_speeds(250.0, 800.0)
        assert refused.value.exit_code is ExitCode.INTERLOCK
        assert refused.value.code == "interlock_refused"
        assert "exceeds the limit" in refused.value.reason
        (omega_r,) = [r for r in refused.value.refusals if r.quantity == "omega_r"]
        assert omega_r.value == 250.0
        assert omega_r.limit is not None and omega_r.limit < 250.0
        client.stop()
        wait_for(lambda: client.status().state == "ARMED", 30.0, "the controlled stop to end")
        settles(client.disarm, client, ControllerState.DISABLED)
    records = list(read_records(service.records / "events.jsonl"))
    refusals = [r for r in records if r["kind"] == "refusal"]
    assert refusals, "the refusal is recorded"
    assert refusals[-1]["source"].startswith("api:operator@")
    assert "250.0" in refusals[-1]["message"]
    kinds = {r["kind"] for r in records}
    assert {"service", "config", "state", "command", "control"} <= kinds
    (config,) = [r for r in records if r["kind"] == "config"]
    assert config["data"]["law"] and config["data"]["sha256"]


def test_one_client_holds_control_and_others_are_told_who(service: Service) -> None:
    with service.client("alice") as alice, service.client("bob") as bob:
        alice.take_control()
        try:
            with pytest.raises(ControlHeld) as held:
                bob.take_control()
            assert held.value.holder is not None and held.value.holder.startswith("api:alice@")
            assert isinstance(held.value, InterlockError)
            with pytest.raises(ControlHeld):
                bob.take_control(force=True)  # a live lease is never taken away
            with pytest.raises(ControlHeld):
                bob.arm()  # no lease
            assert (bob.control_state().holder or "").startswith("api:alice@")
        finally:
            alice.release_control()
        with bob.control():
            assert (bob.control_state().holder or "").startswith("api:bob@")
        assert bob.control_state().held is False


def test_estop_needs_no_lease_and_reset_clears_it(service: Service) -> None:
    with service.client("holder") as holder, service.client("bystander") as bystander, holder.control():
        result = bystander.estop()
        assert result.state is ControllerState.TRIPPED
        assert "E-stop" in bystander.status().trip_cause
        with pytest.raises(ServiceRefused) as refused:
            holder.arm()  # tripped: wrong state, with the cause
        assert refused.value.code == "wrong_state"
        wait_for(lambda: holder.status().node_state == "FAULT", what="the node to report its E-stop fault")
        wait_for(lambda: _reset_ok(holder), 10.0, "reset to be accepted")
        wait_for(lambda: holder.status().state == "DISABLED", what="DISABLED after reset")


def _reset_ok(client: Client) -> bool:
    try:
        client.reset()
    except ServiceRefused:
        return False
    return True


def test_invalid_requests_name_the_field(service: Service) -> None:
    with service.client("typo") as client, client.control():
        with pytest.raises(RequestInvalid) as invalid:
            client.set_speeds(-5.0, 800.0)
        assert invalid.value.field == "body.rotary_rpm"
        assert invalid.value.exit_code is ExitCode.INVALID_INPUT
        response = client._http.post("/v1/setpoints", json={"rotary_rpm": 1, "vibration_rpm": 1, "bypass": True},
                                     headers=client._headers())
        assert response.status_code == 422
        assert response.json()["code"] == "invalid_request"
        assert response.json()["field"] == "body.bypass"


def test_stream_sends_status_and_events(service: Service) -> None:
    with service.client("watcher") as watcher, service.client("actor") as actor:
        items = watcher.stream(count=50)
        first = next(items)
        assert isinstance(first, StatusOut) and first.state is ControllerState.DISABLED
        actor.take_control()
        actor.release_control()
        seen = []
        for item in items:
            if isinstance(item, EventOut) and item.kind is EventKind.CONTROL:
                seen.append(item.seq)
                break
        items.close()
        assert seen and watcher.last_event_id == seen[-1]
        after = watcher.events(after=0)
        assert after.last_seq >= len(after.events) > 0
        # what happens while the watcher is away comes first when it streams again (Last-Event-ID)
        actor.take_control()
        actor.release_control()
        missed = [e.seq for e in watcher.events(after=seen[-1]).events]
        resumed = [item.seq for item in watcher.stream(count=len(missed) + 4) if isinstance(item, EventOut)]
        assert resumed[: len(missed)] == missed


def _probe(socket_path: Path, *prefix: str) -> str:
    command = [*prefix, SYSTEM_PYTHON, "-c", PROBE, str(socket_path)]
    return subprocess.run(command, capture_output=True, text=True, timeout=stretched(30.0), check=False).stdout


def test_socket_is_0600_and_another_user_is_refused(service: Service) -> None:
    assert stat.S_IMODE(service.socket.stat().st_mode) == 0o600
    assert stat.S_IMODE(service.socket.parent.stat().st_mode) & 0o005 == 0o005  # only the socket keeps others out
    if os.geteuid() != 0 or not shutil.which("setpriv") or not Path(SYSTEM_PYTHON).exists():
        pytest.skip("running a client as another user needs root, setpriv and a system python3")
    assert _probe(service.socket).startswith("answered")  # the owner gets in: the probe works
    nobody = _probe(service.socket, "setpriv", "--reuid=65534", "--regid=65534", "--clear-groups")
    assert nobody.startswith("refused"), nobody


def test_a_second_serve_on_the_same_socket_refuses_to_start(
    service: Service, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["--config", str(service.config), "serve"]) == ExitCode.BUS
    stderr = capsys.readouterr().err
    assert str(service.socket) in stderr
    assert f"pid {service.proc.pid}" in stderr
    with service.client() as client:
        assert client.status().state == "DISABLED"  # the first one is untouched


def test_cli_set_beyond_the_limit_is_refused_with_the_reason(
    service: Service, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["--config", str(service.config), "arm"]) == ExitCode.OK
    with service.client() as client:
        wait_for(lambda: client.status().state == "ARMED", what="ARMED")
    capsys.readouterr()
    refused = main(["--config", str(service.config), "set", "--rot-rpm", "250", "--vib-rpm", "800"])
    assert refused == ExitCode.INTERLOCK
    assert "exceeds the limit" in capsys.readouterr().err
    assert main(["--config", str(service.config), "status", "--json"]) == ExitCode.OK
    document = json.loads(capsys.readouterr().out)
    assert (document["schema"], document["ok"], document["result"]["status"]["state"]) == (1, True, "ARMED")
    assert main(["--config", str(service.config), "set", "--rot-rpm", "250", "--vib-rpm", "800", "--json"]) == 2
    error = json.loads(capsys.readouterr().out)["error"]
    assert error["code"] == "interlock_refused" and error["exit_code"] == 2
    assert error["refusals"][0]["flag"] == "--rot-rpm"
    with service.client() as client, client.control():
        assert client.status().state == "ARMED"
        client.disarm()


def test_cli_set_with_a_refused_furnace_target_applies_no_part(
    service: Service, capsys: pytest.CaptureFixture[str]
) -> None:
    """Issue 15 item 7: `set --rot-rpm 150 --vib-rpm 800 --temp-c 5000` is refused whole; the speeds stay."""
    assert main(["--config", str(service.config), "arm"]) == ExitCode.OK
    with service.client() as client:
        wait_for(lambda: client.status().state is ControllerState.ARMED, what="ARMED")
    capsys.readouterr()
    refused = main(["--config", str(service.config), "set", "--rot-rpm", "150", "--vib-rpm", "800", "--temp-c", "5000"])
    assert refused == ExitCode.INTERLOCK
    assert "furnace setpoint 5000.0 °C is outside" in capsys.readouterr().err
    with service.client() as client, client.control():
        status = client.status()
        assert (status.target_rotary_rpm, status.target_vibration_rpm) == (0.0, 0.0)
        assert status.furnace_target_c is None
        assert status.state is ControllerState.ARMED
        client.disarm()


def test_cli_set_with_a_heating_rate_but_no_furnace_target_is_refused_whole(
    service: Service, capsys: pytest.CaptureFixture[str]
) -> None:
    """SAFETY requirement 20: `set --heat-rate 5` without `--temp-c` is not half-applied (speeds on, the rate
    dropped) but refused as invalid input (exit 1), naming the flag, the value and why; nothing changes."""
    assert main(["--config", str(service.config), "arm"]) == ExitCode.OK
    with service.client() as client:
        wait_for(lambda: client.status().state is ControllerState.ARMED, what="ARMED")
    capsys.readouterr()
    refused = main(["--config", str(service.config), "set", "--rot-rpm", "20", "--vib-rpm", "200",
                    "--heat-rate", "5", "--json"])
    assert refused == ExitCode.INVALID_INPUT
    error = json.loads(capsys.readouterr().out)["error"]
    assert error["flag"] == "--heat-rate"
    assert "heating rate 5.0 °C/min given without a furnace target (--temp-c)" in error["message"]
    with service.client() as client, client.control():
        status = client.status()
        assert (status.target_rotary_rpm, status.target_vibration_rpm, status.furnace_target_c) == (0.0, 0.0, None)
        assert status.state is ControllerState.ARMED
        client.disarm()




def test_a_recipe_runs_pauses_and_aborts_and_a_bad_one_is_refused(service: Service, tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text(DEMO.read_text().replace("rotary_rpm = 180.0", "rotary_rpm = 250.0"))
    with service.client("recipes") as client, client.control():
        with pytest.raises(InterlockRefusal) as refused:
            client.recipe_run(bad)
        assert refused.value.code == "recipe_refused"
        assert any(r.quantity == "omega_r" and r.value == 250.0 for r in refused.value.refusals)
        with pytest.raises(InvalidInputError):  # read by the client: the service opens no path
            client.recipe_run(tmp_path / "missing.toml")
        with pytest.raises(RequestInvalid) as invalid:  # sent by content: the service names what is wrong
            client.recipe_run_text("broken.toml", "[recipe]\nname = 3\n")
        assert "broken.toml" in str(invalid.value) and invalid.value.field == "text"
        started = client.recipe_run(DEMO)
        assert started.active is True and started.progress is not None and started.progress.steps == 4
        with pytest.raises(ServiceRefused):
            client.recipe_run(DEMO)  # one run at a time
        with pytest.raises(ServiceRefused):
            client.set_speeds(10.0, 10.0)  # the recipe drives the mill
        wait_for(lambda: (p := client.recipe().progress) is not None and p.state == "RUNNING", what="the run to start")
        assert (paused := client.recipe_pause(now=True).progress) is not None and paused.state == "PAUSED"
        assert (resumed := client.recipe_resume().progress) is not None and resumed.state == "RUNNING"
        client.recipe_abort()
        wait_for(lambda: not client.recipe().active, 30.0, "the aborted run to stop")
        progress = client.recipe().progress
        assert progress is not None and progress.state is RunState.ABORTED
        assert Path(progress.record).exists()
        client.disarm()
        wait_for(lambda: client.status().state == "DISABLED", what="DISABLED")


ABORT_DELAYS_S = (0.0, 0.0, 0.01, 0.02, 0.0, 0.03, 0.005, 0.05, 0.0, 0.015)
"""When the abort follows the resume, one run each: the race window is the ~50 ms between the controller's
first nonzero setpoint to an ARMED node and the node's RUNNING coming back."""


def test_pause_resume_and_abort_back_to_back_stop_cleanly(service: Service) -> None:
    """The CI flake (issue 15): pause → resume → abort in quick succession tripped the controller with "node went
    ARMED → RUNNING, which the controller (state STOPPING) did not command", an E-stop, and left the service
    TRIPPED for the next test. The resume re-issues the ramp: its first nonzero setpoint goes to an ARMED node, and
    the abort's STOP follows it before the node's answer is back (docs/safety.md#a-stop-overtaking-a-setpoint)."""
    with service.client("back-to-back") as client, client.control():
        after = client.events().last_seq
        for run, delay_s in enumerate(ABORT_DELAYS_S, 1):
            client.recipe_run(DEMO)
            wait_for(lambda: (p := client.recipe().progress) is not None and p.state == "RUNNING",
                     what=f"run {run} to start")
            client.recipe_pause(now=True)
            client.recipe_resume()
            time.sleep(delay_s)
            client.recipe_abort()
            wait_for(lambda: not client.recipe().active, 30.0, f"run {run} to stop")
            status = client.status()
            trips = [e.message for e in client.events(after=after).events if e.kind is EventKind.TRIP]
            assert status.state is ControllerState.ARMED and not trips, (
                f"run {run} (abort {delay_s * 1e3:.0f} ms after the resume): {status.state}, trips {trips}"
            )
            progress = client.recipe().progress
            assert progress is not None and progress.state is RunState.ABORTED
        client.disarm()
        wait_for(lambda: client.status().state == "DISABLED", what="DISABLED")


async def test_the_async_client_reads_and_commands(service: Service) -> None:
    async with AsyncClient(service.socket, name="async") as client:
        assert (await client.status()).state == "DISABLED"
        async with client.control():
            assert ((await client.control_state()).holder or "").startswith("api:async@")
            with pytest.raises(InterlockRefusal):
                await _arm_and_refuse(client)
        stream = client.stream(count=2)
        first = await anext(stream)
        assert isinstance(first, StatusOut)
        await stream.aclose()


async def _arm_and_refuse(client: AsyncClient) -> None:
    verdict = await client.check(250.0, 800.0)
    assert verdict.ok is False and verdict.refusals[0].quantity == "omega_r"
    await client.arm()
    for _ in range(200):
        if (await client.status()).state == "ARMED":
            break
        await asyncio.sleep(0.05)
    try:
        await client.set_speeds(250.0, 800.0)
    finally:
        await client.disarm()


def test_sigterm_stops_cleanly_removes_the_socket_and_records_it(service: Service) -> None:
    assert service.stop(signal.SIGTERM) == 0, service.output()
    assert not service.socket.exists()
    records = list(read_records(service.records / "events.jsonl"))
    assert records[-1]["kind"] == "service" and "SIGTERM" in records[-1]["message"]
    (bus_log,) = (service.records / "bus").glob("bus_*.log")  # this session's
    assert bus_log.stat().st_size > 0
