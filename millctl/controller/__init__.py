"""The controller: state machine, heartbeat, telemetry tracking and the interlock in action."""

from millctl.controller.controller import STANDSTILL_RPM, CommandRefused, Controller
from millctl.controller.events import Event, EventKind, EventListener
from millctl.controller.states import TRANSITIONS, ControllerState, IllegalTransition, StateMachine, Transition
from millctl.controller.status import Status

__all__ = [
    "STANDSTILL_RPM",
    "TRANSITIONS",
    "CommandRefused",
    "Controller",
    "ControllerState",
    "Event",
    "EventKind",
    "EventListener",
    "IllegalTransition",
    "StateMachine",
    "Status",
    "Transition",
]
