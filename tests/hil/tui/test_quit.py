"""Quitting the real TUI (a terminal, not the test pilot) while the mill runs: a clean exit, no traceback."""

from __future__ import annotations

import fcntl
import os
import pty
import re
import select
import struct
import subprocess
import sys
import termios
import time

import pytest

from millctl.api import ControllerState
from tests.support.pace import Deadline, stretched
from tests.support.service import wait_for
from tests.support.tui import Service

ANSI = re.compile(r"\x1b\[[0-9;?<>]*[a-zA-Z]")


def _read(fd: int, seconds: float) -> bytes:
    """What the terminal shows within ``seconds`` (wall time: a short poll, not a wait for a process)."""
    got, end = b"", time.monotonic() + seconds
    while time.monotonic() < end:
        ready, _, _ = select.select([fd], [], [], 0.1)
        if ready:
            try:
                got += os.read(fd, 65536)
            except OSError:  # the TUI closed the terminal
                break
    return got


def _read_until(fd: int, text: str, seconds: float) -> str:
    """Read the terminal until ``text`` shows (escape codes stripped); fail after ``seconds``, stretched by load."""
    shown, deadline = "", Deadline(seconds)
    while text not in shown:
        if deadline.expired():
            pytest.fail(f"the TUI did not show {text!r} within {deadline.describe()}: {shown[-2000:]!r}")
        shown += ANSI.sub("", _read(fd, 0.5).decode(errors="replace"))
    return shown


def test_quit_while_running_ends_without_a_traceback(fault_service: Service) -> None:
    base = [sys.executable, "-m", "millctl", "--config", str(fault_service.config)]
    subprocess.run([*base, "arm"], check=True, capture_output=True, timeout=stretched(60.0))
    with fault_service.client() as client:
        wait_for(lambda: client.status().state is ControllerState.ARMED, what="ARMED")
    subprocess.run([*base, "set", "--rot-rpm", "20", "--vib-rpm", "300"], check=True, capture_output=True,
                   timeout=stretched(60.0))
    with fault_service.client() as client:
        wait_for(lambda: client.status().state is ControllerState.RUNNING, what="RUNNING")
    pid, fd = pty.fork()
    if pid == 0:  # the child: the TUI on a 120 × 40 terminal
        os.environ["TERM"] = "xterm-256color"
        os.execv(sys.executable, [*base, "tui"])
    try:
        fcntl.ioctl(fd, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 120, 0, 0))
        _read_until(fd, "RUNNING", 30.0)  # the TUI is up and has the service's status
        os.write(fd, b"q")
        _read_until(fd, "Quit?", 10.0)
        os.write(fd, b"y")
        after = b""
        deadline, done = Deadline(30.0), 0
        while done == 0 and not deadline.expired():
            after += _read(fd, 0.5)
            done, status = os.waitpid(pid, os.WNOHANG)
        text = ANSI.sub("", after.decode(errors="replace"))
        assert done == pid and os.waitstatus_to_exitcode(status) == 0, text[-2000:]
        assert "Traceback" not in text and "InvalidStateError" not in text, text[-3000:]
    finally:
        os.close(fd)
        if not done:
            os.kill(pid, 9)
            os.waitpid(pid, 0)
