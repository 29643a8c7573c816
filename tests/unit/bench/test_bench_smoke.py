"""Smoke test of the benchmark pieces on tiny inputs: the structure of the results, never a timing."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import pytest

from bench import cli, levels, node_budget, report, targets, work_precision
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


def _study_results() -> dict[str, object]:
    parallel = {
        "per_point_s": 0.05,
        "probe_points": 64,
        "workers": 2,
        "local": {"serial_s": [7.0, 7.2, 7.1], "pool_s": [4.0, 4.1, 3.9], "efficiency": 0.87, "speedup": 1.73,
                  "startup_s": 1.5, "points": 256, "efficiency_with_startup": 0.65},
        "dask": {"serial_s": [7.0], "pool_s": [5.0], "efficiency": 0.7, "speedup": 1.4, "startup_s": 3.0,
                 "points": 484, "efficiency_with_startup": 0.44},
        "rule_points": {"local": 240, "dask": 480},
    }  # fmt: skip
    return {
        "arrays": {"points": 10_000, "cam_phases": 4, "phases_per_point": 4.0, "cpu_s": 0.05, "wall_s": 0.1,
                   "points_per_cpu_s": 2e5},
        "arrays_integrated": {"points": 10_000, "cam_phases": 0, "phases_per_point": 66.4, "cpu_s": 5.0,
                              "wall_s": 5.5, "points_per_cpu_s": 2e3},
        "runner": {"points": 10_000, "cpu_s": 0.5, "wall_s": 1.0, "points_per_cpu_s": 2e4},
        "arrays_breakdown": {"points": 10_000, "cam_phases": 0, "cpu_s": 5.0, "kernel_cpu_s": 4.8, "kernel_share": 0.96,
                             "samples": 400_000, "kernel_us_per_sample": 12.0, "samples_per_point": 40.0,
                             "points_at_samples": {"16": 9_000, "≥ 129": 1_000},
                             "sample_share_at": {"16": 0.36, "≥ 129": 0.64}, "floor_points_per_cpu_s": 5.2e3},
        "integral_check": {"points": 600, "rtol": 0.01, "reference_phases": 1024, "within_power": 0.9,
                           "within_share": 0.95, "within_both": 0.88, "power_error_p95": 0.02, "power_error_max": 0.07,
                           "share_error_max": 0.036},
        "offline": {"scenes": 200, "events": 300, "cpu_s": 1.0, "events_per_cpu_s": 300.0, "reference_scenes": 10,
                    "reference_events_per_cpu_s": 3.0, "speedup": 100.0, "points": 9, "runner_events": 90,
                    "runner_cpu_s": 0.5, "runner_wall_s": 0.6, "runner_events_per_cpu_s": 180.0},
        "agreement_c": {"scenes": 1000, "agreeing": 999, "fraction": 0.999, "events": 50_000, "revolutions": 0.5,
                        "differences": ["paper 20.7/618.6 rpm, impact 238: reference rod 1; compiled rod 3"]},
        "parallel": parallel,
    }


def test_study_section_reports_the_array_path_the_runner_and_the_rule_for_workers() -> None:
    from bench import study

    text = "\n".join(study.report(_study_results()))
    assert "| 100 × 100 map, `evaluate_arrays`, 4 cam phases | 10,000 | 0.05 s | 0.1 s | 2e+05 |" in text
    integrated = "| the same integrated over the cam phase to 1 % (66 samples a point) | 10,000 | 5 s | 5.5 s | 2e+03 |"
    assert integrated in text
    assert "| 2 local processes | 256 (240) | 7.1 s | 4 s | 1.73× | 87% | 1.5 s | 65% |" in text
    assert "| 2-worker local Dask cluster | 484 (480) | 7 s | 5 s | 1.40× | 70% | 3 s | 44% |" in text
    assert "c measured first on a 64-point study" in text
    assert "the compiled integral (`kernels.phase_integral`, the rule and its samples) takes 96% of the CPU" in text
    assert "(4.8 of 5 s; 400,000 cam-phase samples, 40 a point, at 12 µs each, the rule's bookkeeping included)" in text
    assert "16: 9,000 (36%), ≥ 129: 1,000 (64%)" in text and "at 5.2e+03 points per CPU second" in text
    checked = "against 1,024 fixed cam phases on 600 random points of the map: the milling power within 1% on 90.0%"
    assert checked in text
    assert "both on 88.0%; the power's error 0.02 at the 95th percentile, 0.07 at worst; the share's 0.036" in text
    assert "N·c ≥ 4·w·S" in text and "two workers pay from 240 / 480 level-(c) points" in text
    assert study.worth_workers_rule(0.05, 1.5, 2) == 240  # 4 · 2 · 1.5 s / 0.05 s
    assert "| level (c) through `StudyRunner`, 9 points, one worker | 9 | 0.5 s | 0.6 s | 180 events/s |" in text
    assert "compiled many-event kernel: 300 events per CPU second" in text and "100× the reference" in text
    assert "999 of 1000 random scenes (99.90%" in text
    assert "- differs: paper 20.7/618.6 rpm, impact 238" in text
    assert "study" in cli.build_parser().format_help()


def test_parallel_sizes_each_study_from_the_rule_it_prints(monkeypatch: pytest.MonkeyPatch) -> None:
    from bench import study
    from millctl.studies import SerialBackend

    class Pool:
        workers = 2

    sizes: list[int] = []

    def run_s(st: object, backend: object) -> float:
        sizes.append(st.parameters["rotary_rpm"].grid.num)  # type: ignore[attr-defined]
        return 1.0 if isinstance(backend, SerialBackend) else 0.55

    monkeypatch.setattr(study, "per_point_s", lambda: 0.002)
    monkeypatch.setattr(study, "_started", lambda key, w: (Pool(), lambda: None, 1.5 if key == "local" else 2.5))
    monkeypatch.setattr(study, "_run_s", run_s)
    p = study.parallel(pairs=1)
    assert p["rule_points"] == {"local": 6000, "dask": 10000}  # 4 · 2 · S / c
    assert p["local"]["points"] == 78 * 78 and p["dask"]["points"] == 100 * 100  # the smallest squares ≥ the rule
    assert sizes == [78, 78, 100, 100]
    assert p["local"]["efficiency"] == pytest.approx(1.0 / (2 * 0.55))
    assert p["dask"]["efficiency_with_startup"] == pytest.approx(1.0 / (2 * (0.55 + 2.5)))
    assert p["local"]["loadavg_start"] >= 0.0 and p["dask"]["loadavg_end"] >= 0.0
    text = "\n".join(study.report(_study_results() | {"parallel": p}))
    assert "at the start and the end of each pool's pairs: local " in text
    sizes.clear()
    capped = study.parallel(pairs=1, max_points=900)
    assert sizes == [30, 30, 30, 30] and capped["rule_points"]["dask"] == 10000
    assert "Measured below the rule (local, dask" in "\n".join(study.report(_study_results() | {"parallel": capped}))


def test_every_issue_40_target_is_printed_with_measured_target_and_met() -> None:
    res = {"command": "t", "quick": True, "duration_s": 0.0, "machine": _machine(), "study": _study_results()}
    res["compiled"] = {
        "batch": {"one": {"events_per_cpu_s": 6e5}, "all": {"events_per_cpu_s": 1.5e5}},
        "public_api": {"us_per_event": 9.5, "one_rod": {"us_per_event": 2.5}},
    }
    res["loads"] = {"compiled": {"loadavg": [3.5, 3.0, 2.0], "cpus": 2}, "study": {"loadavg": [4.25, 3.0, 2.0]}}
    text = "\n".join(targets.report(res))
    assert text.startswith("## Issue 40 targets")
    assert "| batch kernel, one rod's event (events/s/core) | 6e+05 | ≥ 5e+05 | yes |" in text
    assert "| batch kernel, a whole six-rod scene (scenes/s/core) | 1.5e+05 | ≥ 2e+05 | **no** |" in text
    assert "| one event through the public API, one rod's event (`EventCall`) (µs) | 2.5 | ≤ 3 | yes |" in text
    six = "| one event through the public API, a whole six-rod scene (`first_impact`) (µs) | 9.5 | ≤ 3 | **no** |"
    assert six in text
    assert "| 100×100 level-(b) map, 4 cam phases (points/s/core) | 2e+05 | ≥ 1e+05 | yes |" in text
    assert (
        "| 100×100 level-(b) map, integrated over the cam phase to 1 % (points/s/core) | 2e+03 | ≥ 1e+05 | **no** |"
        in text
    )
    assert "| parallel efficiency, 2-worker local Dask cluster (share) | 0.7 | ≥ 0.8 | **no** |" in text
    assert "| level (c) simulation (events/s/core) | 300 | ≥ 1e+05 | **no** |" in text
    assert "| level (c) agrees event for event (share of scenes) | 0.999 | ≥ 0.999 | yes |" in text
    assert "compiled 3.50; study 4.25" in text


def test_write_docs_refuses_the_figures_of_a_loaded_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    docs = tmp_path / "benchmarks.md"
    docs.write_text("the committed figures\n")
    monkeypatch.setattr(cli, "DOCS", docs)
    machine = _machine() | {"cpu_count": 2, "loadavg": [16.0, 15.0, 14.0]}
    path = tmp_path / "r.json"
    path.write_text(json.dumps({"command": "t", "quick": True, "duration_s": 0.0, "machine": machine}))
    assert cli.main(["--from-json", str(path), "--write-docs", "--plots", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "1-minute load average was 16.00 at the start of this run on 2 CPUs, above the threshold 1.50" in err
    assert docs.read_text() == "the committed figures\n"
    quiet = machine | {"loadavg": [0.3, 0.2, 0.1]}
    run = {"command": "t", "quick": True, "duration_s": 0.0, "machine": quiet}
    path.write_text(json.dumps(run | {"loads": {"compiled": {"loadavg": [9.0, 3.0, 1.0], "cpus": 2}}}))
    assert cli.main(["--from-json", str(path), "--write-docs", "--plots", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "was 9.00 at the start of compiled of this run on 2 CPUs, above the threshold 5.50" in err
    # a piece may start with the previous one's workers and hil processes still in the average
    path.write_text(json.dumps(run | {"loads": {"compiled": {"loadavg": [4.0, 3.0, 1.0], "cpus": 2}}}))
    assert cli.main(["--from-json", str(path), "--write-docs", "--plots", str(tmp_path)]) == 0
    assert docs.read_text().startswith("# Benchmarks")


def test_study_section_reports_the_slide_step_against_its_error_and_its_cost() -> None:
    from bench import study

    results = _study_results()
    results["slide_precision"] = {
        "cases": 24, "scenes": 40, "friction": 0.3, "default": 32,
        "rows": [{"steps": 8, "max_dt_s": 2.1e-7, "max_dtheta_rad": 3.6e-6, "missed": 1, "events_per_cpu_s": 7250.0,
                  "real_time_factor": 753.0},
                 {"steps": 32, "max_dt_s": 7.6e-10, "max_dtheta_rad": 1.3e-8, "missed": 0, "events_per_cpu_s": 2110.0,
                  "real_time_factor": 212.0}],
    }  # fmt: skip
    text = "\n".join(study.report(results))
    assert "the first departure of 24 one-rod scenes that slide and leave (200/800, 250/600" in text
    assert "| 8 | 2.1e-07 (1 not left) | 3.6e-06 | 7.25e+03 | 753 |" in text
    assert "| 32 (default) | 7.6e-10 | 1.3e-08 | 2.11e+03 | 212 |" in text
