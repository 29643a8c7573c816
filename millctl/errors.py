"""The narrow exception tree of millctl, and the documented process exit codes.

Every error that reaches a user says the value, the bound, the object and
where to read more; each class maps to one :class:`ExitCode`.
"""

from __future__ import annotations

import enum


class ExitCode(enum.IntEnum):
    """Process exit codes of every ``millctl`` command (documented in ``--help``)."""

    OK = 0
    INVALID_INPUT = 1
    INTERLOCK = 2
    BUS = 3
    INTERNAL = 4
    INTERRUPTED = 130
    """Ctrl+C (128 + SIGINT), never mistaken for a refusal."""
    BROKEN_PIPE = 141
    """The reader of stdout went away (``| head``; 128 + SIGPIPE): ended quietly."""


class MillctlError(Exception):
    """Base class of every error millctl raises on purpose."""

    exit_code: ExitCode = ExitCode.INTERNAL


class InvalidInputError(MillctlError, ValueError):
    """Bad input from a user: config, recipe, CLI argument or API request."""

    exit_code = ExitCode.INVALID_INPUT


class InvalidFileError(InvalidInputError):
    """An input file is missing, unreadable, or fails validation.

    ``problems`` holds one line per problem, each naming the file, the field,
    the value and the bound.
    """

    what = "file"

    def __init__(self, source: str, problems: list[str]) -> None:
        self.source = source
        self.problems = problems
        lines = "\n".join(f"  {p}" for p in problems)
        super().__init__(f"invalid {self.what} {source}:\n{lines}")


class ConfigError(InvalidFileError):
    """A mill configuration file is missing, unreadable, or fails validation."""

    what = "configuration"


class RecipeError(InvalidFileError):
    """A recipe file is missing, unreadable, fails validation, or leaves the envelope."""

    what = "recipe"


class PhysicsInputError(InvalidInputError):
    """Physical parameters that describe no real mill (negative radii, rods that do not fit)."""


class InterlockError(MillctlError):
    """The interlock refused a request or tripped; the run must not go on."""

    exit_code = ExitCode.INTERLOCK


class BusError(MillctlError):
    """The CAN bus, the node or the service could not be reached or misbehaved."""

    exit_code = ExitCode.BUS


__all__ = [
    "BusError",
    "ConfigError",
    "ExitCode",
    "InterlockError",
    "InvalidFileError",
    "InvalidInputError",
    "MillctlError",
    "PhysicsInputError",
    "RecipeError",
]
