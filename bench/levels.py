"""Item 2a, the cost of each level of detail: (a) interlock, (b) node telemetry, (c) offline simulation.

Each level is timed with :func:`bench.common.time_call` (perf_counter, repeats,
median). Speed-ups are stated only against a baseline measured here in the same
run: the vectorised interlock against the scalar one, the telemetry cache hit
against a full summary, and every level against the scalar interlock check.
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np

from bench.common import bench_config, corrected_model, time_call
from millctl.physics import MillModel, Scene, revolution_summary
from millctl.physics.simulate import simulate
from millctl.physics.telemetry import SummaryCache
from millctl.safety import Envelope
from millctl.units import rpm_to_rad_s

SEED = 11


def interlock(points: int, repeats: int) -> dict[str, Any]:
    """Envelope.check per point (scalar loop) against Envelope.contains over ``points`` points at once."""
    env = Envelope.from_config(bench_config())
    rng = np.random.default_rng(SEED)
    w_r = rng.uniform(0.0, env.rotary_max_rpm, points)
    w_v = rng.uniform(0.0, env.vibration_max_rpm, points)
    scalar_n = min(points, 2000)
    pairs = list(zip(w_r[:scalar_n].tolist(), w_v[:scalar_n].tolist(), strict=True))

    def scalar() -> None:
        for a, b in pairs:
            env.check(a, b)

    scalar_s = time_call(scalar, repeats) / scalar_n
    vector_s = time_call(lambda: env.contains(w_r, w_v), repeats) / points
    limit_s = time_call(lambda: env.omega_r_limit_rpm(w_v), repeats) / points
    agree = bool(np.array_equal(env.contains(w_r[:scalar_n], w_v[:scalar_n]), [env.check(a, b).ok for a, b in pairs]))
    return {
        "law": env.law.value,
        "points": points,
        "scalar_points": scalar_n,
        "scalar_s_per_point": scalar_s,
        "vector_s_per_point": vector_s,
        "vector_s_total": vector_s * points,
        "limit_vector_s_per_point": limit_s,
        "speedup_vector_vs_scalar": scalar_s / vector_s,
        "scalar_and_vector_agree": agree,
    }


def _operating_points(count: int) -> list[tuple[float, float]]:
    """Speed pairs (rpm) inside the configured envelope, seeded."""
    env = Envelope.from_config(bench_config())
    rng = np.random.default_rng(SEED)
    out: list[tuple[float, float]] = []
    while len(out) < count:
        w_v = float(rng.uniform(0.0, env.vibration_max_rpm))
        limit = float(env.omega_r_limit_rpm(w_v))
        out.append((float(rng.uniform(min(5.0, limit), max(limit, 5.0))), w_v))
    return out


def telemetry(count: int, repeats: int) -> dict[str, Any]:
    """revolution_summary at the node's model (configured variant) over ``count`` operating points."""
    model = MillModel.from_config(bench_config())
    points = _operating_points(count)
    per_point = []
    for w_r, w_v in points:
        per_point.append(
            time_call(functools.partial(revolution_summary, model, rpm_to_rad_s(w_r), rpm_to_rad_s(w_v)), repeats)
        )
    cache = SummaryCache(model)
    cache(*[float(rpm_to_rad_s(x)) for x in points[0]])
    hit_s = time_call(lambda: cache(*[float(rpm_to_rad_s(x)) for x in points[0]]), repeats, number=200)
    median_s = float(np.median(per_point))
    return {
        "variant": model.variant.value,
        "points": [
            {"omega_r_rpm": a, "omega_v_rpm": b, "seconds": s} for (a, b), s in zip(points, per_point, strict=True)
        ],
        "median_s": median_s,
        "max_s": max(per_point),
        "cache_hit_s": hit_s,
        "speedup_cache_hit_vs_summary": median_s / hit_s,
    }


def offline(mill_time_s: float, repeats: int) -> dict[str, Any]:
    """simulate() per event: Set A corrected at 100/800 rpm for ``mill_time_s`` of mill time."""
    scene = Scene(corrected_model(), float(rpm_to_rad_s(100.0)), float(rpm_to_rad_s(800.0)), -0.5 * math.pi, 0.0)
    events = len(simulate(scene, mill_time_s).impacts)
    total_s = time_call(lambda: simulate(scene, mill_time_s), repeats)
    return {
        "scene": "Set A corrected, 100/800 rpm",
        "mill_time_s": mill_time_s,
        "impacts": events,
        "seconds": total_s,
        "s_per_event": total_s / max(events, 1),
        "realtime_factor": mill_time_s / total_s,
    }


def run(quick: bool) -> dict[str, Any]:
    """Item 2a end to end, with every level also as a multiple of the scalar interlock check."""
    repeats = 3 if quick else 7
    out = {
        "interlock": interlock(100_000 if quick else 1_000_000, repeats),
        "telemetry": telemetry(4 if quick else 16, repeats),
        "offline": offline(0.3 if quick else 2.0, 1 if quick else 3),
    }
    base = out["interlock"]["scalar_s_per_point"]
    out["vs_scalar_interlock"] = {
        "interlock_vector_per_point": out["interlock"]["vector_s_per_point"] / base,
        "telemetry_summary": out["telemetry"]["median_s"] / base,
        "telemetry_cache_hit": out["telemetry"]["cache_hit_s"] / base,
        "offline_per_event": out["offline"]["s_per_event"] / base,
    }
    return out
