"""The TUI shows the host's events (SAFETY 27): a late loop and a trip named host starvation notify the operator."""

from __future__ import annotations

from millctl.api import EventOut
from millctl.tui import MillApp
from tests.unit.tui import frozen

NAMED = (
    "trip caused by host starvation: the control loop ran 612 ms late; the node's watchdog allows 250 ms: the host "
    "is overloaded, see docs/deployment.md#real-time-priority"
)


async def test_a_host_starvation_trip_is_a_warning_notification_and_a_log_line() -> None:
    app = MillApp(frozen.SOCKET, live=False)
    event = EventOut.model_validate({"seq": 9, "t": frozen.T0_UNIX, "time_s": None, "kind": "host",
                                     "source": "service", "message": NAMED, "data": {"host_starvation": True}})
    async with app.run_test(size=(120, 40)) as pilot:
        app.apply_event(event, live=True)
        await pilot.pause()
        shown = list(app._notifications)
        assert [(n.message, n.severity, n.title) for n in shown] == [(NAMED, "warning", "host")]
