"""Every operator command and every refusal is recorded with who asked and what (SAFETY requirement 9).

docs/safety.md#state-machine: the controller's events carry the source (``operator``, ``recipe``,
``api:<client>`` …); a refused command names the operation, the state it was refused in and where it is
possible.
"""

from __future__ import annotations

from collections.abc import Callable

import pytest

from millctl.config import MillConfig
from millctl.controller import CommandRefused, Controller, ControllerState, EventKind
from millctl.protocol import Command, CommandCode, NodeState
from millctl.safety import InterlockRefused
from tests.unit.controller.bench import ScriptedNode

S = ControllerState
WHO = "api:alice"


def test_arm_disarm_and_stop_are_recorded_with_their_source_and_sent(bench: ScriptedNode) -> None:
    bench.armed(WHO)
    assert bench.last_event(EventKind.COMMAND).source == WHO
    bench.controller.disarm(source=WHO)
    bench.run(0.2, state=NodeState.DISABLED)
    assert bench.controller.state is S.DISABLED
    event = bench.last_event(EventKind.COMMAND)
    assert event.source == WHO and event.data["command"] == "DISARM"
    assert [d.message for _, d in bench.of(Command)].count(Command(CommandCode.DISARM)) == 1


def test_furnace_commands_are_recorded_with_their_source(bench: ScriptedNode) -> None:
    bench.armed(WHO)
    bench.controller.set_furnace(60.0, source=WHO)
    event = bench.last_event(EventKind.COMMAND)
    assert event.source == WHO and event.data == {"temp_c": 60.0}
    bench.controller.set_furnace(None, source=WHO)
    event = bench.last_event(EventKind.COMMAND)
    assert event.source == WHO and "heater off" in event.message
    assert bench.controller.furnace_target_c is None


REFUSED_IN_DISABLED: dict[str, Callable[[Controller], object]] = {
    "disarm": lambda c: c.disarm(source=WHO),
    "set speeds": lambda c: c.set_speeds(10.0, 100.0, source=WHO),
    "set the furnace": lambda c: c.set_furnace(60.0, source=WHO),
    "stop": lambda c: c.stop(source=WHO),
    "reset": lambda c: c.reset(source=WHO),
}


@pytest.mark.parametrize("what", list(REFUSED_IN_DISABLED))
def test_a_command_refused_in_the_wrong_state_names_it_and_the_state_and_is_recorded(
    bench: ScriptedNode, what: str
) -> None:
    bench.run(0.2, state=NodeState.DISABLED)
    with pytest.raises(CommandRefused, match=f"^{what} is not possible in state DISABLED \\(possible in "):
        REFUSED_IN_DISABLED[what](bench.controller)
    event = bench.last_event(EventKind.REFUSAL)
    assert event.source == WHO and event.message.startswith(f"{what} is not possible in state DISABLED")
    assert bench.of(Command) == []


def test_arm_refused_when_armed_names_it(bench: ScriptedNode) -> None:
    bench.armed(WHO)
    with pytest.raises(CommandRefused, match=r"^arm is not possible in state ARMED"):
        bench.controller.arm(source=WHO)
    assert bench.last_event(EventKind.REFUSAL).source == WHO


def test_stop_estop_and_every_step_of_a_reset_are_recorded_with_their_source(
    bench: ScriptedNode, config: MillConfig
) -> None:
    bench.armed(WHO)
    bench.controller.stop(source=WHO)
    event = bench.last_event(EventKind.COMMAND)
    assert (event.source, event.data["command"]) == (WHO, "STOP")

    bench.controller.estop(source=WHO)
    [estop] = [e for e in bench.events if e.kind is EventKind.COMMAND and e.message == "E-STOP"]
    assert estop.source == WHO
    assert bench.last_event(EventKind.TRIP).source == WHO  # then the trip's own STOP, by the interlock

    bench.run(2.0)  # the node silent: its telemetry goes stale
    with pytest.raises(CommandRefused, match=r"^reset refused: .*stale"):
        bench.controller.reset(source=WHO)
    assert bench.last_event(EventKind.REFUSAL).source == WHO
    bench.alive(NodeState.FAULT, rotary_rpm=50.0)
    bench.run(0.05)
    with pytest.raises(CommandRefused, match=r"^reset refused: drives not at standstill"):
        bench.controller.reset(source=WHO)
    assert bench.last_event(EventKind.REFUSAL).source == WHO

    bench.run(0.2, state=NodeState.FAULT)
    bench.controller.reset(source=WHO)
    requested, sent = [e for e in bench.events if e.kind is EventKind.COMMAND][-2:]
    assert (requested.source, requested.message) == (WHO, "reset requested")
    assert (sent.source, sent.data["command"]) == (WHO, "RESET")  # sent on the operator's behalf
    bench.run(config.interlock.command_confirm_s + 0.5, state=NodeState.FAULT)  # the node never completes it
    refusal = bench.last_event(EventKind.REFUSAL)
    assert refusal.message.startswith("reset did not complete") and refusal.source == WHO


def test_disarm_after_a_finished_ramp_to_a_speed_is_refused_and_recorded(bench: ScriptedNode) -> None:
    bench.armed(WHO)
    move = bench.controller.set_speeds(0.0, 1.0)
    bench.run(move.duration_s + 0.1, state=NodeState.ARMED, vibration_rpm=1.0)
    assert bench.controller.state is S.ARMED
    assert bench.controller.trajectory is None  # the ramp is over, the speed is still commanded
    with pytest.raises(CommandRefused, match="disarm needs both setpoints at 0"):
        bench.controller.disarm(source=WHO)
    assert bench.last_event(EventKind.REFUSAL).source == WHO
    assert [d.message for _, d in bench.of(Command)].count(Command(CommandCode.DISARM)) == 0


def test_a_refused_furnace_target_or_heating_rate_is_recorded_and_names_the_limit(
    bench: ScriptedNode, config: MillConfig
) -> None:
    bench.armed(WHO)
    too_hot = config.furnace.max_setpoint_c + 50.0
    with pytest.raises(InterlockRefused, match=r"^furnace setpoint refused by the interlock: "):
        bench.controller.set_furnace(too_hot, source=WHO)
    event = bench.last_event(EventKind.REFUSAL)
    assert event.source == WHO and event.data == {"temp_c": too_hot}
    assert f"{config.furnace.max_setpoint_c:.1f}" in event.message
    assert bench.controller.furnace_target_c is None
    too_fast = config.furnace.max_heating_rate_c_per_min + 5.0
    with pytest.raises(InterlockRefused, match=r"^furnace setpoint refused by the interlock: "):
        bench.controller.set_furnace(60.0, rate_c_per_min=too_fast, source=WHO)
    assert bench.last_event(EventKind.REFUSAL).data == {"temp_c": 60.0}
    assert bench.controller.furnace_target_c is None
