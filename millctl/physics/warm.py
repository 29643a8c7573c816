"""Compile every numba kernel of the physics once, into numba's cache: ``python -m millctl.physics.warm``.

A kernel compiles on its first call with a given signature, and numba keeps the result in
``__pycache__`` keyed by the source file and the CPU. On a fresh clone nothing is cached: the first
test, node or study to call a kernel compiles it (seconds of CPU each; ~50 s for the lot on the CI
machine), inside its own time budget. ``.ci/setup`` runs this once instead, so that the unit tier,
the hil nodes and the benchmarks load what is compiled. With the cache current it takes about a second.

Each call below is the first call of a public entry point with the argument types its callers use:
the batch events (:func:`.batch.first_impacts`, one rod and all), the per-scene methods the CLI and
the benchmark compare (:func:`.methods.first_impact`, ``exact`` with and without a tolerance, and
``legacy-compiled``), the detachment times (:func:`.kernels.detachment_times`), the node's
revolution summary (:func:`.telemetry.revolution_summary`, which runs the slip kernels), the design
studies' level-(b) samples (:func:`.kernels.telemetry_batch` at even phases, :func:`.kernels.telemetry_at`
at chosen ones) and their adaptive cam-phase integral (:func:`.kernels.phase_integral`), and level (c)'s
many-event kernel (:func:`.simulate.simulate_compiled`, the studies' multi-rod simulation).
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np

from millctl.config import default_config
from millctl.physics import kernels
from millctl.physics.batch import SceneBatch, first_impacts
from millctl.physics.methods import first_impact
from millctl.physics.model import MillModel, Scene
from millctl.physics.simulate import simulate_compiled
from millctl.physics.telemetry import revolution_summary

OMEGA_R_RAD_S = 10.0
"""The rotary speed of the warm-up scenes (rad/s): inside every shipped envelope, the rods detach."""
OMEGA_V_RAD_S = 80.0
"""The vibration speed of the warm-up scenes (rad/s)."""


def warm() -> None:
    """Call every compiled entry point once with each signature in use (compiling what is not cached)."""
    model = MillModel.from_config(default_config())
    batch = SceneBatch.broadcast(model, omega_r_rad_s=OMEGA_R_RAD_S, omega_v_rad_s=OMEGA_V_RAD_S)
    for rods in ("one", "all"):
        first_impacts(batch, rods=rods)
    scene = Scene(model, OMEGA_R_RAD_S, OMEGA_V_RAD_S)
    first_impact(scene, "exact")
    first_impact(scene, "exact", tol=1e-9)
    first_impact(scene, "legacy-compiled", dt=1e-3)
    kernels.detachment_times(kernels.scene_row(scene), 5.0)
    revolution_summary(model, OMEGA_R_RAD_S, OMEGA_V_RAD_S)
    rows, start, pinned = kernels.scene_row(scene)[None, :], np.array([-0.5 * math.pi]), np.array([False])
    kernels.telemetry_batch(rows, start, pinned, 4, 2.0, model.powder_friction)
    kernels.telemetry_at(rows, start, pinned, np.zeros(2, dtype=np.int64), np.array([0.0, 1.0]), 2.0, 0.3)
    kernels.phase_integral(rows, start, pinned, np.array([0.08]), 0.1, 1e-9, 0.01, 2.0, model.powder_friction)
    simulate_compiled(scene, 0.5, threshold_j=1e-10)


def main() -> int:
    """Warm the cache and say how long it took (stderr)."""
    started = time.perf_counter()
    warm()
    sys.stderr.write(f"millctl.physics.warm: kernels ready in {time.perf_counter() - started:.1f} s\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
