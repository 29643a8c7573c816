"""The typed client of the controller service (``millctl serve``): :class:`Client` (sync) and :class:`AsyncClient`.

Shared by the CLI, the TUI, the recipe runner's front end and users' scripts::

    from millctl import Client

    with Client(name="my-script") as mill, mill.control():
        mill.arm()
        mill.set_speeds(180.0, 800.0)

Errors come back as millctl exceptions with their exit codes: a refusal by
the interlock is an :class:`InterlockRefusal` (exit 2) carrying the reason and
every refusal; a wrong state or control held by someone else is a
:class:`ServiceRefused` / :class:`ControlHeld` (exit 2); an invalid request a
:class:`RequestInvalid` (exit 1); no service a :class:`ServiceUnavailable` (exit 3).
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
from collections.abc import AsyncIterator, Iterator
from pathlib import Path
from typing import Any

import httpx

from millctl.errors import BusError, InterlockError, InvalidInputError

CLIENT_HEADER = "X-Millctl-Client"
LEASE_HEADER = "X-Millctl-Lease"
DEFAULT_TIMEOUT_S = 10.0


class ServiceUnavailable(BusError):
    """No service answers on the socket (or URL): start it with ``millctl serve``."""


class AccessDenied(BusError, PermissionError):
    """The socket's permissions, or the bearer token, keep this client out."""


class NodeUnavailable(BusError):
    """The service runs, but the node is unreachable or the control loop is down (HTTP 503)."""


class ServiceRefused(InterlockError):
    """The service refused a command (wrong state, or a running recipe); ``code`` is the API's error code."""

    def __init__(self, message: str, code: str = "", body: dict[str, Any] | None = None) -> None:
        self.code = code
        self.body = body or {}
        self.reason = str(self.body.get("message", message))
        super().__init__(message)


class InterlockRefusal(ServiceRefused):
    """The interlock refused a command; ``refusals`` lists quantity, value, limit, unit and reason."""

    @property
    def refusals(self) -> list[dict[str, Any]]:
        """Each out-of-envelope quantity with its value and limit."""
        return list(self.body.get("refusals", []))


class ControlHeld(ServiceRefused):
    """Another client holds control (``holder``), or this client has no valid lease (HTTP 423)."""

    @property
    def holder(self) -> str | None:
        """Who holds control."""
        holder = self.body.get("holder")
        return str(holder) if holder else None


class RequestInvalid(InvalidInputError):
    """The service rejected the request as invalid (HTTP 422); ``field`` names the field."""

    def __init__(self, message: str, field: str | None = None) -> None:
        self.field = field
        super().__init__(message)


def default_socket_path(config: str | os.PathLike[str] | None = None) -> str:
    """The service socket of the configuration chosen by precedence (``--config`` > env > ./config > packaged)."""
    from millctl.config import load_config

    return load_config(config).config.service.socket_path


def raise_for_error(response: httpx.Response, where: str) -> None:
    """Turn an API error response into the matching millctl exception."""
    if response.status_code < 400:
        return
    try:
        body = response.json()
    except ValueError:
        body = {}
    if not isinstance(body, dict):
        body = {}
    code = str(body.get("code", f"http_{response.status_code}"))
    message = str(body.get("message", response.text or response.reason_phrase))
    status = response.status_code
    if status == 409 and code in ("interlock_refused", "recipe_refused"):
        raise InterlockRefusal(message, code, body)
    if status == 423:
        raise ControlHeld(message, code, body)
    if status == 409:
        raise ServiceRefused(message, code, body)
    if status == 422:
        raise RequestInvalid(message, body.get("field"))
    if status == 401:
        raise AccessDenied(f"{where}: {message}")
    if status == 503:
        raise NodeUnavailable(f"{where}: {message}")
    raise BusError(f"{where}: HTTP {status} {code}: {message}")


class SseParser:
    """Incremental decoder of server-sent events: feed lines, get ``{"event": kind, "data": payload}`` dicts."""

    def __init__(self) -> None:
        self.kind = "message"
        self.data: list[str] = []

    def feed(self, line: str) -> dict[str, Any] | None:
        """Take one line; return an event when the blank line ending it arrives."""
        if not line:
            item = {"event": self.kind, "data": json.loads("\n".join(self.data))} if self.data else None
            self.kind, self.data = "message", []
            return item
        if line.startswith("event:"):
            self.kind = line[6:].strip()
        elif line.startswith("data:"):
            self.data.append(line[5:].lstrip())
        return None


def parse_sse(lines: Iterator[str]) -> Iterator[dict[str, Any]]:
    """Decode server-sent events from lines."""
    parser = SseParser()
    for line in lines:
        item = parser.feed(line)
        if item is not None:
            yield item


