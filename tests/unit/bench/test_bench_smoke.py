"""Smoke test of the benchmark pieces on tiny inputs: the structure of the results, never a timing."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import pytest

from bench import cli, levels, node_budget, report, work_precision
from bench.common import corrected_model
from bench.scenes import hard_scenes, lhs_scenes
from millctl.physics.methods import ImpactEvent

VERDICTS = {"matched", "missed", "spurious", "none"}


def _event(t: float, rod: int = 0, partner: int = -1) -> ImpactEvent:
    return ImpactEvent(t, rod, partner, 0.0, 0.3, 0.1, 0.2, 1e-4, "test")


def test_scene_set_is_seeded_and_has_the_hard_cases() -> None:
    model = corrected_model()
    a, b = lhs_scenes(model, 5), lhs_scenes(model, 5)
    assert [s.scene for s in a] == [s.scene for s in b]
    assert a[0].scene.model.eccentricity_m == 0.0  # every 4th has r_d = 0 (closed-form reference)
    names = {s.name for s in hard_scenes(model)}
    assert {"near-limit", "gamma-1.5", "packing-limit", "slow-long-flight"} <= names


def test_classify_counts_early_events_as_spurious_and_late_ones_as_missed() -> None:
    ref = _event(1.0)
    assert work_precision.classify(_event(1.0 + 1e-6), ref, flight_s=0.1, slack_s=0.0) == "matched"
    assert work_precision.classify(_event(0.5), ref, flight_s=0.1, slack_s=0.0) == "spurious"
    assert work_precision.classify(_event(1.5), ref, flight_s=0.1, slack_s=0.0) == "missed"
    assert work_precision.classify(None, ref, flight_s=0.1, slack_s=0.0) == "missed"
    assert work_precision.classify(_event(1.0, 1, 0), _event(1.0, 0, 1), 0.1, 0.0) == "matched"  # unordered pair
    assert work_precision.classify(_event(0.2), None, math.nan, 0.0) == "spurious"


def test_pareto_interpolation() -> None:
    front = work_precision.pareto([(1.0, 1e-3), (2.0, 1e-6), (3.0, 1e-5), (4.0, 1e-9)])
    assert front == [(1.0, 1e-3), (2.0, 1e-6), (4.0, 1e-9)]
    assert work_precision.cost_at_error(front, 1e-2) == 1.0  # looser than the cheapest point
    assert math.isnan(work_precision.cost_at_error(front, 1e-12))  # out of reach
    assert 1.0 < work_precision.cost_at_error(front, 1e-4) < 2.0


def test_work_precision_on_two_scenes(monkeypatch: pytest.MonkeyPatch) -> None:
    settings = [
        work_precision.Setting("exact", "tol=4ulp", {"tol": 0.0}),
        work_precision.Setting("legacy", "dt=0.001", {"dt": 1e-3}),
        work_precision.Setting("ivp", "rtol=1e-06", {"tol": 1e-6}),
    ]
    monkeypatch.setattr(work_precision, "sweeps", lambda quick: settings)
    model = corrected_model()
    scenes = [s for s in hard_scenes(model) if s.name in ("near-limit", "slow-long-flight")]  # one rod: quick
    res = work_precision.run(scenes, quick=True)
    assert {r["verdict"] for r in res["rows"]} <= VERDICTS
    assert len(res["rows"]) == len(scenes) * len(settings)
    assert [s["method"] for s in res["summary"]] == ["exact", "legacy", "ivp"]
    for s in res["summary"]:
        assert s["matched"] + s["missed"] + s["spurious"] <= s["scenes"]
        assert s["seconds_per_event"] > 0.0
    assert set(res["headline"]) == {"time_s", "point_m", "energy_rel"}
    text = report.render(
        {"command": "test", "quick": True, "duration_s": 1.0, "machine": _machine()}
        | {"work_precision": json.loads(json.dumps(res, default=str))}
    )
    assert "## 1. Work–precision" in text and "| exact | tol=4ulp |" in text
    figures = report.issue17_figures({"work_precision": res})
    assert set(figures["missed_events"]) == {"exact", "legacy", "ivp"}
    assert figures["missed_events"]["exact"]["tol=4ulp"] == 0
    assert "## Compiled engine (issue 17)" in text


def test_independent_reference_finds_the_closed_form_landing() -> None:
    """The independent reference (dense scan + mpmath, never an engine's answer) against r_d = 0's closed form."""
    from bench.independent import independent_first_impact
    from bench.references import closed_form_wall_landing

    scene = next(s for s in hard_scenes(corrected_model()) if s.name == "slow-long-flight").scene
    import dataclasses

    flat = dataclasses.replace(scene, model=dataclasses.replace(scene.model, eccentricity_m=0.0))
    ind = independent_first_impact(flat)
    closed = closed_form_wall_landing(flat, 0)
    assert ind is not None and closed is not None
    assert (ind.rod, ind.partner) == (0, -1)
    assert abs(ind.time_s - closed.time_s) < 1e-15


def test_failures_count_as_infinite_error_in_the_medians() -> None:
    setting = work_precision.Setting("ivp", "rtol=1e-06", {"tol": 1e-6})
    rows = [
        {
            "method": "ivp",
            "setting": "rtol=1e-06",
            "seconds": 1.0,
            "verdict": "matched",
            "time_s": 1e-9,
            "point_m": 0.0,
            "energy_rel": 0.0,
            "v_n_rel": 0.0,
        },
        {"method": "ivp", "setting": "rtol=1e-06", "seconds": 1.0, "verdict": "missed"},
        {"method": "ivp", "setting": "rtol=1e-06", "seconds": 1.0, "verdict": "spurious"},
    ]
    summary = work_precision.summarise(rows, [setting])[0]
    assert summary["time_s_median"] == math.inf and summary["missed"] == 1 and summary["spurious"] == 1


def _machine() -> dict[str, object]:
    from bench.common import machine

    return machine()


def test_levels_and_node_budget_structure() -> None:
    lv = {
        "interlock": levels.interlock(1000, 1),
        "telemetry": levels.telemetry(1, 1),
        "offline": levels.offline(0.05, 1),
    }
    assert lv["interlock"]["scalar_and_vector_agree"]
    assert lv["interlock"]["speedup_vector_vs_scalar"] > 0.0
    base = lv["interlock"]["scalar_s_per_point"]
    lv["vs_scalar_interlock"] = {
        "interlock_vector_per_point": 1.0,
        "telemetry_summary": lv["telemetry"]["median_s"] / base,
        "telemetry_cache_hit": 1.0,
        "offline_per_event": 1.0,
    }
    run = node_budget._stepped_run("inline", 0.1)
    assert run["ticks"] > 0 and run["realtime_factor"] > 0.0 and run["controller_state"] == "RUNNING"
    nb = {"target_rpm": [150.0, 800.0], "hold_s": 0.1, "thread": run, "inline": run}
    nb |= {"inline_over_thread_tick_mean": 1.0, "inline_over_thread_tick_max": 1.0}
    res = {"command": "t", "quick": True, "duration_s": 1.0, "machine": _machine(), "levels": lv, "node_budget": nb}
    text = report.render(res)
    assert "## 2. Levels of detail" in text and "### Node tick budget" in text
    # The figures measured above are the ones printed (read back from the text, to 3 significant digits).
    i = lv["interlock"]
    assert i["vector_s_per_point"] * i["points"] == pytest.approx(i["vector_s_total"], rel=1e-9)
    printed_speedup = re.search(r"Vectorised interlock vs scalar: \*\*([0-9.e+-]+)×\*\*", text)
    assert printed_speedup is not None
    assert float(printed_speedup[1]) == pytest.approx(i["speedup_vector_vs_scalar"], rel=5e-3)
    printed_scalar_us = re.search(r"scalar, per point \| ([0-9.e+-]+) µs \| 1 \|", text)
    assert printed_scalar_us is not None
    assert float(printed_scalar_us[1]) == pytest.approx(i["scalar_s_per_point"] * 1e6, rel=5e-3)
    for worker in ("thread", "inline"):
        row = re.search(rf"^\| {worker} \| (\d+) \| ([0-9.e+-]+) ms \|", text, re.MULTILINE)
        assert row is not None, f"no node-budget row for the {worker} worker"
        assert int(row[1]) == run["ticks"]
        assert float(row[2]) == pytest.approx(run["tick_mean_s"] * 1e3, rel=5e-3)


def test_cli_renders_a_saved_results_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "r.json"
    path.write_text(json.dumps({"command": "t", "quick": True, "duration_s": 0.0, "machine": _machine()}))
    assert cli.main(["--from-json", str(path)]) == 0
    assert capsys.readouterr().out.startswith("# Benchmarks")


def test_safety_piece_says_why_it_did_not_run(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    from bench import safety_timing

    monkeypatch.setattr(safety_timing, "SUITE", tmp_path / "absent.py")
    monkeypatch.setattr(safety_timing, "ROOT", tmp_path)
    assert "skipped" in safety_timing.hil_trials(1, progress=lambda _: None)
    computed = {"periodic_load": 0.03, "total_load": 0.04, "event_rate_hz": 10.0, "target_load": 0.15, "frames": []}
    st = {"hil": {"skipped": "not there"}, "bus_load": {"computed": computed, "skipped": "no netns"}}
    text = report.render({"command": "t", "quick": True, "duration_s": 0.0, "machine": _machine(), "safety_timing": st})
    assert "Not measured: not there" in text and "Measured: not run (no netns)" in text


def test_millctl_bench_is_an_alias(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from millctl.cli import main as millctl_main

    path = tmp_path / "r.json"
    path.write_text(json.dumps({"command": "t", "quick": True, "duration_s": 0.0, "machine": _machine()}))
    assert millctl_main(["bench", "--from-json", str(path)]) == 0
    assert capsys.readouterr().out.startswith("# Benchmarks")


def test_study_section_reports_points_and_events_per_core() -> None:
    from bench import study

    def run(points: int, events: int, workers: int, elapsed: float, name: str) -> dict[str, object]:
        return {
            "points": points, "events": events, "workers": workers, "backend": name, "elapsed_s": elapsed,
            "points_per_s": points / elapsed, "events_per_s": events / elapsed,
            "points_per_s_per_core": points / elapsed / workers, "events_per_s_per_core": events / elapsed / workers,
        }  # fmt: skip

    res = {
        "map": run(10_000, 40_000, 2, 100.0, "local"),
        "baseline": run(100, 400, 1, 2.0, "serial"),
        "offline": run(9, 300, 1, 1.0, "serial"),
        "parallel_efficiency": 1.0,
        "speedup_vs_one_worker": 2.0,
    }
    text = "\n".join(study.report(res))
    assert "| map 100 × 100 | 10,000 | local × 2 | 100.0 s | 100 | 50 | 200 |" in text
    assert "per-core efficiency 100%" in text
    assert "study" in cli.build_parser().format_help()
