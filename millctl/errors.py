"""The narrow exception tree of millctl, and the documented process exit codes.

Every error that reaches a user says the value, the bound, the object and
where to read more; each class maps to one :class:`ExitCode`.
"""

from __future__ import annotations

import enum
import re


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


class StudyError(InvalidFileError):
    """A study file is missing, unreadable, or fails validation (:mod:`millctl.studies.schema`)."""

    what = "study"


_STEP_LOCATION = re.compile(r"\bsteps\.(\d+)(?:\.(?:ramp|hold|wait_furnace|pause))?(\.)?")
"""A validation error's location in the steps list (``steps.2.ramp.rotary_rpm``: 0-based, with the union's tag)."""


def _step_one_based(match: re.Match[str]) -> str:
    return f"step {int(match.group(1)) + 1}" + (" " if match.group(2) else "")


class RecipeError(InvalidFileError):
    """A recipe file is missing, unreadable, fails validation, or leaves the envelope.

    Steps are numbered from 1 in every message, as the pre-flight and the runner number them: pydantic's
    ``steps.2.ramp.rotary_rpm`` reads ``step 3 rotary_rpm``.
    """

    what = "recipe"

    def __init__(self, source: str, problems: list[str]) -> None:
        super().__init__(source, [_STEP_LOCATION.sub(_step_one_based, p) for p in problems])


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
    "StudyError",
]
