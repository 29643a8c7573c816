"""The array path of a study (engine.evaluate_arrays) against the point-by-point metrics it replaces."""

from __future__ import annotations

import math

import numpy as np
import pytest

from millctl.config import MillConfig
from millctl.config.models import LimitLaw
from millctl.physics.limits import LimitParams, omega_r_max
from millctl.studies.arrays import ARRAY_METRICS
from millctl.studies.engine import ConstraintSpec, evaluate_arrays
from millctl.studies.metrics import DEFAULT_METRICS, PointSettings, compute_metrics
from millctl.units import rad_s_to_rpm, rpm_to_rad_s


def _close(a: float, b: float) -> bool:
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    if math.isinf(a) or math.isinf(b):
        return a == b
    return abs(a - b) <= 1e-12 * max(abs(a), abs(b), 1e-300)


@pytest.mark.parametrize("cam_phases", [3, 0], ids=["fixed-3-phases", "integrated"])
@pytest.mark.parametrize("variant", ["corrected", "paper"])
def test_every_level_a_and_b_metric_agrees_with_the_point_path(
    config: MillConfig, variant: str, cam_phases: int
) -> None:
    # standstill, pinned (low cam, fast vial), detaching, Γ ≥ 1 and micro-hops all on one grid
    rotary, vibration = np.meshgrid([0.0, 0.5, 5.0, 60.0, 200.0, 330.0], [0.0, 300.0, 800.0, 1500.0], indexing="ij")
    data = config.model_dump(mode="json")
    data["model"]["variant"] = variant
    base = MillConfig.model_validate(data)
    settings = PointSettings(cam_phases=cam_phases)
    assert set(DEFAULT_METRICS) <= set(ARRAY_METRICS)  # every one compared here has an array form
    out = evaluate_arrays(
        {"rotary_rpm": rotary.ravel(), "vibration_rpm": vibration.ravel()}, base, DEFAULT_METRICS, settings
    )
    for i, (r, v) in enumerate(zip(rotary.ravel(), vibration.ravel(), strict=True)):
        expected, events = compute_metrics(base, rpm_to_rad_s(r), rpm_to_rad_s(v), DEFAULT_METRICS, settings, 0)
        for name in DEFAULT_METRICS:
            assert _close(float(out[name][i]), expected[name]), (name, r, v, out[name][i], expected[name])
        assert out["events"][i] == events
    if cam_phases == 0:  # the integral refined some points further than others, and counted micro-hops apart
        assert len(set(out["cam_phases_used"].tolist())) > 1
    assert np.nanmax(out["milling_power_w"]) > 0.0


def test_slip_ride_metrics_join_the_array_metrics_point_by_point(config: MillConfig) -> None:
    names = ("milling_power_w", "slip_impact_fraction", "slip_milling_power_w")
    settings = PointSettings(cam_phases=0, slip_phases=4)
    out = evaluate_arrays({"rotary_rpm": np.array([60.0, 200.0]), "vibration_rpm": np.array([800.0, 800.0])},
                          config, names, settings)  # fmt: skip
    for i, r in enumerate((60.0, 200.0)):
        expected, events = compute_metrics(config, rpm_to_rad_s(r), rpm_to_rad_s(800.0), names, settings, 0)
        assert all(_close(float(out[n][i]), expected[n]) for n in names), (r, {n: out[n][i] for n in names}, expected)
        assert out["events"][i] == events


def test_constraints_name_the_value_and_the_bound_per_point(config: MillConfig) -> None:
    constraints = ConstraintSpec(law="corrected-every-phase", drives=True, max_vibration_rpm=900.0)
    rotary = np.array([50.0, 250.0, 50.0])
    vibration = np.array([400.0, 400.0, 1000.0])
    out = evaluate_arrays(
        {"rotary_rpm": rotary, "vibration_rpm": vibration}, config, ("gamma",), constraints=constraints
    )
    limit = (1.0 - config.interlock.margin) * float(
        rad_s_to_rpm(omega_r_max(LimitLaw.CORRECTED_EVERY_PHASE, LimitParams.from_config(config), rpm_to_rad_s(400.0)))
    )
    assert 50.0 < limit < 250.0
    assert out["feasible"].tolist() == [True, False, False]
    assert out["violations"][0] == ""
    assert f"ω_r = 250.0 rpm > {limit:.1f} rpm allowed by corrected-every-phase" in out["violations"][1]
    assert "ω_v = 1000.0 rpm > structural limit 900 rpm" in out["violations"][2]


