"""Does the compiled engine give the reference engine's answers? Random scenes, counted disagreements.

The reference is the numpy/scipy engine (``simulate(scene, stop_after_first=True)``),
the candidate the batch kernel (:func:`millctl.physics.batch.first_impacts`, ``rods="all"``).
A scene agrees when both find no impact, or both find one with the same pair of
bodies within ``time_tol_s`` (default 1e-9 s) of each other. Used by the unit test
(a few hundred seeded scenes) and by ``python -m bench`` (10⁴ scenes).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from millctl.physics.batch import SceneBatch, first_impacts
from millctl.physics.model import MillModel, Scene
from millctl.physics.simulate import simulate

OMEGA_R_RPM = (20.0, 220.0)
OMEGA_V_RPM = (0.0, 1200.0)
ECCENTRICITY_M = (0.0, 2e-3)


def random_scenes(model: MillModel, count: int, seed: int) -> list[Scene]:
    """``count`` scenes of ``model`` with uniform ω_r, ω_v (rpm ranges above), θ0, α0 and r_d (seeded)."""
    rng = np.random.default_rng(seed)
    rpm = 2.0 * math.pi / 60.0
    w_r = rng.uniform(*OMEGA_R_RPM, count) * rpm
    w_v = rng.uniform(*OMEGA_V_RPM, count) * rpm
    theta0 = rng.uniform(-math.pi, math.pi, count)
    alpha0 = rng.uniform(0.0, 2.0 * math.pi, count)
    r_d = rng.uniform(*ECCENTRICITY_M, count)
    return [
        Scene(
            dataclasses.replace(model, eccentricity_m=float(r_d[k])),
            float(w_r[k]),
            float(w_v[k]),
            float(theta0[k]),
            float(alpha0[k]),
        )
        for k in range(count)
    ]


@dataclass
class Agreement:
    """Counts of a comparison and the scenes that disagree (index, what differed)."""

    scenes: int
    agree: int = 0
    disagreements: list[tuple[int, str]] = field(default_factory=list)
    largest_time_difference_s: float = 0.0

    @property
    def fraction(self) -> float:
        """Share of scenes that agree."""
        return self.agree / self.scenes if self.scenes else math.nan


def compare(scenes: list[Scene], time_tol_s: float = 1e-9, t_end_s: float = 5.0) -> Agreement:
    """Compiled batch against the reference engine on every scene (see module docstring)."""
    result = first_impacts(SceneBatch.from_scenes(scenes), rods="all", horizon_s=t_end_s)
    report = Agreement(len(scenes))
    for k, scene in enumerate(scenes):
        impacts = simulate(scene, t_end_s, stop_after_first=True).impacts
        row = result[k]
        if len(impacts) == 0 or not row["found"]:
            if len(impacts) == 0 and not row["found"]:
                report.agree += 1
            else:
                report.disagreements.append((k, f"reference found {len(impacts)}, kernel found {bool(row['found'])}"))
            continue
        ref = impacts[0]
        dt = abs(float(row["time_s"]) - float(ref["time_s"]))
        same_pair = {int(row["rod"]), int(row["partner"])} == {int(ref["rod"]), int(ref["partner"])}
        if same_pair and dt <= time_tol_s:
            report.agree += 1
            report.largest_time_difference_s = max(report.largest_time_difference_s, dt)
        else:
            report.disagreements.append(
                (
                    k,
                    f"reference t = {float(ref['time_s']):.12g} s rod {int(ref['rod'])}–{int(ref['partner'])}, "
                    f"kernel t = {float(row['time_s']):.12g} s rod {int(row['rod'])}–{int(row['partner'])}",
                )
            )
    return report


__all__ = ["Agreement", "compare", "random_scenes"]
