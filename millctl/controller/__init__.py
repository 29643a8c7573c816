"""The controller: state machine, heartbeat, telemetry tracking and the interlock in action."""

from millctl.controller.states import TRANSITIONS, ControllerState, IllegalTransition, StateMachine, Transition

__all__ = ["TRANSITIONS", "ControllerState", "IllegalTransition", "StateMachine", "Transition"]
