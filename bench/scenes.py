"""The benchmark's scenes: a seeded Latin hypercube over the operating space, plus the hard cases of MODEL-NOTES.

Every scene is a :class:`~millctl.physics.Scene` of Set A (corrected variant
unless a hard case needs the paper's), so the set is the same on every run and
every commit for a given seed and size.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from scipy.stats import qmc

from millctl.config import ModelVariant
from millctl.physics import MillModel, Scene
from millctl.units import rpm_to_rad_s

LHS_SEED = 20261121
"""Seed of the Latin hypercube (fixed: the scene set is part of the benchmark's definition)."""

OMEGA_R_RPM = (20.0, 220.0)
OMEGA_V_RPM = (0.0, 1200.0)
ECCENTRICITY_M = (0.0, 2e-3)
ZERO_RD_EVERY = 4
"""Every 4th sampled scene has r_d = 0, where the closed form is the reference."""


@dataclass(frozen=True)
class BenchScene:
    """A named scene; ``hard`` marks the MODEL-NOTES hard cases."""

    name: str
    scene: Scene
    hard: bool = False
    note: str = ""

    def describe(self) -> dict[str, float | int | str]:
        """The scene's parameters in rpm, rad and mm, for the JSON and the report."""
        s, m = self.scene, self.scene.model
        return {
            "name": self.name,
            "omega_r_rpm": s.omega_r_rad_s * 60.0 / (2.0 * math.pi),
            "omega_v_rpm": s.omega_v_rad_s * 60.0 / (2.0 * math.pi),
            "theta0_rad": s.theta0_rad,
            "alpha0_rad": s.alpha0_rad,
            "r_d_mm": m.eccentricity_m * 1e3,
            "n_rods": m.n_rods,
            "variant": m.variant.value,
            "note": self.note,
        }


def lhs_scenes(model: MillModel, count: int, seed: int = LHS_SEED) -> list[BenchScene]:
    """``count`` scenes from a scrambled Latin hypercube over ω_r, ω_v, θ0, α0 and r_d (seeded)."""
    if count <= 0:
        return []
    unit = qmc.LatinHypercube(d=5, rng=seed).random(count)
    lo = [OMEGA_R_RPM[0], OMEGA_V_RPM[0], -math.pi, 0.0, ECCENTRICITY_M[0]]
    hi = [OMEGA_R_RPM[1], OMEGA_V_RPM[1], math.pi, 2.0 * math.pi, ECCENTRICITY_M[1]]
    points = qmc.scale(unit, lo, hi)
    out = []
    for k, (w_r, w_v, theta0, alpha0, r_d) in enumerate(points):
        rd = 0.0 if k % ZERO_RD_EVERY == 0 else float(r_d)
        m = dataclasses.replace(model, eccentricity_m=rd)
        scene = Scene(m, float(rpm_to_rad_s(w_r)), float(rpm_to_rad_s(w_v)), float(theta0), float(alpha0))
        out.append(BenchScene(f"lhs-{k:03d}", scene))
    return out


def hard_scenes(model: MillModel) -> list[BenchScene]:
    """The MODEL-NOTES hard cases as scenes (``model`` is Set A, corrected)."""
    one_rod = dataclasses.replace(model, n_rods=1)
    flat = dataclasses.replace(one_rod, eccentricity_m=0.0)
    limit = math.sqrt(flat.g_m_s2 / flat.r0_m)
    paper = dataclasses.replace(model, variant=ModelVariant.PAPER)
    w_switch = math.sqrt(paper.spring_n_per_m / paper.rod_mass_kg)
    stiff = dataclasses.replace(paper, spring_n_per_m=2000.0)
    w_eq9 = math.sqrt(
        (stiff.spring_n_per_m - stiff.rod_mass_kg * stiff.g_m_s2 / stiff.eccentricity_m) / stiff.rod_mass_kg
    )
    packed = dataclasses.replace(model, rod_radius_m=model.vial_radius_m / 3.0 * (1.0 - 1e-9), n_rods=6)
    return [
        BenchScene(
            "near-limit",
            Scene(flat, limit * (1.0 - 1e-5), 0.0, -0.5 * math.pi, 0.0),
            True,
            "ω_r = (1 − 1e-5)·√(g/r0), r_d = 0, one rod: a ~1 ms flight",
        ),
        BenchScene(
            "N-grazes-zero",
            Scene(flat, limit * (1.0 - 1e-12), rpm_to_rad_s(800.0), -0.5 * math.pi, 0.0),
            True,
            "N's minimum −2e-12 g at the top, r_d = 0: a sub-µs flight",
        ),
        BenchScene(
            "gamma-1.5",
            Scene(model, 35.0, math.sqrt(1.5 * model.g_m_s2 / model.eccentricity_m), -0.5 * math.pi, 0.0),
            True,
            "Γ = 1.5: hops in most cam cycles",
        ),
        BenchScene(
            "k=m*omega_v^2",
            Scene(paper, 10.0, w_switch, -0.5 * math.pi, 0.4),
            True,
            "paper variant at k = mω_v² (the worst phase switches)",
        ),
        BenchScene(
            "eq9-numerator-0",
            Scene(stiff, 3.0, w_eq9, -0.5 * math.pi, 0.0),
            True,
            "paper variant, k = 2000 N/m: eq. 9's numerator ≈ 0",
        ),
        BenchScene(
            "packing-limit",
            Scene(packed, 10.0, 60.0, -0.5 * math.pi, 0.2),
            True,
            "r_r = r_v/3·(1 − 1e-9), n = 6: neighbours 1e-9 apart",
        ),
        BenchScene(
            "slow-long-flight",
            Scene(one_rod, 15.0, 80.0, -0.5 * math.pi, 0.3),
            True,
            "one rod, 15 rad/s: tiny steps fake a contact at departure",
        ),
    ]


def scene_set(model: MillModel, lhs_count: int, with_hard: bool = True) -> list[BenchScene]:
    """The sampled scenes followed by the hard cases."""
    return lhs_scenes(model, lhs_count) + (hard_scenes(model) if with_hard else [])
