"""Design-study throughput (issue 40): the array path, the whole runner, and what workers gain.

* **arrays**: :func:`millctl.studies.engine.evaluate_arrays` on a 100 × 100 map of
  (ω_r 20–300 rpm, ω_v 200–1200 rpm) on Set A (corrected), every level-(a) and level-(b)
  metric at 4 fixed cam phases; points per CPU second of this thread (``time.thread_time``,
  median of 3); and once more integrated over the cam phase to 1 % (the studies' default), with
  the level-(b) kernel's share of the CPU time and the samples by the K the points settled at
  (:func:`where_time_goes`), and the integral's stated error checked against 1,024 fixed phases
  (:func:`integral_check`).
* **runner**: the same map through :class:`~millctl.studies.StudyRunner` in this process (rows,
  constraints, the in-memory store), CPU and wall time.
* **parallel**: a study large enough to need workers — level (c), the multi-rod simulation,
  on a grid of ω_r 120–200 × ω_v 400–800 rpm — on one worker and on two (local processes, and a
  2-worker local Dask cluster), **alternated**: serial, pool, serial, pool …, the pool already
  started and warm; efficiency = median serial time / (2 × median pool time). With c the serial
  cost of a point and S the pool's start-up, a study of N points keeps ≥ 80 % efficiency on w
  workers when N c ≥ 4 w S (from N c / (w S + N c) ≥ 0.8): :func:`worth_workers_rule`. c is
  measured first (:func:`per_point_s`), then S of each pool, and each pool's study is the smallest
  square grid the rule says pays (~10⁴ points: the piece takes minutes, the longest of the study's);
  ``--quick`` caps it at :data:`QUICK_PARALLEL_POINTS`.
* **offline**, **agreement_c** (and ``_slip``): level (c), in :mod:`bench.level_c`.

``--quick`` shrinks every grid.
"""

from __future__ import annotations

import math
import os
import statistics
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from bench import level_c
from bench.common import bench_config
from bench.level_c import OFFLINE, SIM_METRICS
from millctl.physics import kernels
from millctl.studies import SerialBackend, Study, StudyRunner
from millctl.studies.backends import Backend, DaskBackend, LocalBackend
from millctl.studies.engine import evaluate_arrays
from millctl.studies.metrics import DEFAULT_METRICS, PointSettings

MAP = {"rotary_rpm": (20.0, 300.0), "vibration_rpm": (200.0, 1200.0)}
"""The (ω_r, ω_v) ranges of the map (rpm)."""
FIXED_CAM_PHASES = 4
"""The level-(b) map of issue 40's target: 4 fixed cam phases a point (the integral to 1 % is timed beside it)."""


def _study(
    num: int, metrics: list[str] | None = None, revolutions: float = 1.0, ranges: dict[str, tuple[float, float]] = MAP
) -> Study:
    parameters = {name: {"grid": {"start": lo, "stop": hi, "num": num}} for name, (lo, hi) in ranges.items()}
    data: dict[str, Any] = {
        "study": {"name": f"{num} x {num} map", "variant": "corrected", "seed": 1},
        "parameters": parameters,
        "metrics": {
            "revolutions": revolutions,
            "cam_phases": FIXED_CAM_PHASES,
            **({"names": metrics} if metrics else {}),
        },
        "constraints": {"law": "corrected-best-phase"},
        "objective": {"maximize": metrics[0] if metrics else "dose_rate_j_g_s"},
    }
    return Study.model_validate(data)


def _cpu_wall(fn: Callable[[], Any]) -> tuple[float, float, Any]:
    cpu, wall = time.thread_time(), time.perf_counter()
    value = fn()
    return time.thread_time() - cpu, time.perf_counter() - wall, value


