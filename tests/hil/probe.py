"""The hil scenarios' bus probe: the third bus node of a scenario, in the test process.

``Probe`` injects faults, plays the rogue sender and the E-stop button, and
captures every frame with its receive timestamp (the kernel's, on
udp_multicast and socketcan), from which each scenario measures its reaction
time; ``Seen`` is one captured frame, and the ``is_*`` predicates select them.
Split out of :mod:`tests.hil.scenario_support`, which re-exports every name.
"""

from __future__ import annotations

import math
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar

import can
import pytest

from millctl.config.models import Bus
from millctl.protocol import (
    Codec,
    Command,
    CommandCode,
    Decoded,
    FaultCode,
    MillMessage,
    NodeState,
    NodeStatus,
    ProtocolError,
    SimFault,
    SimFaultCode,
    open_bus,
)
from millctl.protocol.e2e import E2EReceiver
from tests.hil.conftest import IN_VM
from tests.support.pace import time_scale

SO_RCVBUFFORCE = getattr(socket, "SO_RCVBUFFORCE", 33)
"""Linux's ``SO_RCVBUFFORCE`` (33; Python names it only where the platform headers do)."""

M = TypeVar("M", bound=MillMessage)

POLL_S = 0.02
"""How often the wait helpers look again (s), times ``bound_scale()``: in the VM each status request costs the
service (whose control loop shares its process) the measured factor times the host's CPU, so polling at the
host's rate would load the process under test that much more."""


def bound_scale() -> float:
    """The factor on every safety bound: ``time_scale()`` inside the VM, 1 on the host (the tight bounds)."""
    return time_scale() if IN_VM else 1.0


# --- the probe ------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Seen:
    """One frame the probe captured: its receive time (s, wall clock), the raw frame and its decoding."""

    t: float
    frame: can.Message
    decoded: Decoded | None
    """None for frames the codec does not know (babble) or cannot read."""

    @property
    def message(self) -> MillMessage | None:
        """The decoded message; None when unknown or its CRC failed."""
        return self.decoded.message if self.decoded is not None else None

    def of(self, kind: type[M]) -> M:
        """The decoded message, which the caller has selected as a ``kind`` (fails the test if it is not one)."""
        message = self.message
        assert isinstance(message, kind), f"expected a {kind.__name__} frame, the probe saw {message!r}"
        return message

    @property
    def crc_failed(self) -> bool:
        """True for an E2E-protected frame whose CRC did not check."""
        return self.decoded is not None and not self.decoded.crc_ok


def is_status(state: NodeState | None = None, first_fault: FaultCode | None = None) -> Callable[[Seen], bool]:
    """A predicate: a NodeStatus (in ``state``, with ``first_fault``)."""

    def check(seen: Seen) -> bool:
        m = seen.message
        return (
            isinstance(m, NodeStatus)
            and (state is None or m.state is state)
            and (first_fault is None or FaultCode(m.first_fault) is first_fault)
        )

    return check


def is_command(code: CommandCode) -> Callable[[Seen], bool]:
    """A predicate: a Command frame with ``code``."""
    return lambda seen: isinstance(seen.message, Command) and seen.message.command is code


def is_kind(kind: type[MillMessage]) -> Callable[[Seen], bool]:
    """A predicate: a frame of this kind, decoded or not (a corrupted frame still has its identifier)."""
    return lambda seen: seen.decoded is not None and seen.decoded.kind is kind


def sequence_limit_reached_at(
    seen: list[Seen], limit: int, decay_frames: int, min_decay_s: float = 0.0
) -> float | None:
    """When the frames ``seen`` on one identifier first give a sequence score of ``limit`` (s), as sent or as received.

    The score is the receiver's own (SAFETY 17, :class:`~millctl.protocol.e2e.E2EReceiver`, with the
    controller's ``min_decay_s`` for the identifier), fed the frames with a good CRC and a counter at their
    capture times. Two orders are judged, and the earlier moment is the evidence (None while neither
    reaches the limit): the order the probe received them in, and the order of their kernel
    timestamps, which is the order they were sent in. On a CAN wire the two are one. On vcan, frames from
    senders on different CPUs reach each socket in the order those CPUs' soft interrupts deliver them, so
    every receiver, the controller's included, may see its own order (seen in the VM: a forged counter 2
    received before the genuine 1 stamped 1.8 ms earlier, and the probe's score resynchronised on it).
    """
    moments = [
        _limit_reached_at(order, E2EReceiver(limit, sequence_decay_frames=decay_frames, min_decay_s=min_decay_s))
        for order in (seen, sorted(seen, key=lambda s: s.t))
    ]
    return min((t for t in moments if t is not None), default=None)


def _limit_reached_at(seen: list[Seen], receiver: E2EReceiver) -> float | None:
    """When the frames ``seen``, in this order, first bring ``receiver``'s sequence score to its limit (s)."""
    limit = receiver.error_limit
    for s in seen:
        if s.decoded is not None and s.decoded.crc_ok and s.decoded.counter is not None:
            receiver.classify(s.decoded.counter, crc_ok=True, now_s=s.t)
            if receiver.sequence_score >= limit:
                return s.t
    return None


