"""Fixtures of the physics tests: the Set A model in both variants."""

from __future__ import annotations

import dataclasses

import pytest

from millctl.config import MillConfig, ModelVariant
from millctl.physics.model import MillModel


@pytest.fixture(scope="session")
def set_a(config: MillConfig) -> MillModel:
    """Set A as configured (the paper variant)."""
    return MillModel.from_config(config)


@pytest.fixture(scope="session")
def set_a_corrected(set_a: MillModel) -> MillModel:
    return dataclasses.replace(set_a, variant=ModelVariant.CORRECTED)


@pytest.fixture(scope="session")
def set_a_paper(set_a: MillModel) -> MillModel:
    return dataclasses.replace(set_a, variant=ModelVariant.PAPER)
