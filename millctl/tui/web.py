"""``millctl tui --web``: the same TUI in a browser, served by textual-serve on loopback only.

Every browser connection starts its own TUI process (:mod:`millctl.tui.web_session`) on
the service's socket, read-only until its operator takes the control lease with ``c``
(docs/operations.md#the-tui-in-a-browser). The server binds 127.0.0.1 and nothing else;
from another machine it is reached through an SSH tunnel (docs/deployment.md#6-clients).
As any local user can open a loopback port, the page and its websocket also need the
one-time key in the URL that this command prints (kept in a same-site cookie after the
first visit), and the websocket only answers pages of its own origin.
"""

from __future__ import annotations

import errno
import hmac
import secrets
import shlex
import socket
import sys
from collections.abc import Awaitable, Callable

from aiohttp import web
from rich.console import Console
from textual_serve.server import Server

from millctl.errors import InvalidInputError

LOOPBACK = "127.0.0.1"
"""The only address the web TUI listens on."""
DEFAULT_WEB_PORT = 8566
"""The web TUI's port unless ``--web-port`` names another (0: any free port)."""
KEY_PARAM = "key"
"""The URL's query parameter that carries the one-time key."""

Handler = Callable[[web.Request], Awaitable[web.StreamResponse]]


class PortInUse(InvalidInputError):
    """The web TUI's port is taken: exit 1, naming the port and how to choose another."""


def bind_loopback(port: int) -> socket.socket:
    """A listening TCP socket on 127.0.0.1:``port`` (0: a free one), or :class:`PortInUse`."""
    if not 0 <= port <= 65535:
        raise InvalidInputError(f"--web-port {port} is not a TCP port (0-65535; 0 picks a free one)")
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind((LOOPBACK, port))
        sock.listen(16)
    except OSError as exc:
        sock.close()
        if exc.errno == errno.EADDRINUSE:
            raise PortInUse(f"port {port} on {LOOPBACK} is in use (another program, or another `millctl tui "
                            "--web`): choose a free one with --web-port PORT (docs/operations.md#the-tui-in-a-browser)"
                            ) from exc
        raise InvalidInputError(f"cannot listen on {LOOPBACK}:{port}: {exc.strerror}") from exc
    return sock


def session_command(socket_path: str, config: str | None, *, sim: bool) -> str:
    """The shell command textual-serve runs for each browser connection: a read-only-until-taken TUI."""
    argv = [sys.executable, "-m", "millctl.tui.web_session", "--socket", socket_path]
    if config:
        argv += ["--config", config]
    if sim:
        argv.append("--simulated")
    return shlex.join(argv)


class LoopbackServer(Server):
    """textual-serve's server on an already bound loopback socket, behind a one-time key."""

    def __init__(self, command: str, sock: socket.socket, *, title: str, sim: bool = False) -> None:
        self.sock = sock
        self.sim = sim
        port = int(sock.getsockname()[1])
        super().__init__(command, host=LOOPBACK, port=port, title=title)
        self.console = Console(file=sys.stderr, highlight=False, soft_wrap=True)
        self.key = secrets.token_urlsafe(18)
        self.cookie = f"millctl_web_key_{port}"  # cookies ignore the port: one name a server
        self.url = f"{self.public_url}/?{KEY_PARAM}={self.key}"

    def _allowed(self, request: web.Request) -> bool:
        given = request.query.get(KEY_PARAM) or request.cookies.get(self.cookie) or ""
        return hmac.compare_digest(given.encode(), self.key.encode())

    @web.middleware
    async def guard(self, request: web.Request, handler: Handler) -> web.StreamResponse:
        """The page, the websocket and downloads need the key; the websocket also the page's own origin."""
        if request.path.startswith("/static/"):
            return await handler(request)  # the page's scripts and fonts: no mill data
        if not self._allowed(request):
            raise web.HTTPForbidden(text="millctl tui --web: this page needs the key in the URL that `millctl tui "
                                         "--web` printed (docs/operations.md#the-tui-in-a-browser)\n")
        origin = request.headers.get("Origin")
        if request.path == "/ws" and origin is not None and origin != self.public_url:
            raise web.HTTPForbidden(text=f"millctl tui --web: websocket from another origin ({origin}) refused\n")
        response = await handler(request)
        if request.query.get(KEY_PARAM) and isinstance(response, web.Response):
            response.set_cookie(self.cookie, self.key, httponly=True, samesite="Strict")
        return response

    async def _make_app(self) -> web.Application:
        app = await super()._make_app()
        app.middlewares.append(self.guard)
        return app

    async def on_startup(self, app: web.Application) -> None:
        """Say where the page is (on stderr: stdout stays for data)."""
        after = "and the simulated mill, controlled stop" if self.sim else "the service and the mill carry on"
        self.console.print(f"millctl tui --web: serving the TUI on {self.url}", markup=False)
        self.console.print(f"  only on {LOOPBACK}; from another machine: ssh -L {self.port}:{LOOPBACK}:{self.port} "
                           "<this host>, then open the same URL there. Each page is read-only until it takes "
                           f"control (c). Ctrl+C stops serving ({after}).", markup=False)

    def serve(self, debug: bool = False) -> None:
        """Serve until SIGINT or SIGTERM, on the bound socket."""
        self.debug = debug
        self.initialize_logging()
        web.run_app(self._make_app(), sock=self.sock, handle_signals=True, print=None)


__all__ = ["DEFAULT_WEB_PORT", "KEY_PARAM", "LOOPBACK", "LoopbackServer", "PortInUse", "bind_loopback",
           "session_command"]
