"""The controller: state machine, ramp planner, heartbeat and telemetry tracking."""

from millctl.controller.planner import STANDSTILL, RampPlanner, Segment, SpeedPoint, Trajectory
from millctl.controller.states import TRANSITIONS, ControllerState, IllegalTransition, StateMachine, Transition

__all__ = [
    "STANDSTILL",
    "TRANSITIONS",
    "ControllerState",
    "IllegalTransition",
    "RampPlanner",
    "Segment",
    "SpeedPoint",
    "StateMachine",
    "Trajectory",
    "Transition",
]
