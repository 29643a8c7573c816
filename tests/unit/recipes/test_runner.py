"""The recipe runner on the real simulated node: complete runs, pause, resume, abort, trips, records."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from millctl.config import MillConfig
from millctl.controller import CommandRefused
from millctl.errors import InterlockError
from millctl.protocol import SimFaultCode
from millctl.recipes import load_recipe, plan_recipe
from millctl.recipes.runner import RecipeRunner, RunState
from millctl.records import read_records
from tests.conftest import REPO
from tests.unit.scenarios.rig import Rig

DEMO = REPO / "config" / "recipes" / "demo.toml"


@pytest.fixture
def rig(config: MillConfig) -> Iterator[Rig]:
    r = Rig(config)
    yield r
    r.close()


def runner_for(rig: Rig, path: Path, tmp_path: Path) -> RecipeRunner:
    loaded = load_recipe(path)
    plan = plan_recipe(loaded.recipe, rig.config)
    return RecipeRunner(rig.controller, loaded, plan, rig.clock, records_dir=tmp_path, config_sha256="0" * 64)


def drive(rig: Rig, runner: RecipeRunner, seconds: float, until: Callable[[], bool] | None = None) -> None:
    for _ in range(round(seconds / rig.dt_s)):
        if runner.finished or (until is not None and until()):
            return
        rig.step()
        runner.tick()


def events(runner: RecipeRunner) -> list[str]:
    return [r["event"] for r in read_records(runner.record.path)]


def test_demo_runs_to_done_with_a_complete_record(rig: Rig, tmp_path: Path) -> None:
    runner = runner_for(rig, DEMO, tmp_path)
    drive(rig, runner, 120.0)
    assert runner.state is RunState.DONE, runner.reason
    rig.run(2.0)  # the last rpm coasts down
    assert max(rig.node.true_speeds_rpm) < 0.5
    log = events(runner)
    assert log[0] == "start" and log[-1] == "end"
    assert log.count("step_start") == log.count("step_end") == 4
    records = list(read_records(runner.record.path))
    assert records[0]["recipe_sha256"] == load_recipe(DEMO).sha256
    assert records[-1]["status"] == "DONE"
    assert rig.node.refused_setpoints == 0
    # the run took about the planned time (plus settling), not more
    assert records[-1]["elapsed_s"] < runner.plan.total_s + 20.0


def test_pause_now_freezes_the_step_clock_and_resume_continues(rig: Rig, tmp_path: Path) -> None:
    runner = runner_for(rig, DEMO, tmp_path)
    drive(rig, runner, 60.0, until=lambda: runner.progress()["kind"] == "hold" and runner.index == 1)
    drive(rig, runner, 2.0)
    runner.pause(now=True)
    assert runner.state is RunState.PAUSED
    before = runner.progress()["step_elapsed_s"]
    drive(rig, runner, 10.0)
    assert runner.progress()["step_elapsed_s"] == pytest.approx(before)
    assert runner.index == 1
    runner.resume()
    drive(rig, runner, 120.0)
    assert runner.state is RunState.DONE
    assert "pause" in events(runner) and "resume" in events(runner)


def test_pause_at_the_next_boundary(rig: Rig, tmp_path: Path) -> None:
    runner = runner_for(rig, DEMO, tmp_path)
    drive(rig, runner, 3.0)
    runner.pause()
    drive(rig, runner, 60.0, until=lambda: runner.state is RunState.PAUSED)
    assert runner.state is RunState.PAUSED and runner.index == 1
    with pytest.raises(CommandRefused):
        runner.pause()
    runner.resume()
    drive(rig, runner, 120.0)
    assert runner.state is RunState.DONE


def test_abort_ramps_down_inside_the_envelope(rig: Rig, tmp_path: Path) -> None:
    runner = runner_for(rig, DEMO, tmp_path)
    drive(rig, runner, 60.0, until=lambda: runner.index == 3)
    runner.abort()
    drive(rig, runner, 60.0)
    assert runner.state is RunState.ABORTED
    rig.run(2.0)
    assert max(rig.node.true_speeds_rpm) < 0.5
    env = rig.controller.envelope
    assert all(env.contains(r, v, tolerance_rpm=env.measurement_tolerance_rpm) for r, v in rig.trace.true)
    assert list(read_records(runner.record.path))[-1]["status"] == "ABORTED"


def test_a_trip_mid_recipe_fails_the_run_with_its_cause(rig: Rig, tmp_path: Path) -> None:
    runner = runner_for(rig, DEMO, tmp_path)
    drive(rig, runner, 60.0, until=lambda: runner.index == 3)
    rig.inject(SimFaultCode.VIB_STALL)
    drive(rig, runner, 30.0)
    assert runner.state is RunState.FAILED
    assert "interlock trip" in runner.reason
    last = list(read_records(runner.record.path))
    assert [r["event"] for r in last][-2:] == ["trip", "end"]
    assert last[-1]["status"] == "FAILED"


def test_a_trip_in_the_final_stop_fails_the_run_instead_of_ending_it_done(rig: Rig, tmp_path: Path) -> None:
    """The recipe's steps are done and its stop under way: a runaway then is a trip, and the run is not DONE."""
    runner = runner_for(rig, DEMO, tmp_path)
    drive(rig, runner, 150.0, until=lambda: runner.state is RunState.STOPPING)
    assert runner.state is RunState.STOPPING and runner.index == len(runner.steps)
    rig.inject(SimFaultCode.ROTARY_RUNAWAY, 200.0)
    drive(rig, runner, 30.0)
    assert rig.controller.trip_cause
    assert runner.state is RunState.FAILED
    assert runner.reason.startswith("interlock trip in the final stop: ")
    last = list(read_records(runner.record.path))
    assert [r["event"] for r in last][-2:] == ["trip", "end"]
    assert last[-1]["status"] == "FAILED"


def test_a_recipe_that_fails_preflight_cannot_start(rig: Rig, tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text('[recipe]\nname = "x"\n[[steps]]\nkind = "ramp"\nrotary_rpm = 250\nvibration_rpm = 800\n')
    with pytest.raises(InterlockError, match=r"bad\.toml does not pass its pre-flight: .*250") as raised:
        runner_for(rig, bad, tmp_path)
    assert type(raised.value) is InterlockError  # the recipe is refused, not some command on the way
