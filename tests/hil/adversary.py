"""The raw-CAN adversary of the hil tier: crafted frames on the bus under test (issue 15).

A fourth bus node, in the test process, that plays what a faulty bus or an
attacker puts on the wire: frames with a bad CRC, forged frames with a good
CRC, counter jumps, replays of recorded frames, a second sender answering a
genuine one, malformed frames and datagrams, and floods. It opens its bus
through the project's factory (so on udp_multicast it never hears itself);
on udp_multicast it can also send datagrams that are not frames at all.

Its send methods return the wall-clock time just before the first frame went
out, the clock of ``scenario_support.Probe``'s capture, from which the
scenarios measure reaction times.
"""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace

import can
import msgpack
from can.interfaces.udp_multicast.utils import pack_message

from millctl.config.models import Bus
from millctl.protocol import (
    BusReader,
    Codec,
    ControllerState,
    Decoded,
    Heartbeat,
    MillMessage,
    NodeStatus,
    ProtocolError,
    Setpoints,
    open_bus,
)
from tests.support.realtime import Role, start_thread

CAN_BITRATE = 500_000
"""The mill bus's bit rate (config/millbus.dbc)."""
FRAME_BITS = 135
"""An 8-byte standard frame with worst-case stuffing and the interframe space (docs/protocol.md, bus load)."""
MAX_FRAME_RATE_HZ = CAN_BITRATE / FRAME_BITS
"""The most frames a 500 kbit/s CAN bus carries per second (~3700): a flood at the bus's maximum rate."""
BURST_S = 0.005
"""A flood sends its frames in bursts this far apart (s)."""


def raw_frame(arbitration_id: int, data: bytes, **kwargs: object) -> can.Message:
    """A frame as a faulty or hostile sender puts it on the bus (python-can's own checks off)."""
    fields: dict[str, object] = {"is_extended_id": False, "check": False, **kwargs}
    return can.Message(arbitration_id=arbitration_id, data=data, **fields)  # type: ignore[arg-type]


@dataclass
class Background:
    """A sender running in a thread until stopped (a flood, a replay, a second sender)."""

    name: str
    sent: int = 0
    first_sent_t: float | None = None
    """Wall-clock time just before its first frame went out (None before)."""
    last_sent_t: float | None = None
    """Wall-clock time just after its last frame went out (None before; set by the senders that need it)."""
    refused: int = 0
    """Sends the interface refused (its transmit queue full)."""
    genuine_counter: int | None = None
    """The counter of the genuine frame a sender that waits for one heard (None before)."""
    _halt: threading.Event = field(default_factory=threading.Event)
    _thread: threading.Thread | None = None

    def start(self, body: Callable[[Background], None], *, realtime: Role | None = None) -> Background:
        """Run ``body`` on a thread; ``realtime``: at that role's real-time policy (tests.support.realtime)."""
        self._thread = threading.Thread(target=body, args=(self,), name=f"adversary-{self.name}", daemon=True)
        start_thread(self._thread, realtime=realtime)
        return self

    @property
    def halted(self) -> bool:
        return self._halt.is_set()

    def stop(self) -> int:
        """Stop the sender; return how many frames it sent."""
        self._halt.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        return self.sent


MAX_BACKLOG_DRAINS = 8
"""At most this many drains skip a backlog (each reads up to BusReader's bound)."""


