"""Fixtures shared by the controller's unit tests."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from millctl.config import MillConfig
from tests.unit.controller.bench import ScriptedNode


@pytest.fixture
def bench(config: MillConfig) -> Iterator[ScriptedNode]:
    """The controller on a scripted node (tests/unit/controller/bench.py), closed after the test."""
    b = ScriptedNode(config)
    yield b
    b.close()
