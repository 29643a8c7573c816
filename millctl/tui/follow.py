"""The follower: keeps the main screen fed from the service and survives it going away and coming back.

Two workers on textual's event loop. The stream worker connects (service
identity, envelope, events since the last one seen), then reads the
service's event stream (a status every 0.25 s, every event as it happens);
when the service goes away, or goes silent for ``STREAM_SILENCE_S``, it shows
"service unavailable — retrying" and tries again every ``RETRY_S``. The poll
worker refreshes the lease holder and the recipe progress, and renews our
lease while we hold it. Neither ever lets an error end the app.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging

from textual.css.query import NoMatches

from millctl.api import EventOut, StatusOut
from millctl.client import StreamItem
from millctl.tui.link import LINK_ERRORS, STREAM_SILENCE_S
from millctl.tui.view import MillView

log = logging.getLogger(__name__)

RETRY_S = 1.0
"""Wait between reconnection attempts (s)."""
POLL_S = 1.0
"""How often control and recipe progress are refreshed (s)."""
RENEW_S = 10.0
"""How often a held lease is renewed (s; the service lets it lapse after 30 s)."""
BACKFILL_EVENTS = 200
"""Recorded events loaded into the log on (re)connecting."""


class Following(MillView):
    """The main screen, fed live from the service."""

    service_started: float | None = None
    """``started_unix`` of the service we follow: a new value means a restarted service (sequence from 0)."""

    def start_following(self) -> None:
        """Start the stream and poll workers."""
        self.run_worker(self._follow(), name="follow", group="follow", exit_on_error=False)
        self.run_worker(self._poll(), name="poll", group="follow", exit_on_error=False)

    async def _connect(self) -> None:
        """Learn who we talk to, the envelope, the status and the events we missed."""
        client = self.link.client
        service = await client.service()
        if service.started_unix != self.service_started:
            self.service_started = service.started_unix
            self.last_seq = 0
            self.link.client.lease_id = None  # a lease does not outlive its service
            for run_id in service.unfinished_runs:  # a run a crash, a kill or a reboot interrupted: offered, not run
                self.notify(f"run {run_id} is unfinished (the service stopped under it): `millctl recipe resume "
                            f"{run_id}` continues it after a pre-flight", title="interrupted run",
                            severity="warning", timeout=30.0, markup=False)
        self.apply_service(service)
        self.apply_envelope(await client.envelope(points=161))
        self.apply_status(await client.status())
        self.apply_control(await client.control_state())
        self.apply_recipe(await client.recipe())
        events = await client.events(after=self.last_seq, limit=BACKFILL_EVENTS)
        for event in events.events:
            self.apply_event(event, live=False)
        client.last_event_id = self.last_seq  # the stream goes on from here: no event is missed in between
        self.show_offline(None)

    async def _follow(self) -> None:
        """Connect, follow the stream, and on any failure show it and retry, forever."""
        while True:
            reason = "the service ended the stream"
            try:
                await self._connect()
                await self._read_stream()
            except TimeoutError:
                reason = f"no status for {STREAM_SILENCE_S:.0f} s"
            except LINK_ERRORS as exc:
                reason = str(exc) or type(exc).__name__
            except NoMatches:
                return  # the screen is gone: the app is closing
            except Exception as exc:  # never let the screen die with the link; say what happened
                log.exception("following the service failed")
                reason = f"{type(exc).__name__}: {exc}"
            self.show_offline(reason)
            await asyncio.sleep(RETRY_S)

    async def _read_stream(self) -> None:
        stream = self.link.stream()
        async with contextlib.aclosing(stream):
            while True:
                try:
                    item = await asyncio.wait_for(anext(stream), STREAM_SILENCE_S)
                except StopAsyncIteration:
                    return
                self._take(item)

    def _take(self, item: StreamItem) -> None:
        if isinstance(item, StatusOut):
            self.apply_status(item)
            if not self.online:
                self.show_offline(None)
        elif isinstance(item, EventOut):
            self.apply_event(item, live=True)

    async def _poll(self) -> None:
        """Refresh the lease holder and recipe progress; renew our lease while we hold it."""
        loop = asyncio.get_running_loop()
        renewed_s = loop.time()
        while True:
            await asyncio.sleep(POLL_S)
            if not self.online:
                continue
            try:
                if self.link.holds_control and loop.time() - renewed_s >= RENEW_S:
                    await self.link.take_control()
                    renewed_s = loop.time()
                self.apply_control(await self.link.client.control_state())
                self.apply_recipe(await self.link.client.recipe())
            except LINK_ERRORS as exc:
                log.debug("poll failed: %s", exc)
            except NoMatches:
                return
            except Exception:
                log.exception("polling the service failed")


__all__ = ["BACKFILL_EVENTS", "POLL_S", "RENEW_S", "RETRY_S", "Following"]
