"""The bluesky tier's fixtures: a RunEngine collecting its documents, and a connected Mill (closed at teardown)."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
from bluesky import RunEngine
from bluesky.run_engine import call_in_bluesky_event_loop
from ophyd_async.plan_stubs import ensure_connected

from millctl.bluesky import Mill
from tests.support.service import service

__all__ = ["Engine", "engine", "service"]


@dataclass
class Engine:
    """A RunEngine and every document it emitted, in order."""

    RE: RunEngine
    documents: list[tuple[str, dict[str, Any]]] = field(default_factory=list)
    mills: list[Mill] = field(default_factory=list)

    def connect(self, socket: Path, name: str = "mill", client: str = "bluesky") -> Mill:
        """A Mill connected to the service on ``socket`` (in the RunEngine's loop)."""
        mill = Mill(socket, name=name, client_name=client, poll_s=0.2)
        self.RE(ensure_connected(mill))
        self.mills.append(mill)
        return mill

    def of(self, name: str, stream: str | None = None) -> list[dict[str, Any]]:
        """The documents named ``name`` (events: of ``stream`` when given)."""
        found = [doc for kind, doc in self.documents if kind == name]
        if stream is None or name != "event":
            return found
        descriptors = {d["uid"] for d in self.of("descriptor") if d["name"] == stream}
        return [e for e in found if e["descriptor"] in descriptors]


@pytest.fixture
def engine() -> Iterator[Engine]:
    """A fresh RunEngine recording its documents; its mills closed (lease given back) afterwards."""
    RE = RunEngine(call_returns_result=True)
    recorded = Engine(RE)

    def collect(name: str, doc: dict[str, Any]) -> None:
        recorded.documents.append((name, doc))

    RE.subscribe(collect)
    try:
        yield recorded
    finally:
        for mill in recorded.mills:
            call_in_bluesky_event_loop(mill.close())
