"""The API protocol's guards, on a real uvicorn server over a Unix socket (issue 37, defect 2).

A half-sent request is closed after its deadline, a kept-alive idle connection is not, and over the bound on
connections the one that waited longest is closed so that a new client is answered at once. The service's own
figures and the attack at the file limit: tests/hil/service/test_api_attacks.py.
"""

from __future__ import annotations

import asyncio
import contextlib
import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import uvicorn
from starlette.types import Receive, Scope, Send

import millctl.service.connections as connections
from tests.support.pace import Deadline, stretched

DEADLINE_S = 0.5
"""The request deadline of the server under test (s): short, so the test is."""
BOUND = 4
"""Its bound on connections (monkeypatched)."""
WAIT_S = 10.0
"""A safety net on each wait for the server (stretched with load), not a measurement."""
REQUEST = b"GET /ping HTTP/1.1\r\nHost: t\r\n\r\n"


async def _app(scope: Scope, receive: Receive, send: Send) -> None:
    assert scope["type"] == "http"
    await send({"type": "http.response.start", "status": 200, "headers": [(b"content-length", b"4")]})
    await send({"type": "http.response.body", "body": b"pong"})


@contextlib.contextmanager
def _serving(path: Path, deadline_s: float) -> Iterator[Path]:
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    sock.bind(str(path))
    config = uvicorn.Config(_app, log_level="warning", lifespan="off", access_log=False, timeout_keep_alive=75,
                            http=connections.guarded_protocol(deadline_s), backlog=connections.LISTEN_BACKLOG)
    served = uvicorn.Server(config)
    thread = threading.Thread(target=lambda: asyncio.run(served.serve(sockets=[sock])), daemon=True)
    thread.start()
    deadline = Deadline(WAIT_S)
    while not served.started:
        assert not deadline.expired(), "the server did not start"
        time.sleep(0.01)
    try:
        yield path
    finally:
        served.should_exit = True
        thread.join(stretched(WAIT_S))
        sock.close()


@pytest.fixture
def server(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """A server whose requests have DEADLINE_S to arrive, and BOUND connections."""
    monkeypatch.setattr(connections, "max_connections", lambda: BOUND)
    with _serving(tmp_path / "api.sock", DEADLINE_S) as path:
        yield path


@pytest.fixture
def patient_server(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """A server with BOUND connections whose deadline no wait of the test reaches: only the bound closes them."""
    monkeypatch.setattr(connections, "max_connections", lambda: BOUND)
    with _serving(tmp_path / "api.sock", 100 * stretched(WAIT_S)) as path:
        yield path


def _connect(path: Path) -> socket.socket:
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    sock.settimeout(stretched(WAIT_S))
    sock.connect(str(path))
    return sock


def _answered(sock: socket.socket) -> bool:
    """Send a whole request; True once the whole answer (200, its body) is back, False if the server closed."""
    sock.settimeout(stretched(WAIT_S))
    sock.sendall(REQUEST)
    answer = b""
    while not answer.endswith(b"pong"):
        chunk = sock.recv(4096)
        if not chunk:
            return False
        answer += chunk
    return answer.startswith(b"HTTP/1.1 200")


def _closed_within(sock: socket.socket, seconds: float) -> bool:
    sock.settimeout(seconds)
    try:
        return sock.recv(1) == b""
    except TimeoutError:
        return False
    except OSError:
        return True


def test_a_half_sent_request_is_closed_after_its_deadline(server: Path) -> None:
    half = _connect(server)
    half.sendall(REQUEST[:12])
    assert _closed_within(half, stretched(WAIT_S))


def test_a_connection_that_never_sends_is_closed_after_the_deadline(server: Path) -> None:
    assert _closed_within(_connect(server), stretched(WAIT_S))


def test_an_idle_kept_alive_connection_outlives_the_deadline_and_is_answered_again(server: Path) -> None:
    client = _connect(server)
    assert _answered(client)
    assert not _closed_within(client, 4 * DEADLINE_S)  # idle between requests: uvicorn's keep-alive applies
    assert _answered(client)


def test_over_the_bound_the_longest_waiting_connection_makes_room(patient_server: Path) -> None:
    waiting = []
    for _ in range(BOUND):
        sock = _connect(patient_server)
        sock.sendall(REQUEST[:5])  # half-sent: each waits for the rest
        assert not _closed_within(sock, DEADLINE_S)  # taken in (the order of arrival is the order of waiting)
        waiting.append(sock)
    newcomer = _connect(patient_server)
    assert _answered(newcomer)
    assert _closed_within(waiting[0], stretched(WAIT_S))  # the longest waiting made room
    assert not any(_closed_within(sock, DEADLINE_S) for sock in waiting[1:])
    busy = _connect(patient_server)  # over the bound again: the next longest waiting goes
    assert _answered(busy)
    assert _closed_within(waiting[1], stretched(WAIT_S))
    for sock in (*waiting, newcomer, busy):
        sock.close()
