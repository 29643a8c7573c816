"""Item 1, work–precision: error of the first impact against a reference versus the time per event.

Every method answers the same question on every scene (:mod:`bench.scenes`) —
"which is the first impact?" — through :func:`millctl.physics.methods.first_impact`;
the time of one call (detachment search included, the same for every method) is
the time per event. Errors are taken against :mod:`bench.references`. An event
counts as *matched* when it names the reference's pair and lies within
max(½ flight, 2 × slack) of it (slack: the legacy step dt or the exact engine's
time tolerance); otherwise it is *spurious* when it comes earlier than the
reference (or where the reference has none) and *missed* when it comes later or
not at all.
"""

from __future__ import annotations

import math
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bench.references import Reference, reference
from bench.scenes import BenchScene
from millctl.physics import kernels
from millctl.physics.detachment import find_detachment
from millctl.physics.methods import ImpactEvent, first_impact
from millctl.physics.simulate import simulate

ERROR_FLOOR = 1e-17
"""Errors below this (exact agreement in binary64) are drawn at the floor on the log plot."""

TINY_DT_S = 1e-8
"""The tiny step MODEL-NOTES warns about, run on the one-rod hard cases only (cost ∝ 1/dt)."""


@dataclass(frozen=True)
class Setting:
    """One point of a method's sweep."""

    method: str
    label: str
    kwargs: dict[str, float] = field(default_factory=dict)
    only_one_rod: bool = False

    @property
    def slack_s(self) -> float:
        """What the setting may be off by (s): a legacy step, the exact engine's time tolerance; 0 for ivp's rtol."""
        if self.method in ("exact", "exact-reference"):
            return float(self.kwargs.get("tol", 0.0))
        return float(self.kwargs.get("dt", 0.0))


def sweeps(quick: bool) -> list[Setting]:
    """The sweep of each method: dt for the paper's scheme, q for its arc wall, tolerances for the others."""
    tols = [1e-3, 1e-9, 0.0] if quick else [1e-3, 1e-5, 1e-7, 1e-9, 1e-11, 0.0]
    dts = [1e-3, 1e-4, 1e-5] if quick else [1e-3, 3e-4, 1e-4, 3e-5, 1e-5, 3e-6, 1e-6]
    interp_dts = [1e-3, 1e-4] if quick else [1e-3, 1e-4, 1e-5]
    arcs_dt = 1e-4 if quick else 1e-5
    qs = [36, 360] if quick else [24, 60, 180, 360, 1080]
    ivp_tols = [1e-6, 1e-10] if quick else [1e-4, 1e-6, 1e-8, 1e-10, 1e-12]
    out = [Setting("exact", f"tol={t:g}" if t else "tol=4ulp", {"tol": t}) for t in tols]
    out += [Setting("exact-reference", f"tol={t:g}" if t else "tol=4ulp", {"tol": t}) for t in (1e-9, 0.0)]
    out += [Setting("legacy", f"dt={d:g}", {"dt": d}) for d in dts]
    out += [Setting("legacy-compiled", f"dt={d:g}", {"dt": d}) for d in dts]
    out += [Setting("legacy-interp", f"dt={d:g}", {"dt": d}) for d in interp_dts]
    out += [Setting("legacy-arcs", f"q={q} dt={arcs_dt:g}", {"dt": arcs_dt, "q": q}) for q in qs]
    out += [Setting("ivp", f"rtol={t:g}", {"tol": t}) for t in ivp_tols]
    out.append(Setting("legacy", f"dt={TINY_DT_S:g}", {"dt": TINY_DT_S}, only_one_rod=True))
    return out


def _flight_s(bs: BenchScene, ref: ImpactEvent) -> float:
    """Time from the reference rod's detachment to the reference impact (s)."""
    run = simulate(bs.scene, ref.time_s + 1e-9, stop_after_first=True)
    starts = [float(r["time_s"]) for r in run.detachments if int(r["rod"]) == ref.rod]
    return ref.time_s - (starts[0] if starts else 0.0)


def classify(event: ImpactEvent | None, ref: ImpactEvent | None, flight_s: float, slack_s: float) -> str:
    """One of matched, missed, spurious or none (both found nothing); see the module docstring."""
    if ref is None:
        return "none" if event is None else "spurious"
    if event is None:
        return "missed"
    same_pair = {event.rod, event.partner} == {ref.rod, ref.partner}
    if same_pair and abs(event.time_s - ref.time_s) <= max(0.5 * flight_s, 2.0 * slack_s):
        return "matched"
    return "spurious" if event.time_s < ref.time_s else "missed"