def arrays(num: int, repeats: int = 3, cam_phases: int = FIXED_CAM_PHASES) -> dict[str, Any]:
    """The level-(a, b) map through evaluate_arrays: points per CPU second of this thread.

    ``cam_phases``: K fixed cam phases a point, or 0 to integrate over the phase to 1 % (the
    studies' default); ``phases_per_point`` is the mean number of cam-phase samples a point took.
    """
    (lo_r, hi_r), (lo_v, hi_v) = MAP["rotary_rpm"], MAP["vibration_rpm"]
    rotary, vibration = np.meshgrid(np.linspace(lo_r, hi_r, num), np.linspace(lo_v, hi_v, num), indexing="ij")
    points = {"rotary_rpm": rotary.ravel(), "vibration_rpm": vibration.ravel()}
    config = bench_config()
    settings = PointSettings(cam_phases=cam_phases)
    evaluate_arrays({k: v[:4] for k, v in points.items()}, config, DEFAULT_METRICS, settings)  # load the compiled code
    runs = [_cpu_wall(lambda: evaluate_arrays(points, config, DEFAULT_METRICS, settings)) for _ in range(repeats)]
    cpu = statistics.median(r[0] for r in runs)
    wall = statistics.median(r[1] for r in runs)
    phases = float(np.mean(runs[0][2]["cam_phases_used"]))
    return {
        "points": num * num, "cam_phases": cam_phases, "phases_per_point": phases,
        "cpu_s": cpu, "wall_s": wall, "points_per_cpu_s": num * num / cpu,
    }  # fmt: skip


CHECK_PHASES = 1024
"""The reference of :func:`integral_check`: this many fixed cam phases a point."""
_SAMPLE_BINS = ((16, 16), (17, 32), (33, 64), (65, 128), (129, 1 << 30))
"""The bins of ``points_at_samples``: a point's samples in [lo, hi]."""


def where_time_goes(num: int, cam_phases: int = 0) -> dict[str, Any]:
    """One more run of :func:`arrays`' map with the compiled level-(b) work counted apart.

    Every call of :func:`millctl.physics.kernels.phase_integral` (the integral: its rule and its samples) and
    :func:`~millctl.physics.kernels.telemetry_batch` (fixed phases) is timed (``time.thread_time``); the rest
    of the CPU time is the Python and numpy around it (the summary's weighted sums, the level-(a) metrics).
    ``kernel_us_per_sample``: the compiled time a sample, the rule's bookkeeping included.
    ``points_at_samples`` counts the points that took 16, 17–32, … samples,
    ``sample_share_at`` the share of all samples those points took; ``floor_points_per_cpu_s`` is the rate
    had every point stopped at the rule's first 16 samples, at this run's cost a sample.
    """
    (lo_r, hi_r), (lo_v, hi_v) = MAP["rotary_rpm"], MAP["vibration_rpm"]
    rotary, vibration = np.meshgrid(np.linspace(lo_r, hi_r, num), np.linspace(lo_v, hi_v, num), indexing="ij")
    points = {"rotary_rpm": rotary.ravel(), "vibration_rpm": vibration.ravel()}
    config, settings = bench_config(), PointSettings(cam_phases=cam_phases)
    evaluate_arrays({k: v[:4] for k, v in points.items()}, config, DEFAULT_METRICS, settings)
    spent: dict[str, Any] = {"cpu_s": 0.0, "samples": 0}
    originals = {name: getattr(kernels, name) for name in ("phase_integral", "telemetry_batch")}

    def timed(name: str, original: Any) -> Any:
        def call(*args: Any, **kwargs: Any) -> Any:
            start = time.thread_time()
            result = original(*args, **kwargs)
            spent["cpu_s"] += time.thread_time() - start
            if name == "phase_integral":  # (table, phase, weight, owner, used, error)
                spent["samples"] += int(result[0].shape[0])
            else:
                spent["samples"] += int(np.prod(result.shape[:-1]))
            return result

        return call

    for name, original in originals.items():
        setattr(kernels, name, timed(name, original))
    try:
        cpu, _, out = _cpu_wall(lambda: evaluate_arrays(points, config, DEFAULT_METRICS, settings))
    finally:
        for name, original in originals.items():
            setattr(kernels, name, original)
    samples = int(spent["samples"])
    per_sample_s = spent["cpu_s"] / max(samples, 1)
    used = np.asarray(out["cam_phases_used"])
    at, share = {}, {}
    for lo, hi in _SAMPLE_BINS:
        inside = (used >= lo) & (used <= hi)
        if inside.any():
            key = str(lo) if lo == hi else (f"{lo}–{hi}" if hi < 1 << 30 else f"≥ {lo}")
            at[key], share[key] = int(inside.sum()), float(used[inside].sum() / max(samples, 1))
    return {
        "points": num * num, "cam_phases": cam_phases, "cpu_s": cpu, "kernel_cpu_s": spent["cpu_s"],
        "kernel_share": spent["cpu_s"] / cpu, "samples": samples, "kernel_us_per_sample": per_sample_s * 1e6,
        "samples_per_point": samples / (num * num), "points_at_samples": at, "sample_share_at": share,
        "floor_points_per_cpu_s": 1.0 / (16 * per_sample_s),
    }  # fmt: skip


