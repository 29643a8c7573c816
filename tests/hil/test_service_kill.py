"""SIGKILL the controller service mid-run: the node's watchdog stops the mill, and the records stay intact.

Three processes on a real transport: the node (``python -m firmware_sim``),
the service (``millctl serve``), and this test as a third, silent bus
listener that watches NodeStatus and DriveTelemetry. udp_multicast runs only
inside the hil tier's private network namespace (``tests/hil/in_netns``).
"""

from __future__ import annotations

import contextlib
import signal
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import can
import pytest

from millctl.client import Client
from millctl.protocol import DriveTelemetry, FaultCode, NodeState, NodeStatus, ProtocolError, default_codec
from millctl.records import read_records
from tests.hil.conftest import _live_group_members
from tests.hil.scenario_support import bound_scale, write_config

if TYPE_CHECKING:
    from tests.hil.conftest import Spawner, Transport

pytestmark = pytest.mark.hil

STANDSTILL_RPM = 1.0


def wait_for(condition: Any, timeout_s: float, what: str) -> None:
    """Poll ``condition()`` until true (a safety net, not a timing assertion)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        with contextlib.suppress(Exception):
            if condition():
                return
        time.sleep(0.05 * bound_scale())  # in the VM a status request costs the service ~25x the host's CPU
    pytest.fail(f"timed out after {timeout_s:.0f} s waiting for {what}")


class Watcher:
    """The third bus listener: the latest NodeStatus and DriveTelemetry, decoded."""

    def __init__(self, bus: can.BusABC) -> None:
        self.bus = bus
        self.codec = default_codec()
        self.status: NodeStatus | None = None
        self.drives: DriveTelemetry | None = None

    def poll(self, duration_s: float = 0.05) -> None:
        """Read every frame that arrives within ``duration_s``."""
        deadline = time.monotonic() + duration_s
        while (left := deadline - time.monotonic()) > 0:
            frame = self.bus.recv(left)
            if frame is None:
                return
            with contextlib.suppress(ProtocolError):
                message = self.codec.decode(frame).message
                if isinstance(message, NodeStatus):
                    self.status = message
                elif isinstance(message, DriveTelemetry):
                    self.drives = message

    def stopped_by_watchdog(self) -> bool:
        """FAULT with WATCHDOG as the first fault, and both drives at standstill."""
        self.poll()
        return (
            self.status is not None
            and self.status.state is NodeState.FAULT
            and FaultCode(self.status.first_fault) is FaultCode.WATCHDOG
            and self.drives is not None
            and max(abs(self.drives.rotary_rpm), abs(self.drives.vibration_rpm)) < STANDSTILL_RPM
        )

    def running(self) -> bool:
        """RUNNING with the rotary drive turning."""
        self.poll()
        return (
            self.status is not None
            and self.status.state is NodeState.RUNNING
            and self.drives is not None
            and self.drives.rotary_rpm > 10.0
        )


@pytest.mark.parametrize("transport", ["udp_multicast", "socketcan"], indirect=True)
def test_sigkill_of_the_service_mid_run_the_node_stops_the_mill_and_records_survive(
    transport: Transport, spawn: Spawner, tmp_path: Path
) -> None:
    config = write_config(tmp_path, transport)  # the scenarios' config: scaled inside the VM like theirs
    node = spawn(["python", "-m", "firmware_sim", "--config", str(config)], realtime="node")
    service = spawn(["python", "-m", "millctl", "--config", str(config), "serve"], realtime="controller")
    watcher = Watcher(transport.open_bus())
    socket_path = tmp_path / "mill.sock"
    wait_for(socket_path.exists, transport.timeout(30.0), f"the service socket\n{spawn.output(service)}")
    with Client(socket_path, name="hil") as client:
        wait_for(lambda: client.status().state == "DISABLED", transport.timeout(20.0), "the node to be seen")
        client.take_control()
        client.arm()
        wait_for(lambda: client.status().state == "ARMED", transport.timeout(10.0), "ARMED")
        client.set_speeds(60.0, 300.0)
        wait_for(watcher.running, transport.timeout(30.0), "the mill to run (seen by the third listener)")

    assert spawn.stop(service, signal.SIGKILL) == -signal.SIGKILL

    wait_for(watcher.stopped_by_watchdog, transport.timeout(30.0), "the node's watchdog to stop the mill")
    records = list(read_records(tmp_path / "records" / "events.jsonl"))
    assert [r["seq"] for r in records] == list(range(1, len(records) + 1))
    messages = [r["message"] for r in records]
    assert any("ARM" in m for m in messages)
    assert any("ramp to ω_r = 60.0 rpm" in m for m in messages)
    assert any(r["kind"] == "state" and "RUNNING" in r["message"] for r in records)
    assert not any("service stopped" in m for m in messages)  # it was killed, not stopped
    assert spawn.stop(node) == 0, spawn.output(node)
    # The node's own helpers (e.g. a physics worker process) may outlive it by a moment: let them exit.
    wait_for(lambda: not _live_group_members(node.pid), transport.timeout(10.0), "the node's helpers to exit")
