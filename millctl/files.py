"""Reading the files a user names: regular files under a stated size, never a device, a FIFO or a directory.

Every file the CLI or the service reads on a user's word (the configuration,
a recipe, a study, the service's token) goes through :func:`read_input_file`:
it opens without blocking (``O_NONBLOCK``: a FIFO with no writer does not
hang the open), checks what the descriptor is (``fstat``: only a regular file
is read) and its size, and then reads at most the bound plus one byte, so a
file that grows while it is read is refused too. ``/dev/zero``, a FIFO, a
directory or a huge file is refused at once, in bounded memory, with the
path, what it is, and the bound (docs/safety.md#files-and-nesting).

A TOML file (:func:`read_toml`, :func:`parse_toml`) is refused as well when its
tables and arrays nest deeper than :data:`MAX_TOML_DEPTH`. Only the standard
library: the CLI checks a named file here before it imports anything heavy
(millctl/cli/precheck.py), and the loaders use the same functions.
"""

from __future__ import annotations

import os
import stat
import tomllib
from pathlib import Path
from typing import Any

from millctl.errors import ConfigError, InvalidFileError

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


MAX_TOML_DEPTH = 32
"""Tables and arrays nest at most this deep in a configuration, recipe or study (a millctl file needs 3)."""


def read_toml(path: Path, error: type[InvalidFileError] = ConfigError) -> tuple[dict[str, Any], bytes]:
    """Read a TOML file (a regular file under MAX_INPUT_BYTES); a bad file or bad syntax raises ``error`` naming it."""
    try:
        raw = read_input_file(path)
    except FileRefused as exc:
        raise error(str(path), [str(exc)]) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(str(path), [f"{path}: not UTF-8 text ({exc.reason})"]) from None
    return parse_toml(text, str(path), error), raw


def parse_toml(text: str, source: str, error: type[InvalidFileError] = ConfigError) -> dict[str, Any]:
    """Parse TOML text; bad syntax, or nesting deeper than MAX_TOML_DEPTH, raises ``error`` naming ``source``."""
    too_deep = (f"{source}: arrays or inline tables nested too deeply: the bound is {MAX_TOML_DEPTH} levels "
                "(a millctl file needs at most 3)")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(source, [f"{source}: TOML syntax error: {exc}"]) from None
    except RecursionError:  # deeper than the parser itself can go: far past the bound
        raise error(source, [f"{too_deep}; this one is nested deeper than the TOML parser can go"]) from None
    depth = nesting_depth(data)
    if depth > MAX_TOML_DEPTH:
        raise error(source, [f"{too_deep}; this one is nested more than {MAX_TOML_DEPTH} levels deep"])
    return data


def nesting_depth(data: object) -> int:
    """How many tables and arrays deep ``data`` goes (a scalar: 0), counted without recursion.

    The count stops at MAX_TOML_DEPTH + 1: deeper is too deep, however deep.
    """
    deepest = 0
    pending: list[tuple[object, int]] = [(data, 0)]
    while pending:
        item, depth = pending.pop()
        children = item.values() if isinstance(item, dict) else item if isinstance(item, list) else None
        if children is None:
            continue
        deepest = max(deepest, depth + 1)
        if deepest > MAX_TOML_DEPTH:
            return deepest
        pending.extend((child, depth + 1) for child in children)
    return deepest


__all__ = [
    "MAX_INPUT_BYTES",
    "MAX_TOML_DEPTH",
    "FileRefused",
    "nesting_depth",
    "parse_toml",
    "read_input_file",
    "read_input_text",
    "read_toml",
]
