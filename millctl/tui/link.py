"""The TUI's connection to the service: the async client, the control lease, and error text for the operator.

Everything here runs on the TUI's event loop as coroutines (the client is
:class:`millctl.client.AsyncClient`), so no call ever blocks the screen. The
lease is taken when the operator first commands, renewed while held (a lease
lapses after 30 s without a command), and released on quit.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import AsyncGenerator, Awaitable, Callable
from typing import Any, TypeVar

import httpx
from textual.notifications import SeverityLevel

from millctl.api import CheckOut, CommandOut, LeaseOut
from millctl.client import (
    AsyncClient,
    ControlHeld,
    InterlockRefusal,
    NodeUnavailable,
    RequestInvalid,
    ServiceRefused,
    ServiceUnavailable,
    StreamItem,
)
from millctl.errors import MillctlError

T = TypeVar("T")
log = logging.getLogger(__name__)

CLIENT_NAME = "tui"
"""Recorded by the service as the source ``api:tui@<host>``."""
LINK_ERRORS = (MillctlError, httpx.HTTPError, OSError)
"""What a lost or refused connection can raise; the TUI shows them and carries on."""
STREAM_SILENCE_S = 5.0
"""With no status for this long the stream is taken for dead and reopened (the service sends one every 0.25 s)."""


RACED_READ = "Exception in callback Future.set_result"
"""How asyncio reports a socket read's wake-up that lost the race with its cancellation (see below)."""


def quiet_raced_reads(loop: asyncio.AbstractEventLoop, context: dict[str, Any]) -> None:
    """The TUI's asyncio exception handler: a socket read cancelled as its data arrived is not an error.

    anyio (under httpx's Unix-socket transport) waits for a readable socket
    with ``loop.add_reader(sock, future.set_result, None)``. When the read is
    cancelled (quitting, or a reconnect) in the same loop iteration as the data
    arrives, the queued wake-up then calls ``set_result`` on a cancelled future
    and asyncio prints an ``InvalidStateError`` traceback on the operator's
    terminal. Nothing was lost: the read had been given up. Logged at debug
    level; every other error goes to asyncio's default handler.
    """
    if isinstance(context.get("exception"), asyncio.InvalidStateError) and str(
        context.get("message", "")
    ).startswith(RACED_READ):
        log.debug("a cancelled socket read raced its data (harmless): %s", context.get("handle"))
        return
    loop.default_exception_handler(context)


def describe(exc: BaseException) -> tuple[str, SeverityLevel]:
    """A one-line message for the operator and a notification severity for an error from the service."""
    if isinstance(exc, InterlockRefusal):
        details = "; ".join(r.reason for r in exc.refusals if r.reason)
        return f"refused by the interlock: {details or exc.reason}", "error"
    if isinstance(exc, ControlHeld):
        holder = exc.holder
        hint = f"{holder} holds control" if holder else exc.reason
        return f"{hint}; wait for it to be released (or, if its lease expired, take over from the palette)", "warning"
    if isinstance(exc, ServiceRefused):
        return f"refused: {exc.reason}", "warning"
    if isinstance(exc, RequestInvalid):
        return f"invalid request: {exc}", "error"
    if isinstance(exc, ServiceUnavailable):
        return "service unavailable — nothing was sent", "error"
    if isinstance(exc, NodeUnavailable):
        return f"node unreachable: {exc}", "error"
    return f"{type(exc).__name__}: {exc}", "error"


class ServiceLink:
    """One service socket: reads, and commands under the control lease."""

    def __init__(self, socket_path: str | None, *, config: str | None = None) -> None:
        self.client = AsyncClient(socket_path, name=CLIENT_NAME, config=config, timeout_s=5.0)
        self.socket_path = self.client.socket_path or self.client.base_url

    @property
    def holds_control(self) -> bool:
        """Whether this TUI holds a lease (as far as it knows)."""
        return self.client.lease_id is not None

    async def take_control(self, force: bool = False) -> LeaseOut:
        """Take the lease (or renew ours); a lapsed lease of ours is simply taken anew."""
        try:
            return await self.client.take_control(force)
        except ControlHeld:
            if self.client.lease_id is None:
                raise
            self.client.lease_id = None  # ours expired: ask for a fresh one
            return await self.client.take_control(force)

    async def release_control(self) -> None:
        """Give the lease back, if held (errors ignored: it lapses anyway)."""
        if self.client.lease_id is not None:
            with contextlib.suppress(*LINK_ERRORS):
                await self.client.release_control()
            self.client.lease_id = None

    async def command(self, call: Callable[[AsyncClient], Awaitable[T]]) -> T:
        """Run a command holding control: take or renew the lease, then ``call(client)``."""
        await self.take_control()
        return await call(self.client)

    async def estop(self) -> CommandOut:
        """Emergency stop: no lease needed, sent straight away."""
        return await self.client.estop()

    async def check(self, rotary_rpm: float, vibration_rpm: float, temp_c: float | None) -> CheckOut:
        """The interlock's verdict on a point (nothing is commanded)."""
        return await self.client.check(rotary_rpm, vibration_rpm, temp_c)

    async def stream(self) -> AsyncGenerator[StreamItem, None]:
        """Status and event items from the service until it ends the stream (resuming after the last event seen)."""
        async for item in self.client.stream():
            yield item

    async def aclose(self) -> None:
        """Close the HTTP connection pool."""
        with contextlib.suppress(*LINK_ERRORS):
            await self.client.aclose()


__all__ = [
    "CLIENT_NAME", "LINK_ERRORS", "RACED_READ", "STREAM_SILENCE_S", "ServiceLink", "describe", "quiet_raced_reads",
]
