"""``millctl tui --web`` in headless Chromium (Debian's), against a real service with the simulated node.

The page is driven with Playwright on the system's ``/usr/bin/chromium`` (no browser
download). xterm.js draws the terminal on a canvas, so what the page shows is read by
feeding the bytes the page's websocket received to a terminal emulator (pyte) of the
page's own size: the screen the browser painted. A missing chromium fails this test
(the hil-service tier must run it): .ci/setup installs it.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pyte
import pytest
from playwright.sync_api import Page, WebSocket, sync_playwright

from tests.support.pace import Deadline
from tests.support.service import REPO, UNBUFFERED, Service, start_service, wait_for, write_config

CHROMIUM = Path("/usr/bin/chromium")
URL = re.compile(r"serving the TUI on (http://127\.0\.0\.1:\d+/\?key=\S+)")


class PageScreen:
    """The page's terminal as the browser received it: every binary websocket frame, fed to pyte."""

    def __init__(self) -> None:
        self.screen = pyte.Screen(80, 24)
        self.stream = pyte.ByteStream(self.screen)

    def attach(self, ws: WebSocket) -> None:
        ws.on("framereceived", self._received)
        ws.on("framesent", self._sent)

    def _received(self, payload: str | bytes) -> None:
        if isinstance(payload, bytes):
            self.stream.feed(payload)

    def _sent(self, payload: str | bytes) -> None:
        if isinstance(payload, str) and payload.startswith('["resize"'):
            size = json.loads(payload)[1]
            self.screen.resize(size["height"], size["width"])

    def text(self) -> str:
        return "\n".join(self.screen.display)


def page_until(page: Page, screen: PageScreen, condition: Any, what: str, timeout_s: float = 30.0) -> None:
    """Let the page run until ``condition(text)`` holds (a load-stretched bound, not a timing assertion)."""
    deadline = Deadline(timeout_s)
    while not deadline.expired():
        if condition(screen.text()):
            return
        page.wait_for_timeout(100)
    pytest.fail(f"timed out after {deadline.describe()} waiting for {what}; the page shows:\n{screen.text()}")


@pytest.fixture
def web_tui(service_dir: Path) -> Iterator[tuple[Service, str]]:
    """A real service, and ``millctl tui --web`` on a free loopback port serving it; the page's URL."""
    config = write_config(service_dir)
    service = start_service(service_dir)
    log = service_dir / "web.log"
    with log.open("wb") as out:
        web = subprocess.Popen(
            [sys.executable, "-m", "millctl", "--config", str(config), "tui", "--web", "--web-port", "0",
             "--socket", str(service.socket)],
            cwd=REPO, stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT, env=UNBUFFERED,
        )
    try:
        found: list[str] = []

        def url_printed() -> bool:
            if web.poll() is not None:
                pytest.fail(f"millctl tui --web exited with {web.returncode}:\n{log.read_text()}")
            found.extend(URL.findall(log.read_text()))
            return bool(found)

        wait_for(url_printed, 60.0, "millctl tui --web to print its URL")
        yield service, found[0]
    finally:
        web.terminate()
        try:
            web.wait(30)
        except subprocess.TimeoutExpired:
            web.kill()
            web.wait()
        service.stop()


def test_the_page_shows_the_mill_and_its_stop_stops_it(web_tui: tuple[Service, str]) -> None:
    service, url = web_tui
    assert CHROMIUM.exists(), "Debian's chromium is missing: bash .ci/setup installs it (apt-get install chromium)"
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=str(CHROMIUM), args=["--no-sandbox"])
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 900})
            screen = PageScreen()
            page.on("websocket", screen.attach)
            page.goto(url, wait_until="domcontentloaded")
            page_until(page, screen, lambda t: "DISABLED" in t.splitlines()[0] and "envelope" in t,
                       "the state bar (DISABLED) and the envelope panel")
            assert "read-only" in screen.text().splitlines()[0]  # the page holds no lease: its state bar says so
            page.locator(".xterm").click()
            page.keyboard.press("a")  # arm needs control: a read-only page sends nothing
            page_until(page, screen, lambda t: "not sent: this browser" in t, "the read-only refusal")
            with service.client("holder") as holder:
                assert holder.status().state == "DISABLED"
                assert holder.control_state().holder is None  # the page took no lease silently
                holder.take_control()
                holder.arm()
                wait_for(lambda: holder.status().state == "ARMED", 30.0, "ARMED")
                holder.set_speeds(30.0, 150.0)
                wait_for(lambda: holder.status().state == "RUNNING", 30.0, "RUNNING")
                page_until(page, screen, lambda t: "RUNNING" in t.splitlines()[0], "the page to show RUNNING")
                page.keyboard.press("o")  # stop: needs no lease, from any station (SAFETY 24)
                wait_for(lambda: holder.status().state in ("STOPPING", "ARMED"), 30.0, "the page's stop")
                wait_for(lambda: holder.status().state == "ARMED", 60.0, "the drives at standstill")

                def standstill() -> bool:  # the node's measured speeds, not only the controller's word
                    status = holder.status()
                    speeds = (status.measured_rotary_rpm or 0.0, status.measured_vibration_rpm or 0.0)
                    return all(abs(rpm) < 3.0 for rpm in speeds)

                wait_for(standstill, 60.0, "both drives below 3 rpm after the page's stop")
                stops = [e.source for e in holder.events(limit=2000).events
                         if e.kind == "command" and e.message.startswith("STOP")]
                assert stops and stops[0].startswith("api:tui"), stops
            page_until(page, screen, lambda t: "ARMED" in t.splitlines()[0], "the page's state bar to show ARMED")
            if shot := os.environ.get("MILLCTL_WEB_SCREENSHOT"):  # to look at the page: a PNG of it
                page.screenshot(path=shot)
        finally:
            browser.close()
