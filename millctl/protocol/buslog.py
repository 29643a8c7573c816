"""Logging the bus: a size-rotating candump ``.log`` (or ``.blf``) writer for the service.

The files are python-can's writers, so they replay with
``python -m can.player -i virtual -c millbus FILE.log`` (or ``can_player``)
and decode with ``cantools decode --single-line config/millbus.dbc < FILE.log``.
When the current file reaches ``rotate_bytes`` it is renamed
``<stem>_<time>_#NNN<suffix>`` and a new one started; only the newest
``keep_files`` rotated files are kept (``[service]`` in the config).

A candump ``.log`` is written line by line, unbuffered, through
:class:`AppendOnlyText`: a line the disk has no room for is cut back off the
file, so a full disk never leaves a torn line in the middle of the log, and
writing resumes after the last complete line once there is room again.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path
from typing import Any

import can
from can.io.canutils import CanutilsLogWriter

log = logging.getLogger(__name__)

SUPPORTED_SUFFIXES = (".log", ".blf")


LOG_MODE = 0o640
"""Bus logs are rw for the service's user, readable by its group, nothing for others."""


class AppendOnlyText:
    """A text file that only grows by whole writes: a write that fails part-way is cut back off (``os.ftruncate``)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_CLOEXEC, LOG_MODE)
        self._size = os.lseek(self._fd, 0, os.SEEK_END)

    def write(self, text: str) -> int:
        """Append ``text`` whole, or raise with the file as it was."""
        data = memoryview(text.encode())
        try:
            while data:
                data = data[os.write(self._fd, data):]
        except OSError:
            os.ftruncate(self._fd, self._size)
            raise
        self._size += len(text.encode())
        return len(text)

    def tell(self) -> int:
        """The file's size (bytes)."""
        return self._size

    def flush(self) -> None:
        """Nothing is buffered."""

    def close(self) -> None:
        """Close the file (idempotent)."""
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1


class RotatingBusLog(can.SizedRotatingLogger):
    """A ``can.Listener`` writing every frame it is given, rotating by size and pruning old files."""

    def __init__(self, path: str | Path, rotate_bytes: int, keep_files: int, **writer_kwargs: Any) -> None:
        path = Path(path)
        if path.suffix.lower() not in SUPPORTED_SUFFIXES:
            raise ValueError(f"bus log {path}: use a .log (candump) or .blf file, not {path.suffix or 'no suffix'}")
        if rotate_bytes <= 0 or keep_files < 1:
            raise ValueError(f"bus log {path}: rotate_bytes ({rotate_bytes}) and keep_files ({keep_files}) must be ≥ 1")
        path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        self.keep_files = keep_files
        super().__init__(base_filename=path, max_bytes=rotate_bytes, **writer_kwargs)

    def _get_new_writer(self, filename: Any) -> Any:
        """A candump writer on an :class:`AppendOnlyText` (python-can's own for ``.blf``)."""
        if Path(filename).suffix.lower() == ".log":
            return CanutilsLogWriter(AppendOnlyText(Path(filename)))  # type: ignore[arg-type]
        return super()._get_new_writer(filename)

    def rotated_files(self) -> list[Path]:
        """The rotated (closed) files of this log, oldest first."""
        stem = self.path.stem.split(".")[0]
        found = self.path.parent.glob(f"{stem}_*_#*{self.path.suffix}")
        return sorted(found, key=lambda p: (p.stat().st_mtime_ns, p.name))

    def rotate(self, source: str | os.PathLike[str], dest: str | os.PathLike[str]) -> None:
        """Rename the full file, then delete the oldest rotated files beyond ``keep_files``."""
        super().rotate(source, dest)
        for old in self.rotated_files()[: -self.keep_files]:
            try:
                old.unlink()
            except OSError as exc:
                log.warning("cannot delete old bus log %s: %s", old, exc)


__all__ = ["LOG_MODE", "SUPPORTED_SUFFIXES", "AppendOnlyText", "RotatingBusLog"]
