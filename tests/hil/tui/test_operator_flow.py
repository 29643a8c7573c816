"""The operator's path through the TUI against a real service with the simulated node.

arm → set speeds → an over-limit value refused in the dialog with the
interlock's reason and nothing sent → a valid set → quitting while running
asks first → a vibration stall injected from the drill dialog (f) trips → the banner shows the first
cause and what to do → reset; and E-stop from inside a dialog.
"""

from __future__ import annotations

import contextlib
from typing import Any

import pytest
from textual.widgets import Input, Static

from millctl.api import StatusOut
from millctl.tui import MillApp
from millctl.tui.drill import FaultDrillModal
from millctl.tui.modals import ConfirmModal, SetpointsModal
from millctl.tui.recipes import RecipePicker
from tests.support.pace import Deadline
from tests.support.tui import Service, until

SIZE = (120, 40)


def text_of(app: MillApp, selector: str) -> str:
    """The plain text a Static shows."""
    return str(app.query_one(selector, Static).content)


def speed_requests(service: Service) -> list[dict[str, Any]]:
    """Every speed request that reached the controller, accepted (``command``) or refused (``refusal``)."""
    with service.client() as client:
        events = client.events(after=0, limit=2000).events
    return [e.model_dump() for e in events if e.kind in ("command", "refusal") and "rotary_rpm" in e.data]


def status_of(service: Service) -> StatusOut:
    """The service's status, read directly."""
    with service.client() as client:
        return client.status()


def at_rest(status: StatusOut | None) -> bool:
    """Both drives commanded to and measured at standstill, no ramp left."""
    speeds = ("setpoint_rotary_rpm", "setpoint_vibration_rpm", "measured_rotary_rpm", "measured_vibration_rpm")
    return status is not None and all(getattr(status, key) == 0.0 for key in speeds) and status.ramp_remaining_s == 0.0


async def fill(app: MillApp, rot: str, vib: str) -> SetpointsModal:
    """Type into the open setpoint dialog."""
    modal = app.screen
    assert isinstance(modal, SetpointsModal)
    modal.query_one("#vib", Input).value = vib
    modal.query_one("#rot", Input).value = rot
    return modal


