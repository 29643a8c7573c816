"""Design-study throughput: points/s and events/s per core for a 100 × 100 map of (ω_r, ω_v).

The map is ω_r 20–300 rpm × ω_v 200–1200 rpm on Set A (corrected), every level-(a)
and level-(b) metric (the heat-map study of docs/studies.md), run by
``millctl.studies`` on every local core. The baseline, measured in the same run,
is one in-process worker on a strided 10 × 10 subset of the same map: the ratio
of per-core rates is the pool's parallel efficiency. Level (c) (the multi-rod
simulation, one revolution a point) is timed on a 3 × 3 grid of ω_r 120–200 ×
ω_v 400–800 rpm, one worker (at a few rpm the model's micro-hops make thousands
of events per revolution).
An event is one detachment-and-first-contact sample of a level-(b) summary
(``cam_phases`` per point) or one detachment or impact of the simulation.
``--quick`` runs the 10 × 10 subset in place of the full map.
"""

from __future__ import annotations

import time
from typing import Any

from bench.common import bench_config
from millctl.studies import SerialBackend, Study, StudyRunner
from millctl.studies.backends import Backend, LocalBackend, local_cores

MAP = {"rotary_rpm": (20.0, 300.0), "vibration_rpm": (200.0, 1200.0)}
"""The (ω_r, ω_v) ranges of the map (rpm)."""


OFFLINE = {"rotary_rpm": (120.0, 200.0), "vibration_rpm": (400.0, 800.0)}
"""Level (c) is timed away from the micro-hops of a few rpm (thousands of events per revolution)."""


def _study(
    num: int, metrics: list[str] | None = None, revolutions: float = 1.0, ranges: dict[str, tuple[float, float]] = MAP
) -> Study:
    parameters = {name: {"grid": {"start": lo, "stop": hi, "num": num}} for name, (lo, hi) in ranges.items()}
    data: dict[str, Any] = {
        "study": {"name": f"{num} x {num} map", "variant": "corrected", "seed": 1},
        "parameters": parameters,
        "metrics": {"revolutions": revolutions, **({"names": metrics} if metrics else {})},
        "constraints": {"law": "corrected-best-phase"},
        "objective": {"maximize": "dose_rate_j_g_s"},
    }
    return Study.model_validate(data)


def _timed(study: Study, backend: Backend) -> dict[str, Any]:
    runner = StudyRunner(study, bench_config(), "bench")
    start = time.perf_counter()
    result = runner.run(backend)
    elapsed = time.perf_counter() - start
    events = sum(int(r["events"]) for r in result.rows)
    points = len(result.rows)
    return {
        "points": points,
        "events": events,
        "workers": backend.workers,
        "backend": backend.name,
        "elapsed_s": elapsed,
        "points_per_s": points / elapsed,
        "events_per_s": events / elapsed,
        "points_per_s_per_core": points / elapsed / backend.workers,
        "events_per_s_per_core": events / elapsed / backend.workers,
    }


def run(quick: bool) -> dict[str, Any]:
    """Time the map on every core, the serial baseline, and level (c)."""
    baseline = _timed(_study(10), SerialBackend())
    cores = local_cores()
    pool: Backend = SerialBackend() if cores == 1 else LocalBackend(cores)
    try:
        mapped = _timed(_study(10 if quick else 100), pool)
    finally:
        pool.close()
    sim_metrics = ["impact_energy_p10_j", "impact_energy_p90_j", "sim_impact_rate_hz"]
    offline = _timed(_study(3, sim_metrics, ranges=OFFLINE), SerialBackend())
    return {
        "map": mapped,
        "baseline": baseline,
        "offline": offline,
        "parallel_efficiency": mapped["points_per_s_per_core"] / baseline["points_per_s_per_core"],
        "speedup_vs_one_worker": mapped["points_per_s"] / baseline["points_per_s"],
    }


def report(st: dict[str, Any]) -> list[str]:
    """The benchmark document's section."""
    m, b, o = st["map"], st["baseline"], st["offline"]

    def row(label: str, r: dict[str, Any]) -> str:
        return (
            f"| {label} | {r['points']:,} | {r['backend']} × {r['workers']} | {r['elapsed_s']:.1f} s "
            f"| {r['points_per_s']:.3g} | {r['points_per_s_per_core']:.3g} | {r['events_per_s_per_core']:.3g} |"
        )

    return [
        "## 4. Design-study throughput",
        "",
        "`millctl study` on Set A (corrected), ω_r 20–300 rpm × ω_v 200–1200 rpm, the level-(a) and level-(b) "
        "metrics of the heat-map study (bench/study.py). An event is one detachment-and-first-contact sample "
        "(level b) or one detachment or impact (level c).",
        "",
        "| run | points | backend | time | points/s | points/s per core | events/s per core |",
        "|---|---|---|---|---|---|---|",
        row(f"map {round(m['points'] ** 0.5)} × {round(m['points'] ** 0.5)}", m),
        row("baseline 10 × 10, one worker", b),
        row("level (c) 3 × 3 (ω_r 120–200, ω_v 400–800, 1 revolution), one worker", o),
        "",
        f"All cores against one worker: {st['speedup_vs_one_worker']:.3g}× the points/s; per-core efficiency "
        f"{st['parallel_efficiency']:.0%} (the pool's start-up and the machine's load included).",
        "",
    ]


__all__ = ["MAP", "OFFLINE", "report", "run"]
