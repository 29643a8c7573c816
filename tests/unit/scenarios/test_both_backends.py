"""The mill's scenarios on both drive backends (issue 36 part 5): the millbus node and standard CiA 402 drives.

What an operator does and what a failing machine does, judged through the
controller and the rotors' true speeds, so that the same test holds on both
backends (tests/unit/scenarios/backends.py). The millbus-only scenarios stay
in test_controller_with_node.py, unchanged.
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest

from firmware_sim.cia402 import Cia402Mill, PowerState
from millctl.config import MillConfig, load_config
from millctl.controller import ControllerState as S
from millctl.protocol import SimFaultCode
from millctl.recipes import load_recipe, plan_recipe
from millctl.recipes.runner import RecipeRunner, RunState
from millctl.safety import InterlockRefused
from tests.conftest import REPO
from tests.unit.scenarios.backends import BACKENDS, CONFIGS, BackendRig

DEMO = REPO / "config" / "recipes" / "demo.toml"


@pytest.fixture(params=BACKENDS)
def backend_config(request: pytest.FixtureRequest, config: MillConfig) -> MillConfig:
    """The repository's config (millbus) or config/mill-cia402.toml (the same mill on CiA 402 drives)."""
    return config if request.param == "millbus" else load_config(REPO / CONFIGS["cia402"]).config


@pytest.fixture
def rig(backend_config: MillConfig) -> Iterator[BackendRig]:
    r = BackendRig(backend_config)
    yield r
    r.close()


def outside_envelope(rig: BackendRig) -> list[tuple[float, float, float]]:
    """Steps where the true pair was outside the envelope by more than the measurement tolerance."""
    env = rig.controller.envelope
    w_r, w_v = np.array(rig.true).T
    bad = ~env.contains(w_r, w_v, tolerance_rpm=env.measurement_tolerance_rpm)
    return [(rig.t_s[i], w_r[i], w_v[i]) for i in np.flatnonzero(bad)]


def test_startup_arm_ramp_steady_milling_and_controlled_stop(rig: BackendRig) -> None:
    rig.run(1.0)
    assert rig.at_rest  # nothing moves before ARM
    rig.start(180.0, 800.0)
    assert rig.controller.state is S.RUNNING, rig.controller.trip_cause
    w_r, w_v = rig.sim.true_speeds_rpm
    assert w_r == pytest.approx(180.0, abs=1.0) and w_v == pytest.approx(800.0, abs=1.0)
    rig.run(10.0)  # steady milling
    assert rig.controller.state is S.RUNNING, rig.controller.trip_cause
    rig.controller.stop()
    rig.run(30.0, until=lambda: rig.controller.state is S.ARMED)
    assert rig.state() is S.ARMED, rig.controller.trip_cause
    rig.run(3.0)
    assert rig.at_rest
    assert outside_envelope(rig) == []


def test_over_limit_request_refused_and_mill_untouched(rig: BackendRig) -> None:
    rig.start(180.0, 800.0)
    with pytest.raises(InterlockRefused, match=r"250\.0 rpm exceeds the limit 190\.0 rpm at ω_v = 800\.0 rpm"):
        rig.controller.set_speeds(250.0, 800.0)
    rig.run(2.0)
    assert rig.controller.state is S.RUNNING
    assert rig.sim.true_speeds_rpm[0] == pytest.approx(180.0, abs=1.0)


def test_estop_stops_both_drives(rig: BackendRig) -> None:
    rig.start(120.0, 400.0)
    rig.controller.estop()
    rig.run(1.0, until=rig.stopped_by_the_mill)
    assert rig.stopped_by_the_mill()  # the node latched it, or both drives quick-stopped
    assert rig.controller.state is S.TRIPPED
    rig.run(20.0, until=lambda: rig.at_rest)
    assert rig.at_rest
    assert outside_envelope(rig) == []


def test_vibration_stall_trips_and_stops_inside_the_envelope(rig: BackendRig) -> None:
    rig.start(180.0, 800.0)
    rig.inject(SimFaultCode.VIB_STALL)
    t_stall = rig.clock.now()
    elapsed = rig.run(5.0, until=lambda: rig.controller.state is S.TRIPPED)
    assert rig.controller.state is S.TRIPPED
    assert elapsed < 2.0, rig.controller.trip_cause
    rig.run(30.0, until=lambda: rig.at_rest)
    assert rig.at_rest and rig.controller.state is S.TRIPPED  # latched
    i0 = next(i for i, t in enumerate(rig.t_s) if t >= t_stall + elapsed)
    rotary = [w for w, _ in rig.true[i0:]]
    assert rotary[0] > 100.0 and rotary[-1] < 1.0, (rotary[0], rotary[-1])
    assert all(b <= a + 0.5 for a, b in itertools.pairwise(rotary))  # the rotary drive only slowed down


