"""The controller alone on CAN error frames and an adapter's bus state: an event each change, bus-off a trip.

docs/protocol.md#bus-errors. tests/unit/scenarios/test_bus_errors.py shows the
same with the node on the bus; these are the unit-tier checks that judge the
controller's mutants (docs/safety.md#mutation-testing), against the scripted
node of tests/unit/controller/bench.py.
"""

from __future__ import annotations

import uuid

import can

from millctl.clock import ManualClock
from millctl.config import MillConfig
from millctl.controller import Controller, ControllerState, Event, EventKind
from millctl.protocol import DriveTelemetry, FurnaceTelemetry, NodeState, NodeStatus, default_codec
from millctl.protocol.bus_health import CAN_ERR_BUSOFF, CAN_ERR_CNT, CAN_ERR_CRTL
from tests.support.virtual_bus import StatefulVirtualBus
from tests.unit.controller.bench import ScriptedNode

BUS_OFF_CAUSE = "error frame: bus-off (class 0x040)"


def error_frame(classes: int, crtl: int = 0, tec: int = 0, rec: int = 0) -> can.Message:
    """An error frame as SocketCAN delivers it: the classes in the identifier, TEC/REC in data[6], data[7]."""
    return can.Message(
        arbitration_id=classes, is_error_frame=True, is_extended_id=False, data=bytes((0, crtl, 0, 0, 0, 0, tec, rec))
    )


def state_of(controller: Controller) -> ControllerState:
    """The controller's state, read afresh (a property mypy would otherwise narrow across ticks)."""
    return controller.state


def bus_events(events: list[Event]) -> list[Event]:
    return [e for e in events if e.kind is EventKind.BUS]


def test_an_error_passive_frame_is_an_event_with_the_counters_and_no_trip(bench: ScriptedNode) -> None:
    bench.armed()
    bench.bus.send(error_frame(CAN_ERR_CRTL | CAN_ERR_CNT, crtl=0x20, tec=136, rec=4))  # TX passive
    bench.run(0.2, state=NodeState.ARMED)
    assert bench.controller.state is ControllerState.ARMED
    (event,) = bus_events(bench.events)
    assert (event.source, event.data) == (
        "bus",
        {"condition": "error-passive", "tx_error_counter": 136, "rx_error_counter": 4},
    )
    assert event.message == "CAN controller error-passive: error frame: controller problem (class 0x204, TEC 136 REC 4)"


def test_a_bus_off_frame_trips_naming_the_bus_and_what_to_check(bench: ScriptedNode, config: MillConfig) -> None:
    bench.armed()
    bench.bus.send(error_frame(CAN_ERR_BUSOFF))
    bench.run(0.2, state=NodeState.ARMED)
    assert bench.controller.state is ControllerState.TRIPPED
    bus = config.bus
    assert bench.controller.trip_cause == (
        f"CAN bus-off on {bus.interface}:{bus.channel} ({BUS_OFF_CAUSE}): the controller cannot send, the node's "
        "watchdog stops the mill; check wiring, termination and bitrate (docs/protocol.md#bus-errors)"
    )
    assert bench.last_event(EventKind.TRIP).source == "bus"
    (event,) = bus_events(bench.events)
    assert event.message == f"CAN controller bus-off: {BUS_OFF_CAUSE}"
    assert event.data == {"condition": "bus-off", "tx_error_counter": None, "rx_error_counter": None}


def test_an_adapter_whose_state_goes_to_error_trips_naming_where_the_state_came_from(config: MillConfig) -> None:
    channel = f"test-{uuid.uuid4().hex}"
    adapter = StatefulVirtualBus(channel=channel)
    node = can.Bus(interface="virtual", channel=channel)
    clock = ManualClock()
    events: list[Event] = []
    controller = Controller(config, adapter, clock, listener=events.append)
    codec = default_codec()
    try:
        for counter in range(4):  # the node seen, DISABLED
            for message in (
                NodeStatus(NodeState.DISABLED),
                DriveTelemetry(0.0, 0.0),
                FurnaceTelemetry(25.0, 25, 0, False),
            ):
                node.send(codec.encode(message, counter))
            controller.tick()
            clock.advance(0.05)
        assert state_of(controller) is ControllerState.DISABLED
        adapter.bus_state = can.BusState.PASSIVE
        controller.tick()
        assert state_of(controller) is ControllerState.DISABLED
        adapter.bus_state = can.BusState.ERROR
        controller.tick()
        assert state_of(controller) is ControllerState.TRIPPED
        source = "error frames and the adapter's bus.state"
        assert [e.message for e in bus_events(events)] == [
            f"CAN controller error-passive: {source}",
            f"CAN controller bus-off: {source}",
        ]
        assert f"({source}): the controller cannot send" in controller.trip_cause
    finally:
        adapter.shutdown()
        node.shutdown()
