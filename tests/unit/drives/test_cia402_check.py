"""``millctl bus check`` on CiA 402 drives: the simulated drives answer; a wrong EDS and a silent drive are named."""

from __future__ import annotations

import threading
import uuid
from collections.abc import Iterator
from pathlib import Path

import can
import pytest

from firmware_sim.cia402 import Cia402Mill
from millctl.clock import MonotonicClock
from millctl.config import load_config
from millctl.config.models import MillConfig
from millctl.drives.cia402.check import check_drives
from tests.support.pace import stretched


@pytest.fixture
def drives_on_a_bus() -> Iterator[tuple[MillConfig, can.BusABC, Cia402Mill]]:
    config = load_config("config/mill-cia402.toml").config
    channel = f"check-{uuid.uuid4().hex}"
    sim_bus, bus = (can.Bus(interface="virtual", channel=channel) for _ in range(2))
    sim = Cia402Mill(config, sim_bus, MonotonicClock())
    stop = threading.Event()

    def run() -> None:
        while not stop.wait(0.005):
            sim.tick()

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    yield config, bus, sim
    stop.set()
    thread.join()
    sim.close()
    sim_bus.shutdown()
    bus.shutdown()


def test_the_simulated_drives_pass_and_show_their_identity_and_limits(
    drives_on_a_bus: tuple[MillConfig, can.BusABC, Cia402Mill],
) -> None:
    config, bus, _ = drives_on_a_bus
    report = check_drives(config, bus, stretched(2.0))
    assert report.ok, report.problems
    rotary = report.drives[0]
    assert rotary.nmt_state in ("PRE-OPERATIONAL", "OPERATIONAL") and rotary.eds_match
    assert rotary.identity["serial"] == 2
    assert "0x607F:00 max profile velocity" in rotary.limits
    assert rotary.limits["0x6080:00 max motor speed"]["millctl_writes"] == 400


def test_an_eds_of_another_drive_is_named_as_not_matching(
    drives_on_a_bus: tuple[MillConfig, can.BusABC, Cia402Mill], tmp_path: Path
) -> None:
    config, bus, _ = drives_on_a_bus
    cia = config.drives.rotary.cia402
    assert cia is not None
    eds = Path(cia.eds).read_text().replace("ProductNumber=0x00000402", "ProductNumber=0x7")
    assert "ProductNumber=0x7" in eds
    (tmp_path / "other.eds").write_text(eds)
    rotary = config.drives.rotary.model_copy(update={"cia402": cia.model_copy(
        update={"eds": str(tmp_path / "other.eds")})})
    config = config.model_copy(update={"drives": config.drives.model_copy(update={"rotary": rotary})})
    report = check_drives(config, bus, stretched(2.0))
    assert not report.ok
    assert any("rotary drive (node 2): the EDS describes vendor" in p and "product 0x00000007" in p
               for p in report.problems)


def test_a_drive_on_another_node_id_is_named_silent(
    drives_on_a_bus: tuple[MillConfig, can.BusABC, Cia402Mill],
) -> None:
    config, bus, _ = drives_on_a_bus
    cia = config.drives.vibration.cia402
    assert cia is not None
    vibration = config.drives.vibration.model_copy(update={"cia402": cia.model_copy(
        update={"node_id": 9})})
    config = config.model_copy(update={"drives": config.drives.model_copy(update={"vibration": vibration})})
    report = check_drives(config, bus, 0.5)
    assert any(p.startswith("vibration drive (node 9): no heartbeat at 0x709 and no SDO answer for the identity")
               for p in report.problems)


def test_millctl_bus_check_prints_each_drive_in_words_and_exits_0(capsys: pytest.CaptureFixture[str]) -> None:
    import argparse

    from millctl.cli.bus_cmd import _check_cia402

    config = load_config("config/mill-cia402.toml").config
    config = config.model_copy(update={"bus": config.bus.model_copy(update={"channel": f"cli-{uuid.uuid4().hex}"})})
    sim_bus = can.Bus(interface="virtual", channel=config.bus.channel)
    sim = Cia402Mill(config, sim_bus, MonotonicClock())
    stop = threading.Event()

    def run() -> None:
        while not stop.wait(0.005):
            sim.tick()

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    try:
        code = _check_cia402(argparse.Namespace(json=False, listen_s=stretched(2.0)), config)
    finally:
        stop.set()
        thread.join()
        sim.close()
        sim_bus.shutdown()
    shown = capsys.readouterr().out
    assert code == 0, shown
    assert "rotary   node 2, NMT PRE-OPERATIONAL, vendor 0x4D494C4C product 0x00000402" in shown
    assert "EDS matches" in shown and "0x607F:00 max profile velocity: holds" in shown