PROBE_RECEIVE_QUEUE_BYTES = 4 * 2**20
"""The probe's socket receive queue on SocketCAN (bytes; udp_multicast's bus sizes its own, millctl.protocol.udp).

The kernel's default (``net.core.rmem_default``, ~208 KiB: a few hundred frames) is what the test process
may fall behind by when it stalls under emulation, and a frame the probe misses is evidence it lacks."""


def deepen_receive_queue(bus: can.BusABC, size_bytes: int = PROBE_RECEIVE_QUEUE_BYTES) -> int | None:
    """Ask the kernel for a receive queue of ``size_bytes`` on a SocketCAN bus; return what it granted (None: not one).

    ``SO_RCVBUFFORCE`` passes ``net.core.rmem_max`` where the process may (root in the VM; the namespace's owner);
    elsewhere ``SO_RCVBUF`` gets what the cap allows.
    """
    sock = getattr(bus, "socket", None)
    if not isinstance(sock, socket.socket):
        return None
    try:
        sock.setsockopt(socket.SOL_SOCKET, SO_RCVBUFFORCE, size_bytes)
    except OSError:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, size_bytes)
    granted: int = sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
    return granted


class Probe:
    """The third bus: a capture thread that timestamps every frame, and a sender (faults, rogue frames, E-stop).

    It is opened by the project's bus factory, so on udp_multicast it does not
    hear its own frames (like a real CAN controller).
    """

    def __init__(self, bus_config: Bus, codec: Codec) -> None:
        self.bus = open_bus(bus_config)
        deepen_receive_queue(self.bus)
        self.codec = codec
        self._seen: list[Seen] = []
        self._lock = threading.Lock()
        self._halt = threading.Event()
        self._thread = threading.Thread(target=self._capture, name="hil-probe", daemon=True)
        self._thread.start()

    def _capture(self) -> None:
        while not self._halt.is_set():
            try:
                frame = self.bus.recv(0.05)
            except (can.CanError, OSError):  # a datagram that is no frame (the adversary's): not ours to judge
                continue
            if frame is None:
                continue
            try:
                decoded: Decoded | None = self.codec.decode(frame)
            except ProtocolError:
                decoded = None
            t = frame.timestamp or time.time()
            with self._lock:
                self._seen.append(Seen(t, frame, decoded))

    def send(self, message: MillMessage, counter: int = 0) -> float:
        """Send one message; return the wall-clock time just before it went out (s)."""
        frame = self.codec.encode(message, counter)
        t = time.time()
        self.bus.send(frame)
        return t

    def inject(self, fault: SimFaultCode, param: float = 0.0, active: bool = True) -> float:
        """Send a SimFault frame to the node (fault injection); return when it was sent."""
        return self.send(SimFault(fault, active, param))

    def frames(self, after: float = -math.inf, where: Callable[[Seen], bool] | None = None) -> list[Seen]:
        """Captured frames received after ``after`` (s) matching ``where``, in order."""
        with self._lock:
            seen = list(self._seen)
        return [s for s in seen if s.t > after and (where is None or where(s))]

    def forget(self) -> None:
        """Drop what was captured so far: a scenario handed a shared mill (tests/hil/mill_pool.py) sees its own."""
        with self._lock:
            self._seen.clear()

    def now(self) -> float:
        """The capture's clock (s, wall clock)."""
        return time.time()

    def wait_first(self, where: Callable[[Seen], bool], after: float, timeout_s: float, what: str) -> Seen:
        """The first frame after ``after`` matching ``where``, waiting up to ``timeout_s`` for it to arrive."""
        deadline = time.monotonic() + timeout_s
        while True:
            found = self.frames(after, where)
            if found:
                return found[0]
            if time.monotonic() > deadline:
                pytest.fail(f"the probe saw no {what} within {timeout_s:.1f} s; {self.describe_since(after)}")
            time.sleep(POLL_S * bound_scale())

    def describe_since(self, after: float) -> str:
        """What the probe captured after ``after``: how many frames, and the node's state in its newest NodeStatus."""
        seen = self.frames(after)
        count = f"{len(seen)} frame{'' if len(seen) == 1 else 's'}"
        statuses = [s for s in seen if isinstance(s.message, NodeStatus)]
        if not statuses:
            return f"it captured {count} since, no NodeStatus among them"
        newest = statuses[-1]
        status = newest.of(NodeStatus)
        return (
            f"it captured {count} since, {len(statuses)} NodeStatus; the newest, at "
            f"+{newest.t - after:.2f} s: {status.state.name}, first fault {FaultCode(status.first_fault).name}, "
            f"fault bits {status.fault_bits!r}"
        )

    def latest(self, kind: type[MillMessage]) -> Any:
        """The newest decoded message of ``kind`` (None before the first)."""
        found = self.frames(where=lambda s: isinstance(s.message, kind))
        return found[-1].message if found else None

    def close(self) -> None:
        """Stop capturing and shut the bus down."""
        self._halt.set()
        self._thread.join(timeout=5.0)
        self.bus.shutdown()


