"""Reading the bus: every frame waiting, the E-stop first, and no input that can stop the reader.

Both control loops (the controller's and the node's) read their bus once per
tick through a :class:`BusReader` (SAFETY.md items 19 and 22):

- **Drain fully.** ``drain()`` reads until the bus has nothing left (a
  ``recv(timeout=0)`` that returns None), so a busy bus delays a loop by at
  most one tick. It stops early only at ``max_frames`` reads in one drain (a
  flood faster than the loop can read; counted as ``capped_drains``), so the
  tick itself stays bounded; the rest is read the next tick.
- **E-stop first.** Frames with the E-stop identifier (``ESTOP_ID``, any
  length, any content, any sender; not error frames) are reported as
  ``Batch.estop`` apart from the rest, so the caller acts on them before
  anything else read in the same drain.
- **An E-stop channel of its own.** Where the interface filters in the kernel
  (SocketCAN), the loops also read a second socket that carries the E-stop
  identifier only (``estop_bus``, :func:`~millctl.protocol.factory.open_estop_channel`),
  before and after the main drain. Each socket has its own receive queue, so
  a flood the loop cannot keep up with fills the main queue, drops frames
  there, and cannot drop an E-stop (seen in the vcan VM: a flood on 0x001
  faster than the node could read lost the one E-stop sent into it).
- **No input kills the reader.** A receive error (``can.CanError`` or
  ``OSError`` from the interface, e.g. an undecodable datagram or a socket
  error) is counted, logged and skipped: the drain goes on with the next
  frame, and gives up for this tick only after ``max_consecutive_errors``
  errors in a row (a broken socket must not spin the loop). Error frames are
  counted apart. Frames that arrive but do not fit the DBC are counted by
  the caller through :meth:`BusReader.malformed`.

Logging is bounded: the 1st, 2nd, 4th, 8th … occurrence of each kind is
logged at WARNING with its count, the others at DEBUG.
"""

from __future__ import annotations

import logging
from dataclasses import asdict, dataclass, field

import can

from millctl.protocol.messages import ESTOP_ID

log = logging.getLogger(__name__)

MAX_FRAMES_PER_DRAIN = 4096
"""At most this many reads in one drain (at 500 kbit/s a CAN bus carries at most ~3700 frames/s)."""
MAX_CONSECUTIVE_ERRORS = 64
"""A drain gives up for this tick after this many receive errors in a row."""


def is_estop(frame: can.Message) -> bool:
    """True for any frame with the E-stop identifier (whatever its length or content), except error frames."""
    return frame.arbitration_id == ESTOP_ID and not frame.is_error_frame


def _power_of_two(count: int) -> bool:
    return count & (count - 1) == 0


@dataclass
class ReceiveCounts:
    """What a reader has seen since it was made (all counts since start)."""

    frames: int = 0
    """Frames read (E-stops and error frames included)."""
    estops: int = 0
    """Frames with the E-stop identifier."""
    malformed: int = 0
    """Frames that do not fit the DBC (unknown ID, length, DLC, FD, remote, value), as told by the caller."""
    error_frames: int = 0
    """CAN error frames reported by the interface."""
    receive_errors: int = 0
    """Reads that raised (undecodable datagram, socket error)."""
    capped_drains: int = 0
    """Drains that stopped at ``max_frames`` with frames possibly left for the next tick."""
    last_error: str = ""
    """The latest receive error or malformed frame, as text ("" before the first)."""

    def as_dict(self) -> dict[str, int | str]:
        """The counts as plain data (for status displays)."""
        return asdict(self)


@dataclass(frozen=True)
class Batch:
    """One drain: whether an E-stop was among the frames, and every other frame in arrival order."""

    estop: bool
    frames: list[can.Message] = field(default_factory=list)
    error_frames: list[can.Message] = field(default_factory=list)
    """CAN error frames of this drain, for :class:`millctl.protocol.bus_health.BusHealthMonitor`."""


