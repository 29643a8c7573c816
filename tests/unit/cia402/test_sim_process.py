"""``python -m firmware_sim`` and the embedded service pick the simulated CiA 402 drives from ``[drives] backend``."""

from __future__ import annotations

from pathlib import Path

import can
import pytest

from firmware_sim.__main__ import main
from firmware_sim.cia402 import Cia402Mill
from firmware_sim.cia402.process import parse_lie
from firmware_sim.embedded import simulated_mill
from firmware_sim.node import Node
from millctl.clock import ManualClock
from millctl.config import MillConfig
from millctl.errors import ConfigError
from tests.unit.cia402.wire import cia402_config


def test_the_embedded_mill_follows_the_backend(config: MillConfig) -> None:
    bus = can.Bus(interface="virtual", channel="embedded-backend")
    try:
        cia = simulated_mill(cia402_config(config), bus, ManualClock(), fault_injection=False)
        assert isinstance(cia, Cia402Mill) and sorted(d.cia.node_id for d in cia.drives.values()) == [2, 3]
        node = simulated_mill(config, bus, ManualClock(), fault_injection=False)
        assert isinstance(node, Node)
        node.close()
    finally:
        bus.shutdown()


def test_lie_readback_specs_are_checked() -> None:
    assert parse_lie("rotary:0x607F") == ("rotary", 0x607F)
    assert parse_lie("vibration:24704") == ("vibration", 0x6080)
    for bad, says in (("rotor:0x607F", "MOTOR one of rotary, vibration"), ("rotary:limit", "not an object index"),
                      ("rotary:0x20", "outside 0x1000")):
        with pytest.raises(ValueError, match=says):
            parse_lie(bad)


def test_lie_readback_on_a_millbus_config_is_invalid_input(caplog: pytest.LogCaptureFixture) -> None:
    assert main(["--config", "config/mill.toml", "--lie-readback", "rotary:0x607F"]) == 1
    assert "needs CiA 402 drives" in caplog.text


def test_an_unreadable_eds_is_a_config_error_naming_the_drive(config: MillConfig, tmp_path: Path) -> None:
    eds = tmp_path / "broken.eds"
    eds.write_text("this is no EDS\n", encoding="utf-8")
    # The config's validator reads the EDS too; this is the file broken after the config was read.
    cia = cia402_config(config)
    vibration = cia.drives.vibration
    assert vibration.cia402 is not None
    broken = vibration.model_copy(update={"cia402": vibration.cia402.model_copy(update={"eds": str(eds)})})
    cia = cia.model_copy(update={"drives": cia.drives.model_copy(update={"vibration": broken})})
    bus = can.Bus(interface="virtual", channel="broken-eds")
    try:
        with pytest.raises(ConfigError, match=r"drives\.vibration\.cia402\.eds: not a readable EDS") as caught:
            Cia402Mill(cia, bus, ManualClock())
        assert str(eds) in str(caught.value)
    finally:
        bus.shutdown()
