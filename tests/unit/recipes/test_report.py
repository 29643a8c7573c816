"""The run record's samples and ``millctl report``: figures and a self-contained page from the record alone."""

from __future__ import annotations

import itertools
import json
import math
from pathlib import Path

import pytest

from millctl.cli import main
from millctl.config import MillConfig
from millctl.errors import ExitCode, InvalidInputError
from millctl.recipes import load_recipe, plan_recipe
from millctl.recipes.runner import RecipeRunner, RunState
from millctl.records import read_records
from millctl.report import FIGURES, load_run, summary
from tests.unit.recipes.test_runner import DEMO, drive
from tests.unit.scenarios.rig import Rig


@pytest.fixture(scope="module")
def demo_record(config: MillConfig, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One run of the demo recipe on the simulated node (~2 s of CPU), read by every test here, written by none."""
    rig = Rig(config)
    try:
        loaded = load_recipe(DEMO)
        plan = plan_recipe(loaded.recipe, rig.config)
        runner = RecipeRunner(rig.controller, loaded, plan, rig.clock, records_dir=tmp_path_factory.mktemp("demo"),
                              config_sha256="0" * 64, sample_s=0.5)
        drive(rig, runner, 120.0)
        assert runner.state is RunState.DONE, runner.reason
        return runner.record.path
    finally:
        rig.close()


def test_the_run_record_has_samples_at_the_configured_rate(demo_record: Path) -> None:
    records = list(read_records(demo_record))
    samples = [r for r in records if r["event"] == "sample"]
    elapsed = records[-1]["elapsed_s"]
    assert records[0]["sample_s"] == 0.5
    assert len(samples) == pytest.approx(elapsed / 0.5, abs=2)
    times = [s["t_s"] for s in samples]
    assert times == sorted(times) and all(0.45 <= b - a <= 0.55 for a, b in itertools.pairwise(times))
    wanted = {"setpoint_rotary_rpm", "measured_rotary_rpm", "limit_rotary_rpm", "margin_rpm", "furnace_temp_c",
              "impact_rate_hz", "impact_energy_mj", "dose_j_g"}
    assert wanted <= set(samples[0])
    doses = [s["dose_j_g"] for s in samples]
    assert doses == sorted(doses) and doses[-1] > 0.0  # the dose accumulates while the rods fly
    # the limit is the one at the measured ω_v: the measured speed never sits above it on the demo
    assert min(s["margin_rpm"] for s in samples if s["margin_rpm"] is not None) > -5.0


def test_report_writes_the_figure_set_and_a_self_contained_page(demo_record: Path, tmp_path: Path,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "report"
    assert main(["report", str(demo_record), "--out", str(out), "--json"]) == ExitCode.OK
    document = json.loads(capsys.readouterr().out)
    files = [Path(f) for f in document["result"]["files"]]
    assert {f.name for f in files} == {f"{n}.png" for n in FIGURES} | {"report.png", "report.html"}
    for png in (f for f in files if f.suffix == ".png"):
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    page = (out / "report.html").read_text()
    assert page.count("data:image/png;base64,") == len(FIGURES) and "src=\"http" not in page
    assert "demo" in page and "DONE" in page and "step_start" in page
    run_summary = document["result"]["summary"]
    assert run_summary["status"] == "DONE" and run_summary["trips"] == 0
    assert run_summary["dose_kj_g"] > 0.0 and math.isfinite(run_summary["min_margin_rpm"])


def test_a_file_that_is_not_a_run_record_is_named(tmp_path: Path) -> None:
    bogus = tmp_path / "events.jsonl"
    bogus.write_text('{"event": "service"}\n')
    with pytest.raises(InvalidInputError, match=r"events\.jsonl.*start"):
        load_run(bogus)
    assert main(["report", str(tmp_path / "nope.jsonl")]) == ExitCode.INVALID_INPUT


def test_summary_counts_trips_and_refusals(demo_record: Path) -> None:
    run = load_run(demo_record)
    run.events.append({"event": "trip", "t_s": 3.0, "cause": "test"})
    assert summary(run)["trips"] == 1
