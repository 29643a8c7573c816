"""Fixtures: real services (``millctl serve``, simulated node) in subprocesses on temporary sockets; TUI helpers.

The TUI and the service run in separate processes, as they do for an
operator: in one process the screen and the 100 Hz control loop would share
the interpreter lock, and the node's 250 ms watchdog is not meant for that.
"""

from __future__ import annotations

import contextlib
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from textual.pilot import Pilot
from textual.widgets import RichLog

from tests.support.service import (
    REPO,
    START_TIMEOUT_S,
    Service,
    private_dir,
    start_service,
    write_config,
)

__all__ = ["Service", "start_fault_service", "start_service", "until"]


def start_fault_service(directory: Path) -> Service:
    """Start :mod:`tests.support.fault_service` (SIGUSR1: vibration stall, SIGUSR2: clear) in ``directory``."""
    config = write_config(directory)
    log = directory / "serve.log"
    with log.open("wb") as out:
        proc = subprocess.Popen([sys.executable, "-m", "tests.support.fault_service", str(config)], cwd=REPO,
                                stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT)
    service = Service(proc, config, directory / "mill.sock", directory / "records", log)
    deadline = time.monotonic() + START_TIMEOUT_S
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            pytest.fail(f"the fault service exited with {proc.returncode}:\n{service.output()}")
        if service.socket.exists():
            with contextlib.suppress(Exception), service.client() as client:
                if client.status()["state"] == "DISABLED":
                    return service
        time.sleep(0.1)
    service.stop(signal.SIGKILL)
    pytest.fail(f"the fault service did not come up within {START_TIMEOUT_S} s:\n{service.output()}")


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
    """Let the app run until ``condition()`` holds; fail after ``timeout_s`` (a bound, not a timing assertion)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if condition():
            return
        await pilot.pause(0.05)
    app = pilot.app
    status = getattr(app, "status", {})
    shown = f"state {status.get('state')} {status.get('trip_cause') or ''}, online {getattr(app, 'online', None)}"
    log = app.query("#events").results(RichLog)
    recent = [strip.text for widget in log for strip in widget.lines][-6:]
    pytest.fail(f"timed out waiting for {what} (the TUI shows {shown}; its last events: {recent})")
