"""The scenarios' fixture: the in-process rig (``rig.py``) on the default config, closed after each test."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from millctl.config import MillConfig
from tests.unit.scenarios.rig import Rig


@pytest.fixture
def rig(config: MillConfig) -> Iterator[Rig]:
    """Node + controller + a bystander on one virtual bus (a module may override it, e.g. without fault injection)."""
    r = Rig(config)
    yield r
    r.close()