def integral_check(points: int, rtol: float = 0.01, seed: int = 3) -> dict[str, Any]:
    """The integral's stated error checked against :data:`CHECK_PHASES` fixed phases on seeded points of the map.

    ``points`` points of the 100 × 100 map, integrated to ``rtol`` as a study does.
    Power error: |P − P_ref| / P_ref (where P_ref = 0: 0 if P = 0, else 1); share error |f − f_ref|.
    """
    rng = np.random.default_rng(seed)
    (lo_r, hi_r), (lo_v, hi_v) = MAP["rotary_rpm"], MAP["vibration_rpm"]
    rotary, vibration = np.meshgrid(np.linspace(lo_r, hi_r, 100), np.linspace(lo_v, hi_v, 100), indexing="ij")
    pick = rng.choice(rotary.size, size=min(points, rotary.size), replace=False)
    chosen = {"rotary_rpm": rotary.ravel()[pick], "vibration_rpm": vibration.ravel()[pick]}
    names = ["milling_power_w", "detach_fraction"]
    config = bench_config()
    est = evaluate_arrays(chosen, config, [*names, "cam_phase_error"], PointSettings(cam_phase_rtol=rtol))
    ref = evaluate_arrays(chosen, config, names, PointSettings(cam_phases=CHECK_PHASES))
    p, p_ref = est["milling_power_w"], ref["milling_power_w"]
    with np.errstate(invalid="ignore", divide="ignore"):
        power = np.where(p_ref > 0.0, np.abs(p - p_ref) / np.where(p_ref > 0.0, p_ref, 1.0), (p != 0.0) * 1.0)
    share = np.abs(est["detach_fraction"] - ref["detach_fraction"])
    return {
        "points": int(pick.size), "rtol": rtol, "reference_phases": CHECK_PHASES,
        "within_power": float(np.mean(power <= rtol)), "within_share": float(np.mean(share <= rtol)),
        "within_both": float(np.mean((power <= rtol) & (share <= rtol))),
        "power_error_p95": float(np.percentile(power, 95)), "power_error_max": float(power.max()),
        "share_error_max": float(share.max()),
    }  # fmt: skip


def runner(num: int) -> dict[str, Any]:
    """The same map through the whole study runner, in this process."""
    study = _study(num)
    cpu, wall, result = _cpu_wall(lambda: StudyRunner(study, bench_config(), "bench").run(SerialBackend()))
    points = len(result.rows)
    return {"points": points, "cpu_s": cpu, "wall_s": wall, "points_per_cpu_s": points / cpu}


def _run_s(study: Study, backend: Backend) -> float:
    start = time.perf_counter()
    StudyRunner(study, bench_config(), "bench").run(backend)
    return time.perf_counter() - start


def _paired(study: Study, pool: Backend, pairs: int) -> dict[str, Any]:
    serial, parallel = [], []
    for _ in range(pairs):
        serial.append(_run_s(study, SerialBackend()))
        parallel.append(_run_s(study, pool))
    s, p = statistics.median(serial), statistics.median(parallel)
    return {"serial_s": serial, "pool_s": parallel, "efficiency": s / (pool.workers * p), "speedup": s / p}


