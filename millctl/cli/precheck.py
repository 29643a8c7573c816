"""The CLI's first look at the files a command names, before anything heavy is imported (issue 37, item 5).

A configuration named by ``--config`` or ``$MILLCTL_CONFIG``, and the recipe or
configuration file of ``recipe check|plan|run FILE`` and ``config check FILE``,
are read here as the loader reads them (:func:`millctl.files.read_input_file`:
a regular file under its bound; UTF-8; TOML nested at most
``MAX_TOML_DEPTH`` deep) using only the standard library. A device, a FIFO, a
huge file, bad syntax or a nesting attack is refused at once with exit 1 and the
loader's own message, instead of after numpy, numba, scipy, pydantic and the
planner have loaded (seconds on a loaded host). A file that passes is read again
by the real loader, which validates it; this check decides nothing the loader
would decide otherwise (tests/unit/test_cli_precheck.py holds the two together).
"""

from __future__ import annotations

import argparse
import os
import tomllib
from pathlib import Path
from typing import Any

from millctl.errors import ConfigError, InvalidFileError, RecipeError
from millctl.files import FileRefused, read_input_file

MAX_TOML_DEPTH = 32
"""Tables and arrays nest at most this deep (the same bound as ``millctl.config.loader.MAX_TOML_DEPTH``)."""

CONFIG_ENV_VAR = "MILLCTL_CONFIG"
"""The environment variable naming the configuration (``millctl.config.loader.ENV_VAR``)."""

FILE_COMMANDS: dict[tuple[str, str], type[InvalidFileError]] = {
    ("recipe", "check"): RecipeError,
    ("recipe", "plan"): RecipeError,
    ("recipe", "run"): RecipeError,
    ("config", "check"): ConfigError,
}
"""(command, action) whose positional ``file`` is checked here → the error its loader raises."""

NO_CONFIG_COMMANDS = frozenset({"completion"})
"""Commands that never read the configuration: a ``--config`` they are given is not looked at."""


def _depth(data: object) -> int:
    """How many tables and arrays deep ``data`` goes, counted without recursion and stopping past the bound."""
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


def check_toml_file(path: str | os.PathLike[str], error: type[InvalidFileError]) -> dict[str, Any]:
    """Read and parse the TOML file ``path`` as the loader does; raise ``error`` naming it and what is wrong."""
    source = str(path)
    try:
        raw = read_input_file(path)
    except FileRefused as exc:
        raise error(source, [str(exc)]) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(source, [f"{source}: not UTF-8 text ({exc.reason})"]) from None
    too_deep = (f"{source}: arrays or inline tables nested too deeply: the bound is {MAX_TOML_DEPTH} levels "
                "(a millctl file needs at most 3)")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(source, [f"{source}: TOML syntax error: {exc}"]) from None
    except RecursionError:  # deeper than the parser itself can go: far past the bound
        raise error(source, [f"{too_deep}; this one is nested deeper than the TOML parser can go"]) from None
    if _depth(data) > MAX_TOML_DEPTH:
        raise error(source, [f"{too_deep}; this one is nested more than {MAX_TOML_DEPTH} levels deep"])
    return data


def named_files(args: argparse.Namespace) -> list[tuple[Path, type[InvalidFileError]]]:
    """The files the parsed command line names for reading, each with the error its loader raises."""
    command = str(getattr(args, "command", None) or "")
    found: list[tuple[Path, type[InvalidFileError]]] = []
    if command not in NO_CONFIG_COMMANDS:
        config = getattr(args, "config", None) or os.environ.get(CONFIG_ENV_VAR, "").strip()
        if config:
            found.append((Path(config), ConfigError))
    action = str(getattr(args, f"{command}_command", None) or "")
    error = FILE_COMMANDS.get((command, action))
    file = getattr(args, "file", None)
    if error is not None and isinstance(file, str):
        found.append((Path(file), error))
    return found


def precheck(args: argparse.Namespace) -> None:
    """Refuse (raise the loader's error) a named file that is no regular file, too big, not TOML or nested too deep."""
    for path, error in named_files(args):
        check_toml_file(path, error)


__all__ = ["FILE_COMMANDS", "MAX_TOML_DEPTH", "check_toml_file", "named_files", "precheck"]
