"""The furnace node's own channel beside CiA 402 drives, as the operator checks, records and drills it (issue 36).

``millctl bus check`` listens to ``[drives.furnace_bus]`` as well as to the drives' bus and names a silent
furnace node; the service's bus log holds the furnace channel's frames beside the drives', each line under
its channel's name; a fault drill's heater fault reaches the furnace node, the drives' faults the drives.
"""

from __future__ import annotations

import argparse
import json
import re
import threading
import uuid
from collections.abc import Iterator
from pathlib import Path

import can
import pytest

from firmware_sim.cia402.furnace_mill import Cia402FurnaceMill
from millctl.cli import main
from millctl.cli.bus_cmd import _check_cia402
from millctl.clock import MonotonicClock
from millctl.config import load_config
from millctl.config.models import MillConfig
from millctl.protocol import SimFaultCode
from millctl.service import ServiceRuntime
from tests.support.pace import stretched
from tests.support.service import wait_for
from tests.unit.service.test_fault_drills import ask

CONFIG = Path("config/mill-cia402-furnace.toml")


def own_channels(directory: Path) -> Path:
    """config/mill-cia402-furnace.toml with channels of its own (drives, furnace) and [service] in ``directory``."""
    tag = uuid.uuid4().hex[:8]
    text = CONFIG.read_text(encoding="utf-8")
    text = text.replace('channel = "millbus-furnace"', f'channel = "furnace-{tag}"')
    text = re.sub(r'(?m)^channel = "millbus"', f'channel = "drives-{tag}"', text)
    assert f"furnace-{tag}" in text and f"drives-{tag}" in text
    head, _, _ = text.partition("[service]")
    service = f'[service]\nsocket_path = "{directory / "mill.sock"}"\nrecords_dir = "{directory / "records"}"\n'
    path = directory / "mill.toml"
    path.write_text(head + service, encoding="utf-8")
    return path


@pytest.fixture
def mill_on_two_channels(tmp_path: Path) -> Iterator[tuple[MillConfig, threading.Event]]:
    """The simulated drives and furnace node on their two virtual channels, ticked by a thread; the furnace
    node ticks while the event is set (cleared: a silent furnace node)."""
    config = load_config(own_channels(tmp_path)).config
    assert config.drives.furnace_bus is not None
    buses = [can.Bus(interface="virtual", channel=config.bus.channel),
             can.Bus(interface="virtual", channel=config.drives.furnace_bus.channel)]
    sim = Cia402FurnaceMill(config, buses[0], MonotonicClock(), furnace_bus=buses[1])
    stop = threading.Event()
    ticking = threading.Event()
    ticking.set()

    def run() -> None:
        while not stop.wait(0.005):
            sim.mill.tick()
            if ticking.is_set():
                sim.furnace_node.tick()

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    yield config, ticking
    stop.set()
    thread.join()
    sim.close()
    for bus in buses:
        bus.shutdown()


def checked(config: MillConfig, capsys: pytest.CaptureFixture[str]) -> tuple[int, dict[str, object]]:
    args = argparse.Namespace(json=True, listen_s=stretched(2.0), command="bus", bus_command="check")
    code = _check_cia402(args, config)
    return code, json.loads(capsys.readouterr().out)


def test_bus_check_hears_the_furnace_node_on_its_own_channel(
    mill_on_two_channels: tuple[MillConfig, threading.Event], capsys: pytest.CaptureFixture[str]
) -> None:
    config, _ = mill_on_two_channels
    code, document = checked(config, capsys)
    result = document["result"]
    assert isinstance(result, dict)
    assert code == 0, document
    furnace = result["furnace"]
    assert furnace["node_present"] and furnace["channel"] == config.drives.furnace_bus.channel  # type: ignore[union-attr]
    assert furnace["node_state"] in ("DISABLED", "ARMED")
    assert result["ok"] is True and len(result["drives"]) == 2


