"""Resuming interrupted runs: reading the record, where the run continues, refusals, and a resumed run to DONE."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import pytest

from millctl.config import MillConfig
from millctl.recipes import parse_recipe, plan_recipe
from millctl.recipes.history import (
    RUNS_DIR,
    RunLock,
    RunNotFound,
    RunNotResumable,
    read_history,
    repair_tail,
    unfinished_runs,
)
from millctl.recipes.resume import check_unchanged, preflight_resume, resume_point, setpoints_before
from millctl.recipes.runner import RecipeRunner, RunState
from millctl.records import read_records
from tests.unit.recipes.test_runner import drive
from tests.unit.scenarios.rig import Rig

CONFIG_SHA = "c" * 64

HOLD = """
[recipe]
name = "resume-test"
[defaults]
tolerances = {{ speed_rpm = 5.0, furnace_c = 3.0 }}
[[steps]]
kind = "ramp"
rotary_rpm = 60.0
vibration_rpm = 300.0
rotary_rate_rpm_s = 40.0
vibration_rate_rpm_s = 120.0
{furnace}
[[steps]]
kind = "hold"
duration_s = {hold_s}
[[steps]]
kind = "ramp"
rotary_rpm = 30.0
vibration_rpm = 300.0
"""


def recipe_text(hold_s: float = 20.0, furnace: str = "") -> str:
    return HOLD.format(hold_s=hold_s, furnace=furnace)


def write_record(directory: Path, run_id: str, records: list[dict[str, Any]], tail: bytes = b"") -> Path:
    path = directory / RUNS_DIR / f"{run_id}.jsonl"
    path.parent.mkdir(parents=True, exist_ok=True)
    lines = b"".join(json.dumps({"run_id": run_id, **r}).encode() + b"\n" for r in records)
    path.write_bytes(lines + tail)
    return path


def started(text: str, t: float = 1000.0) -> dict[str, Any]:
    loaded = parse_recipe(text, "resume-test.toml")
    return {"event": "start", "t": t, "recipe": "resume-test", "recipe_file": "resume-test.toml",
            "recipe_sha256": loaded.sha256, "config_sha256": CONFIG_SHA, "steps": 3, "recipe_text": text}


def interrupted_in_hold(tmp_path: Path, run_id: str = "20260101T000000Z-abcdef", tail: bytes = b"") -> Path:
    text = recipe_text()
    return write_record(tmp_path, run_id, [
        started(text),
        {"event": "step_start", "t": 1001.0, "step": 1, "kind": "ramp"},
        {"event": "step_end", "t": 1010.0, "step": 1, "kind": "ramp"},
        {"event": "step_start", "t": 1010.0, "step": 2, "kind": "hold"},
        {"event": "sample", "t": 1015.0, "step": 2, "step_elapsed_s": 5.0, "step_dose_j_g": 1.5, "run_s": 15.0,
         "dose_j_g": 9.0},
        {"event": "sample", "t": 1018.0, "step": 2, "step_elapsed_s": 8.0, "step_dose_j_g": 2.5, "run_s": 18.0,
         "dose_j_g": 10.0},
    ], tail)


def test_an_unfinished_record_says_the_step_and_the_time_done_in_it(tmp_path: Path) -> None:
    path = interrupted_in_hold(tmp_path, tail=b'{"run_id": "x", "event": "sam')  # a write cut by the kill
    history = read_history(path)
    assert history.ended is None and (history.step, history.kind) == (2, "hold")
    assert history.step_elapsed_s == 8.0 and history.step_dose_j_g == 2.5 and history.run_s == 18.0
    assert history.last_unix == 1018.0 and "crash, a kill or a power loss" in history.reason
    assert [h.run_id for h in unfinished_runs(tmp_path)] == [history.run_id]
    assert repair_tail(path) == len(b'{"run_id": "x", "event": "sam')
    assert path.read_bytes().endswith(b"\n") and len(list(read_records(path))) == 6
    assert repair_tail(path) == 0


def test_a_hold_keeps_its_time_a_ramp_runs_again(tmp_path: Path) -> None:
    history = read_history(interrupted_in_hold(tmp_path))
    loaded = parse_recipe(recipe_text(), "resume-test.toml")
    point = resume_point(history, loaded)
    assert (point.index, point.credit_s, point.dose_j_g) == (1, 8.0, 2.5)
    assert (point.restore.rotary_rpm, point.restore.vibration_rpm) == (60.0, 300.0)
    with (tmp_path / RUNS_DIR / "20260101T000000Z-abcdef.jsonl").open("a") as handle:
        handle.write(json.dumps({"event": "step_end", "t": 1030.0, "step": 2}) + "\n")
        handle.write(json.dumps({"event": "step_start", "t": 1030.0, "step": 3, "kind": "ramp"}) + "\n")
        handle.write(json.dumps({"event": "sample", "t": 1031.0, "step": 3, "step_elapsed_s": 1.0}) + "\n")
    ramp = resume_point(read_history(tmp_path / RUNS_DIR / "20260101T000000Z-abcdef.jsonl"), loaded)
    assert (ramp.index, ramp.credit_s) == (2, 0.0)  # a ramp ends on its target, not on time


def test_the_setpoints_in_force_carry_the_furnace_past_ramps_that_set_none() -> None:
    text = recipe_text(furnace="furnace_c = 400.0\nheating_rate_c_per_min = 10.0")
    loaded = parse_recipe(text, "r.toml")
    held = setpoints_before(loaded.recipe, 3)
    assert (held.rotary_rpm, held.furnace_c, held.heating_rate_c_per_min) == (30.0, 400.0, 10.0)
    assert setpoints_before(loaded.recipe, 0).point.omega_r_rpm == 0.0


def test_a_finished_run_a_changed_recipe_or_config_are_refused(tmp_path: Path) -> None:
    path = interrupted_in_hold(tmp_path)
    history = read_history(path)
    loaded = parse_recipe(recipe_text(), "resume-test.toml")
    changed = parse_recipe(recipe_text(hold_s=21.0), "resume-test.toml")
    with pytest.raises(RunNotResumable, match="the recipe changed"):
        check_unchanged(history, changed, CONFIG_SHA)
    with pytest.raises(RunNotResumable, match="the configuration changed"):
        check_unchanged(history, loaded, "d" * 64)
    check_unchanged(history, loaded, CONFIG_SHA)
    with path.open("a") as handle:
        handle.write(json.dumps({"event": "end", "t": 1040.0, "status": "ABORTED", "reason": "by operator"}) + "\n")
    ended = read_history(path)
    assert ended.ended == "ABORTED" and unfinished_runs(tmp_path) == []
    with pytest.raises(RunNotResumable, match="ended ABORTED: by operator"):
        resume_point(ended, loaded)


def test_a_live_run_is_never_offered_and_a_second_lock_is_refused(tmp_path: Path) -> None:
    path = interrupted_in_hold(tmp_path)
    lock = RunLock.acquire(path)
    try:
        assert unfinished_runs(tmp_path) == []
        with pytest.raises(RunNotResumable, match=r"is running \(or being resumed\) now"):
            RunLock.acquire(path)
    finally:
        lock.release()
    assert len(unfinished_runs(tmp_path)) == 1


def test_a_damaged_or_foreign_record_is_named_and_skipped(tmp_path: Path) -> None:
    write_record(tmp_path, "20260101T000000Z-000000", [{"event": "sample"}])
    bad = interrupted_in_hold(tmp_path, "20260101T000000Z-111111")
    bad.write_bytes(bad.read_bytes().replace(b'"step_end"', b'step_end"', 1))
    with pytest.raises(RunNotFound, match="does not begin with a 'start' record"):
        read_history(tmp_path / RUNS_DIR / "20260101T000000Z-000000.jsonl")
    with pytest.raises(RunNotFound, match="line 3 is not JSON"):
        read_history(bad)
    assert unfinished_runs(tmp_path) == []


# ---------------------------------------------------------------- a resumed run on the simulated node
def interrupt_in_the_hold(config: MillConfig, tmp_path: Path, text: str, done_s: float, step: int = 2) -> Path:
    """Run to ``done_s`` into step ``step``, then lose the service (nothing more is written: a SIGKILL)."""
    loaded = parse_recipe(text, "resume-test.toml")
    rig = Rig(config)
    try:
        runner = RecipeRunner(rig.controller, loaded, plan_recipe(loaded.recipe, config), rig.clock,
                              records_dir=tmp_path, config_sha256=CONFIG_SHA, text=text, sample_s=0.5)
        index = step - 1
        drive(rig, runner, 240.0, until=lambda: runner.index == index and runner._step_elapsed_now() >= done_s)
        assert runner.index == index and runner.state is RunState.RUNNING, runner.reason
        return runner.record.path
    finally:
        rig.close()


def resume_on_a_fresh_mill(config: MillConfig, path: Path, text: str) -> tuple[Rig, RecipeRunner]:
    """A new controller and node (the service and the mill restarted), then the run resumed from its record."""
    rig = Rig(config)
    rig.run(1.0)
    loaded = parse_recipe(text, "resume-test.toml")
    plan = plan_recipe(loaded.recipe, config)
    history = read_history(path)
    point = resume_point(history, loaded)
    check = preflight_resume(point, loaded, plan, rig.controller)
    assert check.ok, check.problems
    runner = RecipeRunner(rig.controller, loaded, plan, rig.clock, records_dir=path.parent.parent,
                          config_sha256=CONFIG_SHA, resume=point, sample_s=0.5)
    return rig, runner


def test_a_run_lost_mid_hold_resumes_with_its_time_credited_and_the_gap_recorded(
    config: MillConfig, tmp_path: Path
) -> None:
    text = recipe_text(hold_s=20.0)
    path = interrupt_in_the_hold(config, tmp_path, text, done_s=8.0)
    credited = read_history(path).step_elapsed_s
    assert 7.0 <= credited <= 8.0  # the last sample before the loss: at most one sample period is repeated
    time.sleep(0.05)  # a gap of wall time
    rig, runner = resume_on_a_fresh_mill(config, path, text)
    try:
        assert runner.run_id == path.stem and runner.index == 1
        drive(rig, runner, 240.0)
        assert runner.state is RunState.DONE, runner.reason
    finally:
        rig.close()
    records = list(read_records(path))
    events = [r["event"] for r in records if r["event"] != "sample"]
    assert events.count("start") == 1 and events[-1] == "end" and records[-1]["status"] == "DONE"
    gap = next(r for r in records if r["event"] == "gap")
    assert gap["step"] == 2 and gap["credited_s"] == credited and gap["gap_s"] >= 0.05
    assert gap["end_t"] - gap["start_t"] == pytest.approx(gap["gap_s"])
    assert "crash, a kill or a power loss" in gap["reason"]
    assert records[-1]["gap_s"] == pytest.approx(gap["gap_s"])
    # the hold's clock ran again only at its setpoints, for the time it still owed
    restored = next(r for r in records if r["event"] == "restored")
    hold_end = next(r for r in records if r["event"] == "step_end" and r["step"] == 2 and r["t"] > gap["t"])
    assert hold_end["clock_s"] - restored["clock_s"] == pytest.approx(20.0 - credited, abs=0.05)
    resumed_start = next(r for r in records if r["event"] == "step_start" and r.get("resumed"))
    assert resumed_start["step"] == 2 and resumed_start["credited_s"] == credited
    assert read_history(path).ended == "DONE" and unfinished_runs(tmp_path) == []


def test_the_restore_ramps_the_furnace_from_its_measured_temperature(config: MillConfig, tmp_path: Path) -> None:
    text = recipe_text(hold_s=10.0, furnace="furnace_c = 40.0\nheating_rate_c_per_min = 20.0")
    path = interrupt_in_the_hold(config, tmp_path, text, done_s=3.0)
    rig, runner = resume_on_a_fresh_mill(config, path, text)
    try:
        furnace = rig.controller.furnace
        assert furnace is not None
        measured_c = furnace.temp_c
        assert measured_c < 30.0  # the restarted furnace is cold
        drive(rig, runner, 10.0, until=lambda: runner._restore is not None)
        c = rig.controller
        assert c.furnace_target_c == 40.0 and c.furnace_setpoint_c < measured_c + 1.0  # not a step to 40 °C
        drive(rig, runner, 300.0, until=lambda: runner._restore is None)
        furnace = rig.controller.furnace
        assert furnace is not None and furnace.temp_c >= 37.0  # the hold waited for its band (40 ± 3 °C)
        drive(rig, runner, 240.0)
        assert runner.state is RunState.DONE, runner.reason
    finally:
        rig.close()


def test_a_resume_is_refused_while_the_mill_turns_or_is_tripped(config: MillConfig, tmp_path: Path) -> None:
    text = recipe_text()
    path = interrupt_in_the_hold(config, tmp_path, text, done_s=2.0)
    rig = Rig(config)
    try:
        rig.run(1.0)
        loaded = parse_recipe(text, "resume-test.toml")
        plan = plan_recipe(loaded.recipe, config)
        point = resume_point(read_history(path), loaded)
        rig.controller.arm()
        rig.run(1.0)
        rig.controller.set_speeds(30.0, 200.0)
        rig.run(10.0)
        problems = preflight_resume(point, loaded, plan, rig.controller).problems
        assert any("the mill is RUNNING" in p for p in problems)
        assert any("the drives are turning (measured ω_r " in p and "stop the mill" in p for p in problems)
        rig.controller.estop()
        rig.run(10.0)
        problems = preflight_resume(point, loaded, plan, rig.controller).problems
        assert any("TRIPPED" in p and "millctl reset" in p for p in problems)
    finally:
        rig.close()


def test_a_ramp_lost_mid_way_runs_again_from_standstill_to_its_target(config: MillConfig, tmp_path: Path) -> None:
    text = recipe_text(hold_s=2.0)
    path = interrupt_in_the_hold(config, tmp_path, text, done_s=1.0, step=1)
    rig, runner = resume_on_a_fresh_mill(config, path, text)
    try:
        assert runner.index == 0 and runner._restore is None  # no restore: the ramp itself is the way back
        drive(rig, runner, 240.0)
        assert runner.state is RunState.DONE, runner.reason
    finally:
        rig.close()
    records = list(read_records(path))
    resumed = next(r for r in records if r["event"] == "step_start" and r.get("resumed"))
    assert resumed["step"] == 1 and resumed["credited_s"] == 0.0
    assert [r["step"] for r in records if r["event"] == "step_end"] == [1, 2, 3]


def test_a_pause_during_the_restore_credits_nothing_and_the_restore_goes_on_after(
    config: MillConfig, tmp_path: Path
) -> None:
    text = recipe_text(hold_s=10.0)
    path = interrupt_in_the_hold(config, tmp_path, text, done_s=4.0)
    credited = read_history(path).step_elapsed_s
    rig, runner = resume_on_a_fresh_mill(config, path, text)
    try:
        drive(rig, runner, 10.0, until=lambda: runner._restore is not None)
        drive(rig, runner, 0.5)
        runner.pause(now=True)
        drive(rig, runner, 3.0)
        assert runner.progress()["step_elapsed_s"] == credited  # paused on the way back: the hold's clock stood
        runner.resume()
        drive(rig, runner, 240.0)
        assert runner.state is RunState.DONE, runner.reason
    finally:
        rig.close()
    records = list(read_records(path))
    restored = next(r for r in records if r["event"] == "restored")
    hold_end = next(r for r in records if r["event"] == "step_end" and r["step"] == 2 and r["t"] >= restored["t"])
    assert hold_end["clock_s"] - restored["clock_s"] == pytest.approx(10.0 - credited, abs=0.05)
