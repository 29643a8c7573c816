"""The request headers every route may read: who the client is, and its control lease."""

from __future__ import annotations

from typing import Annotated

from fastapi import Header

ClientName = Annotated[
    str | None,
    Header(pattern=r"^[A-Za-z0-9_.@:+-]{1,64}$", description="the client's name, recorded as the source 'api:<name>'"),
]
LeaseId = Annotated[
    str | None,
    Header(pattern=r"^[A-Za-z0-9_-]{1,64}$", description="the lease id from POST /v1/control/take"),
]


def client_source(name: str | None) -> str:
    """The source recorded for a client: ``api:<name>``."""
    return f"api:{name or 'anonymous'}"


__all__ = ["ClientName", "LeaseId", "client_source"]
