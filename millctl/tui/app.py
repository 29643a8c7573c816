"""``millctl tui``: the operator's terminal UI, a client of the controller service.

The main screen (:mod:`millctl.tui.view`) shows both drives, the furnace, the
envelope with the operating point, physics telemetry, link health, the
controller state, the recipe and the event log. Commands
(:mod:`millctl.tui.commands`) are footer keys and command-palette entries;
E-stop (Ctrl+X) is a priority binding, so it works in every dialog. The
follower (:mod:`millctl.tui.follow`) keeps the screen fed from the service
and survives it going away; every call is a coroutine on textual's loop.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any, ClassVar

from textual.app import SystemCommand
from textual.binding import Binding, BindingType
from textual.screen import Screen

from millctl.api import ControllerState
from millctl.safety.commands import CONTROLLER_ALLOWS, Operation
from millctl.tui.commands import Commanding
from millctl.tui.follow import Following

ENABLED_IN: dict[str, frozenset[ControllerState]] = {
    **{
        op.value: CONTROLLER_ALLOWS[op]
        for op in (Operation.ARM, Operation.DISARM, Operation.SET, Operation.STOP, Operation.RESET)
    },
    "recipe_run": frozenset({ControllerState.DISABLED, ControllerState.ARMED}),
}
"""Controller states in which a footer command applies (the controller's own table,
:data:`millctl.safety.commands.CONTROLLER_ALLOWS`); elsewhere its key is greyed out (the palette still offers
it, and the service refuses it with its reason)."""
RECIPE_ACTIONS = frozenset({"recipe_pause", "recipe_abort"})
"""Footer commands that apply only while a recipe is active."""


class MillApp(Commanding, Following):
    """The operator terminal UI for one service socket."""

    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("ctrl+x", "estop", "E-STOP", priority=True),
        Binding("q", "quit", "Quit"),  # second: on an 80-column footer the last keys are cut off
        Binding("a", "arm", "Arm"),
        Binding("s", "set", "Set ω, °C"),
        Binding("o", "stop", "Stop"),
        Binding("d", "disarm", "Disarm"),
        Binding("r", "reset", "Reset"),
        Binding("n", "recipe_run", "Recipe"),
        Binding("p", "recipe_pause", "Pause"),
        Binding("b", "recipe_abort", "Abort run"),
        Binding("e", "envelope", "Envelope"),
        Binding("f", "drill", "Fault drill"),
        Binding("c", "control", "Control"),
    ]

    def on_mount(self) -> None:
        """Follow the service (unless fed by hand: ``live=False``)."""
        if self.live:
            self.start_following()

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        """Grey out (None) the keys that do not apply in the present state; E-stop, control and quit always apply."""
        if action in ENABLED_IN:
            return True if self.online and self.state in ENABLED_IN[action] else None
        if action in RECIPE_ACTIONS:
            return True if self.online and self.recipe_active else None
        if action == "drill":
            return self.drills_allowed  # hidden, not greyed: only an instructor's service offers it
        return True

    @property
    def drills_allowed(self) -> bool:
        """True when the service was started with ``--fault-injection`` (a simulated mill)."""
        return self.service is not None and self.service.fault_injection

    def get_system_commands(self, screen: Screen[Any]) -> Iterable[SystemCommand]:
        """Every mill command, searchable, next to textual's own."""
        yield SystemCommand("E-STOP", "Emergency stop (Ctrl+X): always accepted, latches a trip", self.action_estop)
        yield SystemCommand("Arm", "Arm the node (from DISABLED)", self.action_arm)
        yield SystemCommand("Set speeds and furnace", "ω_r, ω_v and °C, checked before sending", self.action_set)
        yield SystemCommand("Stop", "Controlled stop: both drives ramp down inside the envelope", self.action_stop)
        yield SystemCommand("Disarm", "Disarm (from ARMED at standstill)", self.action_disarm)
        yield SystemCommand("Reset trip", "Clear a latched trip (standstill, cause removed)", self.action_reset)
        yield SystemCommand("Heater off", "Turn the furnace heater off", self.action_heater_off)
        yield SystemCommand("Run recipe", "Pick a recipe from the list, each with its pre-flight verdict",
                            self.action_recipe_run)
        yield SystemCommand("Pause recipe now", "Pause the run now, holding the setpoints", self.action_pause_now)
        yield SystemCommand("Pause/resume recipe", "Pause at the next step boundary, or resume",
                            self.action_recipe_pause)
        yield SystemCommand("Abort recipe", "Abort the run with a controlled stop", self.action_recipe_abort)
        if self.drills_allowed:
            yield SystemCommand("Fault drill", "Inject a fault into the simulated node (instructor; f)",
                                self.action_drill)
        yield SystemCommand("Envelope view", "Which rotary speed is safe: every law, the operating point (e)",
                            self.action_envelope)
        yield SystemCommand("Take control", "Take the control lease", self.action_take)
        yield SystemCommand("Take over expired control", "Force over another client's expired lease",
                            self.action_take_force)
        yield SystemCommand("Release control", "Give the control lease back", self.action_release)
        yield from super().get_system_commands(screen)


__all__ = ["MillApp"]
