"""Fixtures: real services (``millctl serve``, simulated node) in subprocesses on temporary sockets; TUI helpers.

The TUI and the service run in separate processes, as they do for an
operator: in one process the screen and the 100 Hz control loop would share
the interpreter lock, and the node's 250 ms watchdog is not meant for that.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from textual.pilot import Pilot
from textual.widgets import RichLog

from tests.support.pace import Deadline
from tests.support.service import (
    Service,
    private_dir,
    start_service,
    write_config,
)

__all__ = ["Service", "start_fault_service", "start_service", "until"]


def start_fault_service(directory: Path) -> Service:
    """Start ``millctl serve --fault-injection`` in ``directory``: faults are injected through ``/v1/sim/faults``."""
    config = write_config(directory)
    return start_service(
        directory,
        module_args=["millctl", "--config", str(config), "serve", "--fault-injection"],
        what="millctl serve --fault-injection",
    )


@pytest.fixture
def service_dir() -> Iterator[Path]:
    """A short private directory for a socket and records, removed afterwards."""
    with private_dir() as directory:
        yield directory


@pytest.fixture
def fault_service(service_dir: Path) -> Iterator[Service]:
    """A service whose embedded node accepts injected faults; stopped (SIGTERM) at teardown."""
    service = start_fault_service(service_dir)
    try:
        yield service
    finally:
        service.stop()


async def until(pilot: Pilot[None], condition: Callable[[], bool], what: str, timeout_s: float = 15.0) -> None:
    """Let the app run until ``condition()`` holds; fail after ``timeout_s`` (a bound, not a timing assertion).

    ``timeout_s`` is for an idle machine; it stretches with load (:class:`tests.support.pace.Deadline`).
    """
    deadline = Deadline(timeout_s)
    while not deadline.expired():
        if condition():
            return
        await pilot.pause(0.05)
    app = pilot.app
    status = getattr(app, "status", None)  # a typed StatusOut once the first status arrived
    state = getattr(status, "state", None)
    cause = getattr(status, "trip_cause", None) or ""
    shown = f"state {state} {cause}, online {getattr(app, 'online', None)}"
    log = app.query("#events").results(RichLog)
    recent = [strip.text for widget in log for strip in widget.lines][-6:]
    pytest.fail(
        f"timed out after {deadline.describe()} waiting for {what} (the TUI shows {shown}; its last events: {recent})"
    )
