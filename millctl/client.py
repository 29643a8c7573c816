"""The typed client of the controller service (``millctl serve``): :class:`Client` (sync) and :class:`AsyncClient`.

Shared by the CLI, the TUI, the recipe runner's front end and users' scripts::

    from millctl import Client

    with Client(name="my-script") as mill, mill.control():
        mill.arm()
        mill.set_speeds(180.0, 800.0)

Both clients are built from one table of operations (:class:`Operations`):
each row says how a call becomes a request and which :mod:`millctl.api` model
the answer is. The two clients differ only in their transport: :class:`Client`
sends with ``httpx.Client``, :class:`AsyncClient` awaits ``httpx.AsyncClient``.

Errors come back as millctl exceptions with their exit codes (see
:mod:`millctl.client_errors`): a refusal by the interlock is an
:class:`InterlockRefusal` (exit 2) carrying the reason and every refusal; a
wrong state or control held by someone else is a :class:`ServiceRefused` /
:class:`ControlHeld` (exit 2); an invalid request a :class:`RequestInvalid`
(exit 1); no service a :class:`ServiceUnavailable` (exit 3).

The live stream (:meth:`Client.stream`) is server-sent events; the client
remembers the id of the last event it saw and sends it as ``Last-Event-ID``
when it streams again, so a client that reconnects misses no event.
"""

from __future__ import annotations

import contextlib
import functools
import os
import socket
import ssl
from collections.abc import AsyncGenerator, AsyncIterator, Callable, Generator, Iterator
from pathlib import Path
from typing import Any, ParamSpec, TypeVar

import httpx
from httpx_sse import ServerSentEvent, aconnect_sse, connect_sse
from pydantic import BaseModel

from millctl.api import (
    BusHealthOut,
    CheckOut,
    CommandOut,
    ControlOut,
    EnvelopeOut,
    EventOut,
    EventsOut,
    FaultsOut,
    LeaseOut,
    RecipeCheckOut,
    RecipeOut,
    RecipeResumeOut,
    ServiceOut,
    StatusOut,
    StreamKind,
    UnfinishedRunOut,
    UnfinishedRunsOut,
)
from millctl.client_errors import (
    AccessDenied,
    ControlHeld,
    InterlockRefusal,
    NodeUnavailable,
    RequestInvalid,
    ServiceRefused,
    ServiceUnavailable,
    raise_for_error,
)
from millctl.client_ops import (
    Operation,
    Request,
    _arm,
    _check,
    _control_state,
    _disarm,
    _envelope,
    _estop,
    _events,
    _faults,
    _inject_fault,
    _recipe,
    _recipe_abort,
    _recipe_check,
    _recipe_check_text,
    _recipe_close_run,
    _recipe_pause,
    _recipe_resume,
    _recipe_resume_run,
    _recipe_run,
    _recipe_run_text,
    _recipe_unfinished,
    _release,
    _reset,
    _service,
    _set_furnace,
    _set_speeds,
    _status,
    _stop,
    _take,
    read_recipe_text,
)
from millctl.errors import BusError, InterlockError

CLIENT_HEADER = "X-Millctl-Client"
LEASE_HEADER = "X-Millctl-Lease"
LAST_EVENT_ID_HEADER = "Last-Event-ID"
DEFAULT_TIMEOUT_S = 10.0
CLIENT_KEEP_ALIVE_S = 2.0
"""How long a client keeps an idle connection for reuse; the service keeps it far longer (SERVICE_KEEP_ALIVE_S).

So an idle connection is always let go by the client first. With both at 5 s (uvicorn's and httpx's defaults), a
request sent just as the service closed the connection met "Connection reset by peer" (tests/vm/README.md).
"""

P = ParamSpec("P")
T = TypeVar("T", bound=BaseModel)
StreamItem = StatusOut | EventOut
"""What the live stream yields: a status snapshot, or an event."""


def default_socket_path(config: str | os.PathLike[str] | None = None) -> str:
    """The service socket of the configuration chosen by precedence (``--config`` > env > ./config > packaged).

    Resolved as the service resolves it (:mod:`millctl.config.paths`): by
    platform convention unless the config names one, never from the working
    folder, so a client in any folder finds the service of the same config.
    """
    from millctl.config import load_config
    from millctl.config.paths import service_paths

    return str(service_paths(load_config(config)).socket)


