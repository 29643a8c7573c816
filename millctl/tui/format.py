"""Formatting shared by the TUI's panels: numbers with units, state colours, times."""

from __future__ import annotations

from typing import Any

from millctl.api import ControllerState

S = ControllerState

STATE_STYLE: dict[ControllerState, str] = {
    S.DISCONNECTED: "bold white on grey37",
    S.DISABLED: "bold black on grey70",
    S.ARMED: "bold black on yellow",
    S.RUNNING: "bold black on green",
    S.STOPPING: "bold black on dark_orange",
    S.TRIPPED: "bold white on red",
}
"""Rich style of each controller state."""

MOVING_STATES = frozenset({S.RUNNING, S.STOPPING})
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


def state_style(state: ControllerState | None) -> str:
    """The style a controller state is shown in (plain bold before the first status)."""
    return STATE_STYLE.get(state, "bold") if state is not None else "bold"


def e2e_errors(counts: dict[str, int]) -> int:
    """E2E frames that were not fresh and intact (every classification but ``ok`` and ``ok-some-lost``)."""
    return sum(n for kind, n in counts.items() if kind not in ("ok", "ok-some-lost"))


__all__ = ["MOVING_STATES", "STATE_STYLE", "duration", "e2e_errors", "num", "state_style"]
