"""Formatting shared by the TUI's panels: numbers with units, state colours, times."""

from __future__ import annotations

from typing import Any

STATE_STYLE = {
    "DISCONNECTED": "bold white on grey37",
    "DISABLED": "bold black on grey70",
    "ARMED": "bold black on yellow",
    "RUNNING": "bold black on green",
    "STOPPING": "bold black on dark_orange",
    "TRIPPED": "bold white on red",
}
"""Rich style of each controller state (millctl.controller.ControllerState values)."""

MOVING_STATES = frozenset({"RUNNING", "STOPPING"})
"""States in which the drives may be turning (quitting asks first)."""


def num(value: Any, fmt: str = ".1f", unit: str = "") -> str:
    """``value`` formatted with ``fmt`` and ``unit``, or an em dash when unknown."""
    if value is None:
        return "—"
    return f"{value:{fmt}}{unit}"


def duration(seconds: float | None) -> str:
    """A duration in s as ``h:mm:ss`` or ``m:ss``; an em dash when unknown."""
    if seconds is None:
        return "—"
    total = max(round(seconds), 0)
    hours, rest = divmod(total, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"


def state_style(state: str) -> str:
    """The style a controller state is shown in."""
    return STATE_STYLE.get(state, "bold")


def e2e_errors(counts: dict[str, Any]) -> int:
    """E2E frames that were not fresh and intact (every classification but ``ok`` and ``ok-some-lost``)."""
    return sum(int(n) for kind, n in counts.items() if kind not in ("ok", "ok-some-lost"))


__all__ = ["MOVING_STATES", "STATE_STYLE", "duration", "e2e_errors", "num", "state_style"]
