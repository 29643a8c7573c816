"""Who may talk to the service: the Unix socket's file mode, and a bearer token on loopback TCP.

On the Unix socket the kernel checks access (mode ``service.socket_mode``,
0600 by default: only the service's user). TCP has no such check, so it is
served only with a token read from ``service.token_file``, and every TCP
request must carry ``Authorization: Bearer <token>`` (compared in constant
time). The guard tells the two apart by the listening address: a Unix socket
has no port.
"""

from __future__ import annotations

import json
import secrets
import stat
from pathlib import Path
from typing import Any

from starlette.types import ASGIApp, Receive, Scope, Send

from millctl.api import ErrorCode
from millctl.errors import InvalidInputError
from millctl.files import FileRefused, read_input_text

MIN_TOKEN_CHARS = 16
MAX_TOKEN_FILE_BYTES = 4096
"""The token file is a line of text: anything longer is refused unread (millctl.files)."""


def read_token(path: str | Path) -> str:
    """Read the bearer token (first line of the file); refuse a missing, empty, short or world-readable one."""
    path = Path(path)
    try:
        mode = path.stat().st_mode
        text = read_input_text(path, MAX_TOKEN_FILE_BYTES)
    except FileRefused as exc:
        raise InvalidInputError(f"service.token_file {path}: cannot read it: {exc}") from None
    except OSError as exc:
        raise InvalidInputError(f"service.token_file {path}: cannot read it: {exc.strerror}") from None
    lines = text.strip().splitlines()
    token = lines[0].strip() if lines else ""
    if mode & 0o007:
        raise InvalidInputError(
            f"service.token_file {path}: mode 0o{stat.S_IMODE(mode):o} lets others read the token; "
            f"`chmod 600 {path}` (or 640 for the service's group) first"
        )
    if len(token) < MIN_TOKEN_CHARS:
        raise InvalidInputError(
            f"service.token_file {path}: the token has {len(token)} characters; it needs at least {MIN_TOKEN_CHARS}"
        )
    return token


def _is_tcp(scope: Scope) -> bool:
    server = scope.get("server")
    return server is not None and server[1] is not None


class TokenGuard:
    """ASGI middleware: requests that arrived over TCP need the bearer token; the Unix socket passes."""

    def __init__(self, app: ASGIApp, token: str) -> None:
        self.app = app
        self._expected = f"Bearer {token}".encode()

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        """Check the token of a TCP request, answer 401 (JSON error) without it."""
        if scope["type"] == "http" and _is_tcp(scope):
            headers = dict(scope.get("headers") or [])
            given = headers.get(b"authorization")
            if given is None or not secrets.compare_digest(given, self._expected):
                message = "missing bearer token" if given is None else "wrong bearer token"
                await _reply_401(send, message)
                return
        await self.app(scope, receive, send)


async def _reply_401(send: Send, message: str) -> None:
    body: dict[str, Any] = {
        "code": ErrorCode.UNAUTHORIZED.value,
        "message": f"{message}: TCP requests need 'Authorization: Bearer <token>' (service.token_file)",
        "field": "Authorization",
    }
    payload = json.dumps(body).encode()
    await send(
        {
            "type": "http.response.start",
            "status": 401,
            "headers": [
                (b"content-type", b"application/json"),
                (b"content-length", str(len(payload)).encode()),
                (b"www-authenticate", b'Bearer realm="millctl"'),
            ],
        }
    )
    await send({"type": "http.response.body", "body": payload})


__all__ = ["MIN_TOKEN_CHARS", "TokenGuard", "read_token"]