def _local_pool(workers: int) -> tuple[Backend, Callable[[], None]]:
    pool = LocalBackend(workers)
    return pool, pool.close


def _dask_pool(workers: int) -> tuple[Backend, Callable[[], None]]:
    from distributed import Client, LocalCluster

    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None)
    client = Client(cluster)
    backend = DaskBackend(client=client)

    def close() -> None:
        client.close()
        cluster.close()

    return backend, close


PROBE = 8
"""The level-(c) probe study that measures c, the serial cost of a point, before the pools are sized (PROBE²)."""


QUICK_PARALLEL_POINTS = 900
"""``--quick`` measures the efficiency on at most this many level-(c) points, whatever the rule says."""


def per_point_s(num: int = PROBE, repeats: int = 3) -> float:
    """c: the median serial wall time of a point of a ``num`` × ``num`` level-(c) study, in this process, warm."""
    study = _study(num, SIM_METRICS, ranges=OFFLINE)
    _run_s(_study(2, SIM_METRICS, ranges=OFFLINE), SerialBackend())  # the compiled code loaded
    return statistics.median(_run_s(study, SerialBackend()) for _ in range(repeats)) / (num * num)


def parallel(pairs: int, workers: int = 2, max_points: int | None = None) -> dict[str, Any]:
    """Serial against ``workers`` workers, alternated, on level-(c) studies sized by the rule they test.

    c (:func:`per_point_s`) is measured first; each pool is started and warmed, its start-up S timed;
    the study is then the smallest square grid of at least :func:`worth_workers_rule` (c, S, w) points,
    the size from which the printed rule says w workers keep ≥ 80 % efficiency. ``max_points`` (``--quick``)
    caps the grid below the rule to keep the run short; the report shows both sizes.
    """
    c = per_point_s()
    out: dict[str, Any] = {"per_point_s": c, "probe_points": PROBE * PROBE, "workers": workers, "rule_points": {}}
    for key in ("local", "dask"):
        pool, close, startup_s = _started(key, workers)
        try:
            rule = worth_workers_rule(c, startup_s, workers)
            num = max(PROBE, math.ceil(math.sqrt(rule if max_points is None else min(rule, max_points))))
            load = os.getloadavg()[0]
            paired = _paired(_study(num, SIM_METRICS, ranges=OFFLINE), pool, pairs)
            cold = statistics.median(paired["serial_s"]) / (workers * (statistics.median(paired["pool_s"]) + startup_s))
            out[key] = paired | {"startup_s": startup_s, "points": num * num, "efficiency_with_startup": cold}
            out[key] |= {"loadavg_start": load, "loadavg_end": os.getloadavg()[0]}
            out["rule_points"][key] = rule
        finally:
            close()
    return out


def _started(key: str, workers: int) -> tuple[Backend, Callable[[], None], float]:
    """A pool (``local`` or ``dask``) started and warmed (imports, compiled code), and how long that took (s)."""
    started = time.perf_counter()
    pool, close = _local_pool(workers) if key == "local" else _dask_pool(workers)
    try:
        _run_s(_study(2, SIM_METRICS, ranges=OFFLINE), pool)
    except BaseException:
        close()
        raise
    return pool, close, time.perf_counter() - started


def worth_workers_rule(per_point_s: float, startup_s: float, workers: int) -> int:
    """The fewest points for which ``workers`` workers keep ≥ 80 % efficiency: N c ≥ 4 w S."""
    return int(np.ceil(4.0 * workers * startup_s / per_point_s))


