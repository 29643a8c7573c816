"""The bus health monitor: every error class counted, the condition followed, the state read only where it means it."""

from __future__ import annotations

import uuid
from collections.abc import Iterator

import can
import pytest

from millctl.api import BusCondition
from millctl.protocol.bus_health import (
    CAN_ERR_ACK,
    CAN_ERR_BUSERROR,
    CAN_ERR_CRTL,
    CAN_ERR_LOSTARB,
    CAN_ERR_PROT,
    CAN_ERR_TX_TIMEOUT,
    BusHealthMonitor,
    adapter_of,
)


@pytest.fixture
def virtual() -> Iterator[can.BusABC]:
    bus = can.Bus(interface="virtual", channel=f"health-{uuid.uuid4().hex}")
    yield bus
    bus.shutdown()


def frame(classes: int, crtl: int = 0, tec: int = 0, rec: int = 0) -> can.Message:
    return can.Message(arbitration_id=classes, is_error_frame=True, is_extended_id=False,
                       data=bytes((0, crtl, 0, 0, 0, 0, tec, rec)))


def test_each_class_lands_in_its_count_and_prot_with_buserror_is_one_bus_error(virtual: can.BusABC) -> None:
    monitor = BusHealthMonitor(virtual, "socketcan")
    for classes in (CAN_ERR_PROT | CAN_ERR_BUSERROR, CAN_ERR_ACK, CAN_ERR_LOSTARB, CAN_ERR_TX_TIMEOUT):
        assert monitor.on_error_frame(frame(classes)) is None
    health = monitor.health
    assert (health.error_frames, health.bus_errors, health.ack_errors) == (4, 1, 1)
    assert (health.arbitration_lost, health.tx_timeouts) == (1, 1)
    assert health.last_error == "error frame: TX timeout (class 0x001)"


def test_warning_passive_and_recovery_each_change_the_condition_once(virtual: can.BusABC) -> None:
    monitor = BusHealthMonitor(virtual, "socketcan")
    seen = [monitor.on_error_frame(frame(CAN_ERR_CRTL, crtl=c, tec=t)) for c, t in
            ((0x08, 96), (0x08, 100), (0x20, 128), (0x20, 130), (0x40, 0))]
    assert seen == [BusCondition.ERROR_WARNING, None, BusCondition.ERROR_PASSIVE, None, BusCondition.ERROR_ACTIVE]
    assert monitor.health.error_passive_count == 1 and monitor.health.tx_error_counter == 0


def test_vendor_error_frames_are_counted_unclassified(virtual: can.BusABC) -> None:
    monitor = BusHealthMonitor(virtual, "kvaser")
    assert monitor.on_error_frame(frame(0x40)) is None  # 0x40 is bus-off only in SocketCAN's layout
    assert monitor.health.error_frames == 1 and monitor.health.condition is BusCondition.ERROR_ACTIVE


class FakePcan(can.BusABC):
    """PCAN's driver: ``status()`` is the controller's condition; ``state`` is the listen-only switch."""

    def __init__(self) -> None:
        self.code = 0
        super().__init__(channel="PCAN_USBBUS1")

    def status(self) -> int:
        return self.code

    @property
    def state(self) -> can.BusState:
        raise AssertionError("pcan's state is the listen-only switch: it must never be read as the condition")

    @state.setter
    def state(self, new_state: can.BusState) -> None:
        raise AssertionError("the controller must never switch pcan's listen-only mode")

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        raise NotImplementedError

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        return None, False


@pytest.mark.parametrize(("code", "condition"), [(0x8, "error-warning"), (0x40000, "error-passive"), (0x10, "bus-off")])
def test_pcan_status_is_read_and_its_state_never(code: int, condition: str) -> None:
    bus = FakePcan()
    monitor = BusHealthMonitor(bus, "pcan")
    assert monitor.poll() is None
    bus.code = code
    assert monitor.poll() == condition
    assert monitor.poll() is None, "a condition is reported once"
    assert monitor.health.state_source == "error frames and PCAN status()"


def test_wrapped_buses_are_unwrapped_to_the_adapter() -> None:
    class Wrapper(can.BusABC):
        def __init__(self, inner: can.BusABC) -> None:
            self.inner = inner
            super().__init__(channel="w")

        def send(self, msg: can.Message, timeout: float | None = None) -> None:
            raise NotImplementedError

        def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
            return None, False

    adapter = FakePcan()
    assert adapter_of(Wrapper(Wrapper(adapter))) is adapter
