"""``millctl tui --web``: its errors (port in use, textual-serve missing, no service), its key, read-only pages.

The browser against a real service is tests/hil/tui/test_web.py.
"""

from __future__ import annotations

import socket
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from aiohttp.test_utils import TestClient, TestServer

from millctl.cli import main
from millctl.errors import ExitCode
from millctl.tui import MillApp
from millctl.tui.commands import READ_ONLY
from millctl.tui.web import LOOPBACK, LoopbackServer, bind_loopback, session_command
from tests.unit.tui import frozen
from tests.unit.tui.test_snapshot import feeder


@pytest.fixture
def taken_port() -> Iterator[int]:
    """A loopback port some other program listens on."""
    with socket.socket() as other:
        other.bind((LOOPBACK, 0))
        other.listen(1)
        yield int(other.getsockname()[1])


def test_a_port_in_use_is_named_with_the_way_out(taken_port: int, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["tui", "--web", "--web-port", str(taken_port), "--socket", str(tmp_path / "none.sock")])
    err = capsys.readouterr().err
    assert code == ExitCode.INVALID_INPUT
    assert f"port {taken_port} on 127.0.0.1 is in use" in err and "--web-port" in err, err


def test_no_service_is_said_before_serving(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["tui", "--web", "--web-port", "0", "--socket", str(tmp_path / "none.sock")])
    err = capsys.readouterr().err
    assert code == ExitCode.BUS
    assert "no millctl service on socket" in err and "millctl serve" in err, err


def test_without_textual_serve_it_says_what_to_install(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setitem(sys.modules, "textual_serve.server", None)  # import fails as when it is not installed
    monkeypatch.delitem(sys.modules, "millctl.tui.web", raising=False)
    code = main(["tui", "--web", "--socket", str(tmp_path / "none.sock")])
    err = capsys.readouterr().err
    assert code == ExitCode.INVALID_INPUT
    assert "textual-serve" in err and "millctl[web]" in err, err


def test_the_server_listens_on_loopback_only() -> None:
    with bind_loopback(0) as sock:
        assert sock.getsockname()[0] == "127.0.0.1"


def test_bad_ports_and_a_stray_web_port_are_refused(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["tui", "--web", "--web-port", "70000"]) == ExitCode.INVALID_INPUT
    assert "--web-port 70000 is not a TCP port" in capsys.readouterr().err
    assert main(["tui", "--web-port", "8566"]) == ExitCode.INVALID_INPUT
    assert "--web-port goes with --web" in capsys.readouterr().err


async def test_the_page_and_its_websocket_need_the_printed_key() -> None:
    sock = bind_loopback(0)
    server = LoopbackServer(session_command("/run/x.sock", None, sim=False), sock, title="t")
    try:
        async with TestClient(TestServer(await server._make_app())) as http:
            assert (await http.get("/")).status == 403
            assert (await http.get("/", params={"key": "wrong"})).status == 403
            assert (await http.get("/ws")).status == 403
            page = await http.get("/", params={"key": server.key})
            assert page.status == 200 and server.cookie in page.cookies
            foreign = await http.get("/ws", headers={"Origin": "http://evil.example"})  # the cookie, not the origin
            assert foreign.status == 403 and "another origin" in await foreign.text()
            assert (await http.get("/static/css/xterm.css")).status == 200
    finally:
        sock.close()


async def test_a_web_page_sends_nothing_that_needs_control_until_it_takes_it() -> None:
    app = MillApp(frozen.SOCKET, live=False, web=True)
    sent: list[str] = []

    async def no_lease_here() -> None:  # the page never reaches the service for a lease it did not ask for
        sent.append("take_control")

    app.link.take_control = no_lease_here  # type: ignore[assignment,method-assign]
    async with app.run_test(size=(120, 40)) as pilot:
        await feeder(app, state="DISABLED")(pilot)
        assert "read-only" in str(app.query_one("#topbar").render())
        await pilot.press("a")
        await pilot.pause()
        messages = [n.message for n in app._notifications]
        assert READ_ONLY in messages, messages
    assert sent == []


def test_a_terminal_tui_is_not_read_only() -> None:
    assert MillApp(frozen.SOCKET, live=False).web is False
