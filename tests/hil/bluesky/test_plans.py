"""Bluesky plans against a real ``millctl serve`` (embedded simulated node): milling, refusals, a recipe as a plan."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import bluesky.plan_stubs as bps
import pytest
from bluesky.run_engine import RunEngineResult
from bluesky.utils import FailedStatus
from ophyd_async.core import soft_signal_rw

from millctl.api import ControllerState, EventKind, RunState, StatusOut
from millctl.bluesky.plans import PreflightRefused, mill_and_measure, mill_at, ramp_through, run_recipe
from millctl.client import InterlockRefusal
from millctl.records import read_records
from tests.hil.bluesky.conftest import Engine
from tests.support.pace import stretched
from tests.support.service import REPO, Service, run_millctl, wait_for

EXAMPLE = REPO / "docs" / "examples" / "bluesky_mill_at.py"
TOLERANCE_RPM = 5.0
"""The Mill's default settle tolerance: a reading at the point is within this of it (rpm)."""


def _resting(status: StatusOut) -> bool:
    """Both targets 0 and both drives measured at rest (ARMED, or RUNNING at zero setpoints), not tripped."""
    return (status.state in (ControllerState.ARMED, ControllerState.RUNNING, ControllerState.DISABLED)
            and not status.target_rotary_rpm and not status.target_vibration_rpm
            and max(status.measured_rotary_rpm or 0.0, status.measured_vibration_rpm or 0.0) < 1.0)


def _at_rest(service: Service) -> None:
    seen: list[StatusOut] = []

    def resting() -> bool:
        seen[:] = [watch.status()]
        return _resting(seen[0])

    with service.client("watch") as watch:
        try:
            wait_for(resting, 60.0, "the mill at rest")
        except pytest.fail.Exception as exc:  # say where the mill is instead
            last = seen[0] if seen else None
            shown = "no status" if last is None else (
                f"{last.state}, targets {last.target_rotary_rpm}/{last.target_vibration_rpm} rpm, measured "
                f"{last.measured_rotary_rpm}/{last.measured_vibration_rpm} rpm, trip cause {last.trip_cause!r}")
            pytest.fail(f"{exc}: last status {shown}")


def test_the_example_mills_at_150_800_for_10_s_and_stores_the_readings_with_units(service: Service,
                                                                                 tmp_path: Path) -> None:
    with service.client("watch") as watch:
        sha256 = watch.service().config_sha256
        before = watch.events(after=0, limit=1).last_seq
    done = subprocess.run([sys.executable, str(EXAMPLE), "--socket", str(service.socket), "--rot-rpm", "150",
                           "--vib-rpm", "800", "--seconds", "10", "--out", str(tmp_path)], cwd=REPO,
                          capture_output=True, text=True, timeout=stretched(240.0), check=False)
    assert done.returncode == 0, done.stderr[-3000:]
    (stored,) = tmp_path.glob("*.jsonl")
    assert stored.with_suffix(".png").stat().st_size > 0
    documents: list[dict[str, Any]] = [json.loads(line) for line in stored.read_text().splitlines()]
    start = next(d["doc"] for d in documents if d["name"] == "start")
    assert start["plan_name"] == "mill_at"
    assert start["millctl_config_sha256"] == sha256
    assert start["millctl_events_after"] >= before
    (descriptor,) = [d["doc"] for d in documents if d["name"] == "descriptor"]
    keys = descriptor["data_keys"]
    assert (keys["mill-rotary"]["units"], keys["mill-vibration"]["units"]) == ("rpm", "rpm")
    assert (keys["mill-furnace"]["units"], keys["mill-margin_rpm"]["units"]) == ("degC", "rpm")
    assert descriptor["configuration"]["mill"]["data"]["mill-law"] == start["millctl_law"]
    events = [d["doc"] for d in documents if d["name"] == "event"]
    assert len(events) >= 10
    for event in events:
        data = event["data"]
        assert abs(data["mill-rotary"] - 150.0) <= TOLERANCE_RPM, data
        assert abs(data["mill-vibration"] - 800.0) <= TOLERANCE_RPM, data
        assert data["mill-state"] == "RUNNING"
        assert data["mill-margin_rpm"] > 0.0
        assert data["mill-event_seq"] > start["millctl_events_after"]
    assert events[-1]["time"] - events[0]["time"] >= 10.0  # the hold counted only time verified at the point
    stop = next(d["doc"] for d in documents if d["name"] == "stop")
    assert stop["exit_status"] == "success"
    _at_rest(service)
    with service.client("watch") as watch:
        assert not watch.control_state().held  # unstaged: the lease given back
        commands = [e for e in watch.events(after=before).events if e.kind is EventKind.COMMAND]
    assert commands and all(e.source.startswith("api:bluesky-example@") for e in commands)