class Adversary:
    """Crafted, forged, replayed and malformed frames, floods and a second sender, on one bus."""

    def __init__(self, bus_config: Bus, codec: Codec) -> None:
        self.bus_config = bus_config
        self.bus = open_bus(bus_config)
        self.codec = codec
        self._lock = threading.Lock()
        self._running: list[Background] = []

    # -- crafting --------------------------------------------------------------------------------------------
    def forged(self, message: MillMessage, counter: int = 0) -> can.Message:
        """A well-formed frame with a good CRC, from the wrong sender."""
        return self.codec.encode(message, counter)

    def bad_crc(self, message: MillMessage, counter: int = 0) -> can.Message:
        """The frame of ``message`` with its CRC byte inverted (every bit wrong)."""
        frame = self.codec.encode(message, counter)
        data = bytes([frame.data[0] ^ 0xFF]) + bytes(frame.data[1:])
        return raw_frame(frame.arbitration_id, data, dlc=len(data))

    def malformed(self) -> dict[str, can.Message]:
        """One frame of every malformed kind this transport can carry, each on an identifier someone reads."""
        frames = {
            "one byte on Command": raw_frame(0x010, b"\x01", dlc=1),
            "empty NodeStatus": raw_frame(0x100, b"", dlc=0),
            "two bytes on DriveTelemetry": raw_frame(0x110, b"\x00\x01", dlc=2),
            "remote frame on Heartbeat": raw_frame(0x020, b"", is_remote_frame=True, dlc=8),
            "extended identifier 0x30": raw_frame(0x030, bytes(8), is_extended_id=True, dlc=8),
            "unknown identifier 0x555": raw_frame(0x555, bytes(8), dlc=8),
        }
        if self.is_udp:  # a CAN controller reports these; on udp_multicast anyone can send one
            frames["error frame"] = raw_frame(0x020, bytes(8), is_error_frame=True, dlc=8)
        return frames

    def malformed_datagrams(self) -> dict[str, bytes]:
        """udp_multicast only: datagrams that no classic CAN bus carries, and some that are no frame at all."""
        return {
            "one byte": b"\x01",
            "a msgpack number": msgpack.packb(7),
            "a map that is no frame": msgpack.packb({"no": "frame"}),
            "DLC 3 with 8 bytes on Setpoints": pack_message(raw_frame(0x030, bytes(8), dlc=3)),
            "DLC 8 with 1 byte on Heartbeat": pack_message(raw_frame(0x020, b"\x00", dlc=8)),
            "FD frame on NodeStatus": pack_message(raw_frame(0x100, bytes(12), is_fd=True, dlc=12)),
        }

    @property
    def is_udp(self) -> bool:
        """True on udp_multicast, where datagrams that are not frames can be sent too."""
        return "udp_multicast" in self.bus_config.interface

    # -- sending ---------------------------------------------------------------------------------------------
    def send(self, *frames: can.Message) -> float:
        """Send frames back to back; return the wall-clock time just before the first went out."""
        t = time.time()
        with self._lock:
            for frame in frames:
                self.bus.send(frame)
        return t

    def datagrams(self, *payloads: bytes) -> float:
        """udp_multicast only: datagrams to the group that are not frames at all (TTL 0, like the bus)."""
        assert self.is_udp, "datagrams exist only on udp_multicast"
        port = int(self.bus_config.options["port"])
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 0)
            t = time.time()
            for payload in payloads:
                sock.sendto(payload, (self.bus_config.channel, port))
        return t

    # -- background senders ------------------------------------------------------------------------------------
    def _background(self, name: str, body: Callable[[Background], None], *, realtime: Role | None = None) -> Background:
        sender = Background(name).start(body, realtime=realtime)
        self._running.append(sender)
        return sender

    def flood(self, frame: can.Message, rate_hz: float = MAX_FRAME_RATE_HZ) -> Background:
        """Send ``frame`` over and over at ``rate_hz`` (in bursts every ``BURST_S``) until stopped."""

        def body(sender: Background) -> None:
            start, credit = time.monotonic(), 0.0
            while not sender.halted:
                due = rate_hz * (time.monotonic() - start) - sender.sent
                # never more than 0.1 s of frames at once after a stall, and at least one when one is due (below
                # 10 frames/s, as the VM's slowed flood can be, 0.1 s of frames rounded down to none: nothing was sent)
                credit = min(due, max(rate_hz * 0.1, 1.0))
                with self._lock:
                    for _ in range(int(credit)):
                        try:
                            self.bus.send(frame)
                        except can.CanError:  # the interface's queue is full: the bus is saturated
                            sender.refused += 1
                            break
                        sender.sent += 1
                time.sleep(BURST_S)

        return self._background(f"flood-0x{frame.arbitration_id:03X}", body)

    def replay(self, frames: list[can.Message], period_s: float) -> Background:
        """Send the recorded ``frames`` in a loop, one every ``period_s``, until stopped."""

        def body(sender: Background) -> None:
            next_s = time.monotonic()
            while not sender.halted:
                self.send(frames[sender.sent % len(frames)])
                sender.sent += 1
                next_s += period_s
                time.sleep(max(next_s - time.monotonic(), 0.0))

        return self._background("replay", body)

    def walk(self, start: Setpoints, step_rpm: tuple[float, float], frames_per_burst: int = 5) -> Background:
        """A fast forger: Setpoints frames with fresh counters, each ``step_rpm`` past the last, ``frames_per_burst``
        at a time every ``BURST_S`` (1000 frames/s by default), until stopped.

        It listens first, as an attacker on the bus would, and starts the moment it hears the controller's next
        Setpoints frame, with that frame's counter + 1 (the socket's backlog is dropped first, so the frame is a
        new one). Started at a random moment instead, the controller's next frame could land inside the forger's
        burst with a counter that happens to be fresh (+1 … +3 past the forged one, 3 chances in 16) while the
        node's rate bound still had room for the step back: the node took it and undid the forgery within
        milliseconds, the drive moved less than the measurement tolerance, so the measured speeds rightly showed
        nothing, and the 0.3 s attack, with a genuine frame or two inside it, was too short for the link check
        (SAFETY 17) to fault. Seen once in the VM, where the scaled watchdog makes the burst some 40 frames
        long and the scaled setpoint period 0.7 s; tests/unit/scenarios/test_fast_forger.py shows both cases.
        Timed this way the next genuine frame comes a setpoint period later, when the burst is spent and the
        node refuses the step back.
        """
        self.skip_backlog()

        def body(sender: Background) -> None:
            heard = next(iter(self._heard(sender, (Setpoints,))), None)
            if heard is None or heard.counter is None:  # stopped before the controller sent one
                return
            sender.genuine_counter = heard.counter
            while not sender.halted:
                frames: list[can.Message] = []
                for _ in range(frames_per_burst):
                    k = sender.sent + len(frames) + 1
                    ask = replace(
                        start,
                        rotary_rpm=round(start.rotary_rpm + k * step_rpm[0], 1),
                        vibration_rpm=round(start.vibration_rpm + k * step_rpm[1], 1),
                    )
                    frames.append(self.forged(ask, (heard.counter + k) % 16))
                t = self.send(*frames)
                sender.first_sent_t = sender.first_sent_t or t
                sender.last_sent_t = time.time()
                sender.sent += len(frames)
                time.sleep(BURST_S)

        return self._background("walk", body)

    def answer(self, kinds: tuple[type[MillMessage], ...], forge: Callable[[Decoded], MillMessage]) -> Background:
        """A second sender: every genuine frame of ``kinds`` heard is answered at once with ``forge``, counter + 1.

        It stands in for a device on the bus, and the trip's bound assumes it answers within a frame
        period: it runs at the service's and node's real-time policy where they have one, so that a
        CPU hog delays neither side. (It blocks in ``recv`` between frames: it never spins.) It answers
        what it hears from now on: the socket's backlog, queued while the mill started, is dropped first
        (answered, it came out as a burst of a few hundred old counters within milliseconds, in the VM
        more than the probe's socket queue held: seen, the probe missing frames of the evidence that the
        candump capture had).
        """
        self.skip_backlog()

        def body(sender: Background) -> None:
            for decoded in self._heard(sender, kinds):
                if decoded.counter is not None:
                    t = self.send(self.forged(forge(decoded), (decoded.counter + 1) % 16))
                    sender.first_sent_t = sender.first_sent_t or t
                    sender.sent += 1

        return self._background("second-sender", body, realtime="node")  # a device on the bus, like the node

    def keep_alive(self, silent_after_s: float) -> Background:
        """A heartbeat forger that takes over once the controller falls silent (SAFETY 26's attacker).

        While it hears the controller's heartbeats it only follows their alive counter. Once none has come for
        ``silent_after_s``, it answers every NodeStatus with a Heartbeat echoing that status's challenge and the
        counter the controller's next one would carry: each is fresh to the node, so the watchdog stays fed.
        It sends no Setpoints.
        """
        self.skip_backlog()

        def body(sender: Background) -> None:
            counter: int | None = None
            last_genuine_s = time.monotonic()
            for decoded in self._heard(sender, (Heartbeat, NodeStatus)):
                message = decoded.message
                if isinstance(message, Heartbeat) and decoded.counter is not None:
                    if counter is None or decoded.counter != (counter - 1) % 16:  # not our own echo
                        counter, last_genuine_s = (decoded.counter + 1) % 16, time.monotonic()
                        sender.genuine_counter = decoded.counter
                elif (isinstance(message, NodeStatus) and counter is not None
                      and time.monotonic() - last_genuine_s >= silent_after_s):
                    t = self.send(self.forged(Heartbeat(ControllerState.RUNNING, message.challenge), counter))
                    counter = (counter + 1) % 16
                    sender.first_sent_t = sender.first_sent_t or t
                    sender.sent += 1

        return self._background("keep-alive", body, realtime="node")

    def skip_backlog(self) -> int:
        """Read and drop every frame queued on the adversary's socket (heard before now); return how many.

        The socket queues all it hears from the moment it opens, and nothing reads it while the mill
        starts. In the VM that start lasts long enough for the kernel to drop frames from the full queue
        (seen: a "recording" of 16 heartbeats from three moments of the start, their alive counters
        jumping where frames were dropped)."""
        reader = BusReader(self.bus, "adversary")
        skipped = 0
        for _ in range(MAX_BACKLOG_DRAINS):  # bounded: a flood never runs dry and must not stall a recording
            capped = reader.counts.capped_drains
            skipped += len(reader.drain().frames)
            if reader.counts.capped_drains == capped:  # this drain reached the queue's end
                break
        return skipped

    def record(self, kind: type[MillMessage], count: int, timeout_s: float) -> list[can.Message]:
        """The next ``count`` frames of ``kind`` heard on the bus from now on, as they were (for a replay)."""
        self.skip_backlog()
        recording: list[can.Message] = []
        deadline = time.monotonic() + timeout_s
        while len(recording) < count and time.monotonic() < deadline:
            frame = self.bus.recv(0.05)
            if frame is None:
                continue
            try:
                if self.codec.decode(frame).kind is kind:
                    recording.append(frame)
            except ProtocolError:
                continue
        return recording

    def _heard(self, sender: Background, kinds: tuple[type[MillMessage], ...]) -> Iterable[Decoded]:
        while not sender.halted:
            frame = self.bus.recv(0.05)
            if frame is None:
                continue
            try:
                decoded = self.codec.decode(frame)
            except ProtocolError:
                continue
            if decoded.kind in kinds and decoded.crc_ok:
                yield decoded

    def close(self) -> None:
        """Stop every background sender and shut the bus down."""
        for sender in self._running:
            sender.stop()
        self.bus.shutdown()


__all__ = ["MAX_FRAME_RATE_HZ", "Adversary", "Background", "raw_frame"]
