"""The main screen of ``millctl tui``: layout, panels, banners, the event log and the top bar.

:class:`MillView` only shows what it is given (:meth:`apply_status`,
:meth:`apply_envelope`, :meth:`apply_control`, :meth:`apply_recipe`,
:meth:`apply_event`); the follower feeds it from the service, tests feed it
frozen data.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Sequence
from typing import Any

from rich.text import Text
from textual.app import App, ComposeResult
from textual.containers import Horizontal, Vertical
from textual.filter import LineFilter, Monochrome, NoColor
from textual.notifications import SeverityLevel
from textual.screen import Screen
from textual.widgets import Footer, RichLog, Static
from textual.worker import Worker, WorkerState

from millctl.api import (
    ControllerState,
    ControlOut,
    EnvelopeOut,
    EventKind,
    EventOut,
    RecipeOut,
    ServiceOut,
    StatusOut,
)
from millctl.tui.envelope import EnvelopeScreen
from millctl.tui.format import state_style
from millctl.tui.legible import LegibleMonochrome
from millctl.tui.link import ServiceLink, quiet_raced_reads
from millctl.tui.panels import DrivePanel, EnvelopePanel, FurnacePanel, LinkPanel, PhysicsPanel, StatePanel
from millctl.tui.styles import CSS, NARROW_BELOW_COLUMNS, SHORT_BELOW_ROWS, SHORT_TOAST_CHARS

log = logging.getLogger(__name__)

NOTIFY_KINDS: dict[EventKind, SeverityLevel] = {
    EventKind.TRIP: "error", EventKind.REFUSAL: "warning", EventKind.STATE: "information",
    EventKind.CONTROL: "information", EventKind.SERVICE: "information", EventKind.DRILL: "warning",
    EventKind.HOST: "warning",
}
"""Event kinds shown as notifications when they happen (the log shows every kind), with their severity."""
EVENT_STYLE: dict[EventKind, str] = {
    EventKind.TRIP: "bold red", EventKind.REFUSAL: "yellow", EventKind.STATE: "cyan", EventKind.CONTROL: "magenta",
    EventKind.DRILL: "bold magenta", EventKind.HOST: "bold yellow",
}
"""How each kind of event is coloured in the log."""
LEGIBLE = LegibleMonochrome()


class MillView(App[None]):
    """The operator terminal UI's screen for one service socket (display only; see :class:`millctl.tui.MillApp`)."""

    CSS = CSS
    TITLE = "millctl"
    HORIZONTAL_BREAKPOINTS = [(0, "-narrow"), (NARROW_BELOW_COLUMNS, "-wide")]  # noqa: RUF012 - textual's
    VERTICAL_BREAKPOINTS = [(0, "-short"), (SHORT_BELOW_ROWS, "-tall")]  # noqa: RUF012

    def __init__(self, socket_path: str | None = None, *, config: str | None = None, live: bool = True,
                 sim: bool = False, web: bool = False) -> None:
        """``live=False`` shows only what :meth:`apply_status` and friends are given (tests, snapshots).

        ``web``: a page of ``millctl tui --web``, read-only until its operator takes control (``c``).
        """
        super().__init__()
        self.link = ServiceLink(socket_path, config=config)
        self.live = live
        self.sim = sim
        self.web = web
        self.status: StatusOut | None = None
        self.control: ControlOut | None = None
        self.recipe: RecipeOut | None = None
        self.envelope: EnvelopeOut | None = None
        self.service: ServiceOut | None = None
        """The service we follow (``GET /v1/service``): its config, whether it allows fault drills."""
        self.online = False
        self.last_seq = 0
        self._applies: tuple[ControllerState | None, bool, bool] | None = None

    def compose(self) -> ComposeResult:
        """The main screen."""
        yield Static(id="topbar")
        yield Static(id="offline")
        yield Static(id="trip")
        with Horizontal(id="row1"):
            with Vertical(id="left"):
                yield DrivePanel("rotary", "rotary drive ω_r", id="rotary")
                yield DrivePanel("vibration", "vibration drive ω_v", id="vibration")
                yield FurnacePanel("furnace", id="furnace")
            yield EnvelopePanel(id="envelope")
        with Horizontal(id="row2"):
            yield StatePanel(id="state", classes="panel")
            yield PhysicsPanel(id="physics", classes="panel")
            yield LinkPanel(id="links", classes="panel")
        yield RichLog(id="events", classes="panel", max_lines=1000, wrap=True, markup=False)
        yield Footer(compact=True)

    def on_mount(self) -> None:
        """Title the panels; until the follower connects, say so; no traceback for a raced socket read."""
        asyncio.get_running_loop().set_exception_handler(quiet_raced_reads)
        for panel_id, title in (("state", "controller"), ("physics", "physics"), ("links", "node links"),
                                ("events", "events")):
            self.main_screen.query_one(f"#{panel_id}").border_title = title
        self.show_offline(None if not self.live else "connecting…")
        self.redraw_top()

    async def on_unmount(self) -> None:
        """Close the connection (a held lease is released by quitting)."""
        await self.link.aclose()

    def on_worker_state_changed(self, event: Worker.StateChanged) -> None:
        """A worker that failed unexpectedly is logged and shown, never fatal (their errors do not exit the app)."""
        if event.state is WorkerState.ERROR:
            error = event.worker.error
            log.error("worker %s failed: %r", event.worker.name, error, exc_info=error)
            self.notify(f"internal error in {event.worker.name}: {error!r}", severity="error", markup=False)

    def notify(self, message: str, *, title: str = "", severity: SeverityLevel = "information",
               timeout: float | None = None, markup: bool = True) -> None:
        """A notification; on a short terminal only the newest shows (over the events panel: styles.CSS).

        There, one too long for the toast's three rows is written whole to the event log as well.
        """
        if self.size.height < SHORT_BELOW_ROWS:
            self.clear_notifications()
            if len(message) > SHORT_TOAST_CHARS and self.screen_stack:
                stamp = time.strftime("%H:%M:%S")
                line = Text.assemble((f"{stamp} ", "dim"), (f"{'tui':<8} ", "dim"), (f"{title}: " if title else "",
                                     "dim"), Text.from_markup(message) if markup else message)
                self.main_screen.query_one("#events", RichLog).write(line)
        super().notify(message, title=title, severity=severity, timeout=timeout, markup=markup)

    def get_line_filters(self) -> Sequence[LineFilter]:
        """Under NO_COLOR, greyscale that keeps every text readable (:mod:`millctl.tui.legible`)."""
        filters = super().get_line_filters()
        if not self.no_color:
            return filters
        return [LEGIBLE if isinstance(f, Monochrome | NoColor) else f for f in filters]

    @property
    def main_screen(self) -> Screen[Any]:
        """The main screen (under any dialog): panels are looked up here, not on the dialog shown on top."""
        return self.screen_stack[0]

    # ------------------------------------------------------------------ what the follower (or a test) feeds in
    @property
    def state(self) -> ControllerState | None:
        """The controller's state as last seen (None before the first status)."""
        return self.status.state if self.status is not None else None

    @property
    def recipe_active(self) -> bool:
        """True while a recipe run is in progress."""
        return self.recipe is not None and self.recipe.active

    def apply_status(self, status: StatusOut) -> None:
        """Show a status (``GET /v1/status`` or a stream item)."""
        self.status = status
        self.main_screen.query_one("#rotary", DrivePanel).show(status)
        self.main_screen.query_one("#vibration", DrivePanel).show(status)
        self.main_screen.query_one("#furnace", FurnacePanel).show(status)
        self.main_screen.query_one("#envelope", EnvelopePanel).show(status)
        self.main_screen.query_one("#physics", PhysicsPanel).show(status)
        self.main_screen.query_one("#links", LinkPanel).show(status)
        self.show_trip(status)
        self.redraw_state()
        self.redraw_envelope_view()

    def apply_service(self, service: ServiceOut) -> None:
        """Take the service's description: the fault drill key shows only where drills are allowed."""
        self.service = service
        self.refresh_bindings()

    def apply_envelope(self, envelope: EnvelopeOut) -> None:
        """Take the service's limit curve (``GET /v1/envelope``)."""
        self.envelope = envelope
        self.main_screen.query_one("#envelope", EnvelopePanel).set_envelope(envelope)
        self.redraw_envelope_view()

    def redraw_envelope_view(self) -> None:
        """Keep the envelope view (when open) on the latest envelope and status."""
        for screen in self.screen_stack:
            if isinstance(screen, EnvelopeScreen):
                screen.show(self.envelope, self.status)

    def apply_control(self, control: ControlOut) -> None:
        """Show who holds control (``GET /v1/control``)."""
        self.control = control
        self.redraw_state()

    def apply_recipe(self, recipe: RecipeOut) -> None:
        """Show recipe progress (``GET /v1/recipe``)."""
        self.recipe = recipe
        self.redraw_state()

    def apply_event(self, event: EventOut, *, live: bool) -> None:
        """Log one recorded event (once, by sequence number); ``live`` ones of some kinds also notify."""
        if event.seq <= self.last_seq:
            return
        self.last_seq = event.seq
        kind, message = event.kind, event.message
        stamp = time.strftime("%H:%M:%S", time.localtime(event.t))
        style = EVENT_STYLE.get(kind, "")
        line = Text.assemble((f"{stamp} ", "dim"), (f"{kind:<8} ", style), (f"{event.source}: ", "dim"), message)
        self.main_screen.query_one("#events", RichLog).write(line)
        severity = NOTIFY_KINDS.get(kind)
        if live and severity is not None:
            timeout = 10.0 if kind is EventKind.TRIP else 5.0
            self.notify(message, title=kind, severity=severity, timeout=timeout, markup=False)

    # ------------------------------------------------------------------ banners and the top bar
    def show_offline(self, reason: str | None) -> None:
        """Show (or with None hide) the banner saying the service is unavailable and we retry."""
        self.online = reason is None
        banner = self.main_screen.query_one("#offline", Static)
        if reason is not None:
            banner.update(Text(f"service unavailable — retrying ({self.link.socket_path}): {reason}"))
        banner.set_class(reason is not None, "shown")
        self.redraw_top()

    def show_trip(self, status: StatusOut) -> None:
        """The persistent trip banner: first cause and what to do, while the controller is TRIPPED."""
        tripped = status.state is ControllerState.TRIPPED
        banner = self.main_screen.query_one("#trip", Static)
        if tripped:
            node = status.node_first_fault
            node_text = f" (node first fault: {node})" if node and node != "NONE" else ""
            banner.update(Text.assemble(
                ("⚠ TRIPPED — first cause: ", "bold"), (status.trip_cause or "unknown", "bold"),
                node_text, "\nWhat to do: wait until both drives stand still, remove the cause, then press r to reset "
                "and a to arm again (docs/safety.md, “How to recover”).",
            ))
        banner.set_class(tripped, "shown")

    def redraw_state(self) -> None:
        """The controller panel and the top bar."""
        panel = self.main_screen.query_one("#state", StatePanel)
        panel.show(self.status, self.control, self.link.holds_control, self.recipe)
        self.redraw_top()

    def redraw_top(self) -> None:
        """State, control and connection in one line; the footer's keys follow state, connection and recipe."""
        state = self.state
        applies = (state, self.online, self.recipe_active)
        if applies != self._applies:
            self._applies = applies
            self.refresh_bindings()
        holder = "you" if self.link.holds_control else ((self.control.holder if self.control else None) or "nobody")
        if self.web and not self.link.holds_control:
            holder += " · this page read-only (c)"
        where = "online" if self.online else "OFFLINE"
        text = Text.assemble(("millctl ", "bold"), (f" {state or '—'} ", state_style(state)), ("  control ", "dim"),
                             holder, ("  service ", "dim"), (where, "green" if self.online else "bold white on red"),
                             (f" {self.link.socket_path}", "dim"), ("  (simulated mill)" if self.sim else "", "cyan"))
        self.main_screen.query_one("#topbar", Static).update(text, layout=False)


__all__ = ["NOTIFY_KINDS", "MillView"]
