"""The real TUI in a real pseudo-terminal of 80 × 24, read through a terminal emulator (pyte) as a person sees it.

Issue 39, item 4: at 80 × 24 the state bar, the set dialog's verdict and its
Enter hint are on screen, the footer offers q, the drives' and the furnace's ramp
targets are not cut off, and q quits cleanly.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import pty
import re
import select
import struct
import sys
import termios
from collections.abc import Callable

import pyte
import pytest

from tests.support.pace import Deadline
from tests.support.tui import Service

ROWS, COLUMNS = 24, 80


class Terminal:
    """The pty's output fed into an 80 × 24 emulated screen."""

    def __init__(self, fd: int) -> None:
        self.fd = fd
        self.screen = pyte.Screen(COLUMNS, ROWS)
        self.stream = pyte.ByteStream(self.screen)

    def pump(self, seconds: float = 0.2) -> None:
        """Read what arrived within ``seconds`` into the screen."""
        ready, _, _ = select.select([self.fd], [], [], seconds)
        if ready:
            with contextlib.suppress(OSError):  # the TUI closed the terminal
                self.stream.feed(os.read(self.fd, 65536))

    def rows(self) -> list[str]:
        """The screen, row by row."""
        return list(self.screen.display)

    def until(self, what: str, condition: Callable[[list[str]], bool], seconds: float = 30.0) -> list[str]:
        """Pump until ``condition(rows)``; fail after ``seconds`` (stretched by load) showing the screen."""
        deadline = Deadline(seconds)
        while not condition(self.rows()):
            if deadline.expired():
                pytest.fail(f"the TUI at 80 × 24 did not show {what} within {deadline.describe()}:\n"
                            + "\n".join(self.rows()))
            self.pump()
        return self.rows()


def test_at_80_by_24_the_state_bar_the_verdict_and_quit_are_on_screen(fault_service: Service) -> None:
    pid, fd = pty.fork()
    if pid == 0:  # the child: the TUI on an 80 × 24 terminal, sized before it starts
        fcntl.ioctl(0, termios.TIOCSWINSZ, struct.pack("HHHH", ROWS, COLUMNS, 0, 0))
        os.environ["TERM"] = "xterm-256color"
        os.execv(sys.executable, [sys.executable, "-m", "millctl", "--config", str(fault_service.config), "tui"])
    done = 0
    term = Terminal(fd)
    try:
        rows = term.until("the state bar and the footer",
                          lambda r: "DISABLED" in r[0] and "millctl" in r[0] and "Quit" in r[-1])
        assert "q Quit" in rows[-1], rows[-1]
        os.write(fd, b"a")  # set needs ARMED
        term.until("ARMED in the state bar", lambda r: "ARMED" in r[0])
        term.until("each drive's ramp target in full (it was cut after 'target')",
                   lambda r: sum(bool(re.search(r"set \S+ → \S+ rpm", row)) for row in r) == 2
                   and any(re.search(r"set \S+ → (\S+ °C|heater off)", row) for row in r))
        os.write(fd, b"s")
        rows = term.until("the set dialog's limit, verdict and keys",
                          lambda r: any("Enter: check and send" in row for row in r)
                          and any("limit at ω_v" in row for row in r)
                          and any("inside the envelope" in row or "refused:" in row for row in r))
        bar = next(i for i, row in enumerate(rows) if "millctl" in row and "ARMED" in row)
        top = next(i for i, row in enumerate(rows) if "Set speeds and furnace" in row)
        assert bar < top, "\n".join(rows)  # the state bar stays in sight, above the dialog
        os.write(fd, b"\x1b")  # Esc closes the dialog
        term.until("the main screen again", lambda r: not any("Enter: check and send" in row for row in r))
        os.write(fd, b"q")
        deadline = Deadline(30.0)
        status, asked = 0, False
        while done == 0 and not deadline.expired():
            term.pump(0.5)
            if not asked and any("Quit?" in row for row in term.rows()):  # asked while the drives are enabled
                os.write(fd, b"y")
                asked = True
            done, status = os.waitpid(pid, os.WNOHANG)
        assert done == pid and os.waitstatus_to_exitcode(status) == 0, "\n".join(term.rows())
    finally:
        os.close(fd)
        if not done:
            os.kill(pid, 9)
            os.waitpid(pid, 0)