async def test_arm_set_refuse_trip_banner_and_reset(fault_service: Service) -> None:
    app = MillApp(str(fault_service.socket))
    async with app.run_test(size=SIZE, notifications=True) as pilot:
        await until(pilot, lambda: app.online and app.state == "DISABLED", "the first status")
        await pilot.press("a")
        await until(pilot, lambda: app.state == "ARMED", "ARMED")
        with fault_service.client() as client:
            assert "tui" in str(client.control_state().holder)

        # an over-limit point: refused in the dialog with the interlock's reason; nothing sent
        await pilot.press("s")
        await until(pilot, lambda: isinstance(app.screen, SetpointsModal), "the setpoint dialog")
        modal = await fill(app, "250", "800")
        await until(pilot, lambda: "190.0 rpm" in str(modal.query_one("#limit", Static).content), "the live limit")
        await pilot.press("enter")
        await until(pilot, lambda: "refused" in str(modal.query_one("#verdict", Static).content), "the refusal")
        verdict = str(modal.query_one("#verdict", Static).content)
        assert "ω_r = 250.0 rpm exceeds the limit 190.0 rpm at ω_v = 800.0 rpm" in verdict
        assert app.screen is modal
        assert speed_requests(fault_service) == []
        assert status_of(fault_service).target_rotary_rpm == 0.0

        # a point inside is sent
        await fill(app, "20", "300")
        await pilot.press("enter")
        await until(pilot, lambda: not isinstance(app.screen, SetpointsModal), "the dialog to close")
        await until(pilot, lambda: (app.status and app.status.target_vibration_rpm) == 300.0, "the new target")
        await until(pilot, lambda: ((app.status and app.status.measured_vibration_rpm) or 0.0) > 250.0,
                    "ω_v near 300 rpm")

        # quitting while the mill runs asks first; "no" keeps the TUI
        await pilot.press("q")
        await until(pilot, lambda: isinstance(app.screen, ConfirmModal), "the quit question")
        await pilot.press("n")
        await until(pilot, lambda: not isinstance(app.screen, ConfirmModal), "the question to close")
        assert app.is_running

        # the instructor's drill (serve --fault-injection): f opens the faults, Enter injects the highlighted
        # first one, a vibration stall; it trips, and the banner shows the first cause and the way out
        await until(pilot, lambda: app.drills_allowed, "the service's fault injection to be known")
        await pilot.press("f")
        await until(pilot, lambda: isinstance(app.screen, FaultDrillModal), "the fault drill dialog")
        await pilot.pause(0.2)
        await pilot.press("enter")
        await until(pilot, lambda: app.state == "TRIPPED", "the trip", timeout_s=30.0)
        banner = app.query_one("#trip", Static)
        assert banner.has_class("shown")
        cause = status_of(fault_service).trip_cause
        assert cause and cause in text_of(app, "#trip")
        assert "STALL" in text_of(app, "#trip")
        assert "press r to reset" in text_of(app, "#trip")

        # the recovery procedure: the controlled stop finishes, the cause is removed, standstill, reset
        await until(pilot, lambda: at_rest(app.status), "the end of the controlled stop", timeout_s=30.0)
        await pilot.press("f")  # x clears every injected fault: the vibration rotor is free again
        await until(pilot, lambda: isinstance(app.screen, FaultDrillModal), "the fault drill dialog")
        await pilot.press("x")
        await until(pilot, lambda: not isinstance(app.screen, FaultDrillModal), "the dialog to close")
        with fault_service.client() as client:
            assert [e.data["fault"] for e in client.events(limit=2000).events if e.kind == "drill"] == [
                "VIB_STALL", "CLEAR"]
        deadline = Deadline(30.0)  # waits for processes: stretches with load
        while app.state != "DISABLED" and not deadline.expired():
            # as an operator would: reset at standstill, and again if it was refused (the freed rotor can
            # read a rpm or two for a moment after the clear: "reset refused: drives not at standstill")
            await until(pilot, lambda: at_rest(status_of(fault_service)), "standstill after the clear", timeout_s=30.0)
            await pilot.press("r")
            with contextlib.suppress(pytest.fail.Exception):
                await until(pilot, lambda: app.state == "DISABLED", "DISABLED", timeout_s=3.0)
        assert app.state == "DISABLED"
        assert not app.query_one("#trip", Static).has_class("shown")
        assert app.is_running


async def test_estop_works_inside_a_dialog(fault_service: Service) -> None:
    app = MillApp(str(fault_service.socket))
    async with app.run_test(size=SIZE, notifications=True) as pilot:
        await until(pilot, lambda: app.online and app.state == "DISABLED", "the first status")
        await pilot.press("n")
        await until(pilot, lambda: isinstance(app.screen, RecipePicker), "the recipe list")
        await pilot.press("ctrl+x")
        await until(pilot, lambda: app.state == "TRIPPED", "the E-stop trip")
        assert "E-stop" in status_of(fault_service).trip_cause
        assert "first cause" in text_of(app, "#trip")


async def test_control_held_by_another_client(fault_service: Service) -> None:
    app = MillApp(str(fault_service.socket))
    with fault_service.client(name="bench") as other:
        other.take_control()
        async with app.run_test(size=SIZE, notifications=True) as pilot:
            await until(pilot, lambda: "api:bench" in text_of(app, "#state"), "the holder on screen")
            await pilot.press("a")  # refused: someone else holds control (textual has no public notification list)
            await until(pilot, lambda: any("holds control" in n.message for n in app._notifications),
                        "the refusal naming the holder")
            assert not app.link.holds_control
            assert status_of(fault_service).state == "DISABLED"

            other.release_control()
            await pilot.press("a")
            await until(pilot, lambda: app.state == "ARMED", "ARMED once control is free")
            await until(pilot, lambda: "you (this terminal)" in text_of(app, "#state"), "us as the holder")
