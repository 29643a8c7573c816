"""Scenarios on the virtual bus with the real simulated node (issue 6, docs/safety.md).

Each scenario is what an operator or a failing machine does; each asserts the
safety behaviour the operator relies on.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from millctl.config import MillConfig
from millctl.controller import CommandRefused
from millctl.controller import ControllerState as S
from millctl.protocol import EStop, FaultFlag, NodeState, SimFaultCode
from millctl.safety import InterlockRefused
from tests.unit.scenarios.rig import Rig


def outside_envelope(rig: Rig) -> list[tuple[float, float, float]]:
    """Steps where the true speed pair was outside the envelope by more than the measurement tolerance."""
    env = rig.controller.envelope
    w_r, w_v = np.array(rig.trace.true).T
    bad = ~env.contains(w_r, w_v, tolerance_rpm=env.measurement_tolerance_rpm)
    return [(rig.trace.t_s[i], w_r[i], w_v[i]) for i in np.flatnonzero(bad)]


def test_startup_ramp_steady_milling_and_controlled_stop(rig: Rig) -> None:
    rig.start(180.0, 800.0)
    assert rig.controller.state is S.RUNNING
    w_r, w_v = rig.node.true_speeds_rpm
    assert w_r == pytest.approx(180.0, abs=1.0) and w_v == pytest.approx(800.0, abs=1.0)
    rig.run(10.0)  # steady milling
    assert rig.controller.state is S.RUNNING
    assert rig.controller.status().detached is not None
    rig.controller.stop()
    rig.run(30.0, until=lambda: rig.controller.state is S.ARMED)
    assert rig.controller.state is S.ARMED
    rig.run(3.0)  # the drives coast the last rpm down
    assert max(rig.node.true_speeds_rpm) < 1.0
    assert outside_envelope(rig) == []
    assert rig.node.refused_setpoints == 0


def test_over_limit_request_refused_and_mill_untouched(rig: Rig) -> None:
    rig.start(180.0, 800.0)
    before = rig.node.last_setpoint
    with pytest.raises(InterlockRefused, match=r"250\.0 rpm exceeds the limit 190\.0 rpm at ω_v = 800\.0 rpm"):
        rig.controller.set_speeds(250.0, 800.0)
    rig.run(2.0)
    assert rig.node.last_setpoint == before
    assert rig.controller.state is S.RUNNING
    assert rig.node.refused_setpoints == 0


def test_vibration_stall_mid_run_trips_and_stops_inside_the_envelope(rig: Rig, config: MillConfig) -> None:
    rig.start(180.0, 800.0)
    rig.inject(SimFaultCode.VIB_STALL)
    t_stall = rig.clock.now()
    elapsed = rig.run(5.0, until=lambda: rig.controller.state is S.TRIPPED)
    assert rig.controller.state is S.TRIPPED
    # the stalled cam decelerates at the drive's limit; the eq. 9 limit falls with it, and the
    # debounced measured-speed interlock (or the node's own checks) must catch it promptly
    assert elapsed < 2.0, rig.controller.trip_cause
    rig.run(30.0, until=lambda: max(rig.node.true_speeds_rpm) < 1.0)
    assert max(rig.node.true_speeds_rpm) < 1.0
    assert rig.controller.state is S.TRIPPED  # latched
    # after the trip the rotary drive only ever slowed down
    i0 = next(i for i, t in enumerate(rig.trace.t_s) if t >= t_stall + elapsed)
    rotary = [w for w, _ in rig.trace.true[i0:]]
    assert rotary[0] > 100.0 and rotary[-1] < 1.0, (rotary[0], rotary[-1])  # the trace covers the slow-down
    assert all(b <= a + 0.5 for a, b in itertools.pairwise(rotary))


def test_node_silence_trips_the_controller(rig: Rig, config: MillConfig) -> None:
    rig.start(120.0, 400.0)
    rig.inject(SimFaultCode.NODE_SILENT)
    elapsed = rig.run(5.0, until=lambda: rig.controller.state is S.TRIPPED)
    assert rig.controller.state is S.TRIPPED
    assert "stale" in rig.controller.trip_cause
    bound = rig.controller.tracker.tracks
    worst = max(t.stale_after_s for t in bound.values())
    assert elapsed <= worst + 2 * config.timing.controller_tick_s + 0.1


def test_controller_silence_stops_the_node_within_the_watchdog_bound(
    rig: Rig, config: MillConfig, monkeypatch: pytest.MonkeyPatch
) -> None:
    rig.start(120.0, 400.0)
    t_last = rig.clock.now()
    monkeypatch.setattr(rig.controller, "tick", lambda: None)  # the control loop hangs: no more heartbeats
    rig.run(2.0, until=lambda: rig.node.state is NodeState.FAULT)
    assert FaultFlag.WATCHDOG in rig.node.fault_bits
    assert rig.clock.now() - t_last <= config.timing.watchdog_timeout_s + 2 * config.timing.node_tick_s
    rig.run(20.0, until=lambda: max(rig.node.true_speeds_rpm) < 1.0)
    assert max(rig.node.true_speeds_rpm) < 1.0 and not rig.node.heater_on
    assert outside_envelope(rig) == []


def test_estop_from_a_bystander(rig: Rig) -> None:
    rig.start(120.0, 400.0)
    rig.probe.send(rig.codec.encode(EStop(7)))
    rig.run(1.0, until=lambda: rig.controller.state is S.TRIPPED)
    assert rig.controller.state is S.TRIPPED and "ESTOP" in rig.controller.trip_cause
    rig.run(20.0, until=lambda: max(rig.node.true_speeds_rpm) < 1.0)
    assert max(rig.node.true_speeds_rpm) < 1.0


def test_reset_procedure(rig: Rig) -> None:
    rig.start(120.0, 400.0)
    rig.inject(SimFaultCode.VIB_STALL)
    rig.run(5.0, until=lambda: rig.controller.state is S.TRIPPED)
    with pytest.raises(CommandRefused, match=r"not at standstill|reset refused"):
        rig.controller.reset()
    rig.run(15.0)  # the node's controlled stop runs to its end
    rig.inject(SimFaultCode.CLEAR)  # the operator clears the cause
    rig.run(10.0, until=lambda: max(rig.node.measured_speeds_rpm) < 0.5)
    rig.run(0.2)
    rig.controller.reset()
    rig.run(2.0, until=lambda: rig.controller.state is S.DISABLED)
    assert rig.controller.state is S.DISABLED and rig.node.state is NodeState.DISABLED
    rig.run(1.0)
    assert max(rig.node.true_speeds_rpm) < 1.0  # nothing moves without ARM
    rig.controller.arm()
    rig.run(1.0, until=lambda: rig.controller.state is S.ARMED)
    assert rig.controller.state is S.ARMED


def test_a_set_with_a_refused_furnace_target_applies_no_part(rig: Rig) -> None:
    """Issue 15 item 7: speeds and furnace are checked whole; a refused furnace target leaves the speeds untouched."""
    rig.start(0.0, 0.0)
    with pytest.raises(InterlockRefused, match=r"furnace setpoint 5000\.0 °C is outside"):
        rig.controller.set_speeds(150.0, 800.0, furnace_c=5000.0)
    with pytest.raises(InterlockRefused, match=r"heating rate"):
        rig.controller.set_speeds(150.0, 800.0, furnace_c=200.0, heating_rate_c_per_min=1000.0)
    with pytest.raises(InterlockRefused, match=r"exceeds the limit"):  # and a refused speed leaves the furnace
        rig.controller.set_speeds(250.0, 800.0, furnace_c=200.0)
    rig.run(3.0)
    assert rig.controller.trajectory is None and rig.controller.furnace_target_c is None
    assert max(rig.node.true_speeds_rpm) < 1.0 and not rig.node.heater_on
    move = rig.controller.set_speeds(150.0, 800.0, furnace_c=200.0)  # both parts inside: both applied
    assert move.end.omega_r_rpm == 150.0 and rig.controller.furnace_target_c == 200.0


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    moves=st.lists(st.tuples(st.floats(0.0, 1.0), st.integers(0, 1100), st.booleans()), min_size=1, max_size=3)
)
@example(moves=[(0.9838, 671.3, False), (0.9993, 382.0, True)])  # issue 15 item 8: (174.0, 671.3) → (153.7, 382.0)
def test_the_planner_never_sends_what_the_node_refuses(
    config: MillConfig, moves: list[tuple[float, float, bool]]
) -> None:
    """SAFETY 13: controller and node share one limit module; random moves, sequenced or linear, are never refused.

    The explicit example is the issue's linear move: the first wave's planner (6c184f8) sent it and the node
    refused its rounded sample (159.2, 459.7); the six random examples alone pass on that code.
    """
    rig = Rig(config)
    try:
        rig.start(0.0, 0.0)
        for fraction, w_v, linear in moves:
            limit = float(rig.controller.envelope.omega_r_limit_rpm(w_v))
            try:
                move = rig.controller.set_speeds(round(fraction * limit * 0.999, 1), round(w_v, 1), linear=linear)
            except InterlockRefused:
                assert linear  # only a straight line can leave the envelope between two inside ends
                continue
            rig.run(move.duration_s + 1.5)
            assert rig.controller.state in (S.ARMED, S.RUNNING), rig.controller.trip_cause
        assert rig.node.refused_setpoints == 0, rig.node.last_refusal
        assert outside_envelope(rig) == []
    finally:
        rig.close()