def test_an_impossible_mill_is_reported_at_its_points_and_the_rest_evaluated(config: MillConfig) -> None:
    points = {
        "rotary_rpm": np.array([100.0, 100.0, 100.0]),
        "vibration_rpm": np.array([800.0, 800.0, 800.0]),
        "n_rods": np.array([6, 40, 6]),  # 40 rods of 6 mm do not fit on r0 = 18 mm
    }
    out = evaluate_arrays(points, config, ("milling_power_w",))
    assert out["feasible"].tolist() == [True, False, True]
    assert "40 rods" in out["violations"][1] and "packing limit" in out["violations"][1]
    assert math.isnan(out["milling_power_w"][1])
    assert out["milling_power_w"][0] == out["milling_power_w"][2] > 0.0


def test_arrays_of_unequal_length_are_refused(config: MillConfig) -> None:
    with pytest.raises(Exception, match="length 2"):
        evaluate_arrays({"rotary_rpm": np.zeros(2), "vibration_rpm": np.zeros(3)}, config, ("gamma",))


def test_workers_are_used_only_where_they_keep_80_percent_efficiency() -> None:
    from millctl.studies.backends import WORKER_STARTUP_S, SerialBackend, make_backend, point_cost_s, worth_workers

    # N·c ≥ 4·w·S: the smallest study that pays, on either side of it
    c = point_cost_s({"c"}, revolutions=1.0)
    smallest = math.ceil(4 * 2 * WORKER_STARTUP_S / c)
    assert worth_workers(smallest, c, 2) and not worth_workers(smallest - 1, c, 2)
    assert not worth_workers(10**9, c, 1)
    # the cost follows the study: more revolutions, fewer points to pay; a level-(a, b) map of 100 × 100 never
    assert point_cost_s({"c"}, revolutions=4.0) > 2.5 * c
    assert worth_workers(smallest // 2, point_cost_s({"c"}, revolutions=4.0), 2)
    assert point_cost_s({"a", "b"}) > point_cost_s({"a", "b"}, cam_phases=4) > point_cost_s({"a"})
    assert not worth_workers(100 * 100, point_cost_s({"a", "b"}), 2)
    assert isinstance(make_backend(None, None, 100 * 100, point_cost_s({"a", "b"})), SerialBackend)
    assert isinstance(make_backend(None, None, smallest - 1, c), SerialBackend)


def test_structural_constraints_break_the_same_points_as_the_point_path(config: MillConfig) -> None:
    from millctl.studies.engine import violations

    constraints = ConstraintSpec(law="none", drives=False, cam_contact=True, contact_fatigue=True)
    rotary = np.full(5, 100.0)
    vibration = np.array([300.0, 800.0, 1500.0, 2500.0, 4000.0])
    out = evaluate_arrays(
        {"rotary_rpm": rotary, "vibration_rpm": vibration}, config, ("follower_jump_margin_rpm",),
        constraints=constraints,
    )  # fmt: skip
    expected = ["; ".join(violations(config, 100.0, float(v), constraints)) for v in vibration]
    assert out["violations"].tolist() == expected
    assert out["feasible"].tolist() == [not e for e in expected]
    jumping = out["follower_jump_margin_rpm"] < 0.0
    assert jumping.any() and not jumping.all()  # the grid straddles the follower's jump speed
    assert all("the roller leaves the cam" in out["violations"][i] for i in np.flatnonzero(jumping))


def test_a_point_whose_slip_ride_fails_is_reported_and_the_rest_evaluated(config: MillConfig) -> None:
    # at 110/1000 rpm the slip ride chatters (2000 stick/slip changes): that point, not the study, fails
    names = ("milling_power_w", "slip_milling_power_w")
    out = evaluate_arrays(
        {"rotary_rpm": np.array([110.0, 200.0]), "vibration_rpm": np.array([1000.0, 1000.0])},
        config, names, PointSettings(slip_phases=4),
    )  # fmt: skip
    assert out["feasible"].tolist() == [False, True]
    assert out["violations"][0].startswith("slip ride chattered") and out["events"][0] == 0
    assert math.isnan(out["milling_power_w"][0]) and math.isnan(out["slip_milling_power_w"][0])
    assert out["milling_power_w"][1] > 0.0 and out["slip_milling_power_w"][1] >= 0.0