def test_a_move_outside_the_envelope_fails_with_the_interlocks_refusal_and_nothing_moves(
        service: Service, engine: Engine) -> None:
    _at_rest(service)
    with service.client("operator") as operator, operator.control():
        if operator.status().state is ControllerState.DISABLED:
            operator.arm()
    mill = engine.connect(service.socket)
    with service.client("watch") as watch:
        before = watch.events(after=0, limit=1).last_seq
        state = watch.status().state
        with pytest.raises(FailedStatus) as failed:
            engine.RE(bps.mv(mill, (250.0, 800.0)))
        refusal = failed.value.__cause__
        assert isinstance(refusal, InterlockRefusal), repr(refusal)
        assert refusal.refusals and refusal.refusals[0].value == 250.0
        assert refusal.refusals[0].limit is not None and refusal.refusals[0].limit < 250.0
        with pytest.raises(FailedStatus) as failed:  # one axis alone: the other keeps its target (0)
            engine.RE(bps.mv(mill.rotary, 250.0))
        assert isinstance(failed.value.__cause__, InterlockRefusal), repr(failed.value.__cause__)
        with pytest.raises(PreflightRefused, match="before any move"):  # the plan: refused by the pre-flight
            engine.RE(mill_at(mill, 250.0, 800.0, duration_s=5.0))
        status = watch.status()
        assert _resting(status), status
        assert status.state is state
        since = watch.events(after=before).events
    assert [e.kind for e in since if e.kind is EventKind.REFUSAL]  # the interlock recorded it
    assert not [e for e in since if e.kind is EventKind.COMMAND and e.message.startswith("setpoints")]


RECIPE = """\
[recipe]
name = "bluesky vs recipe run"

[defaults]
rotary_rate_rpm_s = 40.0
vibration_rate_rpm_s = 120.0

[[steps]]
kind = "ramp"
rotary_rpm = 60.0
vibration_rpm = 300.0

[[steps]]
kind = "hold"
duration_s = 3

[[steps]]
kind = "ramp"
rotary_rpm = 100.0
vibration_rpm = 400.0

[[steps]]
kind = "hold"
duration_s = 2
"""


def _steps_and_outcome(record: Path) -> tuple[list[tuple[str, int, str]], str]:
    entries = list(read_records(record))
    steps = [(e["event"], e["step"], e["kind"]) for e in entries if e["event"] in ("step_start", "step_end")]
    (end,) = [e for e in entries if e["event"] == "end"]
    return steps, end["status"]


def test_a_recipe_as_a_plan_and_with_recipe_run_give_the_same_steps_and_outcome(
        service: Service, engine: Engine, tmp_path: Path) -> None:
    _at_rest(service)
    path = tmp_path / "short.toml"
    path.write_text(RECIPE, encoding="utf-8")
    mill = engine.connect(service.socket)
    result = engine.RE(run_recipe(mill, path, period_s=0.5))
    assert isinstance(result, RunEngineResult)
    progress = result.plan_result
    assert progress.state is RunState.DONE
    (start,) = engine.of("start")
    assert start["millctl_run_id"] == progress.run_id
    assert Path(start["millctl_run_record"]).name == f"{progress.run_id}.jsonl"
    steps = engine.of("event", "steps")
    assert [e["data"]["mill-run_id"] for e in steps] == [progress.run_id] * 4
    assert all(e["data"]["mill-run_id"] == progress.run_id for e in engine.of("event", "primary"))
    _at_rest(service)

    done = run_millctl(service.config, "recipe", "run", str(path), "--json", timeout_s=240.0)
    assert done.returncode == 0, done.stderr[-3000:]
    cli_run_id = json.loads(done.stdout)["result"]["run_id"]
    runs = service.records / "runs"
    as_plan = _steps_and_outcome(runs / f"{progress.run_id}.jsonl")
    as_cli = _steps_and_outcome(runs / f"{cli_run_id}.jsonl")
    assert as_plan == as_cli
    assert as_plan[1] == "DONE"
    assert [s[:2] for s in as_plan[0]] == [(e, n) for n in range(1, 5) for e in ("step_start", "step_end")]


def test_milling_with_measurement_pauses_the_drives_for_each_measurement_and_goes_on(
        service: Service, engine: Engine) -> None:
    _at_rest(service)
    mill = engine.connect(service.socket)
    xrd = soft_signal_rw(float, 42.0, name="xrd", units="counts")
    with service.client("watch") as watch:
        before = watch.events(after=0, limit=1).last_seq
        with pytest.raises(PreflightRefused, match="before any move"):  # the second point leaves the envelope
            engine.RE(ramp_through(mill, [(60.0, 300.0), (250.0, 800.0)], dwell_s=1.0))
        assert not [e for e in watch.events(after=before).events if e.kind is EventKind.COMMAND]
    engine.RE(mill_and_measure(mill, 60.0, 300.0, mill_s=3.0, cycles=2, detectors=[xrd], period_s=1.0))
    measurements = engine.of("event", "measurement")
    assert len(measurements) == 2
    for event in measurements:
        assert event["data"]["xrd"] == 42.0
        assert max(event["data"]["mill-rotary"], event["data"]["mill-vibration"]) < TOLERANCE_RPM  # drives paused
    milling = engine.of("event", "primary")
    assert milling and all(abs(e["data"]["mill-rotary"] - 60.0) <= TOLERANCE_RPM for e in milling)
    first, second = (m["time"] for m in measurements)
    assert any(first < e["time"] < second for e in milling)  # it went on milling between the measurements
    (stop,) = engine.of("stop")
    assert stop["exit_status"] == "success"
