"""Append-only JSON-lines records, flushed and synced per record, rotated by size.

Used for the service's event record and for run records. Each line is one
complete JSON object, written with a single ``write`` and made durable with
``fsync`` before the call returns, so that after a SIGKILL every record up to
the last completed call is intact and parseable (docs/operations.md#records).
"""

from __future__ import annotations

import json
import os
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any


class RecordWriter:
    """Writes ``<directory>/<name>.jsonl``; past ``rotate_bytes`` it becomes ``<name>.1.jsonl`` and so on.

    At most ``keep`` rotated files are kept besides the current one.
    """

    def __init__(self, directory: str | Path, name: str, *, rotate_bytes: int = 16 << 20, keep: int = 10,
                 sync: bool = True) -> None:
        if rotate_bytes < 1024:
            raise ValueError(f"rotate_bytes = {rotate_bytes} must be ≥ 1024")
        if keep < 1:
            raise ValueError(f"keep = {keep} must be ≥ 1")
        self.directory = Path(directory)
        self.directory.mkdir(parents=True, exist_ok=True)
        self.name = name
        self.rotate_bytes = rotate_bytes
        self.keep = keep
        self.sync = sync
        self._lock = threading.Lock()
        self._file = open(self.path, "a", encoding="utf-8")  # noqa: SIM115 - held open for the writer's life

    @property
    def path(self) -> Path:
        """The file being written now."""
        return self.directory / f"{self.name}.jsonl"

    def write(self, record: dict[str, Any]) -> None:
        """Append one record (adds ``"t"``, the Unix time, unless given); durable on return."""
        data = {"t": time.time(), **record}
        line = json.dumps(data, ensure_ascii=False, default=str, separators=(",", ":")) + "\n"
        with self._lock:
            if self._file.tell() + len(line) > self.rotate_bytes and self._file.tell() > 0:
                self._rotate()
            self._file.write(line)
            self._file.flush()
            if self.sync:
                os.fsync(self._file.fileno())

    def _rotate(self) -> None:
        self._file.close()
        (self.directory / f"{self.name}.{self.keep}.jsonl").unlink(missing_ok=True)
        for index in range(self.keep - 1, 0, -1):
            older = self.directory / f"{self.name}.{index}.jsonl"
            if older.exists():
                older.replace(self.directory / f"{self.name}.{index + 1}.jsonl")
        self.path.replace(self.directory / f"{self.name}.1.jsonl")
        self._file = open(self.path, "a", encoding="utf-8")  # noqa: SIM115

    def close(self) -> None:
        """Close the file (further writes raise)."""
        with self._lock:
            self._file.close()


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


__all__ = ["RecordWriter", "read_records"]