def errors(event: ImpactEvent, ref: ImpactEvent) -> dict[str, float]:
    """Time (s), contact point (m), relative energy and relative normal-velocity errors of a matched event.

    The normal velocity's error separates a scheme's own error from how it books the
    energy (m_eff depends on whether it thinks the partner is held by the wall).
    """
    e_scale = abs(ref.energy_j) if ref.energy_j != 0.0 else 1.0
    v_scale = abs(ref.normal_velocity_m_s) if ref.normal_velocity_m_s != 0.0 else 1.0
    return {
        "time_s": abs(event.time_s - ref.time_s),
        "point_m": math.hypot(event.x_m - ref.x_m, event.y_m - ref.y_m),
        "energy_rel": abs(event.energy_j - ref.energy_j) / e_scale,
        "v_n_rel": abs(abs(event.normal_velocity_m_s) - abs(ref.normal_velocity_m_s)) / v_scale,
    }


def detachment_seconds(bs: BenchScene, repeats: int) -> dict[str, float]:
    """The shared detachment search alone (every rod, to the 5 s horizon): numpy reference and compiled."""
    scene = bs.scene
    rods = [scene.rod_theta0_rad(i) for i in range(scene.model.n_rods)]

    def numpy_search() -> None:
        for theta0 in rods:
            find_detachment(scene, theta0, 0.0, 5.0)

    row = kernels.scene_row(scene)
    compiled = statistics.median(_samples(lambda: kernels.detachment_times(row, 5.0), repeats))
    return {"numpy": statistics.median(_samples(numpy_search, repeats)), "compiled": compiled}


def _samples(fn: Callable[[], object], repeats: int) -> list[float]:
    out = []
    for _ in range(repeats):
        start = time.thread_time()  # CPU time of this thread: other processes' load does not count (issue 40)
        fn()
        out.append(time.thread_time() - start)
    return out


def _timed(setting: Setting, bs: BenchScene, repeats: int) -> tuple[ImpactEvent | None, float]:
    samples, event = [], None
    for _ in range(repeats):
        start = time.thread_time()
        event = first_impact(bs.scene, setting.method, **setting.kwargs)  # type: ignore[arg-type]
        samples.append(time.thread_time() - start)
    return event, statistics.median(samples)


def measure(
    scenes: list[BenchScene], settings: list[Setting], repeats: int, progress: Callable[[str], None] = lambda _: None
) -> dict[str, Any]:
    """Run every setting on every scene (scene-major, so drifting load spreads over all methods)."""
    refs: dict[str, Reference] = {}
    flights: dict[str, float] = {}
    t0 = time.perf_counter()
    for bs in scenes:
        refs[bs.name] = reference(bs.scene)
        ev = refs[bs.name].event
        flights[bs.name] = math.nan if ev is None else _flight_s(bs, ev)
    progress(f"references: {len(scenes)} scenes in {time.perf_counter() - t0:.1f} s")
    rows: list[dict[str, Any]] = []
    detach: dict[str, dict[str, float]] = {}
    for k, bs in enumerate(scenes):
        detach[bs.name] = detachment_seconds(bs, repeats)
        ref = refs[bs.name].event
        for s in settings:
            if s.only_one_rod and bs.scene.model.n_rods != 1:
                continue
            event, seconds = _timed(s, bs, repeats)
            verdict = classify(event, ref, flights[bs.name], s.slack_s)
            row: dict[str, Any] = {"scene": bs.name, "method": s.method, "setting": s.label, "seconds": seconds}
            row["verdict"] = verdict
            row["event_time_s"] = None if event is None else event.time_s
            if verdict == "matched":
                assert event is not None and ref is not None
                row.update(errors(event, ref))
            rows.append(row)
        progress(f"scene {k + 1}/{len(scenes)} {bs.name}")
    return {
        "scenes": [bs.describe() | {"hard": bs.hard} for bs in scenes],
        "references": {name: r.to_json() for name, r in refs.items()},
        "closed_vs_mpmath_max_s": max(
            (r.closed_vs_mpmath_s for r in refs.values() if math.isfinite(r.closed_vs_mpmath_s)), default=math.nan
        ),
        "rows": rows,
        "detachment_seconds": detach,
    }


