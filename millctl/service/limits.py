"""Bounded requests: a body larger than ``service.max_request_bytes`` is refused with 413, never read whole.

An ASGI middleware in front of the API: a declared ``Content-Length`` over the
bound is answered at once without reading a byte; a body without one (chunked)
is read up to the bound and refused as soon as it passes it. Either way the request
costs the service at most the bound in memory and never reaches a route, so
no request can starve the control loop (SAFETY 19).
"""

from __future__ import annotations

import json
from typing import Any

from starlette.types import ASGIApp, Message, Receive, Scope, Send

MAX_REQUEST_BYTES = 1 << 20
"""The default bound (bytes): far above any recipe or command."""


class BodyLimit:
    """ASGI middleware: 413 ``body_too_large`` for a body over ``max_bytes``."""

    def __init__(self, app: ASGIApp, max_bytes: int = MAX_REQUEST_BYTES) -> None:
        self.app = app
        self.max_bytes = max_bytes

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        """Refuse an oversized body, declared or streamed."""
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        declared = dict(scope.get("headers") or []).get(b"content-length")
        if declared is not None:
            try:
                length = int(declared)
            except ValueError:
                await _reply(send, 400, "bad_request", f"Content-Length {declared[:32]!r} is not a number")
                return
            if length > self.max_bytes:
                await _reply(send, 413, "body_too_large", self._message(f"declares {length} bytes"))
                return
        body = bytearray()
        more = True
        while more:
            message = await receive()
            if message["type"] != "http.request":  # the client left before its body was complete
                return
            body += message.get("body", b"")
            more = bool(message.get("more_body", False))
            if len(body) > self.max_bytes:
                await _reply(send, 413, "body_too_large", self._message(f"sent more than {self.max_bytes} bytes"))
                return
        replayed = False

        async def replay() -> Message:
            nonlocal replayed
            if not replayed:
                replayed = True
                return {"type": "http.request", "body": bytes(body), "more_body": False}
            return await receive()

        await self.app(scope, replay, send)

    def _message(self, what: str) -> str:
        return (f"request body too large: it {what}; the bound is {self.max_bytes} bytes "
                "(service.max_request_bytes); send a recipe's text, not data")


async def _reply(send: Send, status: int, code: str, message: str) -> None:
    body: dict[str, Any] = {"code": code, "message": message, "field": "body"}
    payload = json.dumps(body).encode()
    await send({"type": "http.response.start", "status": status,
                "headers": [(b"content-type", b"application/json"), (b"content-length", str(len(payload)).encode()),
                            (b"connection", b"close")]})
    await send({"type": "http.response.body", "body": payload})


__all__ = ["MAX_REQUEST_BYTES", "BodyLimit"]
