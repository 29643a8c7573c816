"""The run report plots the control loop's lateness beside the speeds and names a trip a late loop caused (SAFETY 27).

A demo run on the real node and the real controller (the in-process rig),
the service's host watch feeding each sample's lateness as the service does
(``RecipeSlot.sample_extra``). Mid-run the controller's loop is held back
0.6 s while the node ticks on: the node's watchdog stops the mill, the run
ends in a WATCHDOG trip, and the report names it host starvation with the
figures.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from millctl.cli import main
from millctl.config import MillConfig
from millctl.controller import ControllerState as S
from millctl.errors import ExitCode
from millctl.recipes import load_recipe, plan_recipe
from millctl.recipes.runner import RecipeRunner, RunState
from millctl.report import load_run, summary
from millctl.service.host import HostWatch
from millctl.service.sdnotify import Notifier
from tests.unit.recipes.test_runner import DEMO
from tests.unit.scenarios.rig import Rig

STARVED_S = 0.6


def test_a_trip_after_a_starved_loop_is_named_in_the_run_report(
    config: MillConfig, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rig = Rig(config)
    try:
        watch = HostWatch(config, lambda *args, **kwargs: {}, Notifier(path=""))
        loaded = load_recipe(DEMO)
        runner = RecipeRunner(rig.controller, loaded, plan_recipe(loaded.recipe, rig.config), rig.clock,
                              records_dir=tmp_path, config_sha256="0" * 64, sample_s=0.5)
        runner.sampler.extra = watch.sample

        def step(lateness_s: float = 0.001) -> None:
            rig.step()
            watch.tick(rig.clock.now(), lateness_s, rig.controller)
            runner.tick()

        for _ in range(round(8.0 / rig.dt_s)):
            step()
        assert runner.state is RunState.RUNNING
        for _ in range(round(STARVED_S / rig.dt_s)):  # the controller's loop held back, the node ticking on
            rig.node.tick()
            rig.clock.advance(rig.dt_s)
        step(STARVED_S)
        for _ in range(round(3.0 / rig.dt_s)):
            if runner.finished:
                break
            step()
        assert rig.controller.state is S.TRIPPED and "WATCHDOG" in rig.controller.trip_cause
        assert runner.state.name == RunState.FAILED.name  # (not `is`: mypy keeps the RUNNING narrowing above)
        record = runner.record.path
    finally:
        rig.close()
    run = load_run(record)
    lateness = [s["loop_lateness_ms"] for s in run.samples]
    assert max(lateness) == pytest.approx(STARVED_S * 1e3, abs=0.01) and min(lateness) < 5.0
    named = summary(run)["host_starvation"]
    assert named == (
        f"host starvation: the control loop ran {STARVED_S * 1e3:.0f} ms late; the node's watchdog allows 250 ms: "
        "the host is overloaded, see docs/deployment.md#real-time-priority"
    )
    out = tmp_path / "report"
    assert main(["report", str(record), "--out", str(out), "--json"]) == ExitCode.OK
    document = json.loads(capsys.readouterr().out)
    assert (out / "host.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert document["result"]["summary"]["host_starvation"] == named
    assert "host starvation: the control loop ran 600 ms late" in (out / "report.html").read_text()
