"""Reading the files a user names: regular files under a stated size, never a device, a FIFO or a directory.

Every file the CLI or the service reads on a user's word (the configuration,
a recipe, a study, the service's token) goes through :func:`read_input_file`:
it opens without blocking (``O_NONBLOCK``: a FIFO with no writer does not
hang the open), checks what the descriptor is (``fstat``: only a regular file
is read) and its size, and then reads at most the bound plus one byte, so a
file that grows while it is read is refused too. ``/dev/zero``, a FIFO, a
directory or a huge file is refused at once, in bounded memory, with the
path, what it is, and the bound (docs/safety.md#files-and-nesting).
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

MAX_INPUT_BYTES = 4 << 20
"""The bound on a file a user names (bytes): 4 MiB, far above any configuration, recipe or study (a few kB)."""

READ_CHUNK_BYTES = 1 << 16

_KINDS = (
    (stat.S_ISDIR, "a directory"),
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


class FileRefused(OSError):
    """A file that is missing, unreadable, not a regular file, or over its bound; ``str()`` says which and why."""

    def __init__(self, message: str, *, missing: bool = False) -> None:
        super().__init__(message)
        self.message = message
        self.missing = missing

    def __str__(self) -> str:
        return self.message


def _kind(mode: int) -> str:
    return next((name for test, name in _KINDS if test(mode)), "not a regular file")


def read_input_file(path: str | os.PathLike[str], max_bytes: int = MAX_INPUT_BYTES) -> bytes:
    """The bytes of the regular file ``path``, at most ``max_bytes``; raise :class:`FileRefused` naming the problem."""
    shown = os.fspath(path)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY | os.O_CLOEXEC)
    except FileNotFoundError:
        raise FileRefused(f"{shown}: no such file", missing=True) from None
    except OSError as exc:
        raise FileRefused(f"{shown}: cannot open: {exc.strerror}") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise FileRefused(f"{shown}: {_kind(info.st_mode)}, not a regular file: name a file")
        if info.st_size > max_bytes:
            raise FileRefused(f"{shown}: {info.st_size} bytes, over the bound of {max_bytes} bytes for an input file")
        chunks: list[bytes] = []
        total = 0
        while total <= max_bytes:
            try:
                chunk = os.read(fd, min(READ_CHUNK_BYTES, max_bytes + 1 - total))
            except OSError as exc:
                raise FileRefused(f"{shown}: cannot read: {exc.strerror}") from None
            if not chunk:
                break
            chunks.append(chunk)
            total += len(chunk)
        if total > max_bytes:
            raise FileRefused(f"{shown}: grew past the bound of {max_bytes} bytes for an input file while it was read")
        return b"".join(chunks)
    finally:
        os.close(fd)


def read_input_text(path: str | os.PathLike[str], max_bytes: int = MAX_INPUT_BYTES) -> str:
    """:func:`read_input_file` decoded as UTF-8; a file that is not UTF-8 is a :class:`FileRefused` too."""
    raw = read_input_file(path, max_bytes)
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise FileRefused(f"{Path(path)}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None


__all__ = ["MAX_INPUT_BYTES", "FileRefused", "read_input_file", "read_input_text"]
