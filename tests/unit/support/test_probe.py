"""The hil probe's account of what it captured, which a timed-out wait puts in its failure (tests/hil)."""

from __future__ import annotations

import socket
import time
import uuid
from collections.abc import Iterator
from typing import cast

import can
import pytest

from millctl.config.models import Bus
from millctl.protocol import FaultCode, FaultFlag, NodeState, NodeStatus, RefusalCode, default_codec, open_bus
from tests.hil.scenario_support import Probe, deepen_receive_queue

WATCHDOG_THEN_ESTOP = NodeStatus(
    NodeState.FAULT, FaultFlag.WATCHDOG | FaultFlag.ESTOP, FaultCode.WATCHDOG, 0, RefusalCode.NONE
)


@pytest.fixture
def probe_and_sender() -> Iterator[tuple[Probe, can.BusABC]]:
    config = Bus(interface="virtual", channel=f"probe-{uuid.uuid4().hex}")
    probe = Probe(config, default_codec())
    sender = open_bus(config)
    try:
        yield probe, sender
    finally:
        sender.shutdown()
        probe.close()


def captured(probe: Probe, after: float, count: int) -> None:
    deadline = time.monotonic() + 5.0
    while len(probe.frames(after)) < count:
        assert time.monotonic() < deadline, f"the probe captured {len(probe.frames(after))} of {count} frames"
        time.sleep(0.01)


def test_a_timed_out_wait_names_the_frames_captured_and_the_nodes_newest_status(
    probe_and_sender: tuple[Probe, can.BusABC],
) -> None:
    probe, sender = probe_and_sender
    t0 = time.time()
    sender.send(default_codec().encode(WATCHDOG_THEN_ESTOP, 3))
    sender.send(can.Message(arbitration_id=0x555, data=bytes(8), is_extended_id=False))
    captured(probe, t0, 2)
    with pytest.raises(pytest.fail.Exception) as failed:
        probe.wait_first(lambda seen: False, t0, 0.05, "NodeStatus RUNNING")
    message = str(failed.value.msg)
    assert message.startswith("the probe saw no NodeStatus RUNNING within 0.1 s; it captured 2 frames since")
    assert "1 NodeStatus; the newest, at +0." in message
    assert "FAULT, first fault WATCHDOG, fault bits " in message
    assert "ESTOP" in message.rpartition("fault bits")[2]


def test_with_no_status_captured_it_says_so(probe_and_sender: tuple[Probe, can.BusABC]) -> None:
    probe, sender = probe_and_sender
    t0 = time.time()
    sender.send(can.Message(arbitration_id=0x555, data=bytes(8), is_extended_id=False))
    captured(probe, t0, 1)
    assert probe.describe_since(t0) == "it captured 1 frame since, no NodeStatus among them"
    assert probe.describe_since(time.time() + 60.0) == "it captured 0 frames since, no NodeStatus among them"


class SocketBus:
    """A stand-in for python-can's SocketcanBus: what deepen_receive_queue reads of it is its ``socket``."""

    def __init__(self, sock: socket.socket) -> None:
        self.socket = sock


def test_the_probes_receive_queue_is_deepened_on_a_socket_bus() -> None:
    # An unbound UDP socket (it neither sends nor receives): the kernel sizes its queue as it would the probe's.
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        before = sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
        granted = deepen_receive_queue(cast(can.BusABC, SocketBus(sock)))
        assert granted == sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
        assert granted is not None and granted > before


def test_a_bus_without_a_socket_is_left_alone() -> None:
    bus = open_bus(Bus(interface="virtual", channel=f"probe-{uuid.uuid4().hex}"))
    try:
        assert deepen_receive_queue(bus) is None
    finally:
        bus.shutdown()