class _Base:
    """What the sync and async clients share: where to connect, who we are, the lease, error mapping."""

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

    def _headers(self) -> dict[str, str]:
        headers = {CLIENT_HEADER: self.name}
        if self.lease_id:
            headers[LEASE_HEADER] = self.lease_id
        if self.token:
            headers["Authorization"] = f"Bearer {self.token}"
        return headers

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

    def _transport_kwargs(self) -> dict[str, Any]:
        return {"uds": self.socket_path} if self.socket_path is not None else {}


class Client(_Base):
    """Synchronous client of the service (see the module docstring)."""

    def __init__(self, socket_path: str | os.PathLike[str] | None = None, **kwargs: Any) -> None:
        super().__init__(socket_path, **kwargs)
        transport = httpx.HTTPTransport(**self._transport_kwargs())
        self._http = httpx.Client(base_url=self.base_url, transport=transport, timeout=self.timeout_s)

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Close the connection (a held lease stays until released or expired)."""
        self._http.close()

    def _call(self, method: str, path: str, body: Any = None, params: dict[str, Any] | None = None) -> Any:
        try:
            response = self._http.request(method, path, json=body, params=params, headers=self._headers())
        except (httpx.ConnectError, httpx.RemoteProtocolError, FileNotFoundError, ConnectionError) as exc:
            raise self._unavailable(exc) from exc
        raise_for_error(response, self.where)
        return response.json()

    # reading
    def status(self) -> dict[str, Any]:
        """The controller's status (GET /v1/status)."""
        return dict(self._call("GET", "/v1/status"))

    def service(self) -> dict[str, Any]:
        """The running service: pid, config path and sha256, law, margin (GET /v1/service)."""
        return dict(self._call("GET", "/v1/service"))

    def envelope(self, points: int = 41) -> dict[str, Any]:
        """The enforced limit curve (GET /v1/envelope)."""
        return dict(self._call("GET", "/v1/envelope", params={"points": points}))

    def check(self, rotary_rpm: float, vibration_rpm: float, temp_c: float | None = None) -> dict[str, Any]:
        """Check a point against the envelope without commanding anything (POST /v1/envelope/check)."""
        body = {"rotary_rpm": rotary_rpm, "vibration_rpm": vibration_rpm, "temp_c": temp_c}
        return dict(self._call("POST", "/v1/envelope/check", body))

    def events(self, after: int = 0, limit: int = 500) -> dict[str, Any]:
        """Recorded events after sequence number ``after`` (GET /v1/events)."""
        return dict(self._call("GET", "/v1/events", params={"after": after, "limit": limit}))

    def control_state(self) -> dict[str, Any]:
        """Who holds control (GET /v1/control)."""
        return dict(self._call("GET", "/v1/control"))

    def stream(self, count: int | None = None) -> Iterator[dict[str, Any]]:
        """Live ``{"event": "status"|"event", "data": …}`` dicts (GET /v1/stream) until closed or ``count``."""
        params = {"count": count} if count else None
        timeout = httpx.Timeout(self.timeout_s, read=None)
        try:
            with self._http.stream("GET", "/v1/stream", params=params, headers=self._headers(),
                                   timeout=timeout) as response:
                if response.status_code >= 400:
                    response.read()
                    raise_for_error(response, self.where)
                yield from parse_sse(response.iter_lines())
        except (httpx.ConnectError, FileNotFoundError, ConnectionError) as exc:
            raise self._unavailable(exc) from exc

    # control
    def take_control(self, force: bool = False) -> dict[str, Any]:
        """Take (or renew) the control lease; ``force`` takes over an expired one."""
        lease = dict(self._call("POST", "/v1/control/take", {"force": force}))
        self.lease_id = str(lease["lease_id"])
        return lease

    def release_control(self) -> dict[str, Any]:
        """Give control back."""
        result = dict(self._call("POST", "/v1/control/release"))
        self.lease_id = None
        return result

    @contextlib.contextmanager
    def control(self, force: bool = False) -> Iterator[Client]:
        """Hold control for the ``with`` block (take, then release even on error)."""
        self.take_control(force)
        try:
            yield self
        finally:
            with contextlib.suppress(BusError, InterlockError):
                self.release_control()

    # commands
    def arm(self) -> dict[str, Any]:
        """Arm (needs control)."""
        return dict(self._call("POST", "/v1/arm"))

    def disarm(self) -> dict[str, Any]:
        """Disarm (needs control)."""
        return dict(self._call("POST", "/v1/disarm"))

    def stop(self) -> dict[str, Any]:
        """Controlled stop (needs control)."""
        return dict(self._call("POST", "/v1/stop"))

    def estop(self) -> dict[str, Any]:
        """Emergency stop (no control needed, always accepted)."""
        return dict(self._call("POST", "/v1/estop"))

    def reset(self) -> dict[str, Any]:
        """Clear a latched trip (needs control)."""
        return dict(self._call("POST", "/v1/reset"))

    def set_speeds(
        self,
        rotary_rpm: float,
        vibration_rpm: float,
        *,
        rotary_rate_rpm_s: float | None = None,
        vibration_rate_rpm_s: float | None = None,
        linear: bool = False,
        temp_c: float | None = None,
        rate_c_per_min: float | None = None,
    ) -> dict[str, Any]:
        """Ramp to new speeds (rpm), with an optional furnace target (°C), all or nothing (needs control).

        An :class:`InterlockRefusal` when any part is outside the envelope: then no part is applied.
        """
        body = {"rotary_rpm": rotary_rpm, "vibration_rpm": vibration_rpm, "rotary_rate_rpm_s": rotary_rate_rpm_s,
                "vibration_rate_rpm_s": vibration_rate_rpm_s, "linear": linear, "temp_c": temp_c,
                "rate_c_per_min": rate_c_per_min}
        return dict(self._call("POST", "/v1/setpoints", body))

    def set_furnace(self, temp_c: float | None, *, rate_c_per_min: float | None = None) -> dict[str, Any]:
        """Furnace target (°C), or None for heater off (needs control)."""
        return dict(self._call("POST", "/v1/furnace", {"temp_c": temp_c, "rate_c_per_min": rate_c_per_min}))

    # recipes
    def recipe_run(self, path: str | os.PathLike[str]) -> dict[str, Any]:
        """Start a recipe file (a path on the service's machine; needs control)."""
        return dict(self._call("POST", "/v1/recipe/run", {"path": str(Path(path).absolute())}))

    def recipe_pause(self, now: bool = False) -> dict[str, Any]:
        """Pause the run at the next step boundary, or now."""
        return dict(self._call("POST", "/v1/recipe/pause", {"now": now}))

    def recipe_resume(self) -> dict[str, Any]:
        """Resume a paused run."""
        return dict(self._call("POST", "/v1/recipe/resume"))

    def recipe_abort(self) -> dict[str, Any]:
        """Abort the run (controlled stop)."""
        return dict(self._call("POST", "/v1/recipe/abort"))

    def recipe(self) -> dict[str, Any]:
        """Progress of the current or last run."""
        return dict(self._call("GET", "/v1/recipe"))