def runner_c(num: int) -> dict[str, Any]:
    """The whole runner's level-(c) study, for comparison with the kernel (its metrics' post-processing included)."""
    study = _study(num, SIM_METRICS, ranges=OFFLINE)
    run_cpu, run_wall, result = _cpu_wall(lambda: StudyRunner(study, bench_config(), "bench").run(SerialBackend()))
    run_events = sum(int(r["events"]) for r in result.rows)
    return {
        "points": num * num, "runner_events": run_events, "runner_cpu_s": run_cpu, "runner_wall_s": run_wall,
        "runner_events_per_cpu_s": run_events / run_cpu,
    }  # fmt: skip


def run(quick: bool, progress: Callable[[str], None] = lambda _: None) -> dict[str, Any]:
    """Every figure of this piece."""
    progress("study: the level-(b) map as arrays")
    out: dict[str, Any] = {"arrays": arrays(30 if quick else 100)}
    progress("study: the level-(b) map as arrays, integrated over the cam phase to 1 %")
    out["arrays_integrated"] = arrays(30 if quick else 100, 1, cam_phases=0)
    progress("study: where the integrated map's time goes (the level-(b) kernel timed apart)")
    out["arrays_breakdown"] = where_time_goes(30 if quick else 100)
    progress(f"study: the integral's stated error against {CHECK_PHASES} fixed cam phases")
    out["integral_check"] = integral_check(100 if quick else 600)
    progress("study: the map through the runner")
    out["runner"] = runner(30 if quick else 100)
    out.update(level_c.run(quick, progress))
    out["offline"].update(runner_c(3))
    progress("study: parallel efficiency, alternated serial and two workers (local, Dask)")
    out["parallel"] = parallel(1 if quick else 3, max_points=QUICK_PARALLEL_POINTS if quick else None)
    return out


