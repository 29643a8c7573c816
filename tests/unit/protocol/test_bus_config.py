"""The [bus] section: every lab interface accepted, what can be checked is checked, errors name field and bound."""

from __future__ import annotations

import inspect
from pathlib import Path
from typing import Any

import can
import pytest
from pydantic import ValidationError

from millctl.config import load_config
from millctl.config.bus import INTERFACE_BITRATES_BIT_S, KNOWN_OPTIONS, Bus, channel_problem, known_interfaces
from millctl.errors import ConfigError
from millctl.protocol.factory import bus_kwargs
from tests.conftest import CONFIG_FILE

LAB_BUSES: list[dict[str, Any]] = [
    {"interface": "socketcan", "channel": "can0", "bitrate_bit_s": 500_000},
    {"interface": "socketcan", "channel": "can0", "fd": True, "data_bitrate_bit_s": 2_000_000},
    {"interface": "pcan", "channel": "PCAN_USBBUS1", "bitrate_bit_s": 250_000},
    {"interface": "kvaser", "channel": 0, "bitrate_bit_s": 500_000},
    {"interface": "kvaser", "channel": "1", "fd": True, "data_bitrate_bit_s": 2_000_000},
    {"interface": "vector", "channel": "0, 1", "options": {"app_name": "millctl"}},
    {"interface": "slcan", "channel": "/dev/ttyACM0", "bitrate_bit_s": 500_000, "options": {"tty_baudrate": 115200}},
    {"interface": "slcan", "channel": "COM4@115200", "bitrate_bit_s": 83_300},
    {"interface": "slcan", "channel": "socket://192.0.2.7:3333", "bitrate_bit_s": 125_000},
    {"interface": "gs_usb", "channel": 0, "bitrate_bit_s": 1_000_000},
    {"interface": "virtual", "channel": "millbus"},
    {"interface": "udp_multicast", "channel": "239.74.163.2", "options": {"hop_limit": 0}},
    {"interface": "millctl_udp_multicast", "channel": "239.74.163.2", "options": {"hop_limit": 0}},
]


@pytest.mark.parametrize("fields", LAB_BUSES, ids=lambda f: f"{f['interface']}:{f['channel']}")
def test_every_lab_interface_is_accepted(fields: dict[str, Any]) -> None:
    bus = Bus(**fields)
    kwargs = bus_kwargs(bus)
    assert kwargs["receive_own_messages"] is False
    assert "ignore_rx_error_frames" not in kwargs or kwargs["ignore_rx_error_frames"] is False


@pytest.mark.parametrize(
    ("fields", "pattern"),
    [
        ({"interface": "pcann"}, r"not a python-can interface \(did you mean 'pcan'\?\).*deployment\.md"),
        ({"interface": "socketcan", "channel": "can 0"}, r"bus\.channel = 'can 0' is not a Linux network device"),
        ({"interface": "socketcan", "channel": "canbus-of-the-mill0"}, r"≤ 15 characters"),
        ({"interface": "pcan", "channel": "USB1"}, r"bus\.channel = 'USB1' is not a PCAN channel name"),
        ({"interface": "pcan", "channel": "PCAN_USBBUS1", "bitrate_bit_s": 300_000},
         r"bus\.bitrate_bit_s = 300000 is not a bitrate of interface pcan: one of 5000, .*pcan\.html"),
        ({"interface": "slcan", "channel": "/dev/ttyACM0", "bitrate_bit_s": 800_000},
         r"bus\.bitrate_bit_s = 800000 is not a bitrate of interface slcan"),
        ({"interface": "slcan", "channel": "ttyACM0"}, r"bus\.channel = 'ttyACM0' is not a serial port"),
        ({"interface": "kvaser", "channel": "can0"}, r"bus\.channel = 'can0' is not a channel number"),
        ({"interface": "vector", "channel": "CAN1"}, r"bus\.channel = 'CAN1' is not a channel number"),
        ({"interface": "socketcan", "channel": "can0", "bitrate_bit_s": 2_000_000}, r"less than or equal to 1000000"),
        ({"interface": "kvaser", "channel": 0, "fd": True}, r"bus\.fd = true on interface kvaser needs "
         r"bus\.data_bitrate_bit_s"),
        ({"interface": "pcan", "channel": "PCAN_USBBUS1", "fd": True}, r"bus\.fd = true is not supported here"),
        ({"interface": "socketcan", "channel": "can0", "data_bitrate_bit_s": 2_000_000}, r"needs bus\.fd = true"),
        ({"interface": "socketcan", "channel": "can0", "fd": True, "data_bitrate_bit_s": 250_000},
         r"bus\.data_bitrate_bit_s = 250000 must be ≥ bus\.bitrate_bit_s = 500000"),
        ({"interface": "socketcan", "channel": "can0", "options": {"ignore_rx_error_frames": True}},
         r"bus\.options\.ignore_rx_error_frames = True is not allowed: error frames"),
        ({"interface": "socketcan", "channel": "can0", "options": {"bitrate": 250_000}},
         r"bus\.options\.bitrate = 250000 is not allowed: set bus\.bitrate_bit_s instead"),
        ({"interface": "pcan", "channel": "PCAN_USBBUS1", "options": {"state": "PASSIVE"}},
         r"cannot send the controller's heartbeat"),
        ({"interface": "slcan", "channel": "/dev/ttyACM0", "options": {"tty_buadrate": 115200}},
         r"bus\.options\.tty_buadrate = 115200 is not an option of interface slcan \(did you mean 'tty_baudrate'"),
        ({"interface": "slcan", "channel": "/dev/ttyACM0", "options": {"tty_baudrate": "fast"}},
         r"bus\.options\.tty_baudrate = 'fast' must be a whole number of baud"),
        ({"interface": "vector", "channel": 0, "options": {"app_name": 3}}, r"bus\.options\.app_name = 3 must be text"),
        ({"interface": "socketcan", "channel": ""}, r"channel must not be empty"),
    ],
)
def test_bad_bus_settings_name_the_field_value_and_bound(fields: dict[str, Any], pattern: str) -> None:
    with pytest.raises(ValidationError, match=pattern):
        Bus(**fields)


