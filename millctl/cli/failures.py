"""How a failed command reports itself: the exit code, a message naming the CLI flag, and the JSON error.

The service names request fields as the API does (``body.rotary_rpm``) and the
interlock names quantities as the physics does (``omega_r``); a user typed
``--rot-rpm``. :data:`FLAGS` maps each to the flag, so every message and every
JSON error names what the user can change.
"""

from __future__ import annotations

import re
import sys
from typing import Any

from millctl.errors import ExitCode, MillctlError

FLAGS = {
    "rotary_rpm": "--rot-rpm",
    "vibration_rpm": "--vib-rpm",
    "temp_c": "--temp-c",
    "rotary_rate_rpm_s": "--rot-rate",
    "vibration_rate_rpm_s": "--vib-rate",
    "rate_c_per_min": "--heat-rate",
    "omega_r": "--rot-rpm",
    "omega_v": "--vib-rpm",
    "omega_r_rate": "--rot-rate",
    "omega_v_rate": "--vib-rate",
    "temp": "--temp-c",
    "heating_rate": "--heat-rate",
    "path": "FILE",
    "X-Millctl-Lease": "--force (control)",
}
"""API field or interlock quantity → the CLI flag that sets it."""

_API_FIELD = re.compile(r"\bbody\.([a-z_]+)")

EXIT_NAMES = {
    ExitCode.INVALID_INPUT: "invalid_input",
    ExitCode.INTERLOCK: "refused",
    ExitCode.BUS: "unavailable",
    ExitCode.INTERNAL: "internal_error",
    ExitCode.INTERRUPTED: "interrupted",
}
"""The JSON error ``code`` of a failure that has no API code, by exit code."""


def flag_of(name: str | None) -> str | None:
    """The CLI flag for an API field (``body.rotary_rpm``) or an interlock quantity (``omega_r``)."""
    if not name:
        return None
    return FLAGS.get(name.removeprefix("body."))


def with_flags(message: str) -> str:
    """``message`` with every API field path (``body.rotary_rpm``) replaced by its CLI flag."""
    return _API_FIELD.sub(lambda m: FLAGS.get(m.group(1), m.group(0)), message)


def describe_failure(exc: BaseException) -> tuple[int, str, dict[str, Any]]:
    """The exit code, the one-line message and the JSON error of a failure.

    The client's errors are looked up, not imported (httpx, pydantic): a command that never loaded the client
    cannot have raised one.
    """
    client_errors = sys.modules.get("millctl.client_errors")
    if isinstance(exc, KeyboardInterrupt):
        code = int(ExitCode.INTERRUPTED)
        return code, "interrupted", {"code": EXIT_NAMES[ExitCode.INTERRUPTED], "message": "interrupted",
                                     "exit_code": code}
    if not isinstance(exc, MillctlError):
        message = f"internal error: {type(exc).__name__}: {exc} (rerun with --debug)"
        return int(ExitCode.INTERNAL), message, {"code": EXIT_NAMES[ExitCode.INTERNAL], "message": message,
                                                 "exit_code": int(ExitCode.INTERNAL)}
    exit_code = exc.exit_code
    message = with_flags(str(exc))
    error: dict[str, Any] = {"code": EXIT_NAMES.get(exit_code, "error"), "message": message,
                             "exit_code": int(exit_code)}
    if client_errors is not None and isinstance(exc, client_errors.RequestInvalid):
        error["flag"] = flag_of(exc.field)
    if client_errors is not None and isinstance(exc, client_errors.ServiceRefused):
        error["code"] = exc.code.value
        error["flag"] = flag_of(exc.error.field)
        if exc.error.holder:
            error["holder"] = exc.error.holder
    if client_errors is not None and isinstance(exc, client_errors.InterlockRefusal):
        error["refusals"] = [{**r.model_dump(mode="json"), "flag": flag_of(r.quantity)} for r in exc.refusals]
    problems = getattr(exc, "problems", None)
    if isinstance(problems, list):
        error["problems"] = [with_flags(str(p)) for p in problems]
    return int(exit_code), message, error


__all__ = ["EXIT_NAMES", "FLAGS", "describe_failure", "flag_of", "with_flags"]