def summarise(rows: list[dict[str, Any]], settings: list[Setting]) -> list[dict[str, Any]]:
    """Per setting: median time per event (over scenes with a reference event), error medians and maxima, counts."""
    out = []
    for s in settings:
        mine = [r for r in rows if r["method"] == s.method and r["setting"] == s.label]
        if not mine:
            continue
        timed = [r["seconds"] for r in mine if r["verdict"] != "none"] or [r["seconds"] for r in mine]
        matched = [r for r in mine if r["verdict"] == "matched"]
        summary: dict[str, Any] = {
            "method": s.method,
            "setting": s.label,
            "scenes": len(mine),
            "one_rod_only": s.only_one_rod,
            "seconds_per_event": statistics.median(timed),
            "matched": len(matched),
            "missed": sum(r["verdict"] == "missed" for r in mine),
            "spurious": sum(r["verdict"] == "spurious" for r in mine),
        }
        failed = summary["missed"] + summary["spurious"]
        for key in ("time_s", "point_m", "energy_rel", "v_n_rel"):
            # a missed or spurious event is a failure at this setting: it counts as an infinite error
            values = [r[key] for r in matched] + [math.inf] * failed
            summary[f"{key}_median"] = statistics.median(values) if values else math.nan
            summary[f"{key}_max"] = max(values) if values else math.nan
        out.append(summary)
    return out


def pareto(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """The (cost, error) points no cheaper point beats on error, by increasing cost."""
    front: list[tuple[float, float]] = []
    for cost, err in sorted(points):
        err = max(err, ERROR_FLOOR)
        if math.isfinite(err) and (not front or err < front[-1][1]):
            front.append((cost, err))
    return front


def cost_at_error(front: list[tuple[float, float]], err: float) -> float:
    """Time per event (s) to reach ``err`` on a Pareto front, log–log interpolated between measured points.

    Errors looser than the front's cheapest point cost that point (the method cannot be
    measured to go cheaper); errors tighter than its best point are out of reach (nan).
    """
    err = max(err, ERROR_FLOOR)
    if not front or err < front[-1][1]:
        return math.nan
    if err >= front[0][1]:
        return front[0][0]
    log_err = np.log([e for _, e in front])[::-1]
    log_cost = np.log([c for c, _ in front])[::-1]
    return float(np.exp(np.interp(math.log(err), log_err, log_cost)))


def _front(summary: list[dict[str, Any]], method: str, key: str) -> list[tuple[float, float]]:
    return pareto(
        [
            (s["seconds_per_event"], s[f"{key}_median"])
            for s in summary
            if s["method"] == method and not s["one_rod_only"] and s["matched"] > 0
        ]
    )


def headline(summary: list[dict[str, Any]], key: str = "time_s", exact_method: str = "exact") -> dict[str, Any]:
    """The headline ratios on the median ``key`` error (see docs/benchmarks.md for the definitions).

    ``exact_method``: ``exact`` (compiled: against what a user would pick instead) or
    ``exact-reference`` (numpy/scipy, like for like with the numpy baselines).
    """
    exact = _front(summary, exact_method, key)
    out: dict[str, Any] = {"error": key}
    for baseline in ("legacy", "legacy-arcs", "legacy-interp", "legacy-compiled"):
        pts = [
            (s["setting"], s["seconds_per_event"], s[f"{key}_median"])
            for s in summary
            if s["method"] == baseline and not s["one_rod_only"] and s["matched"] > 0
        ]
        ratios = [(label, cost / cost_at_error(exact, err), err) for label, cost, err in pts]
        ratios = [r for r in ratios if math.isfinite(r[1])]
        if ratios:
            best = min(ratios, key=lambda r: r[2])
            out[baseline] = {
                "at_most_accurate": {"setting": best[0], "error": best[2], "speedup": best[1]},
                "speedup_min": min(r[1] for r in ratios),
                "speedup_max": max(r[1] for r in ratios),
                "per_setting": [{"setting": a, "speedup": b, "error": c} for a, b, c in ratios],
            }
    ivp = _front(summary, "ivp", key)
    levels = [e for _, e in ivp if math.isfinite(cost_at_error(exact, e))]
    ratios_ivp = [(e, cost_at_error(ivp, e) / cost_at_error(exact, e)) for e in levels]
    if ratios_ivp:
        out["ivp"] = {
            "per_error": [{"error": e, "speedup": r} for e, r in ratios_ivp],
            "speedup_median": statistics.median(r for _, r in ratios_ivp),
            "speedup_min": min(r for _, r in ratios_ivp),
            "speedup_max": max(r for _, r in ratios_ivp),
        }
    return out


def run(scenes: list[BenchScene], quick: bool, progress: Callable[[str], None] = lambda _: None) -> dict[str, Any]:
    """Item 1 end to end: measure, summarise, headline ratios (JSON-ready)."""
    settings = sweeps(quick)
    result = measure(scenes, settings, repeats=1 if quick else 3, progress=progress)
    result["settings"] = [{"method": s.method, "setting": s.label, "kwargs": s.kwargs} for s in settings]
    result["summary"] = summarise(result["rows"], settings)
    result["headline"] = {key: headline(result["summary"], key) for key in ("time_s", "point_m", "energy_rel")}
    result["like_for_like"] = headline(result["summary"], "time_s", "exact-reference")
    return result
