"""The TUI survives the service going away and coming back: it says so, keeps running, and reconnects."""

from __future__ import annotations

from pathlib import Path

from textual.widgets import RichLog, Static

from millctl.tui import MillApp
from tests.support.service import start_service, write_config
from tests.support.tui import until


def log_lines(app: MillApp) -> list[str]:
    """The event log's lines as plain text."""
    return [strip.text for strip in app.query_one("#events", RichLog).lines]


async def test_service_goes_away_and_comes_back(service_dir: Path) -> None:
    write_config(service_dir)
    service = start_service(service_dir)
    app = MillApp(str(service.socket))
    try:
        async with app.run_test(size=(120, 40)) as pilot:
            await until(pilot, lambda: app.online and app.state == "DISABLED", "the first status")
            assert sum("service started" in line for line in log_lines(app)) == 1

            service.stop()
            await until(pilot, lambda: not app.online, "the TUI to notice", timeout_s=20.0)
            banner = app.query_one("#offline", Static)
            assert banner.has_class("shown")
            assert "service unavailable — retrying" in str(banner.content)
            assert app.check_action("arm", ()) is None  # greyed out while offline
            await pilot.press("ctrl+x")  # E-stop is still tried; failing, it says so (hardware E-stop), no crash
            await pilot.pause(0.2)
            assert app.is_running

            service = start_service(service_dir)
            await until(pilot, lambda: app.online and app.state == "DISABLED", "the reconnection",
                        timeout_s=30.0)
            assert not app.query_one("#offline", Static).has_class("shown")
            await until(pilot, lambda: sum("service started" in line for line in log_lines(app)) == 2,
                        "the new service's events in the log")
            assert app.is_running
    finally:
        service.stop()