def test_bus_check_names_a_silent_furnace_node_and_fails(
    mill_on_two_channels: tuple[MillConfig, threading.Event], capsys: pytest.CaptureFixture[str]
) -> None:
    config, furnace_ticking = mill_on_two_channels
    furnace_ticking.clear()
    code, document = checked(config, capsys)
    assert code == 3, document
    error = document["error"]
    assert isinstance(error, dict)
    assert "furnace channel: no NodeStatus (0x100) from the node" in error["message"]
    assert f"virtual:{config.drives.furnace_bus.channel}" in error["message"]  # type: ignore[union-attr]
    result = document["result"]
    assert isinstance(result, dict) and result["ok"] is False and result["furnace"]["node_present"] is False


def test_the_service_bus_log_records_the_furnace_channel_beside_the_drives(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config_path = own_channels(tmp_path)
    loaded = load_config(config_path)
    furnace_channel = loaded.config.drives.furnace_bus.channel  # type: ignore[union-attr]
    runtime = ServiceRuntime(loaded)
    try:
        runtime.start()
        assert runtime.wait_for_node(stretched(10.0)), runtime.controller.trip_cause
    finally:
        runtime.close()
    lines = runtime.bus_log_path.read_text().splitlines()
    channels = {line.split()[1] for line in lines if line.startswith("(")}
    assert channels == {loaded.config.bus.channel, furnace_channel}, channels
    furnace_lines = [line for line in lines if f" {furnace_channel} " in line]
    assert any(" 100#" in line and line.endswith(" R") for line in furnace_lines)  # its NodeStatus, received
    assert any(line.endswith(" T") for line in furnace_lines)  # the controller's frames to it, sent
    # bus log show reads the furnace channel's frames with the millbus DBC (0x100 is NodeStatus there, not
    # CANopen's TIME) and the drives' with CANopen first
    assert main(["--config", str(config_path), "bus", "log", "show", str(runtime.bus_log_path), "--json"]) == 0
    document = json.loads(capsys.readouterr().out)  # with --json, stdout holds the one document: the frames in it
    shown = document["result"]["frames"]
    assert {s["channel"] for s in shown} == {loaded.config.bus.channel, furnace_channel}
    node_status = [s["decoded"] for s in shown if s["id"] == 0x100]
    assert node_status and all(words.startswith("NodeStatus") for words in node_status), node_status[:3]
    assert any(s["decoded"].startswith("heartbeat") or "NMT" in s["decoded"] for s in shown)


def test_a_heater_drill_reaches_the_furnace_node_and_clear_clears_both(tmp_path: Path) -> None:
    """POST /v1/sim/faults: HEATER_FAIL goes to the furnace node on its channel, VIB_STALL to the drives."""
    runtime = ServiceRuntime(load_config(own_channels(tmp_path)), fault_injection=True)
    try:
        runtime.start()
        assert runtime.wait_for_node(stretched(10.0)), runtime.controller.trip_cause
        sim = runtime.node
        assert isinstance(sim, Cia402FurnaceMill)
        for fault in ("HEATER_FAIL", "VIB_STALL"):
            assert ask(runtime, "POST", "/v1/sim/faults", json={"fault": fault}).status_code == 200
        wait_for(lambda: sim.furnace_node.furnace.element_open and sim.drives["vibration"].model.stalled,
                 stretched(5.0), "the heater fault at the furnace node and the stall at the vibration drive")
        assert set(sim.furnace_node.faults.active) == {SimFaultCode.HEATER_FAIL}  # not the drives'
        assert set(sim.mill.faults.active) == {SimFaultCode.VIB_STALL}
        assert set(ask(runtime, "GET", "/v1/sim/faults").json()["active"]) == {"HEATER_FAIL", "VIB_STALL"}
        assert ask(runtime, "POST", "/v1/sim/faults", json={"fault": "CLEAR"}).status_code == 200
        wait_for(lambda: not sim.faults.active, stretched(5.0), "CLEAR to reach both devices")
        assert not sim.furnace_node.furnace.element_open
    finally:
        runtime.close()
