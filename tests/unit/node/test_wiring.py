"""How a node is built: what it listens on and what it accepts when nobody asks for more (``Node.__init__``)."""

from __future__ import annotations

import uuid

import can

from firmware_sim.node import Node
from millctl.clock import ManualClock
from millctl.config import MillConfig
from millctl.protocol import EStop, EStopSource, FaultFlag, NodeState, SimFault, SimFaultCode, default_codec


def test_an_estop_on_the_nodes_estop_channel_alone_latches_it(config: MillConfig) -> None:
    """On SocketCAN the node also reads a channel that passes only the E-stop ID (a flood on the main queue
    cannot push it out): an E-stop that arrives there and nowhere else stops the node."""
    main, estops = f"main-{uuid.uuid4().hex}", f"estop-{uuid.uuid4().hex}"
    node_bus, estop_bus = can.Bus(interface="virtual", channel=main), can.Bus(interface="virtual", channel=estops)
    button = can.Bus(interface="virtual", channel=estops)
    node = Node(config, node_bus, ManualClock(100.0), estop_bus=estop_bus)
    try:
        node.tick()
        assert not node.fault_bits
        button.send(default_codec().encode(EStop(EStopSource.BUTTON)))
        node.tick()
        assert node.state is NodeState.FAULT and FaultFlag.ESTOP in node.fault_bits
    finally:
        node.close()
        for bus in (node_bus, estop_bus, button):
            bus.shutdown()


def test_a_node_built_without_the_flag_ignores_fault_injection(config: MillConfig) -> None:
    """Fault injection is opt-in (`firmware_sim --fault-injection`): a node built plainly ignores SimFault."""
    channel = f"plain-{uuid.uuid4().hex}"
    node_bus, tester = can.Bus(interface="virtual", channel=channel), can.Bus(interface="virtual", channel=channel)
    node = Node(config, node_bus, ManualClock(100.0))
    try:
        tester.send(default_codec().encode(SimFault(SimFaultCode.NODE_SILENT, True, 0.0)))
        node.tick()
        assert node.faults.ignored == 1 and not node.faults.silent
    finally:
        node.close()
        for bus in (node_bus, tester):
            bus.shutdown()
