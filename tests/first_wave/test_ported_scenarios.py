"""Issue 15 items 2, 5, 6, 7, 8 on the unit tier's rig, in the API the first wave's main (6c184f8) already had.

The named tests (docs/safety.md#each-defect-on-the-first-waves-main-6c184f8) fail on 6c184f8 before they
reach the defect: they import ``millctl.protocol.receive`` or read ``Node.reader``, ``estops_sent``,
``interlock.command_confirm_s``, ``set_speeds(furnace_c=…)``, which the fixes added. These are their bodies
with only that replaced: the config keys by their defaults, the counters by what the events and the node
show, the one-call set by what `millctl set` sent before it (the speeds, then the furnace). They pass here
and fail on 6c184f8 by the defect; ``tests/first_wave/run`` runs them on both.
"""

from __future__ import annotations

from collections.abc import Iterator

import can
import pytest

from millctl.config import MillConfig
from millctl.controller import ControllerState as S
from millctl.protocol import (
    Command,
    CommandCode,
    MillMessage,
    NodeState,
    NodeStatus,
    RefusalCode,
    Setpoints,
    SimFaultCode,
)
from millctl.safety import InterlockRefused
from tests.unit.scenarios.rig import Rig
from tests.unit.scenarios.test_bus_input import FailingReads

COMMAND_CONFIRM_S = 1.0
"""``interlock.command_confirm_s``'s default (the key is the fix's)."""


@pytest.fixture
def rig(config: MillConfig) -> Iterator[Rig]:
    r = Rig(config)
    yield r
    r.close()


def forge(rig: Rig, message: MillMessage, counter: int) -> None:
    """Another sender puts ``message`` on the bus with the alive counter ``counter``."""
    rig.probe.send(rig.codec.encode(message, counter))


def next_counter(rig: Rig, kind: type[MillMessage]) -> int:
    """The counter the controller's next frame of ``kind`` will carry."""
    return rig.controller._counters[kind].value


def shown(rig: Rig) -> str:
    w_r, w_v = rig.node.true_speeds_rpm
    return f"node {rig.node.state.name} at {w_r:.1f}/{w_v:.1f} rpm, controller {rig.controller.state}"


def test_item_2_a_stop_dropped_as_not_fresh_after_a_forged_disarm_is_repeated(rig: Rig) -> None:
    """test_commands_confirmed.py::test_a_stop_dropped_as_not_fresh_after_a_forged_disarm_is_repeated_and_the_mill_stops"""
    rig.start(60.0, 300.0)
    forge(rig, Command(CommandCode.DISARM), next_counter(rig, Command))
    rig.step()
    rig.controller.stop()
    rig.run(0.1)
    assert rig.node.last_refusal is RefusalCode.NOT_FRESH and rig.node.state is NodeState.RUNNING
    rig.run(COMMAND_CONFIRM_S)
    assert rig.node.state in (NodeState.STOPPING, NodeState.ARMED), f"{COMMAND_CONFIRM_S} s after STOP: {shown(rig)}"
    rig.run(20.0, until=lambda: rig.controller.state is S.ARMED)
    assert rig.controller.state is S.ARMED, shown(rig)
    rig.run(2.0)
    assert max(rig.node.true_speeds_rpm) < 1.0, shown(rig)


def test_item_5_a_forged_reset_and_arm_after_an_estop_is_met_with_another_estop(
    rig: Rig, config: MillConfig
) -> None:
    """test_commands_confirmed.py::test_a_forged_reset_and_arm_after_an_estop_is_met_with_another_estop"""
    rig.start(120.0, 400.0)
    rig.controller.estop()
    rig.run(30.0, until=lambda: max(rig.node.true_speeds_rpm) < 0.01)
    rig.run(0.5)
    assert rig.node.state is NodeState.FAULT
    counter = next_counter(rig, Command)
    forge(rig, Command(CommandCode.RESET), counter)
    forge(rig, Command(CommandCode.ARM), (counter + 1) % 16)
    t_forged = rig.clock.now()
    setpoints_counter = next_counter(rig, Setpoints)
    for i in range(30):
        forge(rig, Setpoints(4.0 * (i + 1), 16.0 * (i + 1), 25.0, False), (setpoints_counter + i) % 16)
        rig.run(config.timing.setpoint_period_s)
    after = [(t, n) for t, n in zip(rig.trace.t_s, rig.trace.node, strict=True) if t > t_forged]
    relatched = next((t for t, n in after if n == "FAULT"), None)
    assert relatched is not None, f"never back in FAULT in 3 s after the forged RESET+ARM: {shown(rig)}"
    status_period_s = rig.codec.cycle_time_s(NodeStatus) or 0.05
    assert relatched - t_forged <= status_period_s + 3 * rig.dt_s


