"""``millctl status`` and the TUI show the drives backend and each CiA 402 drive's state; millbus shows none."""

from __future__ import annotations

from rich.console import Console

from millctl.api import StatusOut
from millctl.api.models import DriveOut
from millctl.cli.client_cmd import render_status
from millctl.tui.panels import StatePanel
from tests.unit.tui.frozen import status_at


def _cia402(status: StatusOut) -> StatusOut:
    return status.model_copy(update={"drives_backend": "cia402", "drives": [
        DriveOut(name="rotary", state="OPERATION ENABLED", node_id=2, detail="NMT OPERATIONAL"),
        DriveOut(name="vibration", state="QUICK STOP ACTIVE", node_id=3, detail="EMCY 0x8110 (error register 0x11)"),
    ]})


def _with_furnace(status: StatusOut) -> StatusOut:
    """CiA 402 drives with the millbus furnace node on a channel of its own (config/mill-cia402-furnace.toml)."""
    furnace = DriveOut(name="furnace", state="ARMED", detail="millbus furnace node on virtual:furnace; 612.0 °C")
    return status.model_copy(update={"drives": [*_cia402(status).drives, furnace], "drives_backend": "cia402"})


def _shown(status: StatusOut) -> str:
    console = Console(width=240, record=True)
    console.print(render_status(status))
    return console.export_text()


def test_status_shows_each_cia402_drive_with_its_node_and_state() -> None:
    shown = _shown(_cia402(status_at(3)))
    assert "cia402: rotary (node 2) OPERATION ENABLED — NMT OPERATIONAL" in shown
    assert "vibration (node 3) QUICK STOP ACTIVE — EMCY 0x8110" in shown


def test_status_on_millbus_has_no_drives_row() -> None:
    assert "drives " not in _shown(status_at(3))


def _panel(status: StatusOut) -> str:
    """What the TUI's state panel shows for ``status``."""
    seen: list[str] = []

    class Recording(StatePanel):
        def update(self, content: object = "", *, layout: bool = True) -> None:
            seen.append(str(content))

    Recording().show(status, None, False, None)
    return seen[-1]


def test_the_tui_state_panel_lists_each_cia402_drive() -> None:
    panel = _panel(_cia402(status_at(3)))
    assert "rotary OPERATION ENABLED  (cia402 node 2)" in panel
    assert "vibration QUICK STOP ACTIVE  (cia402 node 3)" in panel


def test_a_furnace_node_beside_the_drives_is_named_by_its_channel_not_a_node_id() -> None:
    shown = _shown(_with_furnace(status_at(3)))
    assert "furnace ARMED — millbus furnace node on virtual:furnace" in shown
    assert "None" not in shown
    panel = _panel(_with_furnace(status_at(3)))
    assert "furnace ARMED  (millbus furnace node on virtual:furnace)" in panel
    assert "None" not in panel
