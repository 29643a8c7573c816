"""Bus load of the mill protocol, computed from the DBC (never typed by hand).

A classic CAN data frame with an 11-bit identifier and ``n`` data bytes is,
with worst-case bit stuffing and the 3-bit interframe space,
``34 + 8n + 13 + ⌊(34 + 8n − 1)/4⌋`` bits long (Davis, Burns, Bril, Lukkien,
"Controller Area Network (CAN) schedulability analysis", Real-Time Systems
35, 2007, eq. 4; 54 instead of 34 for 29-bit identifiers): 135 bits for
8 bytes. Periodic frames count at ``1/GenMsgCycleTime``; event frames
(E-stop, commands, fault injection) at an assumed worst-case rate.
"""

from __future__ import annotations

from dataclasses import dataclass

from millctl.protocol.codec import Codec
from millctl.protocol.messages import MESSAGE_TYPES

DEFAULT_BITRATE_BIT_S = 500_000
DEFAULT_EVENT_RATE_HZ = 10.0
"""Assumed worst-case rate of each event (non-periodic) frame for the load figure."""
TARGET_LOAD = 0.15


def worst_case_frame_bits(data_bytes: int, extended_id: bool = False) -> int:
    """Bits on the wire of one classic CAN data frame, worst-case stuffing and interframe space included."""
    if not 0 <= data_bytes <= 8:
        raise ValueError(f"a classic CAN frame carries 0 … 8 data bytes, not {data_bytes}")
    header = 54 if extended_id else 34
    stuffable = header + 8 * data_bytes
    return stuffable + 13 + (stuffable - 1) // 4


@dataclass(frozen=True)
class FrameLoad:
    """One frame's share of the bus."""

    name: str
    frame_id: int
    periodic: bool
    rate_hz: float
    frame_bits: int

    @property
    def bit_rate_bit_s(self) -> float:
        """Bits per second this frame occupies."""
        return self.rate_hz * self.frame_bits


@dataclass(frozen=True)
class BusLoad:
    """The load of every frame and the total, at one bitrate."""

    bitrate_bit_s: int
    event_rate_hz: float
    frames: tuple[FrameLoad, ...]

    @property
    def periodic_load(self) -> float:
        """Fraction of the bus used by the periodic frames alone."""
        return sum(f.bit_rate_bit_s for f in self.frames if f.periodic) / self.bitrate_bit_s

    @property
    def total_load(self) -> float:
        """Fraction of the bus used by periodic frames plus every event frame at its assumed rate."""
        return sum(f.bit_rate_bit_s for f in self.frames) / self.bitrate_bit_s


def bus_load(
    codec: Codec, bitrate_bit_s: int = DEFAULT_BITRATE_BIT_S, event_rate_hz: float = DEFAULT_EVENT_RATE_HZ
) -> BusLoad:
    """The worst-case bus load of the protocol in ``codec``'s DBC."""
    if bitrate_bit_s <= 0 or event_rate_hz < 0:
        raise ValueError(f"need bitrate > 0 and event rate ≥ 0, got {bitrate_bit_s} and {event_rate_hz}")
    frames = []
    for kind in MESSAGE_TYPES:
        dbc = codec.database.get_message_by_name(kind.__name__)
        cycle_s = codec.cycle_time_s(kind)
        frames.append(
            FrameLoad(
                name=kind.__name__,
                frame_id=codec.frame_id(kind),
                periodic=cycle_s is not None,
                rate_hz=1.0 / cycle_s if cycle_s else event_rate_hz,
                frame_bits=worst_case_frame_bits(dbc.length, dbc.is_extended_frame),
            )
        )
    return BusLoad(bitrate_bit_s, event_rate_hz, tuple(frames))


__all__ = [
    "DEFAULT_BITRATE_BIT_S",
    "DEFAULT_EVENT_RATE_HZ",
    "TARGET_LOAD",
    "BusLoad",
    "FrameLoad",
    "bus_load",
    "worst_case_frame_bits",
]