def report(st: dict[str, Any]) -> list[str]:
    """The benchmark document's section."""
    a, r, o, p = st["arrays"], st["runner"], st["offline"], st["parallel"]
    side = round(a["points"] ** 0.5)
    integrated = [
        f"| the same integrated over the cam phase to 1 % ({i['phases_per_point']:.0f} samples a point) "
        f"| {i['points']:,} | {i['cpu_s']:.3g} s | {i['wall_s']:.3g} s | {i['points_per_cpu_s']:.3g} |"
        for i in [st[k] for k in ("arrays_integrated",) if k in st]
    ]
    lines = [
        "## 4. Design-study throughput",
        "",
        "Set A (corrected), ω_r 20–300 rpm × ω_v 200–1200 rpm, every level-(a) and level-(b) metric "
        "(bench/study.py). CPU time of the measuring thread (`time.thread_time`).",
        "",
        "| run | points | CPU | wall | points per CPU second |",
        "|---|---|---|---|---|",
        f"| {side} × {side} map, `evaluate_arrays`, {a['cam_phases']} cam phases | {a['points']:,} "
        f"| {a['cpu_s']:.3g} s | {a['wall_s']:.3g} s | {a['points_per_cpu_s']:.3g} |",
        *integrated,
        f"| the same through `StudyRunner` (rows, constraints, store) | {r['points']:,} | {r['cpu_s']:.3g} s "
        f"| {r['wall_s']:.3g} s | {r['points_per_cpu_s']:.3g} |",
        f"| level (c) through `StudyRunner`, {o['points']} points, one worker | {o['points']} "
        f"| {o['runner_cpu_s']:.3g} s | {o['runner_wall_s']:.3g} s | {o['runner_events_per_cpu_s']:.3g} events/s |",
        "",
        *breakdown_lines(st),
        *level_c.offline_lines(st),
        "",
        "Parallel efficiency on level-(c) studies sized by the rule below (c measured first on a "
        f"{p.get('probe_points', '—')}-point study, then each pool started and warmed and its start-up S timed, then "
        "the smallest square grid of at least 4·w·S/c points; serial and two workers alternated, medians of the wall "
        "times, workers warm; the last column counts S into the two workers' time):",
        "",
        "| workers | points (rule) | serial | two workers | speed-up | efficiency | start-up S | efficiency with S |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for key, label in (("local", "2 local processes"), ("dask", "2-worker local Dask cluster")):
        q = {"points": p.get("points", 0), "efficiency_with_startup": math.nan} | p[key]  # older results: one size
        lines.append(
            f"| {label} | {q['points']:,} ({p['rule_points'][key]:,}) | {statistics.median(q['serial_s']):.3g} s "
            f"| {statistics.median(q['pool_s']):.3g} s | {q['speedup']:.2f}× | {q['efficiency']:.0%} "
            f"| {q['startup_s']:.2g} s | {q['efficiency_with_startup']:.0%} |"
        )
    if all("loadavg_start" in p[k] for k in ("local", "dask")):
        loads = "; ".join(f"{k} {p[k]['loadavg_start']:.2f} → {p[k]['loadavg_end']:.2f}" for k in ("local", "dask"))
        lines += ["", f"Host load (1-minute average) at the start and the end of each pool's pairs: {loads}."]
    below = [k for k in ("local", "dask") if p[k].get("points", p.get("points", 0)) < p["rule_points"][k]]
    if below:
        lines += [
            "",
            f"Measured below the rule ({', '.join(below)}: `--quick` caps the study, or older results): "
            "not the target's figure.",
        ]
    lines += ["", rule_text(p), ""]
    return lines


def breakdown_lines(st: dict[str, Any]) -> list[str]:
    """Where the integrated map's CPU time goes (:func:`where_time_goes`), when it ran."""
    if "arrays_breakdown" not in st:
        return []
    b = st["arrays_breakdown"]
    settled = ", ".join(f"{k}: {n:,} ({b['sample_share_at'][k]:.0%})" for k, n in b["points_at_samples"].items())
    lines = [
        f"Where the integrated map's time goes: the compiled integral (`kernels.phase_integral`, the rule and "
        f"its samples) takes {b['kernel_share']:.0%} of the CPU time ({b['kernel_cpu_s']:.3g} of {b['cpu_s']:.3g} s; "
        f"{b['samples']:,} cam-phase samples, {b['samples_per_point']:.3g} a point, at {b['kernel_us_per_sample']:.3g} "
        f"µs each, the rule's bookkeeping included), the numpy summary and the level-(a) metrics the rest. Points by "
        f"the samples they took (their share of the samples): "
        f"{settled}. Had every point stopped at the rule's first 16 samples, the map would run at "
        f"{b['floor_points_per_cpu_s']:.3g} points per CPU second.",
        "",
    ]
    if "integral_check" in st:
        c = st["integral_check"]
        lines += [
            f"The integral's stated error checked against {c['reference_phases']:,} fixed cam phases on {c['points']} "
            f"random points of the map: the milling power within {c['rtol']:.0%} on {c['within_power']:.1%} of them, "
            f"the detaching share within {c['rtol']:g} on {c['within_share']:.1%}, both on {c['within_both']:.1%}; "
            f"the power's error {c['power_error_p95']:.2g} at the 95th percentile, {c['power_error_max']:.2g} at "
            f"worst; the share's {c['share_error_max']:.2g} at worst.",
            "",
        ]
    return lines


def rule_text(p: dict[str, Any]) -> str:
    """The printed rule for when a study is too small to gain from workers."""
    c = p["per_point_s"]
    return (
        f"Rule: w workers keep ≥ 80 % efficiency when N·c ≥ 4·w·S (N points, c the serial cost of a point, S the "
        f"pool's start-up). Here c = {c * 1e3:.3g} ms for a level-(c) point, S = {p['local']['startup_s']:.2g} s "
        f"(local) / {p['dask']['startup_s']:.2g} s (Dask): two workers pay from "
        f"{p['rule_points']['local']:,} / {p['rule_points']['dask']:,} level-(c) points; a level-(a, b) study costs "
        "~10⁻⁵ s a point and gains from workers only past ~10⁶ points — run it with --workers 1."
    )


__all__ = [
    "MAP",
    "arrays",
    "breakdown_lines",
    "integral_check",
    "parallel",
    "per_point_s",
    "report",
    "rule_text",
    "run",
    "runner",
    "runner_c",
    "where_time_goes",
]
