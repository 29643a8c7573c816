"""Issue 17's figures for the compiled engine: batch throughput, agreement, compile and cached start, interlock.

* batch: :func:`millctl.physics.batch.first_impacts` on N random scenes
  (:func:`millctl.physics.agreement.random_scenes`), one-rod events (``rods="one"``, the
  telemetry's and a design study's unit) and whole-scene first impacts (``rods="all"``);
  events per second per core = scenes / process CPU seconds (one thread; wall-clock too);
* agreement: the batch against the numpy/scipy reference engine on N scenes (counted);
* compile: a fresh process with an empty ``NUMBA_CACHE_DIR`` (first call compiles) and
  a second one on that cache (the cached start), each timed from interpreter start to the
  first batch result;
* interlock: :meth:`Envelope.allows` (the scalar path in plain ``math``) per check.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from bench.common import bench_config, corrected_model
from millctl.physics.agreement import compare, random_scenes
from millctl.physics.batch import SceneBatch, first_impacts
from millctl.physics.methods import EventCall, first_impact
from millctl.physics.model import Scene
from millctl.safety import Envelope

SEED = 17
"""Seed of the random scenes (the same sample as tests/unit/physics/test_kernels.py draws from)."""

_FIRST_CALL = (
    "import time; t0 = time.perf_counter(); import math; "
    "from millctl.physics.batch import SceneBatch, first_impacts; "
    "from millctl.physics.telemetry import revolution_summary; "
    "from bench.common import corrected_model; m = corrected_model(); "
    "first_impacts(SceneBatch.broadcast(m, omega_r_rad_s=15.0, omega_v_rad_s=80.0), rods='one'); "
    "first_impacts(SceneBatch.broadcast(m, omega_r_rad_s=15.0, omega_v_rad_s=80.0), rods='all'); "
    "revolution_summary(m, 15.0, 80.0); print(time.perf_counter() - t0)"
)


def _cpu_and_wall(fn: Callable[[], object]) -> tuple[float, float]:
    cpu, wall = time.thread_time(), time.perf_counter()
    fn()
    return time.thread_time() - cpu, time.perf_counter() - wall


def public_api(count: int, repeats: int = 5) -> dict[str, Any]:
    """One event through the public API, CPU µs per call (median), against the batch kernel on the same scenes.

    ``one_rod``: one rod's event (``rods="one"``) through a prepared :class:`~millctl.physics.methods.EventCall`
    of one model (the random scenes' speeds and phases, the model's own eccentricity), the scene as four floats;
    the rest: a whole six-rod scene through ``methods.first_impact(scene, "exact")`` (a model per scene, as
    :func:`~millctl.physics.agreement.random_scenes` draws them). Each is timed alternately with the batch kernel
    (``rods`` the same) on the same scenes: ``wrapping_us`` is what the Python call path adds to the kernel.
    """
    model = corrected_model()
    scenes = random_scenes(model, count, SEED)
    rows = SceneBatch.from_scenes(scenes)
    floats = [(s.omega_r_rad_s, s.omega_v_rad_s, s.theta0_rad, s.alpha0_rad) for s in scenes]
    one_rows = SceneBatch.from_scenes([Scene(model, *f) for f in floats])
    call = EventCall(model, rods="one")
    first_impact(scenes[0], "exact")  # load the compiled code
    call(*floats[0])
    first_impacts(SceneBatch(rows.rows[:2]), rods="all")
    first_impacts(SceneBatch(one_rows.rows[:2]), rods="one")

    def loop() -> None:
        for scene in scenes:
            first_impact(scene, "exact")

    def one_rod_loop() -> None:
        for f in floats:
            call(*f)

    runs, kernel, one_runs, one_kernel = [], [], [], []
    for _ in range(repeats):
        runs.append(_cpu_and_wall(loop))
        kernel.append(_cpu_and_wall(lambda: first_impacts(rows, rods="all"))[0])
        one_runs.append(_cpu_and_wall(one_rod_loop)[0])
        one_kernel.append(_cpu_and_wall(lambda: first_impacts(one_rows, rods="one"))[0])
    us = float(np.median([c for c, _ in runs])) / count * 1e6
    kernel_us = float(np.median(kernel)) / count * 1e6
    one_us = float(np.median(one_runs)) / count * 1e6
    one_kernel_us = float(np.median(one_kernel)) / count * 1e6
    return {
        "scenes": count,
        "us_per_event": us,
        "us_per_event_wall": float(np.median([w for _, w in runs])) / count * 1e6,
        "kernel_us_per_scene": kernel_us,
        "wrapping_us": us - kernel_us,
        "one_rod": {
            "us_per_event": one_us,
            "kernel_us_per_event": one_kernel_us,
            "wrapping_us": one_us - one_kernel_us,
        },
    }


def batch(count: int, repeats: int = 5) -> dict[str, Any]:
    """Events per second per core of the batch API on ``count`` random scenes (median of ``repeats`` runs)."""
    batch_ = SceneBatch.from_scenes(random_scenes(corrected_model(), count, SEED))
    first_impacts(SceneBatch(batch_.rows[:2]), rods="one")  # load the compiled code
    out: dict[str, Any] = {"scenes": count, "repeats": repeats}
    for rods in ("one", "all"):
        runs = [_cpu_and_wall(lambda r=rods: first_impacts(batch_, rods=r)) for _ in range(repeats)]  # type: ignore[misc]
        cpu = float(np.median([c for c, _ in runs]))
        wall = float(np.median([w for _, w in runs]))
        found = int(np.count_nonzero(first_impacts(batch_, rods=rods)["found"]))
        out[rods] = {
            "cpu_s": cpu,
            "wall_s": wall,
            "events_per_cpu_s": count / cpu,
            "events_per_wall_s": count / wall,
            "cpu_s_min": float(min(c for c, _ in runs)),
            "found": found,
        }
    return out


def agreement(count: int) -> dict[str, Any]:
    """The batch (rods='all') against the reference engine on ``count`` random scenes."""
    start = time.perf_counter()
    report = compare(random_scenes(corrected_model(), count, SEED))
    return {
        "scenes": report.scenes,
        "agree": report.agree,
        "fraction": report.fraction,
        "largest_time_difference_s": report.largest_time_difference_s,
        "disagreements": [{"index": k, "what": what} for k, what in report.disagreements],
        "seconds": time.perf_counter() - start,
    }


def compile_times() -> dict[str, Any]:
    """First call with an empty numba cache (compiles), then a fresh process on that cache."""
    with tempfile.TemporaryDirectory(prefix="bench-numba-") as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        out = {}
        for label in ("first_call_s", "cached_start_s"):
            done = subprocess.run(
                [sys.executable, "-c", _FIRST_CALL], env=env, capture_output=True, text=True, check=True, timeout=900
            )
            out[label] = float(done.stdout.strip().splitlines()[-1])
    return out


def interlock(points: int, repeats: int) -> dict[str, Any]:
    """Envelope.allows per check (µs): wall clock (perf_counter) and process CPU, median of ``repeats``."""
    env = Envelope.from_config(bench_config())
    rng = np.random.default_rng(SEED)
    pairs = list(
        zip(
            rng.uniform(0.0, env.rotary_max_rpm, points).tolist(),
            rng.uniform(0.0, env.vibration_max_rpm, points).tolist(),
            strict=True,
        )
    )
    allows = env.allows

    def loop() -> None:
        for a, b in pairs:
            allows(a, b)

    runs = [_cpu_and_wall(loop) for _ in range(repeats)]
    return {
        "points": points,
        "scalar_us_wall": float(np.median([w for _, w in runs])) / points * 1e6,
        "scalar_us_cpu": float(np.median([c for c, _ in runs])) / points * 1e6,
    }


def run(quick: bool, progress: Callable[[str], None] = lambda _: None) -> dict[str, Any]:
    """All of the above (``quick``: 10³ scenes, 300 compared, no compile-time processes)."""
    out: dict[str, Any] = {}
    progress("compiled: batch throughput")
    out["batch"] = batch(1000 if quick else 10_000)
    progress("compiled: one event through the public API")
    out["public_api"] = public_api(300 if quick else 3000)
    progress("compiled: agreement with the reference engine")
    out["agreement"] = agreement(300 if quick else 10_000)
    out["interlock"] = interlock(20_000, 5)
    if not quick:
        progress("compiled: first-call compile and cached start (two fresh processes)")
        out["compile"] = compile_times()
    return out
