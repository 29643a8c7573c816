"""The bus reader: drains everything, reports the E-stop apart, and never raises for bus input (SAFETY 19, 22)."""

from __future__ import annotations

import uuid
from collections.abc import Iterator

import can
import pytest

from millctl.config.models import Bus
from millctl.protocol import ESTOP_ID, BusReader, Command, CommandCode, default_codec, estop_channel_kwargs


@pytest.fixture
def pair() -> Iterator[tuple[can.BusABC, can.BusABC]]:
    channel = f"receive-{uuid.uuid4().hex}"
    buses = can.Bus(interface="virtual", channel=channel), can.Bus(interface="virtual", channel=channel)
    yield buses
    for bus in buses:
        bus.shutdown()


def frame(arbitration_id: int, data: bytes = bytes(8), **kwargs: object) -> can.Message:
    return can.Message(arbitration_id=arbitration_id, data=data, is_extended_id=False, **kwargs)  # type: ignore[arg-type]


class FlakyBus(can.BusABC):
    """Hands out a script of frames and exceptions, one per recv, then None."""

    def __init__(self, script: list[can.Message | BaseException]) -> None:
        self.script = list(script)
        self.reads = 0
        super().__init__(channel="flaky")

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        self.reads += 1
        if not self.script:
            return None, True
        item = self.script.pop(0)
        if isinstance(item, BaseException):
            raise item
        return item, True

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        raise AssertionError("the reader never sends")


class BrokenBus(FlakyBus):
    """A socket that fails on every read."""

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        self.reads += 1
        raise OSError(9, "Bad file descriptor")


def test_a_drain_reads_every_frame_waiting_and_the_estop_behind_a_babble(pair: tuple[can.BusABC, can.BusABC]) -> None:
    sender, receiver = pair
    for _ in range(1000):
        sender.send(frame(0x001))
    sender.send(frame(ESTOP_ID, b"\x02"))
    sender.send(frame(0x001))
    reader = BusReader(receiver, "test")
    batch = reader.drain()
    assert batch.estop
    assert len(batch.frames) == 1001 and all(f.arbitration_id == 0x001 for f in batch.frames)
    assert reader.counts.frames == 1002 and reader.counts.estops == 1
    assert reader.drain() == type(batch)(estop=False, frames=[])


def test_receive_errors_are_counted_and_the_drain_reads_on_to_the_estop() -> None:
    codec = default_codec()
    command = codec.encode(Command(CommandCode.STOP), 1)
    errors: list[can.Message | BaseException] = [
        can.CanOperationError("undecodable datagram of 1 bytes"),
        OSError(104, "Connection reset by peer"),
        ValueError("DLC 8 for 1 byte of data"),
    ]
    bus = FlakyBus([*errors, command, frame(ESTOP_ID, b""), *errors])
    reader = BusReader(bus, "test")
    batch = reader.drain()
    assert batch.estop and batch.frames == [command]
    assert reader.counts.receive_errors == 6 and reader.counts.estops == 1
    assert "ValueError" in reader.counts.last_error
    bus.shutdown()


def test_a_broken_socket_ends_the_drain_for_this_tick_without_raising() -> None:
    bus = BrokenBus([])
    reader = BusReader(bus, "test", max_consecutive_errors=8)
    for _ in range(3):
        assert reader.drain().frames == []
    assert bus.reads == 24 and reader.counts.receive_errors == 24
    assert "Bad file descriptor" in reader.counts.last_error
    bus.shutdown()


def test_error_frames_are_counted_and_never_an_estop() -> None:
    error = can.Message(arbitration_id=ESTOP_ID, is_error_frame=True, data=bytes(8))
    bus = FlakyBus([error, frame(0x110)])
    reader = BusReader(bus, "test")
    batch = reader.drain()
    assert not batch.estop and [f.arbitration_id for f in batch.frames] == [0x110]
    assert reader.counts.error_frames == 1
    bus.shutdown()


def test_a_flood_beyond_the_bound_is_read_over_the_next_ticks_and_counted(
    pair: tuple[can.BusABC, can.BusABC],
) -> None:
    sender, receiver = pair
    for _ in range(25):
        sender.send(frame(0x001))
    sender.send(frame(ESTOP_ID))
    reader = BusReader(receiver, "test", max_frames=10)
    assert [reader.drain().estop for _ in range(3)] == [False, False, True]
    assert reader.counts.capped_drains == 2 and reader.counts.frames == 26


