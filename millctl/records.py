"""Append-only JSON-lines records, flushed and synced per record, rotated by size.

Used for the service's event record and for run records. Each line is one
complete JSON object, written with a single ``write`` and made durable with
``fsync``, so that after a SIGKILL every record up to the last completed write
is intact and parseable (docs/operations.md#records). In the service the
writes go through a :class:`RecordQueue` (a thread of their own), so that no
control step ever waits for the disk.
"""

from __future__ import annotations

import json
import logging
import os
import queue
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

log = logging.getLogger(__name__)


RECORD_MODE = 0o640
"""Record files are created rw for the service's user, readable by its group, nothing for others."""

QUEUE_SIZE = 20_000
"""Records waiting for the writer thread; past this, new ones are counted as lost (never waited for)."""

RECOVERED_AFTER_S = 5.0
"""Writes count as working again only after this long without a failure (s): a nearly full disk that takes
one small record and refuses the next does not flap the warning."""


class RecordQueue:
    """One writer thread for the record files of a service: callers enqueue and never wait for the disk.

    A write that fails (a full or failing disk) is retried no more: the record
    is counted as lost, ``failing`` names the error, and ``on_change(failing)``
    is called once when writes start failing and once when they have succeeded
    again for RECOVERED_AFTER_S (SAFETY 23: the control loop never sees the disk).
    """

    def __init__(self, on_change: Callable[[str | None], None] | None = None, size: int = QUEUE_SIZE) -> None:
        self._queue: queue.Queue[Callable[[], None] | None] = queue.Queue(maxsize=size)
        self.on_change = on_change
        self.failing: str | None = None
        self.lost = 0
        self.written = 0
        self._failed_at_s = 0.0
        self._thread = threading.Thread(target=self._run, name="millctl-records", daemon=True)
        self._thread.start()

    def submit(self, job: Callable[[], None]) -> None:
        """Queue one write; when the queue is full the record is lost (counted), the caller never blocks."""
        try:
            self._queue.put_nowait(job)
        except queue.Full:
            self._failed(f"the record queue is full ({self._queue.maxsize} records waiting: the disk is too slow)")

    def _failed(self, reason: str) -> None:
        self.lost += 1
        self._failed_at_s = time.monotonic()
        if self.failing is None:
            self.failing = reason
            self._notify(reason)

    def _notify(self, failing: str | None) -> None:
        if self.on_change is not None:
            try:
                self.on_change(failing)
            except Exception:  # a listener's error must not stop the writer
                log.exception("record queue listener failed")

    def _run(self) -> None:
        while True:
            job = self._queue.get()
            try:
                if job is None:
                    return
                try:
                    job()
                except (OSError, ValueError) as exc:
                    log.error("record write failed: %s", exc)
                    self._failed(str(exc))
                else:
                    self.written += 1
                    if self.failing is not None and time.monotonic() - self._failed_at_s >= RECOVERED_AFTER_S:
                        self.failing = None
                        self._notify(None)
            finally:
                self._queue.task_done()

    def flush(self) -> None:
        """Wait until every queued record has been written (or lost)."""
        if self._thread.is_alive():
            self._queue.join()

    def close(self) -> None:
        """Write what is queued, then stop the thread."""
        if self._thread.is_alive():
            self._queue.put(None)
            self._thread.join()


