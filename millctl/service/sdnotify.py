"""systemd's notify protocol, stdlib only: READY=1 and WATCHDOG=1 over ``$NOTIFY_SOCKET`` (sd_notify(3)).

Under ``Type=notify`` systemd waits for READY=1 before it counts the service
started; with ``WatchdogSec=`` it restarts a service that sends no WATCHDOG=1
for that long. The control loop sends WATCHDOG=1 (:class:`Notifier`), so a
hung loop is restarted, after the node's own watchdog has stopped the mill
(docs/deployment.md#systemd). Outside systemd ``$NOTIFY_SOCKET`` is unset and
every call does nothing.
"""

from __future__ import annotations

import logging
import os
import socket

log = logging.getLogger(__name__)


def _address(raw: str) -> str:
    """The socket address: a leading ``@`` is Linux's abstract namespace (a NUL byte)."""
    return "\0" + raw[1:] if raw.startswith("@") else raw


class Notifier:
    """Sends notify messages to ``$NOTIFY_SOCKET`` (or to ``path``); the WATCHDOG=1 pings at half ``WATCHDOG_USEC``."""

    def __init__(self, path: str | None = None, watchdog_usec: str | None = None) -> None:
        self.path = os.environ.get("NOTIFY_SOCKET", "") if path is None else path
        raw = os.environ.get("WATCHDOG_USEC", "") if watchdog_usec is None else watchdog_usec
        self.watchdog_s = int(raw) / 1e6 if raw.isdigit() and int(raw) > 0 else None
        """systemd's watchdog interval (s), None when it has none."""
        self._next_ping_s = 0.0
        self.failures = 0

    @property
    def enabled(self) -> bool:
        """True under systemd (a notify socket is named)."""
        return bool(self.path)

    def send(self, message: str) -> bool:
        """Send one datagram (e.g. ``READY=1``); False when there is no socket or it failed (logged, never raised)."""
        if not self.path:
            return False
        try:
            with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM | socket.SOCK_CLOEXEC) as sock:
                sock.sendto(message.encode(), _address(self.path))
        except OSError as exc:
            self.failures += 1
            log.warning("sd_notify %r to %s failed: %s", message, self.path, exc)
            return False
        return True

    def ready(self, status: str = "") -> bool:
        """READY=1 (with a STATUS= line when given)."""
        return self.send("READY=1" + (f"\nSTATUS={status}" if status else ""))

    def ping(self, now_s: float) -> bool:
        """WATCHDOG=1 when half the watchdog interval has passed since the last one (``now_s``: time.monotonic)."""
        if self.watchdog_s is None or now_s < self._next_ping_s:
            return False
        self._next_ping_s = now_s + self.watchdog_s / 2.0
        return self.send("WATCHDOG=1")

    def stopping(self) -> bool:
        """STOPPING=1: the service begins its controlled shutdown."""
        return self.send("STOPPING=1")


__all__ = ["Notifier"]
