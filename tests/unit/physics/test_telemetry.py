"""Level (b): the node's per-revolution summary."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import pytest

from millctl.config import MillConfig, ModelVariant
from millctl.errors import PhysicsInputError
from millctl.physics.limits import LimitParams, omega_r_max_paper_eq9
from millctl.physics.model import MillModel
from millctl.physics.telemetry import RevolutionSummary, revolution_summary
from millctl.units import rpm_to_rad_s


def test_from_config_takes_the_variant(config: MillConfig, set_a: MillModel) -> None:
    assert set_a.variant is ModelVariant(config.model.variant)
    assert set_a.r0_m == pytest.approx(0.018)
    assert set_a.rod_mass_kg == pytest.approx(0.0886, abs=5e-4)


@pytest.mark.parametrize("variant", list(ModelVariant))
@pytest.mark.parametrize("omega_r", [0.0, -0.0, 1e-9, -1e-3])
def test_standstill_is_pinned_and_never_raises(set_a: MillModel, variant: ModelVariant, omega_r: float) -> None:
    model = dataclasses.replace(set_a, variant=variant)
    s = revolution_summary(model, omega_r, rpm_to_rad_s(800.0))
    assert isinstance(s, RevolutionSummary)
    assert not s.detached and math.isnan(s.theta_d_rad)
    assert s.impact_rate_hz == 0.0 and s.impact_power_w == 0.0 and s.mean_impact_energy_j == 0.0


def test_corrected_set_a_detaches_and_counts_whole_mill(set_a_corrected: MillModel) -> None:
    w_r = rpm_to_rad_s(200.0)
    s = revolution_summary(set_a_corrected, w_r, rpm_to_rad_s(800.0))
    assert s.detached
    assert 0.0 < s.theta_d_rad < math.pi / 2
    # sin θ_d = r0 ω_r² / g_eff with g_eff within g(1 ± Γ)
    gamma = set_a_corrected.eccentricity_m * rpm_to_rad_s(800.0) ** 2 / set_a_corrected.g_m_s2
    lo = set_a_corrected.r0_m * w_r**2 / (set_a_corrected.g_m_s2 * (1 + gamma))
    assert math.sin(s.theta_d_rad) >= lo
    expected = set_a_corrected.n_rods * s.collisions_per_rod_rev * w_r / (2 * math.pi)
    assert s.impact_rate_hz == pytest.approx(expected, rel=1e-12)
    assert s.impact_power_w == pytest.approx(s.impact_rate_hz * s.mean_impact_energy_j, rel=1e-12)
    assert s.mean_impact_energy_j > 0.0 and s.mean_shear_pa > 0.0


def test_paper_rate_is_eq18_per_rod(set_a_paper: MillModel) -> None:
    w_r = rpm_to_rad_s(100.0)
    s = revolution_summary(set_a_paper, w_r, rpm_to_rad_s(800.0))
    assert s.detached
    assert s.impact_rate_hz == pytest.approx(s.collisions_per_rod_rev * w_r / (2 * math.pi), rel=1e-12)


def test_paper_pinned_above_its_best_phase_limit(set_a_paper: MillModel) -> None:
    """Above printed eq. 9 (k < mω_v² there, so eq. 9 is the paper's most permissive phase) nothing detaches."""
    w_v = rpm_to_rad_s(800.0)
    p = LimitParams(set_a_paper.rod_mass_kg, set_a_paper.r0_m, set_a_paper.eccentricity_m, set_a_paper.spring_n_per_m)
    limit = float(omega_r_max_paper_eq9(p, w_v))
    s = revolution_summary(set_a_paper, 1.01 * limit, w_v)
    assert not s.detached and s.impact_rate_hz == 0.0


def test_nonfinite_speed_rejected(set_a: MillModel) -> None:
    with pytest.raises(PhysicsInputError):
        revolution_summary(set_a, math.nan, 1.0)


@pytest.mark.parametrize(
    ("field", "value"),
    [("rod_radius_m", -0.006), ("vial_radius_m", 0.005), ("n_rods", 10), ("restitution", 1.5), ("rod_mass_kg", 0.0)],
)
def test_invalid_physical_inputs_rejected(set_a: MillModel, field: str, value: float) -> None:
    changes: dict[str, Any] = {field: value}
    with pytest.raises(PhysicsInputError):
        dataclasses.replace(set_a, **changes)


def test_packing_limit_is_exact(set_a: MillModel) -> None:
    """n at the packing limit: 2 r0 sin(π/n) = 2 r_r is allowed, a hair more rods' radius is not."""
    r_v = set_a.vial_radius_m
    # r0 sin(π/6) = r_r  ⇔  (r_v − r_r)/2 = r_r  ⇔  r_r = r_v/3
    ok = dataclasses.replace(set_a, rod_radius_m=r_v / 3 * (1 - 1e-12), n_rods=6)
    assert ok.n_rods == 6
    with pytest.raises(PhysicsInputError, match="packing limit"):
        dataclasses.replace(set_a, rod_radius_m=r_v / 3 * (1 + 1e-9), n_rods=6)


def test_summary_cache_rounds_to_its_grid(set_a_corrected: MillModel) -> None:
    from millctl.physics.telemetry import SummaryCache

    cache = SummaryCache(set_a_corrected, step_rpm=1.0)
    a = cache(rpm_to_rad_s(150.2), rpm_to_rad_s(799.9))
    assert a is cache(rpm_to_rad_s(149.8), rpm_to_rad_s(800.3))
    assert a == revolution_summary(set_a_corrected, rpm_to_rad_s(150.0), rpm_to_rad_s(800.0))
    with pytest.raises(PhysicsInputError):
        SummaryCache(set_a_corrected, step_rpm=0.0)


def test_start_angle_shortcut_matches_the_bottom_start(set_a_corrected: MillModel) -> None:
    """Starting each sample where detachment first becomes possible gives the same θ_d as starting at the bottom."""
    from millctl.physics.detachment import find_detachment
    from millctl.physics.model import Scene
    from millctl.physics.telemetry import _start_angle_rad

    w_r, w_v = rpm_to_rad_s(120.0), rpm_to_rad_s(800.0)
    start = _start_angle_rad(set_a_corrected, w_r, w_v)
    assert start is not None and -0.5 * math.pi < start
    bottom = Scene(set_a_corrected, w_r, w_v, -0.5 * math.pi, 0.3)
    det = find_detachment(bottom)
    t_s = (start + 0.5 * math.pi) / w_r  # when the bottom-started rod reaches the start angle
    later = Scene(set_a_corrected, w_r, w_v, start, 0.3 + w_v * t_s)
    assert find_detachment(later).theta_rad == pytest.approx(det.theta_rad, abs=1e-9)


def test_critical_point_at_t0_does_not_stall_the_root_finder(set_a_paper: MillModel) -> None:
    """Regression: paper, 30/1000 rpm put a root of N' at t = 0, where a purely relative tolerance never converges."""
    s = revolution_summary(set_a_paper, rpm_to_rad_s(30.0), rpm_to_rad_s(1000.0))
    assert isinstance(s, RevolutionSummary)


@pytest.mark.parametrize("variant", ["corrected", "paper"])
def test_compiled_summary_is_the_reference_summary(set_a: MillModel, variant: str) -> None:
    """The node's compiled level-(b) summary (issue 17) gives the numpy engine's numbers, field by field."""
    dc = dataclasses
    model = dc.replace(set_a, variant=ModelVariant(variant))
    for w_r in (5.0, 30.0, 80.0, 150.0, 199.0, 250.0, 400.0):
        for w_v in (0.0, 300.0, 800.0, 1200.0):
            args = (model, rpm_to_rad_s(w_r), rpm_to_rad_s(w_v))
            compiled = dc.astuple(revolution_summary(*args))
            reference = dc.astuple(revolution_summary(*args, engine="reference"))
            for name, a, b in zip([f.name for f in dc.fields(RevolutionSummary)], compiled, reference, strict=True):
                if isinstance(a, float) and math.isnan(a):
                    assert math.isnan(b), (w_r, w_v, name)
                else:
                    assert a == pytest.approx(b, rel=1e-9, abs=1e-30), (w_r, w_v, name)


def test_samples_at_chosen_phases_are_the_fixed_phase_samples_bit_for_bit(config: MillConfig) -> None:
    import numpy as np

    from millctl.physics import kernels
    from millctl.studies.arrays import FLIGHT_CAP_S, PointArrays

    model = MillModel.from_config(config)
    points = PointArrays(config, model, rpm_to_rad_s(np.array([60.0, 200.0, 5.0])), rpm_to_rad_s(np.full(3, 800.0)))
    start, pinned = points.start_angles()
    rows, mu = points.rows(start), model.powder_friction
    sixteen = kernels.telemetry_batch(rows, start, pinned, 16, FLIGHT_CAP_S, mu)
    scene = np.array([2, 0, 1, 1, 0])  # any order, any scene twice
    k = np.array([3, 15, 0, 7, 8])
    at = kernels.telemetry_at(rows, start, pinned, scene, 2.0 * math.pi * k / 16, FLIGHT_CAP_S, mu)
    assert np.array_equal(at, sixteen[scene, k], equal_nan=True)
    assert not np.array_equal(at[1], at[4], equal_nan=True)  # two phases of one scene: two samples
    with pytest.raises(ValueError, match=r"scene_index must lie in \[0, 3\), got 0\.\.3"):
        kernels.telemetry_at(rows, start, pinned, np.array([0, 3]), np.zeros(2), FLIGHT_CAP_S, mu)