class AsyncClient(_Base):
    """Asynchronous client of the service: the methods of :class:`Client`, as coroutines."""

    def __init__(self, socket_path: str | os.PathLike[str] | None = None, **kwargs: Any) -> None:
        super().__init__(socket_path, **kwargs)
        transport = httpx.AsyncHTTPTransport(**self._transport_kwargs())
        self._http = httpx.AsyncClient(base_url=self.base_url, transport=transport, timeout=self.timeout_s)

    async def __aenter__(self) -> AsyncClient:
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.aclose()

    async def aclose(self) -> None:
        """Close the connection."""
        await self._http.aclose()

    async def _call(self, method: str, path: str, body: Any = None, params: dict[str, Any] | None = None) -> Any:
        try:
            response = await self._http.request(method, path, json=body, params=params, headers=self._headers())
        except (httpx.ConnectError, httpx.RemoteProtocolError, FileNotFoundError, ConnectionError) as exc:
            raise self._unavailable(exc) from exc
        raise_for_error(response, self.where)
        return response.json()

    async def status(self) -> dict[str, Any]:
        """The controller's status."""
        return dict(await self._call("GET", "/v1/status"))

    async def service(self) -> dict[str, Any]:
        """The running service."""
        return dict(await self._call("GET", "/v1/service"))

    async def envelope(self, points: int = 41) -> dict[str, Any]:
        """The enforced limit curve."""
        return dict(await self._call("GET", "/v1/envelope", params={"points": points}))

    async def check(self, rotary_rpm: float, vibration_rpm: float, temp_c: float | None = None) -> dict[str, Any]:
        """Check a point against the envelope."""
        body = {"rotary_rpm": rotary_rpm, "vibration_rpm": vibration_rpm, "temp_c": temp_c}
        return dict(await self._call("POST", "/v1/envelope/check", body))

    async def events(self, after: int = 0, limit: int = 500) -> dict[str, Any]:
        """Recorded events after ``after``."""
        return dict(await self._call("GET", "/v1/events", params={"after": after, "limit": limit}))

    async def control_state(self) -> dict[str, Any]:
        """Who holds control."""
        return dict(await self._call("GET", "/v1/control"))

    async def stream(self, count: int | None = None) -> AsyncIterator[dict[str, Any]]:
        """Live status and event dicts, as :meth:`Client.stream`."""
        params = {"count": count} if count else None
        timeout = httpx.Timeout(self.timeout_s, read=None)
        try:
            async with self._http.stream("GET", "/v1/stream", params=params, headers=self._headers(),
                                         timeout=timeout) as response:
                if response.status_code >= 400:
                    await response.aread()
                    raise_for_error(response, self.where)
                parser = SseParser()
                async for line in response.aiter_lines():
                    item = parser.feed(line)
                    if item is not None:
                        yield item
        except (httpx.ConnectError, FileNotFoundError, ConnectionError) as exc:
            raise self._unavailable(exc) from exc

    async def take_control(self, force: bool = False) -> dict[str, Any]:
        """Take (or renew) the control lease."""
        lease = dict(await self._call("POST", "/v1/control/take", {"force": force}))
        self.lease_id = str(lease["lease_id"])
        return lease

    async def release_control(self) -> dict[str, Any]:
        """Give control back."""
        result = dict(await self._call("POST", "/v1/control/release"))
        self.lease_id = None
        return result

    @contextlib.asynccontextmanager
    async def control(self, force: bool = False) -> AsyncIterator[AsyncClient]:
        """Hold control for the ``async with`` block."""
        await self.take_control(force)
        try:
            yield self
        finally:
            with contextlib.suppress(BusError, InterlockError):
                await self.release_control()

    async def arm(self) -> dict[str, Any]:
        """Arm."""
        return dict(await self._call("POST", "/v1/arm"))

    async def disarm(self) -> dict[str, Any]:
        """Disarm."""
        return dict(await self._call("POST", "/v1/disarm"))

    async def stop(self) -> dict[str, Any]:
        """Controlled stop."""
        return dict(await self._call("POST", "/v1/stop"))

    async def estop(self) -> dict[str, Any]:
        """Emergency stop (no control needed)."""
        return dict(await self._call("POST", "/v1/estop"))

    async def reset(self) -> dict[str, Any]:
        """Clear a latched trip."""
        return dict(await self._call("POST", "/v1/reset"))

    async def set_speeds(
        self,
        rotary_rpm: float,
        vibration_rpm: float,
        *,
        rotary_rate_rpm_s: float | None = None,
        vibration_rate_rpm_s: float | None = None,
        linear: bool = False,
        temp_c: float | None = None,
        rate_c_per_min: float | None = None,
    ) -> dict[str, Any]:
        """Ramp to new speeds (rpm), with an optional furnace target (°C), all or nothing."""
        body = {"rotary_rpm": rotary_rpm, "vibration_rpm": vibration_rpm, "rotary_rate_rpm_s": rotary_rate_rpm_s,
                "vibration_rate_rpm_s": vibration_rate_rpm_s, "linear": linear, "temp_c": temp_c,
                "rate_c_per_min": rate_c_per_min}
        return dict(await self._call("POST", "/v1/setpoints", body))

    async def set_furnace(self, temp_c: float | None, *, rate_c_per_min: float | None = None) -> dict[str, Any]:
        """Furnace target (°C), or None for heater off."""
        return dict(await self._call("POST", "/v1/furnace", {"temp_c": temp_c, "rate_c_per_min": rate_c_per_min}))

    async def recipe_run(self, path: str | os.PathLike[str]) -> dict[str, Any]:
        """Start a recipe file."""
        return dict(await self._call("POST", "/v1/recipe/run", {"path": str(Path(path).absolute())}))

    async def recipe_pause(self, now: bool = False) -> dict[str, Any]:
        """Pause the run."""
        return dict(await self._call("POST", "/v1/recipe/pause", {"now": now}))

    async def recipe_resume(self) -> dict[str, Any]:
        """Resume the run."""
        return dict(await self._call("POST", "/v1/recipe/resume"))

    async def recipe_abort(self) -> dict[str, Any]:
        """Abort the run."""
        return dict(await self._call("POST", "/v1/recipe/abort"))

    async def recipe(self) -> dict[str, Any]:
        """Progress of the current or last run."""
        return dict(await self._call("GET", "/v1/recipe"))


__all__ = [
    "CLIENT_HEADER",
    "LEASE_HEADER",
    "AccessDenied",
    "AsyncClient",
    "Client",
    "ControlHeld",
    "InterlockRefusal",
    "NodeUnavailable",
    "RequestInvalid",
    "ServiceRefused",
    "ServiceUnavailable",
    "SseParser",
    "default_socket_path",
    "parse_sse",
    "raise_for_error",
]
