"""The service's event record: every event to ``<records_dir>/events.jsonl`` (fsync per record) and a ring buffer.

Controller events (state changes, commands, refusals, trips) arrive through
the controller's listener; the service adds its own (start, stop, config,
control taken and released). Each gets a sequence number, so clients can ask
for the events after the last one they saw (``GET /v1/events?after=N``); the
numbering continues from the last recorded event of the previous session.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from pathlib import Path
from typing import Any

from millctl.controller import Event
from millctl.records import RecordQueue, RecordWriter, last_record

log = logging.getLogger(__name__)

EVENTS_NAME = "events"
"""The record's file stem: ``events.jsonl``, rotated to ``events.1.jsonl`` …"""

RING_SIZE = 2000
"""Events kept in memory for ``GET /v1/events`` and the stream."""


def finite(value: Any) -> Any:
    """``value`` with every non-finite float replaced by None (JSON has no inf or nan), recursively."""
    if isinstance(value, float):
        return value if value == value and value not in (float("inf"), float("-inf")) else None
    if isinstance(value, dict):
        return {str(k): finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [finite(v) for v in value]
    return value


def previous_seq(records_dir: Path) -> int:
    """The sequence number of the last recorded event of an earlier session (0 if none): numbering continues."""
    for name in (f"{EVENTS_NAME}.jsonl", f"{EVENTS_NAME}.1.jsonl"):
        last = last_record(records_dir / name)
        if last is not None and isinstance(last.get("seq"), int):
            return int(last["seq"])
    return 0


class Journal:
    """Numbers, keeps and records events; thread-safe (the control loop and API threads both write)."""

    def __init__(
        self, records_dir: str | Path, *, rotate_bytes: int, keep_files: int, queue: RecordQueue | None = None
    ) -> None:
        self.writer = RecordWriter(records_dir, EVENTS_NAME, rotate_bytes=rotate_bytes, keep=keep_files, queue=queue)
        self._ring: deque[dict[str, Any]] = deque(maxlen=RING_SIZE)
        self._seq = previous_seq(Path(records_dir))
        self._lock = threading.Lock()

    @property
    def path(self) -> Path:
        """The record file being written."""
        return self.writer.path

    @property
    def last_seq(self) -> int:
        """Sequence number of the newest event (0 before the first)."""
        return self._seq

    def add(self, kind: str, source: str, message: str, *, time_s: float | None = None, **data: Any) -> dict[str, Any]:
        """Record one event and keep it in the ring; return it as recorded."""
        with self._lock:
            self._seq += 1
            record = {
                "seq": self._seq,
                "t": time.time(),
                "time_s": time_s,
                "kind": kind,
                "source": source,
                "message": message,
                "data": finite(data),
            }
            self._ring.append(record)
            try:
                self.writer.write(record)  # queued: the disk is written on the record thread
            except (OSError, ValueError) as exc:  # a full disk must not stop the control loop
                log.error("cannot write the event record %s: %s", self.writer.path, exc)
        return record

    def on_event(self, event: Event) -> None:
        """The controller's listener: record a controller event."""
        self.add(str(event.kind), event.source, event.message, time_s=event.time_s, **event.data)

    def after(self, seq: int, limit: int = RING_SIZE) -> list[dict[str, Any]]:
        """Events with a sequence number above ``seq``, oldest first, at most ``limit``."""
        with self._lock:
            found = [e for e in self._ring if e["seq"] > seq]
        return found[:limit]

    def close(self) -> None:
        """Close the record file."""
        self.writer.close()


__all__ = ["EVENTS_NAME", "RING_SIZE", "Journal", "finite", "previous_seq"]
