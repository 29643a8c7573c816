"""``furnace = "millbus"`` beside CiA 402 drives: its channel ``[drives.furnace_bus]``; bad values name the field."""

from __future__ import annotations

from pathlib import Path

import pytest

from millctl.config import load_config
from millctl.config.models import FurnaceBackend
from millctl.errors import ConfigError

WITH_FURNACE = Path("config/mill-cia402-furnace.toml")
COLD = Path("config/mill-cia402.toml")
FURNACE_BUS = '''[drives.furnace_bus]            # the furnace node's own channel (millbus frames), never [bus]
interface = "virtual"
channel = "millbus-furnace"     # e.g. "can1" on socketcan
bitrate_bit_s = 500000
'''


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "mill.toml"
    path.write_text(text)
    return path


def _error(path: Path) -> str:
    with pytest.raises(ConfigError) as caught:
        load_config(path)
    return str(caught.value)


def test_the_shipped_furnace_config_names_a_second_channel() -> None:
    config = load_config(WITH_FURNACE).config
    assert config.drives.furnace is FurnaceBackend.MILLBUS
    assert config.drives.furnace_bus is not None
    assert (config.drives.furnace_bus.interface, config.drives.furnace_bus.channel) == ("virtual", "millbus-furnace")
    assert config.bus.channel != config.drives.furnace_bus.channel


def test_a_millbus_furnace_without_its_channel_is_refused(tmp_path: Path) -> None:
    text = WITH_FURNACE.read_text()
    assert FURNACE_BUS in text
    message = _error(_write(tmp_path, text.replace(FURNACE_BUS, "")))
    assert 'drives.furnace = "millbus" beside CiA 402 drives needs [drives.furnace_bus]' in message
    assert "0x000 is CANopen's NMT" in message and "docs/deployment.md#a-furnace-beside-the-drives" in message


def test_the_drives_own_bus_as_the_furnace_channel_is_refused(tmp_path: Path) -> None:
    text = WITH_FURNACE.read_text().replace('channel = "millbus-furnace"', 'channel = "millbus"')
    message = _error(_write(tmp_path, text))
    assert "drives.furnace_bus.channel = 'millbus' on virtual is the drives' own bus ([bus])" in message
    assert "second CAN channel" in message


def test_the_same_group_on_another_port_is_a_second_channel(tmp_path: Path) -> None:
    text = WITH_FURNACE.read_text()
    text = text.replace('interface = "virtual"           # embedded default: service, drives and furnace node in '
                        'one process\nchannel = "millbus"',
                        'interface = "udp_multicast"\nchannel = "239.74.163.2"\noptions = { port = 43113 }')
    text = text.replace('interface = "virtual"\nchannel = "millbus-furnace"',
                        'interface = "udp_multicast"\nchannel = "239.74.163.2"\noptions = { port = 43114 }')
    config = load_config(_write(tmp_path, text)).config
    assert config.drives.furnace_bus is not None and config.drives.furnace_bus.options == {"port": 43114}
    same = text.replace("port = 43114", "port = 43113")
    assert "is the drives' own bus" in _error(_write(tmp_path, same))


def test_a_furnace_channel_for_cold_milling_is_refused(tmp_path: Path) -> None:
    text = WITH_FURNACE.read_text().replace('furnace = "millbus" ', 'furnace = "none"    ')
    message = _error(_write(tmp_path, text))
    assert "[drives.furnace_bus] is given but the furnace has no channel of its own here" in message


def test_a_furnace_channel_on_the_millbus_backend_is_refused(tmp_path: Path) -> None:
    text = Path("config/mill.toml").read_text() + "\n" + FURNACE_BUS
    message = _error(_write(tmp_path, text))
    assert "[drives.furnace_bus] is given" in message
    assert 'backend = "millbus" the furnace is the millbus node' in message


def test_a_bad_furnace_channel_is_refused_naming_its_field(tmp_path: Path) -> None:
    text = WITH_FURNACE.read_text().replace('channel = "millbus-furnace"', 'channel = ""')
    assert "drives.furnace_bus.channel" in _error(_write(tmp_path, text))


def test_cold_milling_is_unchanged() -> None:
    config = load_config(COLD).config
    assert config.drives.furnace is FurnaceBackend.NONE and config.drives.furnace_bus is None


def test_serve_sim_moves_the_furnace_channel_to_a_private_virtual_one_too() -> None:
    from millctl.cli.service_cmd import simulated

    loaded = simulated(load_config(WITH_FURNACE))
    bus, furnace = loaded.config.bus, loaded.config.drives.furnace_bus
    assert furnace is not None and furnace.interface == "virtual" and bus.interface == "virtual"
    assert furnace.channel.startswith("millctl-sim-furnace-") and furnace.channel != bus.channel


def test_the_furnace_only_node_needs_a_furnace_channel(caplog: pytest.LogCaptureFixture) -> None:
    from firmware_sim.__main__ import main

    assert main(["--config", "config/mill.toml", "--furnace-only"]) == 1
    assert "--furnace-only needs [drives.furnace_bus]" in caplog.text


@pytest.mark.parametrize("config", ["config/mill.toml", str(WITH_FURNACE)])
def test_the_heated_demo_passes_the_recipe_check_on_the_mills_with_a_furnace(
    config: str, capsys: pytest.CaptureFixture[str]
) -> None:
    from millctl.cli import main

    code = main(["--config", config, "recipe", "check", "config/recipes/heated/demo-heated.toml"])
    assert code == 0, capsys.readouterr().err