class BusReader:
    """Drains one bus per tick, E-stop apart, counting every bad input instead of raising."""

    def __init__(
        self,
        bus: can.BusABC,
        name: str,
        *,
        estop_bus: can.BusABC | None = None,
        max_frames: int = MAX_FRAMES_PER_DRAIN,
        max_consecutive_errors: int = MAX_CONSECUTIVE_ERRORS,
    ) -> None:
        if max_frames < 1 or max_consecutive_errors < 1:
            raise ValueError(
                f"{name} bus reader: max_frames = {max_frames} and max_consecutive_errors = "
                f"{max_consecutive_errors} must both be ≥ 1"
            )
        self.bus = bus
        self.estop_bus = estop_bus
        """A receive channel that carries E-stops only (None where the interface has none)."""
        self.estop_channel_frames = 0
        """E-stops read on that channel (each is also read on the main bus, unless its queue dropped it)."""
        self.name = name
        self.max_frames = max_frames
        self.max_consecutive_errors = max_consecutive_errors
        self.counts = ReceiveCounts()

    def drain(self) -> Batch:
        """Read every frame waiting (bounded by ``max_frames``); never raises for anything the bus delivers.

        The E-stop channel, if any, is read before the main bus and again after it, so an E-stop that
        arrives while a long drain runs is still reported by this one.
        """
        counts = self.counts
        frames: list[can.Message] = []
        error_frames: list[can.Message] = []
        estop = self._estop_channel()
        errors_in_a_row = 0
        for _ in range(self.max_frames):
            try:
                frame = self.bus.recv(timeout=0.0)
            except (can.CanError, OSError, ValueError) as exc:
                counts.receive_errors += 1
                self._note("receive error", counts.receive_errors, f"{type(exc).__name__}: {exc}")
                errors_in_a_row += 1
                if errors_in_a_row >= self.max_consecutive_errors:
                    break
                continue
            errors_in_a_row = 0
            if frame is None:
                break
            counts.frames += 1
            if is_estop(frame):
                counts.estops += 1
                estop = True
            elif frame.is_error_frame:
                counts.error_frames += 1
                error_frames.append(frame)
                self._note("error frame", counts.error_frames, repr(frame))
            else:
                frames.append(frame)
        else:
            counts.capped_drains += 1
            self._note("drain stopped at its bound", counts.capped_drains, f"{self.max_frames} reads in one tick")
        estop = self._estop_channel() or estop
        return Batch(estop, frames, error_frames)

    def _estop_channel(self) -> bool:
        """Read the E-stop channel empty (bounded); True when it held an E-stop. Never raises for bus input."""
        bus = self.estop_bus
        if bus is None:
            return False
        counts = self.counts
        found = False
        for _ in range(self.max_consecutive_errors):
            try:
                frame = bus.recv(timeout=0.0)
            except (can.CanError, OSError, ValueError) as exc:
                counts.receive_errors += 1
                self._note("receive error on the E-stop channel", counts.receive_errors, f"{type(exc).__name__}: {exc}")
                continue
            if frame is None:
                break
            if is_estop(frame):  # the kernel's filter passes nothing else; a frame that is no E-stop is ignored
                self.estop_channel_frames += 1
                found = True
        return found

    def malformed(self, frame: can.Message, reason: object) -> None:
        """Count (and log, bounded) a frame that does not fit the DBC; the caller drops it."""
        self.counts.malformed += 1
        ident = frame.arbitration_id
        shown = f"0x{ident:03X}" if isinstance(ident, int) else repr(ident)
        self._note("malformed frame", self.counts.malformed, f"{shown}: {reason}")

    def _note(self, what: str, count: int, detail: str) -> None:
        self.counts.last_error = f"{what}: {detail}"
        level = logging.WARNING if _power_of_two(count) else logging.DEBUG
        log.log(level, "%s bus: %s #%d (dropped, the loop goes on): %s", self.name, what, count, detail)


__all__ = ["MAX_CONSECUTIVE_ERRORS", "MAX_FRAMES_PER_DRAIN", "Batch", "BusReader", "ReceiveCounts", "is_estop"]