def describe_mill(service: ServiceOut) -> str:
    """One line naming the mill a service controls: config name, bus, simulated or real, and the socket."""
    kind = "SIMULATED mill (embedded node)" if service.simulated else "real bus"
    return (f"mill {service.mill_name!r} on {service.bus_interface}:{service.bus_channel} ({kind}), "
            f"config {service.config_path}, socket {service.socket_path}")


def describe_bus_health(health: BusHealthOut) -> str:
    """One line of the CAN controller's condition and error counts (``millctl status``, the TUI, ``bus check``)."""
    counters = "" if health.tx_error_counter is None else (
        f"   TEC {health.tx_error_counter} REC {health.rx_error_counter}"
    )
    return (f"{health.condition}   error frames {health.error_frames} (bus {health.bus_errors}, no ACK "
            f"{health.ack_errors}, controller {health.controller_errors})   error-passive "
            f"{health.error_passive_count}×, bus-off {health.bus_off_count}×{counters}")


class _Base:
    """What both clients share: where to connect, who we are, the lease and the last event seen."""

    def __init__(
        self,
        socket_path: str | os.PathLike[str] | None = None,
        *,
        base_url: str | None = None,
        token: str | None = None,
        name: str = "cli",
        config: str | os.PathLike[str] | None = None,
        timeout_s: float = DEFAULT_TIMEOUT_S,
    ) -> None:
        self.base_url = base_url.rstrip("/") if base_url else "http://millctl"
        self.socket_path: str | None = None
        if base_url is None:
            self.socket_path = str(socket_path) if socket_path else default_socket_path(config)
        self.where = f"service at {base_url}" if base_url else f"service socket {self.socket_path}"
        self.name = name if "@" in name else f"{name}@{socket.gethostname()}"
        self.token = token
        self.timeout_s = timeout_s
        self.lease_id: str | None = None
        self.last_event_id: int | None = None
        """Sequence number of the last event streamed; sent as ``Last-Event-ID`` when streaming again."""

    _perform: Callable[[Operation[Any, Any], Request], Any]
    """The transport: sends a request and returns the answer (:class:`Client`) or awaits it (:class:`AsyncClient`)."""

    def _headers(self) -> dict[str, str]:
        headers = {CLIENT_HEADER: self.name}
        if self.lease_id:
            headers[LEASE_HEADER] = self.lease_id
        if self.token:
            headers["Authorization"] = f"Bearer {self.token}"
        return headers

    def _stream_headers(self) -> dict[str, str]:
        headers = self._headers()
        if self.last_event_id is not None:
            headers[LAST_EVENT_ID_HEADER] = str(self.last_event_id)
        return headers

    def _answer(self, op: Operation[Any, T], response: httpx.Response) -> T:
        """The response as the operation's model (or its error raised); the lease kept up to date."""
        raise_for_error(response, self.where)
        result = op.out.model_validate(response.json())
        if isinstance(result, LeaseOut):
            self.lease_id = result.lease_id
        elif op.build is _release:
            self.lease_id = None
        return result

    def _stream_item(self, sse: ServerSentEvent) -> StreamItem | None:
        """One server-sent event as a model (None for kinds this client does not know)."""
        if sse.event == StreamKind.EVENT:
            event = EventOut.model_validate_json(sse.data)
            self.last_event_id = event.seq
            return event
        if sse.event == StreamKind.STATUS:
            return StatusOut.model_validate_json(sse.data)
        return None

    def _unavailable(self, exc: Exception) -> BusError:
        if self.socket_path is not None:
            path = Path(self.socket_path)
            if isinstance(exc.__cause__ or exc.__context__, PermissionError) or (
                path.exists() and not os.access(path, os.R_OK | os.W_OK)
            ):
                return AccessDenied(f"no access to the service socket {path}: its mode or owner keeps this user "
                                    "out (service.socket_mode)")
            return ServiceUnavailable(f"no millctl service on socket {path} ({exc}); start it with `millctl serve`")
        return ServiceUnavailable(f"no millctl service at {self.base_url} ({exc}); start it with `millctl serve`")

    def _failed(self, request: Request, exc: Exception) -> BusError:
        """The error for a request the transport failed: the service is gone, or the connection broke mid-request."""
        if not isinstance(exc, _LOST):
            return self._unavailable(exc)
        return ServiceUnavailable(f"the connection to the millctl {self.where} broke during "
                                  f"{request.method} {request.path} ({exc}): whether it was carried out is unknown; "
                                  "see `millctl status` and `millctl events`")

    def _transport_kwargs(self) -> dict[str, Any]:
        where = {"uds": self.socket_path} if self.socket_path is not None else {}
        return {**where, "verify": _tls_context()}

    def _stream_request(self, count: int | None) -> dict[str, Any]:
        return {"params": {"count": count} if count else None, "headers": self._stream_headers(),
                "timeout": httpx.Timeout(self.timeout_s, read=None)}