def test_malformed_frames_are_counted_with_what_they_were() -> None:
    bus = FlakyBus([])
    reader = BusReader(bus, "test")
    reader.malformed(frame(0x123, b"\x01"), "unknown identifier")
    assert reader.counts.malformed == 1 and reader.counts.last_error == "malformed frame: 0x123: unknown identifier"
    assert reader.counts.as_dict()["malformed"] == 1
    with pytest.raises(ValueError, match="must both be ≥ 1"):
        BusReader(bus, "test", max_frames=0)
    bus.shutdown()


# --- the E-stop channel: a queue of its own (SocketCAN's kernel filter) ------------------------------------------


class KernelQueue(can.BusABC):
    """A socket's receive queue as the kernel keeps it: bounded, a frame that arrives when it is full is dropped."""

    def __init__(self, capacity: int, accepts: int | None = None) -> None:
        self.queue: list[can.Message] = []
        self.capacity = capacity
        self.accepts = accepts
        """The only identifier this socket's filter lets in (None: every frame)."""
        self.dropped = 0
        super().__init__(channel="kernel-queue")

    def deliver(self, message: can.Message) -> None:
        """The bus carried ``message``: the kernel queues it for this socket, if it passes the filter and fits."""
        if self.accepts is not None and message.arbitration_id != self.accepts:
            return
        if len(self.queue) >= self.capacity:
            self.dropped += 1
            return
        self.queue.append(message)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        return (self.queue.pop(0) if self.queue else None), True

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        raise AssertionError("the reader never sends")


def test_an_estop_sent_into_a_flood_that_filled_the_queue_is_read_on_the_estop_channel() -> None:
    main, estops = KernelQueue(capacity=100), KernelQueue(capacity=100, accepts=ESTOP_ID)
    for message in [frame(0x001)] * 500 + [frame(ESTOP_ID, b"\x02")] + [frame(0x001)] * 500:
        main.deliver(message)
        estops.deliver(message)
    assert main.dropped == 901  # the E-stop among them: the main queue alone would have lost it
    reader = BusReader(main, "test", estop_bus=estops, max_frames=50)
    batch = reader.drain()
    assert batch.estop and len(batch.frames) == 50
    assert reader.estop_channel_frames == 1 and reader.counts.estops == 0  # never reached the main queue
    main.shutdown()
    estops.shutdown()


def test_an_estop_that_arrives_during_a_long_drain_is_reported_by_that_drain() -> None:
    estops = KernelQueue(capacity=10, accepts=ESTOP_ID)

    class Flood(FlakyBus):
        def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
            if self.reads == 500:  # half way through the drain the button is pressed
                estops.deliver(frame(ESTOP_ID))
            return super()._recv_internal(timeout)

    main = Flood([frame(0x001)] * 1000)
    batch = BusReader(main, "test", estop_bus=estops).drain()
    assert batch.estop and len(batch.frames) == 1000
    main.shutdown()
    estops.shutdown()


def test_the_estop_channel_never_raises_and_its_errors_are_counted() -> None:
    main, broken = FlakyBus([frame(0x110)]), BrokenBus([])
    reader = BusReader(main, "test", estop_bus=broken, max_consecutive_errors=4)
    batch = reader.drain()
    assert not batch.estop and [f.arbitration_id for f in batch.frames] == [0x110]
    assert broken.reads == 8 and reader.counts.receive_errors == 8  # 4 before the main drain, 4 after
    assert "E-stop channel" in reader.counts.last_error
    main.shutdown()
    broken.shutdown()


def test_the_estop_channel_filter_is_one_python_can_applies() -> None:
    kwargs = estop_channel_kwargs(Bus(interface="socketcan", channel="vcan0"))
    assert kwargs is not None and kwargs["interface"] == "socketcan" and kwargs["channel"] == "vcan0"
    name = f"estop-{uuid.uuid4().hex}"  # python-can's virtual bus applies the same filters in software
    sender = can.Bus(interface="virtual", channel=name)
    channel = can.Bus(interface="virtual", channel=name, can_filters=kwargs["can_filters"])
    try:
        extended_zero = can.Message(arbitration_id=ESTOP_ID, data=bytes(8), is_extended_id=True)
        for message in (frame(0x001), frame(ESTOP_ID), frame(0x010), extended_zero):
            sender.send(message)
        received = [channel.recv(0.0) for _ in range(4)]
        assert [m.arbitration_id for m in received if m is not None] == [ESTOP_ID]
    finally:
        channel.shutdown()
        sender.shutdown()


@pytest.mark.parametrize("interface", ["virtual", "udp_multicast"])
def test_no_estop_channel_where_filters_are_not_in_the_kernel(interface: str) -> None:
    # every socket gets every datagram on udp_multicast: a second one would read the whole bus again
    assert estop_channel_kwargs(Bus(interface=interface, channel="239.0.0.1")) is None