def test_item_5_the_measured_speed_is_checked_in_tripped(rig: Rig) -> None:
    """test_commands_confirmed.py::test_the_measured_speed_is_checked_in_tripped"""
    rig.start(0.0, 0.0)
    rig.controller.estop()
    rig.run(0.5)
    t_inject = rig.clock.now()
    rig.inject(SimFaultCode.ROTARY_RUNAWAY, 120.0)  # the rotor runs away whatever it is told
    rig.run(3.0)
    later = [e.message for e in rig.events if e.time_s > t_inject]
    assert any("measured ω_r" in m for m in later), f"rotor runs away in TRIPPED, {shown(rig)}; events: {later}"


@pytest.mark.parametrize(
    "error",
    [OSError(105, "No buffer space available"), can.CanOperationError("undecodable datagram of 1 bytes")],
    ids=["OSError", "CanOperationError"],
)
def test_item_6_receive_errors_kill_neither_loop(rig: Rig, error: Exception) -> None:
    """test_bus_input.py::test_receive_errors_are_counted_and_neither_loop_stops"""
    rig.start(60.0, 300.0)
    for loop in (rig.node, rig.controller):
        reader = getattr(loop, "reader", loop)  # where the loop reads its bus (6c184f8: the bus itself)
        reader.bus = FailingReads(loop.bus, 3, error)
    died = {}
    for name, tick in (("node", rig.node.tick), ("controller", rig.controller.tick)):
        try:
            for _ in range(10):
                tick()
        except Exception as exc:  # the loop's tick raised: its process exits
            died[name] = f"{type(exc).__name__}: {exc}"
    assert died == {}, f"a receive error killed the loop: {died}"


def test_item_7_a_set_with_a_refused_furnace_target_applies_no_part(rig: Rig) -> None:
    """test_controller_with_node.py::test_a_set_with_a_refused_furnace_target_applies_no_part, as the CLI sends it"""
    rig.start(0.0, 0.0)
    refused_by = "nothing refused"
    try:
        try:
            rig.controller.set_speeds(150.0, 800.0, furnace_c=5000.0)
        except TypeError:  # 6c184f8: no one-call set; `millctl set` sent the speeds, then the furnace
            rig.controller.set_speeds(150.0, 800.0)
            rig.controller.set_furnace(5000.0)
    except InterlockRefused as refused:
        refused_by = str(refused)
    rig.run(20.0)
    assert max(rig.node.true_speeds_rpm) < 1.0, f"{refused_by!r}, yet {shown(rig)}"


def test_item_8_the_issues_linear_ramp_is_never_sent_for_the_node_to_refuse(rig: Rig) -> None:
    """(174.0, 671.3) → (153.7, 382.0) rpm, linear, on the real node: its rounded sample (159.2, 459.7) is outside."""
    rig.start(174.0, 671.3)
    assert rig.controller.state is S.RUNNING and rig.node.refused_setpoints == 0
    try:
        move = rig.controller.set_speeds(153.7, 382.0, linear=True)
    except InterlockRefused as refused:
        assert "rounded to 0.1 rpm" in str(refused)
        return
    rig.run(move.duration_s + 1.0)
    count = rig.node.refused_setpoints
    assert count == 0, f"planner sent the ramp; the node refused {count} setpoints ({rig.node.last_refusal.name})"
