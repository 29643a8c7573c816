"""The operator's commands: each a textual action, sent by a worker under the control lease.

Refusals come back as notifications with the service's reason (the
interlock's, the state machine's, or who holds control). E-stop needs no
lease and is sent at once; if it cannot be delivered the operator is told to
use the hardware E-stop.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Awaitable, Callable
from pathlib import Path

from pydantic import BaseModel

from millctl.api import CommandOut, ServiceOut, SimFaultName
from millctl.client import AsyncClient
from millctl.tui.drill import DrillRequest, FaultDrillModal
from millctl.tui.envelope import EnvelopeScreen
from millctl.tui.format import MOVING_STATES
from millctl.tui.link import LINK_ERRORS, describe
from millctl.tui.modals import ConfirmModal, SetpointsModal, SetRequest
from millctl.tui.recipes import RecipePicker, recipe_files
from millctl.tui.view import MillView

Call = Callable[[AsyncClient], Awaitable[BaseModel]]

QUIT_RELEASE_S = 2.0
"""At most this long is spent giving control back when quitting (s)."""

READ_ONLY = ("not sent: this browser page is read-only until it takes control (press c); stop (o) and E-stop "
             "(Ctrl+X) need no control")
"""What a web page's command that needs the lease answers before its operator has taken control."""


def recipe_folders(service: ServiceOut | None) -> list[Path]:
    """Where the recipe picker looks: ``config/recipes`` here, and ``recipes`` beside the service's config."""
    folders = [Path("config/recipes")]
    if service is not None:
        folders.append(Path(service.config_path).parent / "recipes")
    return folders


