"""The CiA 402 rig, closed after each test."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from tests.unit.drives.rig402 import Rig402


@pytest.fixture
def rig() -> Iterator[Rig402]:
    made = Rig402()
    yield made
    made.close()
