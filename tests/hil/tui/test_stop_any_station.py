"""The TUI's stop key stops a mill whose control another client holds: a stop needs no lease (SAFETY 24).

On the old code the TUI took control first and was refused ("control is held by …"); the mill ran on.
"""

from __future__ import annotations

from pathlib import Path

from millctl.tui import MillApp
from tests.support.service import start_service, wait_for, write_config
from tests.support.tui import until


async def test_the_tui_stops_a_mill_another_client_controls(service_dir: Path) -> None:
    write_config(service_dir)
    service = start_service(service_dir)
    try:
        with service.client("holder") as holder:
            holder.take_control()
            holder.arm()
            wait_for(lambda: holder.status().state == "ARMED", 30.0, "ARMED")
            holder.set_speeds(30.0, 150.0)
            wait_for(lambda: holder.status().state == "RUNNING", 30.0, "RUNNING")
            app = MillApp(str(service.socket))
            async with app.run_test(size=(120, 40)) as pilot:
                await until(pilot, lambda: app.online and app.state == "RUNNING", "the TUI to see RUNNING")
                await pilot.press("o")
                await until(pilot, lambda: app.state in ("STOPPING", "ARMED"), "the TUI's stop", timeout_s=20.0)
            control = holder.control_state()
            assert (control.holder or "").startswith("api:holder@")  # the TUI neither needed nor took it
            events = holder.events(limit=2000).events
            stops = [e.source for e in events if e.kind == "command" and e.message.startswith("STOP")]
            assert stops and stops[0].startswith("api:tui"), stops
    finally:
        service.stop()