@functools.cache
def _tls_context() -> ssl.SSLContext:
    """The default TLS context of httpx (system CA bundle, ``SSL_CERT_FILE``/``SSL_CERT_DIR``), made once a process.

    A transport makes a fresh one otherwise, reading the CA bundle (~20 ms of CPU) for every client,
    though a client of the Unix socket never speaks TLS.
    """
    return httpx.create_ssl_context()


_GONE = (httpx.ConnectError, httpx.ConnectTimeout, httpx.PoolTimeout, httpx.RemoteProtocolError, FileNotFoundError,
         ConnectionError)
"""What a missing, vanished or unreachable service looks like to httpx."""
_LOST = (httpx.ReadError, httpx.WriteError, httpx.ReadTimeout, httpx.WriteTimeout)
"""A connection broken, or unanswered, mid-request: the service may or may not have carried the request out."""
_FAILED = _GONE + _LOST
_LIMITS = httpx.Limits(keepalive_expiry=CLIENT_KEEP_ALIVE_S)
_STREAM = Request("GET", "/v1/stream")


class Operations(_Base):
    """The table: every API operation, once, with the model it returns."""

    status = Operation(StatusOut, _status)
    service = Operation(ServiceOut, _service)
    envelope = Operation(EnvelopeOut, _envelope)
    check = Operation(CheckOut, _check)
    events = Operation(EventsOut, _events)
    control_state = Operation(ControlOut, _control_state)
    take_control = Operation(LeaseOut, _take)
    release_control = Operation(ControlOut, _release)
    arm = Operation(CommandOut, _arm)
    disarm = Operation(CommandOut, _disarm)
    stop = Operation(CommandOut, _stop)
    estop = Operation(CommandOut, _estop)
    reset = Operation(CommandOut, _reset)
    set_speeds = Operation(CommandOut, _set_speeds)
    set_furnace = Operation(CommandOut, _set_furnace)
    recipe_run = Operation(RecipeOut, _recipe_run)
    recipe_run_text = Operation(RecipeOut, _recipe_run_text)
    recipe_pause = Operation(RecipeOut, _recipe_pause)
    recipe_resume = Operation(RecipeOut, _recipe_resume)
    recipe_abort = Operation(RecipeOut, _recipe_abort)
    recipe = Operation(RecipeOut, _recipe)
    recipe_unfinished = Operation(UnfinishedRunsOut, _recipe_unfinished)
    recipe_resume_run = Operation(RecipeResumeOut, _recipe_resume_run)
    recipe_close_run = Operation(UnfinishedRunOut, _recipe_close_run)
    recipe_check = Operation(RecipeCheckOut, _recipe_check)
    recipe_check_text = Operation(RecipeCheckOut, _recipe_check_text)
    faults = Operation(FaultsOut, _faults)
    inject_fault = Operation(FaultsOut, _inject_fault)


