"""The CLI's first look at the files a command names, before anything heavy is imported (issue 37, item 5).

A configuration named by ``--config`` or ``$MILLCTL_CONFIG``, the recipe or
configuration file of ``recipe check|plan|run FILE`` and ``config check FILE``,
and the study of ``study FILE`` are read here with the loaders' own function (:func:`millctl.files.read_toml`:
a regular file under its bound; UTF-8; TOML nested at most
``MAX_TOML_DEPTH`` deep), which needs only the standard library. A device, a
FIFO, a huge file, bad syntax or a nesting attack is refused at once with exit 1
and the loader's own message, instead of after numpy, numba, scipy, pydantic and
the planner have loaded (seconds on a loaded host). A file that passes is read
again by the real loader, which validates it (tests/unit/test_cli_startup.py).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Any

from millctl.errors import ConfigError, InvalidFileError, RecipeError, StudyError
from millctl.files import MAX_TOML_DEPTH, read_toml

CONFIG_ENV_VAR = "MILLCTL_CONFIG"
"""The environment variable naming the configuration (``millctl.config.loader.ENV_VAR``)."""

FILE_COMMANDS: dict[tuple[str, str], type[InvalidFileError]] = {
    ("recipe", "check"): RecipeError,
    ("recipe", "plan"): RecipeError,
    ("recipe", "run"): RecipeError,
    ("config", "check"): ConfigError,
    ("study", ""): StudyError,
}
"""(command, action) whose positional ``file`` is checked here → the error its loader raises."""

NO_CONFIG_COMMANDS = frozenset({"completion"})
"""Commands that never read the configuration: a ``--config`` they are given is not looked at."""


def check_toml_file(path: str | os.PathLike[str], error: type[InvalidFileError]) -> dict[str, Any]:
    """Read and parse the TOML file ``path`` as the loader does (:func:`millctl.files.read_toml`); raise ``error``."""
    return read_toml(Path(path), error)[0]


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