class RecordWriter:
    """Writes ``<directory>/<name>.jsonl``; past ``rotate_bytes`` it becomes ``<name>.1.jsonl`` and so on.

    At most ``keep`` rotated files are kept besides the current one. With a
    :class:`RecordQueue` the writes happen on its thread (the file is opened
    there too); without one, in the caller. A write that fails part-way is cut
    back to the last complete record, so a full disk never leaves a torn line
    inside a record: what was written stays readable.
    """

    def __init__(self, directory: str | Path, name: str, *, rotate_bytes: int = 16 << 20, keep: int = 10,
                 sync: bool = True, queue: RecordQueue | None = None) -> None:
        if rotate_bytes < 1024:
            raise ValueError(f"rotate_bytes = {rotate_bytes} must be ≥ 1024")
        if keep < 1:
            raise ValueError(f"keep = {keep} must be ≥ 1")
        self.directory = Path(directory)
        self.name = name
        self.rotate_bytes = rotate_bytes
        self.keep = keep
        self.sync = sync
        self.queue = queue
        self._lock = threading.Lock()
        self._fd: int | None = None
        self._closed = False
        if queue is None:
            self._open()

    @property
    def path(self) -> Path:
        """The file being written now."""
        return self.directory / f"{self.name}.jsonl"

    def _open(self) -> int:
        if self._fd is None:
            self.directory.mkdir(mode=0o750, parents=True, exist_ok=True)
            self._fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_CLOEXEC, RECORD_MODE)
        return self._fd

    def write(self, record: dict[str, Any]) -> None:
        """Append one record (adds ``"t"``, the Unix time, unless given); durable on return without a queue."""
        data = {"t": time.time(), **record}
        line = (json.dumps(data, ensure_ascii=False, default=str, separators=(",", ":")) + "\n").encode()
        if self.queue is None:
            self._append(line)
        else:
            self.queue.submit(lambda: self._append(line))

    def _append(self, line: bytes) -> None:
        with self._lock:
            if self._closed:
                raise ValueError(f"record {self.path} is closed")
            fd = self._open()
            size = os.lseek(fd, 0, os.SEEK_END)
            if size + len(line) > self.rotate_bytes and size > 0:
                self._rotate()
                fd = self._open()
                size = 0
            try:
                view = memoryview(line)
                while view:
                    view = view[os.write(fd, view):]
                if self.sync:
                    os.fsync(fd)
            except OSError:
                os.ftruncate(fd, size)  # never leave a torn record behind a later, complete one
                raise

    def _rotate(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
        (self.directory / f"{self.name}.{self.keep}.jsonl").unlink(missing_ok=True)
        for index in range(self.keep - 1, 0, -1):
            older = self.directory / f"{self.name}.{index}.jsonl"
            if older.exists():
                older.replace(self.directory / f"{self.name}.{index + 1}.jsonl")
        self.path.replace(self.directory / f"{self.name}.1.jsonl")

    def close(self) -> None:
        """Close the file once what was queued is written (further writes raise)."""
        if self.queue is not None:
            self.queue.submit(self._close)
        else:
            self._close()

    def _close(self) -> None:
        with self._lock:
            self._closed = True
            if self._fd is not None:
                os.close(self._fd)
                self._fd = None


def last_record(path: str | Path) -> dict[str, Any] | None:
    """The last complete record of a JSON-lines file (reads only its tail), or None if there is none."""
    try:
        with open(path, "rb") as handle:
            handle.seek(0, os.SEEK_END)
            end = handle.tell()
            handle.seek(max(end - 65_536, 0))
            tail = handle.read()
    except FileNotFoundError:
        return None
    for line in reversed(tail.split(b"\n")):
        try:
            found = json.loads(line)
        except (json.JSONDecodeError, UnicodeDecodeError):
            continue
        if isinstance(found, dict):
            return found
    return None


def read_records(path: str | Path) -> Iterator[dict[str, Any]]:
    """Read a JSON-lines record; a torn last line (a write cut by a kill) is skipped, nothing else."""
    with open(path, encoding="utf-8") as handle:
        lines = handle.read().split("\n")
    for number, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        try:
            yield json.loads(line)
        except json.JSONDecodeError:
            if number == len(lines):
                return
            raise


__all__ = [
    "QUEUE_SIZE",
    "RECORD_MODE",
    "RECOVERED_AFTER_S",
    "RecordQueue",
    "RecordWriter",
    "last_record",
    "read_records",
]
