"""``millctl serve``: the runtime and its API on a Unix socket (and optional loopback TCP), one instance per socket.

The socket is created by the service itself, never by uvicorn (which would
chmod it 0666): the umask is narrowed before ``bind`` and the mode set with
``chmod`` after, so it is never briefly wider than ``service.socket_mode``.
A lock file beside the socket (``<socket>.lock``, ``flock``) makes a second
``serve`` on the same socket refuse to start; a stale socket file with
nothing listening is replaced. SIGTERM and SIGINT end the server, then the
runtime performs a controlled stop and the socket file is removed.
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import fcntl
import gc
import logging
import os
import signal
import socket
import stat
from collections.abc import Callable, Iterator
from pathlib import Path
from types import FrameType
from typing import IO

import uvicorn
from starlette.types import ASGIApp

from millctl.api import ServiceOut
from millctl.config.loader import LoadedConfig
from millctl.config.paths import service_paths
from millctl.errors import BusError, ConfigError, ExitCode
from millctl.service.app import create_app
from millctl.service.auth import TokenGuard, read_token
from millctl.service.connections import LISTEN_BACKLOG, guarded_protocol
from millctl.service.faults import require_simulated
from millctl.service.runtime import EMBEDDED_NODE_WAIT_S, ServiceRuntime

log = logging.getLogger(__name__)

SERVICE_UMASK = 0o027
"""Added to the process umask: nothing the service creates is readable by others, nor writable by its group."""


SERVICE_KEEP_ALIVE_S = 75
"""How long (s) the service keeps an idle connection: far past ``millctl.client.CLIENT_KEEP_ALIVE_S`` (the client's).

uvicorn's default (5 s) equals httpx's: a client that reuses a connection idle for 5 s can send its request
just as the service closes it, and get "Connection reset by peer" for a request that was never read.
75 s is the common server default (nginx, gunicorn).
"""


class ServiceRunning(BusError):
    """Another service already serves this socket."""


class _Server(uvicorn.Server):
    """uvicorn's server without its own signal handling (ours ends it cleanly), stopping if the loop dies."""

    def __init__(self, config: uvicorn.Config, runtime: ServiceRuntime) -> None:
        super().__init__(config)
        self.runtime = runtime

    @contextlib.contextmanager
    def capture_signals(self) -> Iterator[None]:
        """Signals are handled by :func:`serve`, not re-raised after shutdown as uvicorn would."""
        yield

    async def on_tick(self, counter: int) -> bool:
        """Also stop serving once the control loop has died (the exit code says so)."""
        if self.runtime.failed is not None:
            return True
        return await super().on_tick(counter)


def server_config(app: ASGIApp) -> uvicorn.Config:
    """The service's uvicorn settings: quiet, no lifespan, idle connections kept past the client's expiry.

    Its protocol bounds each request's arrival and the number of connections (:mod:`.connections`).
    """
    return uvicorn.Config(app, log_level="warning", lifespan="off", timeout_graceful_shutdown=2, access_log=False,
                          timeout_keep_alive=SERVICE_KEEP_ALIVE_S, http=guarded_protocol(), backlog=LISTEN_BACKLOG)


@contextlib.contextmanager
def instance_lock(socket_path: Path) -> Iterator[IO[str]]:
    """Hold ``<socket>.lock`` for the service's life; raise :class:`ServiceRunning` if another holds it."""
    lock_path = socket_path.with_name(socket_path.name + ".lock")
    try:
        handle = open(lock_path, "a+", encoding="utf-8")  # noqa: SIM115 - held for the context
    except OSError as exc:
        raise BusError(f"cannot open the service lock {lock_path}: {exc.strerror}") from exc
    try:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            handle.seek(0)
            pid = handle.read().strip() or "unknown"
            raise ServiceRunning(
                f"another millctl serve (pid {pid}) is already running on socket {socket_path} "
                f"(lock {lock_path}); stop it first, or pass --socket for a second mill"
            ) from None
        handle.seek(0)
        handle.truncate()
        handle.write(f"{os.getpid()}\n")
        handle.flush()
        yield handle
    finally:
        handle.close()


def _clear_stale_socket(path: Path) -> None:
    """Remove a socket file nobody listens on; refuse if something does."""
    if not path.exists() and not path.is_symlink():
        return
    if not stat.S_ISSOCK(path.lstat().st_mode):
        raise BusError(f"{path} exists and is not a socket: refusing to replace it (service.socket_path / --socket)")
    probe = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        probe.settimeout(1.0)
        probe.connect(str(path))
    except OSError as exc:
        if exc.errno not in (errno.ECONNREFUSED, errno.ENOENT, errno.ENOTSOCK):
            raise BusError(f"cannot check the existing socket {path}: {exc}") from exc
        log.warning("replacing stale socket %s (nothing listening)", path)
        path.unlink(missing_ok=True)
        return
    finally:
        probe.close()
    raise ServiceRunning(f"a service is already listening on socket {path}; stop it first, or pass --socket")


def bind_unix(path: Path, mode: int) -> socket.socket:
    """Bind and listen on a Unix socket whose mode is never wider than ``mode``."""
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    old_umask = os.umask(0o777 & ~mode | 0o111)
    try:
        sock.bind(str(path))
    except OSError as exc:
        sock.close()
        raise BusError(f"cannot bind the service socket {path}: {exc.strerror}") from exc
    finally:
        os.umask(old_umask)
    os.chmod(path, mode)
    sock.listen(LISTEN_BACKLOG)
    return sock


def bind_tcp(port: int) -> socket.socket:
    """Bind and listen on loopback TCP."""
    try:
        return socket.create_server(("127.0.0.1", port), backlog=LISTEN_BACKLOG)
    except OSError as exc:
        raise BusError(f"cannot listen on 127.0.0.1:{port} (service.tcp_port): {exc.strerror}") from exc


def serve(
    loaded: LoadedConfig,
    socket_path: str | None = None,
    *,
    on_ready: Callable[[Path, ServiceOut], None] | None = None,
    fault_injection: bool = False,
) -> int:
    """Run the service until SIGTERM/SIGINT; return the process exit code.

    ``on_ready(socket, the GET /v1/service body)`` is called once it serves. ``fault_injection`` lets an
    instructor inject the embedded simulated node's faults; refused (before anything starts) on a real bus.

    Files it creates are never readable by others: the umask is narrowed to
    SERVICE_UMASK for the service's life (records 0640, folders 0750).
    """
    service = loaded.config.service
    if fault_injection:
        require_simulated(loaded.config)
    path = service_paths(loaded, socket_path).socket
    os.umask(SERVICE_UMASK | os.umask(SERVICE_UMASK))
    token = None
    if service.tcp_port > 0:
        if not service.token_file:
            raise ConfigError(loaded.source, [f"{loaded.source}: service.tcp_port = {service.tcp_port} needs "
                                              "service.token_file (a bearer token); refusing to serve TCP without"])
        token = read_token(service.token_file)
    try:
        path.parent.mkdir(mode=0o750, parents=True, exist_ok=True)
    except OSError as exc:
        raise BusError(f"cannot create the socket directory {path.parent}: {exc.strerror}") from exc
    with instance_lock(path):
        _clear_stale_socket(path)
        sockets = [bind_unix(path, service.socket_mode)]
        try:
            if token is not None:
                sockets.append(bind_tcp(service.tcp_port))
            return _run(loaded, sockets, token, path, on_ready, fault_injection)
        finally:
            for sock in sockets:
                sock.close()
            path.unlink(missing_ok=True)


def _run(
    loaded: LoadedConfig,
    sockets: list[socket.socket],
    token: str | None,
    path: Path,
    on_ready: Callable[[Path, ServiceOut], None] | None,
    fault_injection: bool,
) -> int:
    runtime = ServiceRuntime(loaded, fault_injection=fault_injection)
    runtime.socket_path = str(path)
    app: ASGIApp = create_app(runtime)
    if token is not None:
        app = TokenGuard(app, token)
    server = _Server(server_config(app), runtime)
    received: list[str] = []

    def on_signal(signum: int, frame: FrameType | None) -> None:
        received.append(signal.Signals(signum).name)
        runtime.stopping = True  # ends the event streams, so the server need not wait for them
        if server.should_exit:
            server.force_exit = True
        server.should_exit = True

    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGTERM, signal.SIGINT)}
    # Everything imported and built so far lives as long as the service: keep it out of the garbage
    # collector's full passes, which otherwise stop every thread, the control loop too, for 0.1-0.2 s.
    gc.collect()
    gc.freeze()
    runtime.start()
    if runtime.node is not None and not runtime.wait_for_node(EMBEDDED_NODE_WAIT_S):
        log.warning("the embedded node was not seen within %.0f s; serving anyway", EMBEDDED_NODE_WAIT_S)
    log.info("listening on %s (pid %d)", path, os.getpid())
    if on_ready is not None:
        on_ready(path, runtime.describe())
    try:
        asyncio.run(server.serve(sockets=sockets))
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        failed = runtime.failed
        reason = f"{received[0]} received" if received else (failed or "server ended")
        runtime.shutdown(reason)
    return int(ExitCode.INTERNAL) if failed else int(ExitCode.OK)


__all__ = [
    "SERVICE_KEEP_ALIVE_S",
    "SERVICE_UMASK",
    "ServiceRunning",
    "bind_tcp",
    "bind_unix",
    "instance_lock",
    "serve",
    "server_config",
]
