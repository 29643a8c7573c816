"""At 80 × 24 and 120 × 40, in colour and with NO_COLOR: the state bar and the set dialog's verdict in sight.

Issue 39, item 4: at 80 × 24 the set dialog covered the state bar and cut off its
verdict and Enter hint, the footer lacked q, and with NO_COLOR the linear-path
checkbox looked the same ticked and unticked.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import pytest
from textual.geometry import Region
from textual.widget import Widget
from textual.widgets import Checkbox, Footer, Input, RichLog, Static

from millctl.tui import MillApp
from millctl.tui.modals import SetpointsModal
from tests.support.tui import until
from tests.unit.tui import frozen
from tests.unit.tui.test_snapshot import envelope_check, feeder

SIZES = [(80, 24), (120, 40)]


@pytest.fixture
def utc(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """Event times shown in UTC, whatever the machine's zone (as test_snapshot's)."""
    monkeypatch.setenv("TZ", "UTC")
    time.tzset()
    yield
    monkeypatch.undo()
    time.tzset()


async def _open_set_dialog(app: MillApp, pilot: Any) -> SetpointsModal:
    await feeder(app)(pilot)
    app.push_screen(SetpointsModal(envelope_check, 180.0, 800.0, None))
    await pilot.pause()
    modal = app.screen
    assert isinstance(modal, SetpointsModal)
    verdict = modal.query_one("#verdict", Static)
    await until(pilot, lambda: "inside the envelope" in str(verdict.render()) and not modal.workers, "the verdict")
    return modal


def _visible(modal: SetpointsModal, selector: str, rows: int) -> bool:
    """The widget lies wholly on screen, inside the dialog's visible part (not scrolled away)."""
    region = modal.query_one(selector).region
    dialog = modal.query_one("#dialog").region
    return region.height > 0 and region.y > 0 and region.bottom <= min(rows, dialog.bottom)


