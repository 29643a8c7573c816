"""Snapshots of the main screen at 120 × 40 with frozen content (no service, no clock, no noise)."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest
from textual.pilot import Pilot

from millctl.tui import MillApp
from tests.unit.tui import frozen

SIZE = (120, 40)


@pytest.fixture
def utc(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """Event times shown in UTC, whatever the machine's zone."""
    monkeypatch.setenv("TZ", "UTC")
    time.tzset()
    yield
    monkeypatch.undo()
    time.tzset()


def feeder(app: MillApp, **status: Any) -> Callable[[Pilot[None]], Any]:
    """Feed the app a run of frozen statuses (the trends), the envelope, the lease, a recipe and events."""

    async def feed(pilot: Pilot[None]) -> None:
        app.apply_envelope(frozen.ENVELOPE)
        for i in range(40):
            app.apply_status(frozen.status_at(i, **status))
        app.apply_control(frozen.CONTROL)
        app.apply_recipe(frozen.RECIPE)
        for event in frozen.EVENTS:
            app.apply_event(event, live=False)
        await pilot.pause()

    return feed


def test_main_screen_running(snap_compare: Any, utc: None) -> None:
    app = MillApp(frozen.SOCKET, live=False)
    assert snap_compare(app, terminal_size=SIZE, run_before=feeder(app))


def test_main_screen_tripped_shows_the_banner(snap_compare: Any, utc: None) -> None:
    app = MillApp(frozen.SOCKET, live=False)
    cause = "node fault STALL (fault bits <FaultFlag.STALL: 32>)"
    assert snap_compare(app, terminal_size=SIZE, run_before=feeder(app, state="TRIPPED", trip_cause=cause))
