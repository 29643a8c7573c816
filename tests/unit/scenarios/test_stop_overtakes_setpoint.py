"""A stop right after the controller's own first setpoint to an ARMED node is no forgery (issue 15).

The seen flake (CI, hil-service, pause → resume → abort back to back): the
controller sent its first nonzero Setpoints frame to an ARMED node, and the
operator's STOP followed before the node's next NodeStatus came back. The
node takes frames in the order sent: the setpoint first (ARMED → RUNNING, and
a NodeStatus saying so), then the STOP. The controller, already STOPPING,
read that RUNNING as a change it never commanded and sent an E-stop: "node
went ARMED → RUNNING, which the controller (state STOPPING) did not command".

The real simulated node and the controller on one virtual bus, stepped in the
service's order (controller, then node, then the queued operator command), so
the ordering is exact, not a matter of luck (docs/safety.md#a-stop-overtaking-a-setpoint).
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from millctl.config import MillConfig
from millctl.controller import ControllerState as S
from millctl.controller import EventKind
from millctl.protocol import MillMessage, NodeState, NodeStatus
from tests.unit.scenarios.rig import Rig


@pytest.fixture
def rig(config: MillConfig) -> Iterator[Rig]:
    r = Rig(config, fault_injection=False)
    yield r
    r.close()


def service_tick(rig: Rig) -> list[type[MillMessage]]:
    """One tick in the service's order: the controller, then the embedded node; the kinds put on the bus."""
    rig.controller.tick()
    rig.node.tick()
    rig.clock.advance(rig.dt_s)
    return [rig.codec.decode(f).kind for f in iter(lambda: rig.probe.recv(timeout=0.0), None)]


def armed(rig: Rig) -> None:
    rig.run(1.0, until=lambda: rig.controller.state is S.DISABLED)
    rig.controller.arm()
    rig.run(1.0, until=lambda: rig.controller.state is S.ARMED)
    rig.run(0.2)
    assert rig.controller.state is S.ARMED and rig.node.state is NodeState.ARMED


def until_the_node_reports_running_unseen(rig: Rig) -> None:
    """Tick until the node took the controller's first nonzero setpoint and said RUNNING, which the
    controller has not read yet (the tick an operator command lands in, in the service)."""
    for _ in range(200):
        sent = service_tick(rig)
        if rig.node.state is NodeState.RUNNING and NodeStatus in sent:
            assert rig.controller.state is S.ARMED  # it has not read the node's RUNNING
            return
    raise AssertionError("the node never reported RUNNING")


def estops(rig: Rig) -> list[str]:
    return [e.message for e in rig.events if e.kind is EventKind.TRIP]


def test_a_stop_right_after_the_first_setpoint_is_a_clean_stop_not_an_estop(rig: Rig) -> None:
    armed(rig)
    rig.controller.set_speeds(120.0, 400.0)
    until_the_node_reports_running_unseen(rig)
    rig.controller.stop()  # the operator's abort, queued behind that tick
    for _ in range(round(5.0 / rig.dt_s)):
        service_tick(rig)
        if rig.controller.state is S.ARMED and rig.node.state is NodeState.ARMED:
            break
    assert rig.controller.state is S.ARMED, f"{rig.controller.state}: {rig.controller.trip_cause}"
    assert estops(rig) == []
    assert rig.controller.estops_sent == 0
    assert rig.node.fault_bits == 0 and rig.node.state is NodeState.ARMED
    assert max(rig.node.true_speeds_rpm) < 1.0 + rig.config.interlock.measurement_tolerance_rpm


def test_back_to_back_hold_resume_and_stop_never_trip(rig: Rig) -> None:
    """The recipe's pause → resume → abort, each landing in a different tick after the ramp's start."""
    armed(rig)
    for delay_ticks in range(0, 12):
        rig.controller.set_speeds(120.0, 400.0)
        for _ in range(delay_ticks):
            service_tick(rig)
        c = rig.controller.commanded
        rig.controller.set_speeds(c.omega_r_rpm, c.omega_v_rpm)  # pause: hold where the ramp is
        service_tick(rig)
        rig.controller.set_speeds(120.0, 400.0)  # resume: the ramp again from there
        service_tick(rig)
        rig.controller.stop()  # abort
        for _ in range(round(10.0 / rig.dt_s)):
            service_tick(rig)
            if rig.controller.state is S.ARMED and rig.node.state is NodeState.ARMED and rig.node.at_standstill:
                break
        assert rig.controller.state is S.ARMED, f"delay {delay_ticks}: {rig.controller.trip_cause}"
        assert rig.controller.estops_sent == 0
