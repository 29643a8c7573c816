"""Events the controller reports: state changes, commands, refusals and trips, each with a reason."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from millctl.api.enums import EventKind


@dataclass(frozen=True)
class Event:
    """One thing the controller did or saw, with its reason (docs/safety.md#state-machine)."""

    time_s: float
    """Controller clock time (s)."""
    kind: EventKind
    source: str
    """Who caused it: ``operator``, ``recipe``, ``interlock``, ``node``, ``api:<client>`` …"""
    message: str
    data: dict[str, Any] = field(default_factory=dict)
    wall_time: float = field(default_factory=time.time)
    """Unix time when it happened (s)."""


EventListener = Callable[[Event], None]

__all__ = ["Event", "EventKind", "EventListener"]