def test_rotary_runaway_trips(rig: BackendRig) -> None:
    rig.start(120.0, 800.0)
    rig.inject(SimFaultCode.ROTARY_RUNAWAY)
    rig.run(10.0, until=lambda: rig.controller.state is S.TRIPPED)
    assert rig.controller.state is S.TRIPPED
    assert rig.controller.trip_cause


def test_silent_drives_trip_the_controller_on_stale_telemetry(rig: BackendRig) -> None:
    rig.start(120.0, 400.0)
    rig.inject(SimFaultCode.NODE_SILENT)
    rig.run(5.0, until=lambda: rig.controller.state is S.TRIPPED)
    assert rig.controller.state is S.TRIPPED
    assert "stale" in rig.controller.trip_cause


def stop_bound_s(rig: BackendRig, speeds: tuple[float, float]) -> float:
    """Silence to standstill: the watchdog (consumer) time, the slower drive's stop at its max rate, its lag."""
    drives, timing = rig.config.drives, rig.config.timing
    ramp_s = max(speeds[0] / drives.rotary.max_accel_rpm_s, speeds[1] / drives.vibration.max_accel_rpm_s)
    lag_s = 5.0 * max(drives.rotary.time_constant_s, drives.vibration.time_constant_s)
    # the millbus node's stop follows the planner (ω_r first where the limit falls with ω_v): both ramps in turn
    planned_s = ramp_s if isinstance(rig.sim, Cia402Mill) else 2.0 * ramp_s + 2.0
    return timing.watchdog_timeout_s + planned_s + lag_s + 2 * timing.node_tick_s


def test_a_silent_controller_stops_the_mill_by_its_own_means(rig: BackendRig) -> None:
    speeds = (120.0, 400.0)
    rig.start(*speeds)
    t_last = rig.clock.now()
    rig.controller_alive = False  # the control loop is gone (a SIGKILL): no heartbeat, no setpoint
    rig.run(2.0, until=rig.stopped_by_the_mill)
    assert rig.stopped_by_the_mill()
    timing = rig.config.timing
    assert rig.clock.now() - t_last <= timing.watchdog_timeout_s + 3 * timing.node_tick_s
    rig.run(30.0, until=lambda: rig.at_rest)
    assert rig.at_rest
    assert rig.clock.now() - t_last <= stop_bound_s(rig, speeds)
    assert outside_envelope(rig) == []


def drive_recipe(rig: BackendRig, runner: RecipeRunner, seconds: float, until: Callable[[], bool]) -> None:
    for _ in range(round(seconds / rig.dt_s)):
        if until():
            return
        rig.step()
        runner.tick()


def test_the_demo_recipe_runs_to_done(rig: BackendRig, tmp_path: Path) -> None:
    loaded = load_recipe(DEMO)
    plan = plan_recipe(loaded.recipe, rig.config)
    runner = RecipeRunner(rig.controller, loaded, plan, rig.clock, records_dir=tmp_path, config_sha256="0" * 64)
    drive_recipe(rig, runner, 150.0, until=lambda: runner.finished)
    assert runner.state is RunState.DONE, runner.reason
    rig.run(5.0)
    assert rig.at_rest
    assert outside_envelope(rig) == []


def test_a_drive_whose_limit_read_back_differs_is_refused_with_the_object() -> None:
    rig = BackendRig(load_config(REPO / CONFIGS["cia402"]).config)
    try:
        assert isinstance(rig.sim, Cia402Mill)
        rig.sim.drives["rotary"].lie_readback(0x607F, 0, offset=1)  # the drive reads back what it was not given
        rig.run(30.0, until=lambda: rig.controller.state is S.DISABLED)
        assert rig.state() is S.DISABLED, rig.controller.trip_cause
        rig.controller.arm()

        def refusal() -> str | None:
            return next((e.message for e in rig.events if "0x607F" in e.message), None)

        rig.run(30.0, until=lambda: refusal() is not None)
        message = refusal()
        assert message is not None, [e.message for e in rig.events]
        found = re.search(r"rotary drive \(node 2\): 0x607F:00 max profile velocity written (\d+), read back (\d+)",
                          message)
        assert found and int(found[2]) == int(found[1]) + 1, message
        rig.run(1.0)
        assert rig.state() is not S.ARMED  # the arm is refused: the drive is not enabled
        assert rig.sim.drives["rotary"].state is not PowerState.OPERATION_ENABLED
        assert rig.at_rest
    finally:
        rig.close()
