"""The VM's config: its periods scaled by the measured slowdown, valid at any factor (tests/hil/scenario_support.py)."""

from __future__ import annotations

from pathlib import Path

import pytest

from millctl.config import load_config
from millctl.config.loader import packaged_file
from millctl.config.models import Furnace, Timing
from tests.hil.scenario_config import VM_SCALED_KEYS, _scale_keys, upper_bound, vm_scaled


def test_the_upper_bound_is_read_from_the_config_model() -> None:
    assert upper_bound(Furnace, "setpoint_refresh_s") == 60.0
    assert upper_bound(Timing, "watchdog_timeout_s") == 10.0


def test_a_scaled_value_is_held_at_its_upper_bound() -> None:
    assert vm_scaled("watchdog_timeout_s", 0.25, 10.0) == 2.5
    assert vm_scaled("setpoint_refresh_s", 3.0, 26.6) == 60.0  # 79.8 s would break the config's bound


@pytest.mark.parametrize("factor", [1.0, 10.0, 26.6, 100.0])
def test_the_packaged_config_scaled_by_any_factor_loads(factor: float, tmp_path: Path) -> None:
    text = packaged_file("mill.toml").read_text(encoding="utf-8")
    path = tmp_path / "mill.toml"
    path.write_text(_scale_keys(text, factor), encoding="utf-8")
    config = load_config(path).config
    packaged = load_config(packaged_file("mill.toml")).config
    for key, section in VM_SCALED_KEYS.items():
        name = {"Timing": "timing", "Interlock": "interlock", "Furnace": "furnace"}[section.__name__]
        scaled = getattr(getattr(config, name), key)
        assert scaled == pytest.approx(min(getattr(getattr(packaged, name), key) * factor, upper_bound(section, key)))
