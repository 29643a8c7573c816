"""Where CLI output goes: data on stdout, diagnostics on stderr, colour only on a TTY.

With ``--json`` every command prints one JSON document on stdout, in one shape::

    {"schema": 1, "command": "set", "ok": true, "result": {...}}
    {"schema": 1, "command": "set", "ok": false, "error": {"code": ..., "message": ..., "exit_code": 2, ...}}

``schema`` is the version of this contract (:data:`JSON_SCHEMA_VERSION`). Keys
follow one scheme: snake_case, ``<what>_<axis>_<unit>`` (``setpoint_rotary_rpm``,
``limit_rotary_rpm``, ``vibration_rpm``), the unit last.
"""

from __future__ import annotations

import contextlib
import functools
import json
import os
import sys
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

if TYPE_CHECKING:
    from rich.console import Console

PIPE_WIDTH = 160
"""Width of tables written to a pipe or file, where no terminal says how wide to be."""


@functools.cache
def _pipe_console_class() -> type[Console]:
    """The rich Console with a closed pipe as :class:`BrokenPipeError`, made on first use (rich loads only then).

    rich's own handling exits 1 (``Console.on_broken_pipe``), which would make ``millctl … | head`` look failed;
    ``main`` ends a BrokenPipeError as 141, quietly.
    """
    from rich.console import Console

    class _PipeConsole(Console):
        def on_broken_pipe(self) -> None:
            self.quiet = True
            raise BrokenPipeError

    return _PipeConsole


def stdout_console() -> Console:
    """A console for data on stdout (rich honours NO_COLOR and detects TTYs)."""
    width = None if sys.stdout.isatty() else PIPE_WIDTH
    return _pipe_console_class()(file=sys.stdout, highlight=False, soft_wrap=True, width=width)


def stderr_console() -> Console:
    """A console for progress and diagnostics on stderr."""
    return _pipe_console_class()(file=sys.stderr, highlight=False, soft_wrap=True)


JSON_SCHEMA_VERSION = 1
"""Version of the CLI's JSON contract: raised when a key is renamed or removed (new keys do not raise it)."""


def plain(data: Any) -> Any:
    """``data`` with every :mod:`millctl.api` model (and model inside lists and dicts) as plain JSON data.

    pydantic is looked up, not imported: a command that never loaded it has no model to turn into data.
    """
    pydantic = sys.modules.get("pydantic")
    if pydantic is not None and isinstance(data, pydantic.BaseModel):
        return data.model_dump(mode="json")
    if isinstance(data, dict):
        return {str(k): plain(v) for k, v in data.items()}
    if isinstance(data, list | tuple):
        return [plain(v) for v in data]
    return data


def command_name(args: Any) -> str:
    """The command as typed: ``set``, ``recipe run``, ``bus load``."""
    words = [str(getattr(args, "command", None) or "")]
    while sub := getattr(args, f"{words[-1]}_command", None):  # bus → log → convert
        words.append(str(sub))
    return " ".join(words)


def json_document(command: str, *, result: Any = None, error: dict[str, Any] | None = None) -> dict[str, Any]:
    """The one shape of every ``--json`` output: schema version, command, ok, the result and/or the error.

    ``ok`` is false exactly when there is an error (and the exit code is not 0).
    """
    document: dict[str, Any] = {"schema": JSON_SCHEMA_VERSION, "command": command, "ok": error is None}
    if result is not None:
        document["result"] = plain(result)
    if error is not None:
        document["error"] = plain(error)
    return document


class _Documents:
    """Where ``--json`` documents go while a command runs, and how many it printed (``main`` adds one if none)."""

    stream: TextIO | None = None
    """The real stdout while a ``--json`` command runs (its other output goes to stderr); None: sys.stdout."""
    printed = 0


@contextlib.contextmanager
def json_mode(enabled: bool) -> Iterator[None]:
    """With ``--json``: stdout carries the one document only; whatever else the command says goes to stderr."""
    _Documents.printed = 0
    if not enabled:
        yield
        return
    _Documents.stream = sys.stdout
    try:
        with contextlib.redirect_stdout(sys.stderr):
            yield
    finally:
        _Documents.stream = None


def documents_printed() -> int:
    """How many JSON documents the running command has printed."""
    return _Documents.printed


def _dump(document: dict[str, Any]) -> None:
    stream = _Documents.stream or sys.stdout
    _Documents.printed += 1
    json.dump(document, stream, indent=2, ensure_ascii=False, default=str)
    stream.write("\n")
    stream.flush()


def print_json(args: Any, result: Any, error: dict[str, Any] | None = None) -> None:
    """Print a command's result (and its error, for a result that is a failure) on stdout, in the contract's shape."""
    _dump(json_document(command_name(args), result=result, error=error))


def print_json_error(args: Any, error: dict[str, Any]) -> None:
    """Print a command's error on stdout, in the JSON contract's shape."""
    _dump(json_document(command_name(args), error=error))


def write_atomically(path: Path, write: Callable[[Path], None]) -> None:
    """Call ``write(tmp)`` on a temporary file beside ``path``, then rename it into place.

    A failure leaves no half-written file behind. The file gets the mode a plain
    ``open()`` would give it under the user's umask (mkstemp's own 0600 would not).
    """
    path = Path(path)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix, dir=path.parent or ".")
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        write(tmp)
        tmp.chmod(0o666 & ~current_umask())
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def current_umask() -> int:
    """The process's umask (read by setting it and putting it back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def hms(seconds: float) -> str:
    """A duration as h:mm:ss (rounded to the second)."""
    whole = round(seconds)
    return f"{whole // 3600:d}:{whole % 3600 // 60:02d}:{whole % 60:02d}"


__all__ = [
    "JSON_SCHEMA_VERSION",
    "command_name",
    "current_umask",
    "documents_printed",
    "hms",
    "json_document",
    "json_mode",
    "plain",
    "print_json",
    "print_json_error",
    "stderr_console",
    "stdout_console",
    "write_atomically",
]
