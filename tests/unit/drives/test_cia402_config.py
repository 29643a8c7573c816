"""[drives] for CiA 402: every bad value is refused naming the file, the field, the value and the bound."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from millctl.config import load_config
from millctl.config.models import DriveBackend
from millctl.errors import ConfigError

SHIPPED = Path("config/mill-cia402.toml")


def _variant(tmp_path: Path, old: str, new: str, count: int = 1) -> Path:
    text = SHIPPED.read_text()
    assert old in text
    path = tmp_path / "mill.toml"
    path.write_text(text.replace(old, new, count))
    return path


def _error(path: Path) -> str:
    with pytest.raises(ConfigError) as caught:
        load_config(path)
    return str(caught.value)


def test_the_shipped_cia402_config_loads_with_the_generic_eds() -> None:
    config = load_config(SHIPPED).config
    assert config.drives.backend is DriveBackend.CIA402
    assert config.drives.rotary.cia402 is not None and config.drives.vibration.cia402 is not None
    assert Path(config.drives.rotary.cia402.eds).name == "cia402-drive.eds"
    assert Path(config.drives.rotary.cia402.eds).is_file()


def test_the_millbus_config_is_unchanged_by_the_new_keys() -> None:
    assert load_config("config/mill.toml").config.drives.backend is DriveBackend.MILLBUS


def test_an_unknown_eds_file_is_refused_naming_it(tmp_path: Path) -> None:
    path = _variant(tmp_path, 'eds = ""', 'eds = "acme-servo.eds"')
    message = _error(path)
    assert str(path) in message and "drives.rotary.cia402.eds" in message
    assert str(tmp_path / "acme-servo.eds") in message and "not found" in message


def test_a_file_that_is_not_an_eds_is_refused_naming_it(tmp_path: Path) -> None:
    (tmp_path / "notes.eds").write_text("these are my notes\n")
    message = _error(_variant(tmp_path, 'eds = ""', 'eds = "notes.eds"'))
    assert "drives.rotary.cia402.eds" in message and "is not a readable EDS" in message
    assert str(tmp_path / "notes.eds") in message


@pytest.mark.parametrize("node_id", [0, 128, -1])
def test_a_node_id_outside_1_to_127_is_refused_with_its_bound(tmp_path: Path, node_id: int) -> None:
    message = _error(_variant(tmp_path, "node_id = 3", f"node_id = {node_id}"))
    assert f"drives.vibration.cia402.node_id = {node_id}" in message
    assert "1" in message and "127" in message


def test_two_drives_on_one_id_are_refused(tmp_path: Path) -> None:
    message = _error(_variant(tmp_path, "node_id = 3", "node_id = 2"))
    assert "drives.vibration.cia402.node_id = 2 is already drives.rotary.cia402.node_id" in message


def test_a_drive_on_the_controllers_id_is_refused(tmp_path: Path) -> None:
    message = _error(_variant(tmp_path, "node_id = 2 ", "node_id = 1 "))
    assert "drives.rotary.cia402.node_id = 1 is already drives.controller_node_id" in message


@pytest.mark.parametrize("field", ["units_per_rpm", "gear_ratio"])
@pytest.mark.parametrize("value", ["0.0", "nan", "inf", "-2.0"])
def test_a_scaling_of_zero_nan_inf_or_negative_is_refused(tmp_path: Path, field: str, value: str) -> None:
    message = _error(_variant(tmp_path, f"{field} = 1.0", f"{field} = {value}"))
    assert f"drives.rotary.cia402.{field} = " in message
    shown = message.split(f"drives.rotary.cia402.{field} = ")[1]
    assert "must be a finite number > 0 (bound: 0 < value ≤ 1e+09)" in shown


def test_a_cia402_backend_without_its_drives_is_refused(tmp_path: Path) -> None:
    text = SHIPPED.read_text()
    start = text.index("[drives.vibration.cia402]")
    end = text.index("[furnace]")
    path = tmp_path / "mill.toml"
    path.write_text(text[:start] + text[end:])
    assert 'backend = "cia402" needs [drives.vibration.cia402]' in _error(path)


def test_the_wire_value_is_mill_rpm_times_gear_ratio_times_units(tmp_path: Path) -> None:
    path = _variant(tmp_path, "gear_ratio = 1.0", "gear_ratio = 10.0")
    cia = load_config(path).config.drives.rotary.cia402
    assert cia is not None
    assert cia.wire_velocity(123.4) == 1234
    assert math.isclose(cia.mill_rpm(1234), 123.4)
