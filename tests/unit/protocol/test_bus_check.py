"""`millctl bus check`: the node found on the virtual bus (exit 0), a silent bus (exit 3), the link bitrate."""

from __future__ import annotations

import json
import threading
import uuid
from collections.abc import Iterator
from pathlib import Path

import can
import pytest

from firmware_sim.node import Node
from millctl.cli import main
from millctl.clock import MonotonicClock
from millctl.config import load_config
from millctl.config.bus import Bus
from millctl.errors import ExitCode
from millctl.protocol.bus_check import link_problems, parse_link
from tests.conftest import CONFIG_FILE


def config_on(tmp_path: Path, channel: str) -> Path:
    path = tmp_path / "mill.toml"
    path.write_text(CONFIG_FILE.read_text().replace('channel = "millbus"', f'channel = "{channel}"', 1))
    return path


@pytest.fixture
def channel() -> str:
    return f"bus-check-{uuid.uuid4().hex}"


@pytest.fixture
def simulated_node(tmp_path: Path, channel: str) -> Iterator[Node]:
    """The simulated node on the virtual bus, ticking in real time on a thread of its own."""
    config = load_config(config_on(tmp_path, channel)).config
    bus = can.Bus(interface="virtual", channel=channel)
    node = Node(config, bus, MonotonicClock())
    stop = threading.Event()

    def run() -> None:
        while not stop.wait(config.timing.node_tick_s):
            node.tick()

    thread = threading.Thread(target=run, name="simulated-node", daemon=True)
    thread.start()
    yield node
    stop.set()
    thread.join(timeout=5)
    node.close()
    bus.shutdown()


def test_finds_the_simulated_node_on_the_virtual_bus(
    tmp_path: Path, channel: str, simulated_node: Node, capsys: pytest.CaptureFixture[str]
) -> None:
    path = config_on(tmp_path, channel)
    assert main(["--config", str(path), "bus", "check", "--listen-s", "10", "--json"]) == ExitCode.OK
    document = json.loads(capsys.readouterr().out)
    report = document["result"]
    assert document["ok"] is True and report["ok"] is True and report["node_present"] is True
    assert report["node_state"] == "DISABLED" and report["node_first_fault"] == "NONE"
    assert report["interface"] == "virtual" and report["channel"] == channel
    assert report["health"]["condition"] == "error-active" and report["problems"] == []


def test_a_silent_bus_exits_3_naming_what_is_missing(
    tmp_path: Path, channel: str, capsys: pytest.CaptureFixture[str]
) -> None:
    path = config_on(tmp_path, channel)
    assert main(["--config", str(path), "bus", "check", "--listen-s", "0.2"]) == ExitCode.BUS
    captured = capsys.readouterr()
    assert "node     ABSENT" in captured.out
    assert f"no NodeStatus (0x100) from the node within 0.2 s on virtual:{channel}" in captured.err
    assert main(["--config", str(path), "bus", "check", "--listen-s", "0.1", "--json"]) == ExitCode.BUS
    document = json.loads(capsys.readouterr().out)
    assert document["ok"] is False and document["error"]["exit_code"] == 3
    assert document["result"]["node_present"] is False


CAN0 = json.dumps([{
    "ifname": "can0", "operstate": "UP",
    "linkinfo": {
        "info_kind": "can",
        "info_data": {"ctrlmode": [], "state": "ERROR-PASSIVE", "berr_counter": {"tx": 128, "rx": 3},
                      "restart_ms": 100, "bittiming": {"bitrate": 250000, "sample_point": "0.875"}},
        "info_xstats": {"restarts": 2, "bus_error": 0, "arbitration_lost": 0, "error_warning": 4,
                        "error_passive": 3, "bus_off": 2},
    },
}])
VCAN0 = json.dumps([{"ifname": "vcan0", "operstate": "UNKNOWN", "linkinfo": {"info_kind": "vcan"}}])


def test_the_links_bitrate_is_compared_with_the_configuration() -> None:
    link = parse_link(CAN0)
    assert (link.state, link.bitrate_bit_s, link.tx_error_counter, link.rx_error_counter, link.bus_off) == (
        "ERROR-PASSIVE", 250000, 128, 3, 2)
    problems = link_problems(link, Bus(interface="socketcan", channel="can0", bitrate_bit_s=500_000))
    assert len(problems) == 1
    assert problems[0].startswith("link can0 runs at 250000 bit/s but bus.bitrate_bit_s = 500000: python-can's "
                                  "socketcan does not set the bitrate")
    assert link_problems(link, Bus(interface="socketcan", channel="can0", bitrate_bit_s=250_000)) == []
    vcan = parse_link(VCAN0)
    assert vcan.bitrate_bit_s is None and link_problems(vcan, Bus(interface="socketcan", channel="vcan0")) == []


def test_the_service_warns_at_start_of_a_socketcan_link_at_another_bitrate(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from millctl.protocol import bus_check
    from millctl.service.runtime import ServiceRuntime
    from tests.support.service import write_config

    socketcan = Bus(interface="socketcan", channel="can0", bitrate_bit_s=500_000)
    calls: list[str] = []

    def fake_read_link(channel: str) -> object:
        calls.append(channel)
        return parse_link(CAN0)

    monkeypatch.setattr(bus_check, "read_link", fake_read_link)
    assert bus_check.startup_link_problems(Bus(interface="virtual")) == [] and calls == []
    expected = bus_check.startup_link_problems(socketcan)
    assert calls == ["can0"] and expected[0].startswith("link can0 runs at 250000 bit/s")
    monkeypatch.setattr(bus_check, "read_link", lambda channel: "`ip` (iproute2) is not installed")
    assert bus_check.startup_link_problems(socketcan) == [], "an unreadable link is bus check's to explain"
    # the service's start: the problem is a warning of the service and an event of kind bus
    monkeypatch.setattr(bus_check, "startup_link_problems", lambda bus: expected)
    runtime = ServiceRuntime(load_config(write_config(tmp_path)), embed_node=False)
    try:
        runtime.start()
        assert runtime.describe().warnings == expected
        events = [e for e in runtime.journal.after(0) if e["kind"] == "bus"]
        assert [e["message"] for e in events] == expected
    finally:
        runtime.close()
