"""The tests' ``virtual`` bus delivers what python-can's does, without deepcopy (tests/support/virtual_bus.py)."""

from __future__ import annotations

import uuid
from collections.abc import Iterator

import can
import pytest
from can.interfaces.virtual import VirtualBus as PythonCanVirtualBus

from tests.support import virtual_bus

FIELDS = tuple(name for name in can.Message.__slots__ if name != "__weakref__")
FRAMES = [
    can.Message(arbitration_id=0x123, is_extended_id=False, data=bytes(range(8)), timestamp=12.5),
    can.Message(arbitration_id=0x1ABCDE, is_extended_id=True, data=b"\x01", timestamp=13.0),
    can.Message(arbitration_id=0x7FF, is_extended_id=False, is_remote_frame=True, dlc=4, timestamp=14.0),
    can.Message(arbitration_id=0x55, is_extended_id=False, is_fd=True, bitrate_switch=True,
                error_state_indicator=True, data=bytes(range(64)), timestamp=15.0),
    can.Message(is_error_frame=True, data=b"\x00\x04", timestamp=16.0),
]  # fmt: skip


class Channel:
    """Buses of one class on a channel of their own; shut down after the test."""

    def __init__(self, cls: type[PythonCanVirtualBus]) -> None:
        self.cls = cls
        self.name = f"vbus-{uuid.uuid4().hex}"
        self.buses: list[can.BusABC] = []

    def bus(self, *, receive_own_messages: bool = False, preserve_timestamps: bool = False) -> can.BusABC:
        bus = self.cls(
            channel=self.name, receive_own_messages=receive_own_messages, preserve_timestamps=preserve_timestamps
        )
        self.buses.append(bus)
        return bus

    def close(self) -> None:
        for bus in self.buses:
            bus.shutdown()


@pytest.fixture(params=[PythonCanVirtualBus, virtual_bus.VirtualBus], ids=["python-can", "tests"])
def channel(request: pytest.FixtureRequest) -> Iterator[Channel]:
    """Each property below holds for python-can's bus and for the tests' alike."""
    ch = Channel(request.param)
    yield ch
    ch.close()


def fields(message: can.Message) -> dict[str, object]:
    return {name: getattr(message, name) for name in FIELDS}


def received(cls: type[PythonCanVirtualBus], frames: list[can.Message], *, echo: bool) -> list[dict[str, object]]:
    """The fields of what a second bus receives of ``frames`` sent by a first (then the first's echoes, with ``echo``).

    Both keep the frames' timestamps, so that every field compares.

    Each message's ``channel`` is given as whether it names the channel the buses share.
    """
    ch = Channel(cls)
    try:
        sender = ch.bus(receive_own_messages=echo, preserve_timestamps=True)
        receiver = ch.bus(preserve_timestamps=True)
        for frame in frames:
            sender.send(frame)
        got = list(iter(lambda: receiver.recv(0.0), None)) + list(iter(lambda: sender.recv(0.0), None))
        assert all(type(m) is can.Message for m in got), [type(m) for m in got]
        return [{**fields(m), "channel": m.channel == ch.name} for m in got]
    finally:
        ch.close()


@pytest.mark.parametrize("echo", [False, True], ids=["no-echo", "own-echo"])
def test_every_field_of_every_frame_arrives_as_python_cans_bus_delivers_it(echo: bool) -> None:
    ours = received(virtual_bus.VirtualBus, FRAMES, echo=echo)
    theirs = received(PythonCanVirtualBus, FRAMES, echo=echo)
    assert len(theirs) == len(FRAMES) * (2 if echo else 1)
    assert ours == theirs
    assert all(m["channel"] is True for m in ours)


def test_each_receiver_gets_a_message_of_its_own(channel: Channel) -> None:
    sender, one, other = channel.bus(), channel.bus(), channel.bus()
    sent = can.Message(arbitration_id=0x10, is_extended_id=False, data=b"\x01\x02\x03")
    sender.send(sent)
    first, second = one.recv(0.0), other.recv(0.0)
    assert first is not None and second is not None
    assert first is not second and first is not sent
    first.data[0] = 0xFF
    assert second.data == sent.data == bytearray(b"\x01\x02\x03")
    assert first.is_rx and second.is_rx and first.channel == second.channel == channel.name


def test_no_own_echo_unless_asked_and_then_it_is_not_rx(channel: Channel) -> None:
    quiet, echoing, listener = channel.bus(), channel.bus(receive_own_messages=True), channel.bus()
    quiet.send(can.Message(arbitration_id=1, is_extended_id=False))
    assert quiet.recv(0.0) is None
    echoing.recv(0.0)  # quiet's frame
    echoing.send(can.Message(arbitration_id=2, is_extended_id=False))
    echo = echoing.recv(0.0)
    assert echo is not None and echo.arbitration_id == 2 and not echo.is_rx
    assert [m.arbitration_id for m in iter(lambda: listener.recv(0.0), None)] == [1, 2]


def test_the_send_time_is_stamped_unless_timestamps_are_preserved(channel: Channel) -> None:
    stamping, preserving, listener = channel.bus(), channel.bus(preserve_timestamps=True), channel.bus()
    stamping.send(can.Message(arbitration_id=1, is_extended_id=False, timestamp=5.0))
    preserving.send(can.Message(arbitration_id=2, is_extended_id=False, timestamp=5.0))
    stamped, preserved = listener.recv(0.0), listener.recv(0.0)
    assert stamped is not None and preserved is not None
    assert stamped.timestamp > 5.0 and preserved.timestamp == 5.0


def test_an_empty_bus_times_out_and_a_shut_bus_refuses_to_send(channel: Channel) -> None:
    bus, other = channel.bus(), channel.bus()
    assert other.recv(0.01) is None
    bus.shutdown()
    with pytest.raises(can.CanOperationError):
        bus.send(can.Message(arbitration_id=1, is_extended_id=False))


def test_the_tests_virtual_interface_is_this_bus() -> None:
    """``can.Bus(interface="virtual")``, as the rigs and the product's ``open_bus`` ask for it, is the tests' bus."""
    bus = can.Bus(interface="virtual", channel=f"vbus-{uuid.uuid4().hex}")
    try:
        assert type(bus) is virtual_bus.VirtualBus
    finally:
        bus.shutdown()
