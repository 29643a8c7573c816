"""The API's connections: each request must arrive whole within a bound, and their number stays under the file limit.

uvicorn times out only idle keep-alive connections (``timeout_keep_alive``,
between requests) and bounds only requests (``limit_concurrency``, answered
503, which would refuse an E-stop). A client that sends half a request and
waits was kept forever, and 1,100 of them took every file descriptor of a
service at the systemd default of 1,024: the E-stop could not connect
(issue 37). :class:`GuardedH11Protocol`, uvicorn's h11 protocol with two
guards, closes that:

* **A deadline on every request** (REQUEST_TIMEOUT_S): a new connection, or
  one that starts a request after a response, must deliver the whole request
  (headers and body) within the bound, or it is closed. Idle keep-alive
  connections keep uvicorn's own timeout (``SERVICE_KEEP_ALIVE_S``).
* **A bound on connections** below the file limit (:func:`max_connections`:
  RLIMIT_NOFILE as it is now, less FDS_KEPT for the service's own files and
  the listen backlog, at most MAX_CONNECTIONS). A connection over the bound
  makes room by closing the one that has waited longest without a request
  being answered (half-sent or idle); only when every connection is busy
  with a request is the newcomer closed instead. So an operator's STOP or
  E-stop always gets a connection: the room is taken from the idlest client,
  never refused (SAFETY 24; docs/deployment.md#connections).
"""

from __future__ import annotations

import asyncio
import logging
import resource
import time
from typing import Any, ClassVar

import h11
from uvicorn.protocols.http.h11_impl import H11Protocol

log = logging.getLogger(__name__)

REQUEST_TIMEOUT_S = 10.0
"""A request must arrive whole (headers and body) within this long of its first byte, or of the connection (s)."""
MAX_CONNECTIONS = 1024
"""The most connections the API keeps open, whatever the file limit."""
FDS_KEPT = 256
"""File descriptors kept out of the connections' reach: the service's own files (bus, records, logs, sockets)
and the connections accepted in one burst before their protocol sees them (LISTEN_BACKLOG)."""
LISTEN_BACKLOG = 64
"""The listen backlog, and so the most connections accepted at once before the bound is applied to them."""
WARN_EVERY_S = 10.0
"""Closed connections are logged at most this often (a summary with the count), never once each."""

_RECEIVING = (h11.IDLE, h11.SEND_BODY)
"""h11 states of the client's side while its request has not arrived whole."""


def max_connections() -> int:
    """How many connections the API may keep now: below RLIMIT_NOFILE (read each time) by FDS_KEPT."""
    soft, _ = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft == resource.RLIM_INFINITY:
        return MAX_CONNECTIONS
    return max(1, min(MAX_CONNECTIONS, soft - FDS_KEPT))


class _Tally:
    """Closed connections by reason, logged together at most every WARN_EVERY_S."""

    def __init__(self) -> None:
        self.counts: dict[str, int] = {}
        self.logged_s = -WARN_EVERY_S

    def add(self, reason: str) -> None:
        self.counts[reason] = self.counts.get(reason, 0) + 1
        now = time.monotonic()
        if now - self.logged_s >= WARN_EVERY_S:
            shown = ", ".join(f"{count} {what}" for what, count in sorted(self.counts.items()))
            log.warning("API connections closed since the last report: %s (docs/deployment.md#connections)", shown)
            self.counts.clear()
            self.logged_s = now


class GuardedH11Protocol(H11Protocol):
    """uvicorn's h11 protocol with a deadline on each request and a bound on the number of connections.

    One subclass per server (:func:`guarded_protocol`): ``waiting`` holds the server's connections without a
    request being answered, oldest first, the ones to close when the bound is reached.
    """

    waiting: ClassVar[dict[GuardedH11Protocol, None]]
    tally: ClassVar[_Tally]
    request_timeout_s: ClassVar[float] = REQUEST_TIMEOUT_S

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._deadline: asyncio.TimerHandle | None = None

    # ------------------------------------------------------------------ asyncio.Protocol
    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        """Start the request's deadline; over the bound, close the connection that has waited longest."""
        super().connection_made(transport)
        self._arm()
        self._wait()
        if len(self.connections) > max_connections():
            self._make_room()

    def data_received(self, data: bytes) -> None:
        """A request's first bytes start its deadline; once the request is whole, the deadline ends."""
        if self._deadline is None and self.conn.their_state is h11.IDLE:
            self._arm()  # a new request on a kept-alive connection
        super().data_received(data)
        if self.conn.their_state not in _RECEIVING:
            self._disarm()
            self.waiting.pop(self, None)  # a request being answered: never closed for room

    def connection_lost(self, exc: Exception | None) -> None:
        """Forget the connection."""
        self._disarm()
        self.waiting.pop(self, None)
        super().connection_lost(exc)

    def on_response_complete(self) -> None:
        """After a response the connection waits again (uvicorn's keep-alive timeout applies, not the deadline)."""
        super().on_response_complete()
        if not self.transport.is_closing() and self.conn.their_state is h11.IDLE and self._deadline is None:
            self._wait()

    # ------------------------------------------------------------------ the guards
    def _arm(self) -> None:
        self._disarm()
        self._deadline = self.loop.call_later(self.request_timeout_s, self._timed_out)

    def _disarm(self) -> None:
        if self._deadline is not None:
            self._deadline.cancel()
            self._deadline = None

    def _wait(self) -> None:
        self.waiting.pop(self, None)
        self.waiting[self] = None  # the newest waiter, last to be closed for room

    def _timed_out(self) -> None:
        self._deadline = None
        if self.conn.their_state in _RECEIVING and not self.transport.is_closing():
            self.tally.add(f"not sending a whole request within {self.request_timeout_s:.0f} s")
            self._close()

    def _make_room(self) -> None:
        victim = next((c for c in self.waiting if c is not self), None)
        if victim is None:
            self.tally.add(f"over the bound of {max_connections()} connections, all busy with a request")
            self._close()
            return
        self.tally.add(f"waiting longest without a request while the bound of {max_connections()} was reached")
        victim._close()

    def _close(self) -> None:
        self._disarm()
        self.waiting.pop(self, None)
        self.transport.abort()  # at once: its descriptor is what the bound is about


def guarded_protocol(request_timeout_s: float = REQUEST_TIMEOUT_S) -> type[GuardedH11Protocol]:
    """A protocol class for one server: its own register of waiting connections and its own log tally."""

    class ServiceH11Protocol(GuardedH11Protocol):
        waiting: ClassVar[dict[GuardedH11Protocol, None]] = {}
        tally: ClassVar[_Tally] = _Tally()

    ServiceH11Protocol.request_timeout_s = request_timeout_s
    return ServiceH11Protocol


__all__ = [
    "FDS_KEPT",
    "LISTEN_BACKLOG",
    "MAX_CONNECTIONS",
    "REQUEST_TIMEOUT_S",
    "GuardedH11Protocol",
    "guarded_protocol",
    "max_connections",
]