class Commanding(MillView):
    """The main screen's commands."""

    def send(self, what: str, call: Call, *, take: bool = True) -> None:
        """Send a command in a worker (taking control first, unless ``take`` is false)."""
        self.run_worker(self._send(what, call, take=take), group="command", exit_on_error=False)

    async def _send(self, what: str, call: Call, *, take: bool = True) -> bool:
        if take and self.web and not self.link.holds_control:
            self.notify(READ_ONLY, title=what, severity="warning", timeout=8.0, markup=False)
            return False
        try:
            result = await (self.link.command(call) if take else call(self.link.client))
        except LINK_ERRORS as exc:
            message, severity = describe(exc)
            self.notify(message, title=what, severity=severity, timeout=8.0, markup=False)
            self.redraw_state()
            return False
        ramp = result.duration_s if isinstance(result, CommandOut) else None
        self.notify(f"accepted{f', ramp {ramp:.1f} s' if ramp else ''}", title=what, timeout=3.0)
        self.redraw_state()
        return True

    # ------------------------------------------------------------------ the mill
    def action_estop(self) -> None:
        """Emergency stop: no lease, no dialog, always tried."""
        self.run_worker(self._estop(), group="estop", exit_on_error=False)

    async def _estop(self) -> None:
        try:
            await self.link.estop()
        except LINK_ERRORS as exc:
            self.notify(f"E-STOP NOT DELIVERED ({describe(exc)[0]}): use the mill's hardware E-stop",
                        title="E-STOP", severity="error", timeout=30.0, markup=False)
            return
        self.notify("E-stop sent: the mill stops and the trip latches; reset with r at standstill",
                    title="E-STOP", severity="warning", timeout=10.0)

    def action_arm(self) -> None:
        """Arm the node."""
        self.send("arm", lambda c: c.arm())

    def action_disarm(self) -> None:
        """Disarm the node."""
        self.send("disarm", lambda c: c.disarm())

    def action_stop(self) -> None:
        """Controlled stop (also aborts a running recipe): no lease, from any station (SAFETY 24)."""
        self.send("stop", lambda c: c.stop(), take=False)

    def action_reset(self) -> None:
        """Clear a latched trip."""
        self.send("reset", lambda c: c.reset())

    def action_heater_off(self) -> None:
        """Turn the furnace heater off."""
        self.send("heater off", lambda c: c.set_furnace(None))

    def action_set(self) -> None:
        """Open the setpoint dialog, prefilled with the present targets."""
        s = self.status
        modal = SetpointsModal(self.link.check, (s.target_rotary_rpm if s else None) or 0.0,
                               (s.target_vibration_rpm if s else None) or 0.0, s.furnace_target_c if s else None)
        self.push_screen(modal, self._set_chosen)

    def _set_chosen(self, request: SetRequest | None) -> None:
        if request is not None:
            self.run_worker(self._set(request), group="command", exit_on_error=False)

    async def _set(self, request: SetRequest) -> None:
        what = f"set ω_r {request.rotary_rpm:g} rpm, ω_v {request.vibration_rpm:g} rpm"
        temp = request.temp_c if request.furnace else None
        if temp is not None:
            what += f", furnace {temp:g} °C"
        if request.linear:
            what += " (linear path)"
        ok = await self._send(what, lambda c: c.set_speeds(
            request.rotary_rpm, request.vibration_rpm, temp_c=temp, rotary_rate_rpm_s=request.rotary_rate_rpm_s,
            vibration_rate_rpm_s=request.vibration_rate_rpm_s, linear=request.linear))
        if ok and request.furnace and temp is None:
            await self._send("heater off", lambda c: c.set_furnace(None))

    def action_envelope(self) -> None:
        """Show the envelope view: every law, the regime warning, the operating point."""
        self.push_screen(EnvelopeScreen(self.envelope, self.status))

    # ------------------------------------------------------------------ recipes
    def action_recipe_run(self) -> None:
        """Pick a recipe from the list, each with the service's pre-flight verdict, and run it."""
        files = recipe_files(recipe_folders(self.service))
        self.push_screen(RecipePicker(files, self.link.client.recipe_check), self._recipe_chosen)

    def _recipe_chosen(self, path: str | None) -> None:
        if path:
            self.send(f"recipe {Path(path).name}", lambda c: c.recipe_run(path))

    def action_recipe_pause(self) -> None:
        """Pause at the next step boundary, or resume a paused or held run."""
        progress = self.recipe.progress if self.recipe else None
        if progress is not None and progress.state.resumable:
            self.send("resume recipe", lambda c: c.recipe_resume())
        else:
            self.send("pause recipe", lambda c: c.recipe_pause(False))

    def action_pause_now(self) -> None:
        """Pause the run now, holding the setpoints."""
        self.send("pause recipe now", lambda c: c.recipe_pause(True))

    def action_recipe_abort(self) -> None:
        """Abort the run (controlled stop)."""
        self.send("abort recipe", lambda c: c.recipe_abort())

    # ------------------------------------------------------------------ fault drills (serve --fault-injection)
    def action_drill(self) -> None:
        """Open the fault drill dialog (a service started with ``--fault-injection`` only)."""
        self.push_screen(FaultDrillModal(self.link.client.faults), self._drill_chosen)

    def _drill_chosen(self, request: DrillRequest | None) -> None:
        if request is None:
            return
        what = "clear every fault" if request.fault is SimFaultName.CLEAR else f"inject {request.fault}"
        self.send(f"drill: {what}", lambda c: c.inject_fault(request.fault, request.active, request.param),
                  take=False)

    # ------------------------------------------------------------------ control and quitting
    def action_control(self) -> None:
        """Take control, or give it back if we hold it."""
        if self.link.holds_control:
            self.action_release()
        else:
            self.action_take()

    def action_take(self) -> None:
        """Take the control lease."""
        self.send("take control", lambda c: self.link.take_control(), take=False)

    def action_take_force(self) -> None:
        """Take over another client's expired lease (never a live one: the service refuses that)."""
        self.send("take over control", lambda c: self.link.take_control(force=True), take=False)

    def action_release(self) -> None:
        """Give the control lease back."""
        self.run_worker(self._release(), group="command", exit_on_error=False)

    async def _release(self) -> None:
        await self.link.release_control()
        self.notify("control released", timeout=3.0)
        self.redraw_state()

    async def action_quit(self) -> None:
        """Quit; ask first while the mill runs. Quitting never stops the service (except the one --sim started)."""
        state = self.state
        running = state in MOVING_STATES or self.recipe_active
        if not running:
            await self._leave()
            return
        after = ("The simulated service started with --sim stops with the TUI (controlled stop)." if self.sim else
                 "The service keeps the mill running; reconnect with `millctl tui`.")
        question = f"The mill is {state}{' with a recipe running' if self.recipe_active else ''}. Quit? {after}"
        self.push_screen(ConfirmModal(question), self._quit_answered)

    async def _quit_answered(self, answer: bool | None) -> None:
        # On the app's own task, not in a worker: a worker that calls exit() is cancelled by the shutdown it
        # starts, and the cancellation raced the stream's socket read (asyncio InvalidStateError on quit).
        if answer:
            await self._leave()

    async def _leave(self) -> None:
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(self.link.release_control(), QUIT_RELEASE_S)
        self.exit()


__all__ = ["QUIT_RELEASE_S", "READ_ONLY", "Commanding", "recipe_folders"]
