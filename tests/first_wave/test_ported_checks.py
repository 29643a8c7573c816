"""Issue 15 item 8 and the start-up survivor, in the API the first wave's main (6c184f8) already had.

tests/unit/test_ramps.py imports ``millctl.safety.wire`` and the controller's tests read
``interlock.startup_grace_s``, both the fixes'; these are the named tests' bodies without them (the grace
by its default, 2.0 s). They pass here and fail on 6c184f8 by the defect; ``tests/first_wave/run`` runs
them on both.
"""

from __future__ import annotations

import numpy as np
import pytest

from millctl.config import MillConfig
from millctl.controller import ControllerState
from millctl.safety import Envelope, InterlockRefused
from millctl.safety.ramps import RampPlanner, SpeedPoint
from tests.unit.controller.bench import ScriptedNode
from tests.unit.controller.test_controller import _without_furnace

S = ControllerState


def test_item_8_linear_ramp_is_checked_on_the_wire_rounded_samples(config: MillConfig) -> None:
    """test_ramps.py::test_linear_ramp_is_checked_on_the_wire_rounded_samples"""
    planner = RampPlanner(Envelope.from_config(config))
    env = planner.envelope
    assert env.check(159.2, 459.7).ok is False
    assert bool(np.all(env.contains(np.linspace(174.0, 153.7, 4001), np.linspace(671.3, 382.0, 4001))))
    with pytest.raises(InterlockRefused, match=r"linear ramp at t = .* \(as sent, rounded to 0\.1 rpm\)"):
        planner.plan_linear(SpeedPoint(174.0, 671.3), SpeedPoint(153.7, 382.0))


def state_of(bench: ScriptedNode) -> ControllerState:
    """The controller's state, read afresh (mypy would keep the narrowing of an earlier assert)."""
    return bench.controller.state


def test_survivor_a_stream_that_never_comes_is_a_fault_after_the_start_up_grace(config: MillConfig) -> None:
    """test_controller.py::test_a_stream_that_never_comes_is_a_fault_after_the_start_up_grace"""
    grace_s = getattr(config.interlock, "startup_grace_s", 2.0)
    bench = ScriptedNode(config)
    try:
        _without_furnace(bench, grace_s - 0.1)
        assert bench.controller.state is S.DISABLED, bench.controller.trip_cause
        _without_furnace(bench, 0.2)
        assert state_of(bench) is S.TRIPPED
        assert "FurnaceTelemetry stale: never received" in bench.controller.trip_cause
    finally:
        bench.close()