@pytest.mark.parametrize("no_color", [False, True])
@pytest.mark.parametrize("size", SIZES)
async def test_the_set_dialog_leaves_the_state_bar_and_shows_its_verdict(
    size: tuple[int, int], no_color: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    if no_color:
        monkeypatch.setenv("NO_COLOR", "1")
    else:
        monkeypatch.delenv("NO_COLOR", raising=False)
    app = MillApp(frozen.SOCKET, live=False)
    async with app.run_test(size=size) as pilot:
        modal = await _open_set_dialog(app, pilot)
        assert modal.query_one("#dialog").region.y >= 1  # row 0: the state bar, under the dialog's shade
        assert app.screen_stack[0].query_one("#topbar").region.y == 0
        for selector in ("#vib", "#rot", "#temp", "#linear", "#limit", "#verdict", ".hint"):
            assert _visible(modal, selector, size[1]), (selector, modal.query_one(selector).region)
        for field in modal.query(Input):
            assert field.region.width >= 8, field  # the typed value is not cut to nothing


@pytest.mark.parametrize("size", SIZES)
async def test_the_footer_offers_quit(size: tuple[int, int]) -> None:
    app = MillApp(frozen.SOCKET, live=False)
    async with app.run_test(size=size) as pilot:
        await feeder(app)(pilot)

        def quit_shown() -> bool:
            keys = app.query_one(Footer).query("FooterKey")
            return any(getattr(k, "key", "") == "q" and k.region.width > 0 and k.region.right <= size[0] for k in keys)

        await until(pilot, quit_shown, "q (Quit) in the footer, inside the terminal's width")


async def test_ticked_and_unticked_differ_without_colour(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("NO_COLOR", "1")
    app = MillApp(frozen.SOCKET, live=False)
    async with app.run_test(size=(80, 24)) as pilot:
        modal = await _open_set_dialog(app, pilot)
        box = modal.query_one("#linear", Checkbox)
        unticked = "".join(s.text for s in box.render_line(0)) + "".join(s.text for s in box.render_line(1))
        box.value = True
        await pilot.pause()
        ticked = "".join(s.text for s in box.render_line(0)) + "".join(s.text for s in box.render_line(1))
        assert "X" in ticked and "X" not in unticked


@pytest.mark.parametrize("no_color", [False, True], ids=["colour", "no-color"])
@pytest.mark.parametrize("size", SIZES, ids=["80x24", "120x40"])
def test_set_dialog_snapshot(snap_compare: Any, utc: None, size: tuple[int, int], no_color: bool,
                             monkeypatch: pytest.MonkeyPatch) -> None:
    if no_color:
        monkeypatch.setenv("NO_COLOR", "1")
    else:
        monkeypatch.delenv("NO_COLOR", raising=False)
    app = MillApp(frozen.SOCKET, live=False)

    async def run(pilot: Any) -> None:
        modal = await _open_set_dialog(app, pilot)
        modal.query_one("#linear", Checkbox).value = True
        for field in modal.query(Input):  # a blinking cursor would be caught in either phase
            field.cursor_blink = False
        await pilot.pause()

    assert snap_compare(app, terminal_size=size, run_before=run)


def _screen_text(app: MillApp) -> str:
    lines = []
    for widget in app.screen.walk_children(Widget):
        if widget.display and widget.region:
            for strip in widget.render_lines(Region(0, 0, widget.region.width, widget.region.height)):
                lines.append("".join(segment.text for segment in strip))
    return "\n".join(lines)


@pytest.mark.parametrize("no_color", [False, True], ids=["colour", "no-color"])
@pytest.mark.parametrize("size", SIZES, ids=["80x24", "120x40"])
async def test_no_legend_names_a_colour_under_no_color(size: tuple[int, int], no_color: bool,
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    if no_color:
        monkeypatch.setenv("NO_COLOR", "1")
    else:
        monkeypatch.delenv("NO_COLOR", raising=False)
    app = MillApp(frozen.SOCKET, live=False)
    async with app.run_test(size=size) as pilot:
        await feeder(app)(pilot)
        await pilot.pause()
        main = _screen_text(app)
        await pilot.press("e")
        await pilot.pause()
        envelope = _screen_text(app)
    for text in (main, envelope):
        named = "green" in text or "yellow" in text
        assert named is not no_color, text


def _lines(widget: Widget) -> list[str]:
    region = widget.region
    return ["".join(s.text for s in strip) for strip in widget.render_lines(Region(0, 0, region.width, region.height))]


@pytest.mark.parametrize("no_color", [False, True], ids=["colour", "no-color"])
@pytest.mark.parametrize("size", SIZES, ids=["80x24", "120x40"])
async def test_the_targets_are_not_cut_off(size: tuple[int, int], no_color: bool,
                                           monkeypatch: pytest.MonkeyPatch) -> None:
    """Each drive's and the furnace's ramp target is on screen in full (at 80 × 24 it was cut after "target")."""
    if no_color:
        monkeypatch.setenv("NO_COLOR", "1")
    else:
        monkeypatch.delenv("NO_COLOR", raising=False)
    app = MillApp(frozen.SOCKET, live=False)
    async with app.run_test(size=size) as pilot:
        await feeder(app)(pilot)
        await pilot.pause()
        status = app.status
        assert status is not None and status.furnace_target_c is not None
        for panel, target in (("rotary", f"{status.target_rotary_rpm:.1f} rpm"),
                              ("vibration", f"{status.target_vibration_rpm:.1f} rpm"),
                              ("furnace", f"{status.furnace_target_c:.1f} °C")):
            lines = _lines(app.query_one(f"#{panel}-text", Static))
            ramp = [line for line in lines if "→" in line]
            assert ramp and target in ramp[0], (panel, lines)


async def _notify_three(app: MillApp, pilot: Any) -> list[str]:
    sent = [f"refused by the interlock ({i}): ω_r 300 rpm is above the limit 143.6 rpm at ω_v 800 rpm; "
            "nothing was sent; lower ω_r or raise ω_v" for i in range(3)]
    for message in sent:
        app.notify(message, title="set", severity="error", markup=False)
        await pilot.pause(0.1)
    for _ in range(5):  # the rack's removals and its scroll to the newest land over the next refreshes
        await pilot.pause(0.1)
    return sent


def _toasts_on_screen(app: MillApp, rows: int) -> list[Region]:
    from textual.widgets._toast import Toast, ToastRack

    rack = app.screen.get_child_by_type(ToastRack)
    return [t.region for t in rack.walk_children(Toast) if t.region.height and t.region.y < rows]


@pytest.mark.parametrize("dialog", [False, True], ids=["main", "set-dialog"])
async def test_at_80_by_24_notifications_leave_the_fields_in_sight(dialog: bool) -> None:
    """One notification at a time, over the events panel: not over the drives, envelope, controller or a dialog."""
    app = MillApp(frozen.SOCKET, live=False)
    async with app.run_test(size=(80, 24), notifications=True) as pilot:
        if dialog:
            modal = await _open_set_dialog(app, pilot)
        else:
            await feeder(app)(pilot)
        sent = await _notify_three(app, pilot)
        toasts = _toasts_on_screen(app, 24)
        assert len(toasts) == 1, (toasts, _toasts_on_screen(app, 99))
        main = app.main_screen
        covered = [main.query_one(s).region for s in ("#rotary", "#vibration", "#furnace", "#envelope", "#state")]
        if dialog:
            covered += [modal.query_one(s).region for s in ("#vib", "#rot", "#temp", "#linear", "#verdict", ".hint")]
        for region in covered:
            assert not toasts[0].overlaps(region), (toasts[0], region)
        assert toasts[0].bottom <= 23  # not over the footer
        assert [n.message for n in app._notifications] == sent[-1:]  # the newest, and only it
        logged = [strip.text for strip in main.query_one("#events", RichLog).lines]
        for i in range(3):  # too long for the toast's rows: each is in the event log, whole
            assert any(f"({i})" in line for line in logged), logged
        assert any("raise ω_v" in line for line in logged), logged


@pytest.mark.parametrize("size", SIZES, ids=["80x24", "120x40"])
def test_main_screen_snapshot_without_colour(snap_compare: Any, utc: None, size: tuple[int, int],
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    """The main screen under NO_COLOR at both sizes (the colour ones are test_snapshot's)."""
    monkeypatch.setenv("NO_COLOR", "1")
    app = MillApp(frozen.SOCKET, live=False)
    assert snap_compare(app, terminal_size=size, run_before=feeder(app))
