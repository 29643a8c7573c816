"""Snapshots of the main screen and the envelope view (120 × 40, and 80 × 24) with frozen content; NO_COLOR."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest
from textual.geometry import Region
from textual.pilot import Pilot
from textual.widget import Widget
from textual.widgets import Checkbox, Input, Static

from millctl.api import CheckOut
from millctl.config import LimitLaw, load_config
from millctl.config.loader import packaged_file
from millctl.safety import Envelope
from millctl.tui import MillApp
from millctl.tui.envelope import EnvelopeScreen
from millctl.tui.legible import MIN_CONTRAST, contrast
from millctl.tui.modals import SetpointsModal, SetRequest
from tests.support.tui import until
from tests.unit.tui import frozen

SIZE = (120, 40)
ENVELOPE = Envelope.from_config(load_config(packaged_file("mill.toml")).config)


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


def test_main_screen_at_80_by_24(snap_compare: Any, utc: None) -> None:
    """The smallest usual terminal: the state bar stays on top, trends give way, links replace physics."""
    app = MillApp(frozen.SOCKET, live=False)
    assert snap_compare(app, terminal_size=(80, 24), run_before=feeder(app))


async def test_at_80_by_24_every_panel_is_on_screen() -> None:
    app = MillApp(frozen.SOCKET, live=False)
    async with app.run_test(size=(80, 24)) as pilot:
        await feeder(app)(pilot)
        for selector in ("#topbar", "#rotary", "#vibration", "#furnace", "#envelope", "#state", "#links", "#events"):
            region = app.query_one(selector).region
            assert region.y >= 0 and region.bottom <= 23 and region.height > 0, (selector, region)
        assert app.query_one("#topbar").region.y == 0


def _low_contrast(app: MillApp) -> list[tuple[float, str, str]]:
    """Every text segment on screen whose foreground is below 4.5:1 against its background (box lines aside)."""
    found = []
    for widget in app.screen.walk_children(Widget):
        if not widget.display or not widget.region:
            continue
        for strip in widget.render_lines(Region(0, 0, widget.region.width, widget.region.height)):
            for segment in strip:
                style, text = segment.style, segment.text.strip()
                if not text or style is None or style.color is None or style.bgcolor is None:
                    continue
                if all(0x2500 <= ord(ch) < 0x2600 for ch in text):
                    continue
                ratio = contrast(style.color.get_truecolor(), style.bgcolor.get_truecolor())
                if ratio < MIN_CONTRAST or style.dim:
                    found.append((round(ratio, 2), text[:20], type(widget).__name__))
    return found


@pytest.mark.parametrize("size", [(120, 40), (80, 24)])
async def test_no_color_keeps_every_text_readable(monkeypatch: pytest.MonkeyPatch, size: tuple[int, int]) -> None:
    monkeypatch.setenv("NO_COLOR", "1")
    app = MillApp(frozen.SOCKET, live=False)
    async with app.run_test(size=size) as pilot:
        await feeder(app)(pilot)
        app.show_offline("the service went away")
        await pilot.pause()
        assert app.no_color
        assert _low_contrast(app) == []


def opened_envelope_view(app: MillApp) -> Callable[[Pilot[None]], Any]:
    """Feed the app, then open the envelope view (key e)."""

    async def run(pilot: Pilot[None]) -> None:
        await feeder(app)(pilot)
        await pilot.press("e")
        await pilot.pause()

    return run


def test_envelope_view_every_law_the_regime_and_the_points(snap_compare: Any, utc: None) -> None:
    """Which rotary speed is safe: the enforced curve over every other law, the legend, the warning once."""
    app = MillApp(frozen.SOCKET, live=False)
    assert snap_compare(app, terminal_size=SIZE, run_before=opened_envelope_view(app))


def test_envelope_view_at_80_by_24(snap_compare: Any, utc: None) -> None:
    app = MillApp(frozen.SOCKET, live=False)
    assert snap_compare(app, terminal_size=(80, 24), run_before=opened_envelope_view(app))


async def test_envelope_view_follows_the_status_and_goes_back() -> None:
    app = MillApp(frozen.SOCKET, live=False)
    async with app.run_test(size=SIZE) as pilot:
        await feeder(app)(pilot)
        await pilot.press("e")
        await pilot.pause()
        view = app.screen
        assert isinstance(view, EnvelopeScreen)
        legend = str(view.query_one("#envelope-legend", Static).render())
        assert legend.count("307.8 rpm") == 1 and all(law.value in legend for law in LimitLaw)
        app.apply_status(frozen.status_at(5))
        await pilot.pause()
        assert view.status is not None and view.status.time_s == frozen.status_at(5).time_s
        await pilot.press("escape")
        await pilot.pause()
        assert not isinstance(app.screen, EnvelopeScreen)


async def envelope_check(rotary_rpm: float, vibration_rpm: float, temp_c: float | None) -> CheckOut:
    """The service's ``POST /v1/envelope/check`` verdict, from the packaged config's own envelope, in-process."""
    verdict = ENVELOPE.check(rotary_rpm, vibration_rpm, temp_c)
    return CheckOut(ok=verdict.ok, reason=verdict.reason(), limit_rotary_rpm=verdict.omega_r_limit_rpm,
                    margin_rpm=verdict.margin_rpm, refusals=[])


def test_set_dialog_with_ramp_rates_and_the_linear_path(snap_compare: Any, utc: None) -> None:
    """The set dialog offers both ramp rates and the linear path, and shows the interlock's limit and verdict."""
    app = MillApp(frozen.SOCKET, live=False)

    async def run(pilot: Pilot[None]) -> None:
        await feeder(app)(pilot)
        app.push_screen(SetpointsModal(envelope_check, 180.0, 800.0, None))
        await pilot.pause()
        modal = app.screen
        modal.query_one("#rot_rate", Input).value = "12.5"
        modal.query_one("#vib_rate", Input).value = "60"
        modal.query_one("#linear", Checkbox).value = True
        for field in modal.query(Input):  # a blinking cursor would be caught in either phase
            field.cursor_blink = False
        verdict = modal.query_one("#verdict", Static)
        await pilot.pause(0.02)  # the last field's change reaches its handler (which starts the check)
        await until(  # the check of the last field's change has answered
            pilot, lambda: "margin" in str(verdict.render()) and not modal.workers, "the set dialog's verdict"
        )
        assert "inside the envelope" in str(verdict.render())

    assert snap_compare(app, terminal_size=SIZE, run_before=run)


async def test_set_dialog_hands_over_rates_and_the_linear_path() -> None:
    app = MillApp(frozen.SOCKET, live=False)
    chosen: list[SetRequest | None] = []
    async with app.run_test(size=SIZE) as pilot:
        modal = SetpointsModal(envelope_check, 180.0, 800.0, None)
        app.push_screen(modal, chosen.append)
        await pilot.pause()
        modal.query_one("#rot_rate", Input).value = "12.5"
        modal.query_one("#linear", Checkbox).value = True
        await pilot.press("enter")
        await pilot.pause()
    assert chosen == [SetRequest(180.0, 800.0, False, None, 12.5, None, True)]
