"""Bus input against both loops: drained fully, E-stop first, and nothing on the bus stops a loop (SAFETY 19, 22).

The node and the controller on one virtual bus (``Rig``); the bystander bus
plays the babbling node, the flooder and the sender of malformed frames.
"""

from __future__ import annotations

import can
import pytest

from millctl.controller import ControllerState as S
from millctl.protocol import (
    ControllerState,
    EStop,
    EStopSource,
    FaultFlag,
    Heartbeat,
    NodeState,
    SimFaultCode,
)
from tests.unit.scenarios.rig import Rig

LOW_RPM = (60.0, 300.0)


def raw(arbitration_id: int, data: bytes, **kwargs: object) -> can.Message:
    """A frame as a faulty or hostile sender may put it on the bus (python-can's own checks off)."""
    fields: dict[str, object] = {"is_extended_id": False, "check": False, **kwargs}
    return can.Message(arbitration_id=arbitration_id, data=data, **fields)  # type: ignore[arg-type]


def malformed_frames(rig: Rig) -> dict[str, can.Message]:
    """One frame of every malformed kind, each on an identifier that one of the loops reads."""
    heartbeat = bytes(rig.codec.encode(Heartbeat(ControllerState.RUNNING), 3).data)
    return {
        "one byte on Command": raw(0x010, b"\x01"),
        "DLC 3, 8 bytes of data on Heartbeat": raw(0x020, heartbeat, dlc=3),
        "DLC 8, 2 bytes of data on NodeStatus": raw(0x100, b"\x00\x01", dlc=8),
        "FD frame on Setpoints": raw(0x030, bytes(12), is_fd=True),
        "remote frame on DriveTelemetry": raw(0x110, b"", is_remote_frame=True, dlc=8),
        "extended identifier 0x10": raw(0x010, bytes(8), is_extended_id=True),
        "unknown identifier 0x555": raw(0x555, bytes(8)),
        "empty frame on FurnaceTelemetry": raw(0x120, b""),
    }


def test_malformed_frames_of_every_kind_are_counted_and_neither_loop_stops(rig: Rig) -> None:
    rig.start(*LOW_RPM)
    frames = malformed_frames(rig)
    error_frame = can.Message(arbitration_id=0x020, is_error_frame=True, data=bytes(8))
    for _ in range(50):
        for frame in (*frames.values(), error_frame):
            rig.probe.send(frame)
        rig.step()
    rig.run(1.0)
    assert rig.controller.state is S.RUNNING and rig.node.state is NodeState.RUNNING
    assert rig.node.fault_bits == FaultFlag(0)
    # each loop reads every frame; it counts those on identifiers it decodes, the rest are not its business
    node, controller = rig.node.reader.counts, rig.controller.reader.counts
    assert node.malformed == controller.malformed == 50 * len(frames)
    assert node.error_frames == controller.error_frames == 50
    status = rig.controller.status()
    assert status.invalid_frames == 50 * len(frames) and status.receive_errors == 50
    assert status.bus_receive["error_frames"] == 50
    assert controller.last_error.startswith("malformed frame: 0x120")


class FailingReads(can.BusABC):
    """The inner bus, but every ``every``-th read raises the socket error ``error`` (the frame stays queued)."""

    def __init__(self, inner: can.BusABC, every: int, error: Exception) -> None:
        self.inner, self.every, self.error, self.reads = inner, every, error, 0
        super().__init__(channel="failing")

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        self.reads += 1
        if self.reads % self.every == 0:
            raise self.error
        return self.inner.recv(timeout), True

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self.inner.send(msg, timeout)


@pytest.mark.parametrize(
    "error",
    [OSError(105, "No buffer space available"), can.CanOperationError("undecodable datagram of 1 bytes")],
    ids=["OSError", "CanOperationError"],
)
def test_receive_errors_are_counted_and_neither_loop_stops(rig: Rig, error: Exception) -> None:
    rig.start(*LOW_RPM)
    rig.node.reader.bus = FailingReads(rig.node.bus, 3, error)
    rig.controller.reader.bus = FailingReads(rig.controller.bus, 3, error)
    rig.run(2.0)
    assert rig.controller.state is S.RUNNING and rig.node.state is NodeState.RUNNING
    assert rig.node.reader.counts.receive_errors > 100
    assert rig.controller.status().receive_errors == rig.controller.reader.counts.receive_errors > 100
    assert type(error).__name__ in rig.controller.reader.counts.last_error


@pytest.mark.parametrize("babble_hz", [100.0, 500.0, 1000.0])
def test_estop_under_a_babbling_node_is_acted_on_at_the_next_node_tick(rig: Rig, babble_hz: float) -> None:
    rig.start(*LOW_RPM)
    rig.inject(SimFaultCode.NODE_BABBLE, babble_hz)
    rig.run(1.0)
    assert rig.node.reader.counts.frames > 0 and rig.controller.state is S.RUNNING
    rig.probe.send(rig.codec.encode(EStop(EStopSource.BUTTON)))
    rig.step()
    assert FaultFlag.ESTOP in rig.node.fault_bits and rig.node.state is NodeState.FAULT
    rig.run(1.0, until=lambda: rig.controller.state is S.TRIPPED)
    assert "ESTOP" in rig.controller.trip_cause
    rig.run(20.0, until=lambda: max(rig.node.true_speeds_rpm) < 1.0)
    assert max(rig.node.true_speeds_rpm) < 1.0


def test_estop_inside_a_flood_on_0x001_is_acted_on_at_the_next_node_tick(rig: Rig) -> None:
    rig.start(*LOW_RPM)
    flood = raw(0x001, bytes(8))
    for _ in range(2000):  # more than 0.5 s of a 500 kbit/s bus at its maximum frame rate, queued at once
        rig.probe.send(flood)
    rig.probe.send(rig.codec.encode(EStop(EStopSource.BUTTON)))
    for _ in range(1000):
        rig.probe.send(flood)
    rig.step()
    assert FaultFlag.ESTOP in rig.node.fault_bits
    assert rig.node.reader.counts.capped_drains == 0

