"""CAN error frames, error-passive and bus-off: seen, counted, shown in the status; bus-off trips with its reason.

The node and the controller on one virtual bus (``Rig``); the bystander bus
injects error frames in SocketCAN's layout (linux/can/error.h), as a real
``can0`` delivers them to a socket whose error mask is set (python-can's
socketcan driver sets it: ``ignore_rx_error_frames`` is refused by the
config). A bus whose ``state`` goes to ``can.BusState.ERROR`` stands for the
drivers that report the controller's state instead (ixxat, etas).
"""

from __future__ import annotations

import can

from millctl.api import BusCondition, EventKind, StatusOut
from millctl.config import MillConfig
from millctl.controller import ControllerState as S
from millctl.protocol.bus_health import CAN_ERR_BUSOFF, CAN_ERR_CNT, CAN_ERR_CRTL, CAN_ERR_PROT, CAN_ERR_RESTARTED
from tests.support.virtual_bus import StatefulVirtualBus
from tests.unit.scenarios.rig import Rig

LOW_RPM = (60.0, 300.0)


def error_frame(classes: int, crtl: int = 0, tec: int = 0, rec: int = 0) -> can.Message:
    """An error frame as SocketCAN delivers it: the classes in the identifier, TEC/REC in data[6], data[7]."""
    return can.Message(arbitration_id=classes, is_error_frame=True, is_extended_id=False,
                       data=bytes((0, crtl, 0, 0, 0, 0, tec, rec)))


def bus_events(rig: Rig) -> list[str]:
    return [e.data["condition"] for e in rig.events if e.kind is EventKind.BUS]


def test_error_passive_is_seen_counted_and_shown_without_a_trip(rig: Rig) -> None:
    rig.start(*LOW_RPM)
    for _ in range(5):
        rig.probe.send(error_frame(CAN_ERR_PROT, tec=8))
        rig.step()
    rig.probe.send(error_frame(CAN_ERR_CRTL | CAN_ERR_CNT, crtl=0x20, tec=136, rec=4))  # TX passive
    rig.run(0.5)
    assert rig.controller.state is S.RUNNING
    health = StatusOut.model_validate(rig.controller.status().as_dict()).bus_health
    assert health.condition is BusCondition.ERROR_PASSIVE
    assert (health.error_frames, health.bus_errors, health.controller_errors) == (6, 5, 1)
    assert (health.tx_error_counter, health.rx_error_counter, health.error_passive_count) == (136, 4, 1)
    assert bus_events(rig) == ["error-passive"]


def test_bus_off_error_frame_trips_the_controller_with_its_reason(rig: Rig) -> None:
    rig.start(*LOW_RPM)
    rig.probe.send(error_frame(CAN_ERR_BUSOFF))
    rig.run(0.2)
    assert rig.controller.state is S.TRIPPED
    assert rig.controller.trip_cause.startswith("CAN bus-off on virtual:millbus (error frame: bus-off")
    trips = [e for e in rig.events if e.kind is EventKind.TRIP]
    assert trips[0].source == "bus" and "docs/protocol.md#bus-errors" in trips[0].message
    health = rig.controller.status().bus_health
    assert health["condition"] == "bus-off" and health["bus_off_count"] == 1
    rig.probe.send(error_frame(CAN_ERR_RESTARTED))  # `ip link … restart-ms` brought the controller back
    rig.run(0.2)
    assert rig.controller.status().bus_health["condition"] == "error-active"
    assert rig.controller.state is S.TRIPPED, "a trip latches until reset, whatever the bus does after"
    assert bus_events(rig) == ["bus-off", "error-active"]


def test_a_bus_whose_state_goes_to_error_trips_the_controller(config: MillConfig) -> None:
    buses: list[StatefulVirtualBus] = []

    def open_stateful(channel: str) -> can.BusABC:
        buses.append(StatefulVirtualBus(channel=channel))
        return buses[-1]

    rig = Rig(config, controller_bus=open_stateful)
    try:
        rig.start(*LOW_RPM)
        assert rig.controller.status().bus_health["state_source"] == "error frames and the adapter's bus.state"
        buses[0].bus_state = can.BusState.PASSIVE
        rig.run(0.2)
        assert rig.controller.state is S.RUNNING
        assert rig.controller.status().bus_health["condition"] == "error-passive"
        buses[0].bus_state = can.BusState.ERROR
        rig.run(0.2)
        assert rig.controller.state is S.TRIPPED
        assert "CAN bus-off" in rig.controller.trip_cause
        assert bus_events(rig) == ["error-passive", "bus-off"]
    finally:
        rig.close()