class Client(Operations):
    """Synchronous client of the service: the operations as methods (see the module docstring)."""

    def __init__(self, socket_path: str | os.PathLike[str] | None = None, **kwargs: Any) -> None:
        super().__init__(socket_path, **kwargs)
        transport = httpx.HTTPTransport(**self._transport_kwargs(), limits=_LIMITS)
        self._http = httpx.Client(base_url=self.base_url, transport=transport, timeout=self.timeout_s)

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Close the connection (a held lease stays until released or expired)."""
        self._http.close()

    def _perform(self, op: Operation[Any, T], request: Request) -> T:
        try:
            response = self._http.request(request.method, request.path, json=request.body, params=request.params,
                                          headers=self._headers())
        except _FAILED as exc:
            raise self._failed(request, exc) from exc
        return self._answer(op, response)

    @contextlib.contextmanager
    def control(self, force: bool = False) -> Iterator[Client]:
        """Hold control for the ``with`` block (take, then release even on error)."""
        self.take_control(force)
        try:
            yield self
        finally:
            with contextlib.suppress(BusError, InterlockError):
                self.release_control()

    def stream(self, count: int | None = None) -> Generator[StreamItem, None, None]:
        """Live :class:`StatusOut` and :class:`EventOut` items (GET /v1/stream) until closed or ``count``.

        Resumes after :attr:`last_event_id` when set (a reconnection misses no event).
        """
        try:
            with connect_sse(self._http, _STREAM.method, _STREAM.path, **self._stream_request(count)) as source:
                if source.response.status_code >= 400:
                    source.response.read()
                    raise_for_error(source.response, self.where)
                for sse in source.iter_sse():
                    item = self._stream_item(sse)
                    if item is not None:
                        yield item
        except _FAILED as exc:
            raise self._failed(_STREAM, exc) from exc


class AsyncClient(Operations):
    """Asynchronous client of the service: the operations of :class:`Client`, as coroutines."""

    def __init__(self, socket_path: str | os.PathLike[str] | None = None, **kwargs: Any) -> None:
        super().__init__(socket_path, **kwargs)
        transport = httpx.AsyncHTTPTransport(**self._transport_kwargs(), limits=_LIMITS)
        self._http = httpx.AsyncClient(base_url=self.base_url, transport=transport, timeout=self.timeout_s)

    async def __aenter__(self) -> AsyncClient:
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.aclose()

    async def aclose(self) -> None:
        """Close the connection."""
        await self._http.aclose()

    async def _perform(self, op: Operation[Any, T], request: Request) -> T:
        try:
            response = await self._http.request(request.method, request.path, json=request.body,
                                                params=request.params, headers=self._headers())
        except _FAILED as exc:
            raise self._failed(request, exc) from exc
        return self._answer(op, response)

    @contextlib.asynccontextmanager
    async def control(self, force: bool = False) -> AsyncIterator[AsyncClient]:
        """Hold control for the ``async with`` block."""
        await self.take_control(force)
        try:
            yield self
        finally:
            with contextlib.suppress(BusError, InterlockError):
                await self.release_control()

    async def stream(self, count: int | None = None) -> AsyncGenerator[StreamItem, None]:
        """Live status and event items, as :meth:`Client.stream` (resuming after :attr:`last_event_id`)."""
        try:
            async with aconnect_sse(self._http, _STREAM.method, _STREAM.path, **self._stream_request(count)) as source:
                if source.response.status_code >= 400:
                    await source.response.aread()
                    raise_for_error(source.response, self.where)
                async for sse in source.aiter_sse():
                    item = self._stream_item(sse)
                    if item is not None:
                        yield item
        except _FAILED as exc:
            raise self._failed(_STREAM, exc) from exc


__all__ = [
    "CLIENT_HEADER",
    "CLIENT_KEEP_ALIVE_S",
    "LAST_EVENT_ID_HEADER",
    "LEASE_HEADER",
    "AccessDenied",
    "AsyncClient",
    "Client",
    "ControlHeld",
    "InterlockRefusal",
    "NodeUnavailable",
    "Operation",
    "Operations",
    "Request",
    "RequestInvalid",
    "ServiceRefused",
    "ServiceUnavailable",
    "StreamItem",
    "default_socket_path",
    "describe_bus_health",
    "describe_mill",
    "raise_for_error",
    "read_recipe_text",
]