def test_a_bad_bus_in_the_file_names_the_file_and_the_field(tmp_path: Path) -> None:
    text = CONFIG_FILE.read_text().replace('interface = "virtual"', 'interface = "pcan"', 1)
    text = text.replace('channel = "millbus"', 'channel = "PCAN_USBBUS1"\noptions = { listen_only = true }', 1)
    path = tmp_path / "mill.toml"
    path.write_text(text)
    with pytest.raises(ConfigError) as caught:
        load_config(path)
    assert f"{path}: bus: bus.options.listen_only = True is not allowed" in str(caught.value)


def test_tables_match_python_cans_own() -> None:
    from can.interfaces.pcan.basic import PCAN_BITRATES, PCAN_CHANNEL_NAMES
    from can.interfaces.slcan import slcanBus

    assert INTERFACE_BITRATES_BIT_S["pcan"] == frozenset(PCAN_BITRATES)
    assert INTERFACE_BITRATES_BIT_S["slcan"] == frozenset(slcanBus._BITRATES)
    accepted = {name for name in PCAN_CHANNEL_NAMES if channel_problem("pcan", name) is None}
    assert accepted == set(PCAN_CHANNEL_NAMES) - {"PCAN_NONEBUS"}
    assert known_interfaces() == frozenset(can.interfaces.VALID_INTERFACES)


@pytest.mark.parametrize("interface", ["socketcan", "vector", "slcan", "virtual", "udp_multicast"])
def test_known_options_are_named_parameters_of_the_driver(interface: str) -> None:
    import importlib

    module, name = can.interfaces.BACKENDS[interface]
    parameters = inspect.signature(getattr(importlib.import_module(module), name).__init__).parameters
    assert KNOWN_OPTIONS[interface] <= set(parameters)


def test_kwargs_give_each_driver_its_channel_type_and_bitrate() -> None:
    assert bus_kwargs(Bus(interface="kvaser", channel="2"))["channel"] == 2
    assert bus_kwargs(Bus(interface="vector", channel="0, 1"))["channel"] == [0, 1]
    pcan = bus_kwargs(Bus(interface="pcan", channel="PCAN_USBBUS2", bitrate_bit_s=125_000))
    assert pcan["bitrate"] == 125_000 and pcan["channel"] == "PCAN_USBBUS2"
    socketcan = bus_kwargs(Bus(interface="socketcan", channel="can0", bitrate_bit_s=250_000))
    assert "bitrate" not in socketcan  # python-can's socketcan sets no bitrate: the link does (bus check compares)
    assert socketcan["ignore_rx_error_frames"] is False
    kvaser_fd = bus_kwargs(Bus(interface="kvaser", channel=0, fd=True, data_bitrate_bit_s=2_000_000))
    assert kvaser_fd["fd"] is True and kvaser_fd["data_bitrate"] == 2_000_000
