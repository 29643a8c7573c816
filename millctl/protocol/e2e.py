"""End-to-end protection, AUTOSAR E2E profile 1 style (SAFETY.md item 3).

Every E2E-protected frame carries, in byte 0, a CRC8 and, in the low nibble
of byte 1, a 4-bit alive counter that the sender advances by one per frame
(0…15, wrapping; unlike profile 1 the value 15 is used too).

The CRC is CRC-8/SAE-J1850: polynomial 0x1D, initial value 0xFF, final XOR
0xFF, no reflection (check value 0x4B for ``b"123456789"``). It runs over the
message's 16-bit data ID (``E2EDataID`` in the DBC; low byte, then high
byte, as profile 1's "both bytes" mode) and then the payload without the CRC
byte, so a frame that arrives under a wrong identifier fails its CRC.

A receiver keeps one :class:`E2EReceiver` per message: it classifies every
frame and keeps two scores; the link is faulted while either is at or above
the limit (``interlock.e2e_error_limit``):

- the **net error score**: +1 per error of any kind, −1 per ``OK`` frame,
  never below 0. It tolerates a noisy link (occasional bad CRCs).
- the **sequence score** (SAFETY.md item 17): +1 per ``REPEATED`` or
  ``WRONG_SEQUENCE`` frame, and only −1 per ``sequence_decay_frames`` fresh
  frames. A repeated or out-of-sequence counter with a good CRC is what a
  second sender on the identifier (or a replay) produces, and that sender's
  own frames arrive as ``OK``: under the net score alone, answering every
  genuine frame with counter + 1 keeps the score level (genuine ``REPEATED``
  +1, spoof ``OK`` −1) for ever. Good frames do not pay for sequence errors
  here, so a second sender faults the link unless it sends less than one
  frame in ``sequence_decay_frames``. Nor may a sender buy forgiveness by
  sending fast: with ``min_decay_s`` set (:func:`sequence_decay_s`: the time
  the identifier's own sender takes for ``sequence_decay_frames`` frames, at
  up to ``SEQUENCE_RATE_SLACK`` times its rate), a point comes off only when
  that long has also passed since the last sequence error or the last point
  forgiven. Counted in frames alone, a forger that out-sends the genuine
  sender 16 to 1 paid back the errors its interleaving made as fast as it
  made them, and the link never faulted.

Only ``OK`` and ``OK_SOME_LOST`` frames are fresh; a repeated or
out-of-sequence counter never counts as a heartbeat.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Protocol

CRC8_POLY = 0x1D
CRC8_INIT = 0xFF
CRC8_XOR_OUT = 0xFF
COUNTER_MODULO = 16
DEFAULT_MAX_DELTA = 3
"""Largest counter step still accepted as "some frames lost" (profile 1's MaxDeltaCounter)."""
DEFAULT_SEQUENCE_DECAY_FRAMES = 16
"""Fresh frames that take one off the sequence score (``interlock.e2e_sequence_decay_frames``)."""
SEQUENCE_RATE_SLACK = 2.0
"""How many times its nominal rate an identifier's sender may send and still be forgiven at the frames' pace."""


def sequence_decay_s(decay_frames: int, period_s: float) -> float:
    """The least time a point of the sequence score takes to come off, for a sender with this period (s).

    ``decay_frames`` frames at ``SEQUENCE_RATE_SLACK`` times the nominal rate: a genuine sender's jitter and
    catch-up frames never meet it, a sender many times faster (a forger out-sending the genuine one) does.
    """
    if not period_s > 0.0:
        raise ValueError(f"E2E sequence decay: the sender's period {period_s!r} s must be > 0")
    return decay_frames * period_s / SEQUENCE_RATE_SLACK


def _table() -> tuple[int, ...]:
    """The 256-entry CRC-8 table (poly 0x1D), computed bit by bit once.

    Hand-written on purpose, where a library (crccheck) exists: the controller and the node compute a CRC
    for every frame they send and receive, and this table-driven loop is ~20-30x faster than crccheck's
    (``python -m bench.crc`` measures both in one run and prints the ratio). crccheck stays the independent
    oracle the E2E tests hold this to.
    """
    rows = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = ((crc << 1) ^ CRC8_POLY) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
        rows.append(crc)
    return tuple(rows)


_TABLE = _table()


def crc8_sae_j1850(data: bytes, start: int = CRC8_INIT, xor_out: int = CRC8_XOR_OUT) -> int:
    """CRC-8/SAE-J1850 of ``data`` (poly 0x1D, init 0xFF, xorout 0xFF unless given)."""
    crc = start
    for byte in data:
        crc = _TABLE[crc ^ byte]
    return crc ^ xor_out


def e2e_crc(data_id: int, payload_without_crc: bytes) -> int:
    """The E2E CRC8 over the data ID (low byte, high byte) and the payload without its CRC byte."""
    if not 0 <= data_id <= 0xFFFF:
        raise ValueError(f"E2E data ID {data_id} is outside 0 … 65535")
    return crc8_sae_j1850(bytes((data_id & 0xFF, data_id >> 8)) + payload_without_crc)


class AliveCounter:
    """A sender's 4-bit alive counter: ``next()`` returns the value for the next frame, then advances."""

    def __init__(self, start: int = 0) -> None:
        if not 0 <= start < COUNTER_MODULO:
            raise ValueError(f"alive counter start {start} is outside 0 … {COUNTER_MODULO - 1}")
        self._value = start

    @property
    def value(self) -> int:
        """The value the next frame will carry."""
        return self._value

    def next(self) -> int:
        """Return the counter for this frame and advance (15 wraps to 0)."""
        value = self._value
        self._value = (value + 1) % COUNTER_MODULO
        return value


class E2EStatus(enum.Enum):
    """Classification of one received E2E frame."""

    OK = "ok"
    """Counter advanced by exactly one (or first frame after start/resync)."""
    OK_SOME_LOST = "ok-some-lost"
    """Counter advanced by 2 … max_delta: some frames were lost, this one is fresh."""
    REPEATED = "repeated"
    """Same counter as the last accepted frame: not fresh."""
    WRONG_SEQUENCE = "wrong-sequence"
    """Counter jumped by more than max_delta (or went back): not fresh; the receiver resynchronises."""
    WRONG_CRC = "wrong-crc"
    """The CRC does not match: the frame is discarded."""

    @property
    def fresh(self) -> bool:
        """True when the frame's data may be used and may feed a watchdog."""
        return self in (E2EStatus.OK, E2EStatus.OK_SOME_LOST)

    @property
    def is_error(self) -> bool:
        """True when the frame adds to the error score."""
        return self in (E2EStatus.REPEATED, E2EStatus.WRONG_SEQUENCE, E2EStatus.WRONG_CRC)

    @property
    def is_sequence_error(self) -> bool:
        """True for a good CRC with a repeated or out-of-sequence counter (a second sender, a replay)."""
        return self in (E2EStatus.REPEATED, E2EStatus.WRONG_SEQUENCE)


class _HasE2E(Protocol):
    """What the checker reads of :class:`millctl.protocol.codec.Decoded` (avoids an import cycle)."""

    @property
    def counter(self) -> int | None: ...

    @property
    def crc_ok(self) -> bool: ...


@dataclass
class E2EReceiver:
    """Receiver-side checker for one E2E-protected message (one instance per identifier).

    ``check`` takes the CRC verdict and counter of a decoded frame
    (:class:`millctl.protocol.codec.Decoded` has both) and returns its
    :class:`E2EStatus`, updating the error score.
    """

    error_limit: int
    """Net error score, and sequence score, at which the link is faulted (``interlock.e2e_error_limit``)."""
    max_delta: int = DEFAULT_MAX_DELTA
    name: str = ""
    """What this receiver guards, for messages (e.g. the message name)."""
    sequence_decay_frames: int = DEFAULT_SEQUENCE_DECAY_FRAMES
    """Fresh frames per point taken off the sequence score (``interlock.e2e_sequence_decay_frames``)."""
    min_decay_s: float = 0.0
    """The least time per point taken off the sequence score (s, :func:`sequence_decay_s`); 0: frames alone.
    When set, every frame is classified with its time of arrival."""
    score: int = field(default=0, init=False)
    sequence_score: int = field(default=0, init=False)
    """Repeated and out-of-sequence counters, decaying by one per ``sequence_decay_frames`` fresh frames
    (and ``min_decay_s``)."""
    _fresh_run: int = field(default=0, init=False, repr=False)
    _decay_from_s: float = field(default=0.0, init=False, repr=False)
    """When the last sequence error came or the last point was forgiven (s): the time toward the next point."""
    last_counter: int | None = field(default=None, init=False)
    counts: dict[E2EStatus, int] = field(default_factory=lambda: dict.fromkeys(E2EStatus, 0), init=False)

    def __post_init__(self) -> None:
        if self.error_limit < 1:
            raise ValueError(f"E2E error limit {self.error_limit} must be ≥ 1")
        if not 1 <= self.max_delta < COUNTER_MODULO - 1:
            raise ValueError(f"E2E max_delta {self.max_delta} must be in 1 … {COUNTER_MODULO - 2}")
        if self.sequence_decay_frames < 1:
            raise ValueError(f"E2E sequence_decay_frames {self.sequence_decay_frames} must be ≥ 1")
        if not 0.0 <= self.min_decay_s < float("inf"):
            raise ValueError(f"E2E min_decay_s {self.min_decay_s!r} s must be finite and ≥ 0")

    @property
    def faulted(self) -> bool:
        """True while the net error score or the sequence score is at or above the limit."""
        return self.score >= self.error_limit or self.sequence_score >= self.error_limit

    def fault_reason(self) -> str | None:
        """Why the link is faulted (naming the score, its value and the limit), or None."""
        what = self.name or "E2E link"
        if self.sequence_score >= self.error_limit:
            return (
                f"{what} E2E sequence score {self.sequence_score} ≥ limit {self.error_limit}: repeated or "
                "out-of-sequence counters with good CRCs (a second sender or a replay on the identifier)"
            )
        if self.score >= self.error_limit:
            return f"{what} E2E error score {self.score} ≥ limit {self.error_limit}"
        return None

    def classify(self, counter: int | None, crc_ok: bool, now_s: float | None = None) -> E2EStatus:
        """Classify one frame by its CRC verdict and alive counter, and update the scores.

        ``now_s``: when the frame arrived (s, any monotonic clock); needed when ``min_decay_s`` is set.
        """
        if self.min_decay_s > 0.0 and now_s is None:
            raise ValueError(f"{self.name or 'E2E receiver'}: min_decay_s is set, so classify needs the time (now_s)")
        if not crc_ok or counter is None or not 0 <= counter < COUNTER_MODULO:
            status = E2EStatus.WRONG_CRC
        elif self.last_counter is None:
            status = E2EStatus.OK
        else:
            delta = (counter - self.last_counter) % COUNTER_MODULO
            if delta == 0:
                status = E2EStatus.REPEATED
            elif delta == 1:
                status = E2EStatus.OK
            elif delta <= self.max_delta:
                status = E2EStatus.OK_SOME_LOST
            else:
                status = E2EStatus.WRONG_SEQUENCE
        if status is not E2EStatus.WRONG_CRC and status is not E2EStatus.REPEATED:
            self.last_counter = counter
        self.counts[status] += 1
        if status.is_error:
            self.score += 1
        elif status is E2EStatus.OK:
            self.score = max(0, self.score - 1)
        t_s = 0.0 if now_s is None else now_s
        if status.is_sequence_error:
            self.sequence_score += 1
            self._fresh_run = 0
            self._decay_from_s = t_s
        elif status.fresh and self.sequence_score > 0:
            self._fresh_run += 1
            if self._fresh_run >= self.sequence_decay_frames and t_s - self._decay_from_s >= self.min_decay_s:
                self.sequence_score -= 1
                self._fresh_run = 0
                self._decay_from_s = t_s
        return status

    def check(self, decoded: _HasE2E, now_s: float | None = None) -> E2EStatus:
        """Classify a decoded frame (anything with ``counter`` and ``crc_ok``), arrived at ``now_s`` (s)."""
        return self.classify(decoded.counter, decoded.crc_ok, now_s)

    def reset(self) -> None:
        """Forget the last counter and the scores (e.g. after an explicit RESET of the link)."""
        self.clear_scores()
        self.last_counter = None

    def clear_scores(self) -> None:
        """Clear both scores, keeping the counter (the node's accepted RESET).

        The run of fresh frames toward the next decay needs no clearing: it
        counts only while the sequence score is above 0, and the sequence
        error that raises it again restarts the run.
        """
        self.score = 0
        self.sequence_score = 0


__all__ = [
    "COUNTER_MODULO",
    "CRC8_INIT",
    "CRC8_POLY",
    "CRC8_XOR_OUT",
    "DEFAULT_MAX_DELTA",
    "DEFAULT_SEQUENCE_DECAY_FRAMES",
    "SEQUENCE_RATE_SLACK",
    "AliveCounter",
    "E2EReceiver",
    "E2EStatus",
    "crc8_sae_j1850",
    "e2e_crc",
    "sequence_decay_s",
]
