"""Fixtures shared by every tier."""

from __future__ import annotations

from pathlib import Path

import pytest

from millctl.config import MillConfig, load_config

REPO = Path(__file__).resolve().parents[1]
CONFIG_FILE = REPO / "config" / "mill.toml"


@pytest.fixture(scope="session")
def config() -> MillConfig:
    """The repository's default configuration (parameter Set A)."""
    return load_config(CONFIG_FILE).config
