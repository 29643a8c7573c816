"""The adaptive cam-phase integral of level (b) (millctl.studies.phase_integral) against fixed fine phases."""

from __future__ import annotations

import math

import numpy as np

from millctl.config import MillConfig
from millctl.physics import kernels
from millctl.physics.model import MillModel
from millctl.studies import phase_integral as pi
from millctl.studies.loads import impact_threshold_j
from millctl.units import rpm_to_rad_s

RTOL = 0.01


def _speeds(*rpm: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    r, v = zip(*rpm, strict=True)
    return rpm_to_rad_s(np.array(r)), rpm_to_rad_s(np.array(v))


def _fixed(model: MillModel, w_r: np.ndarray, w_v: np.ndarray, k: int) -> dict[str, np.ndarray]:
    """The summary at k even phases through the same weighted sums (unit weights)."""
    start, pinned = pi.start_angles(model, w_r, w_v)
    rows = pi.scene_rows(model, w_r, w_v, start)
    point = np.repeat(np.arange(w_r.size, dtype=np.int64), k)
    phases = np.tile(2.0 * math.pi * np.arange(k) / k, w_r.size)
    table = kernels.telemetry_at(rows, start, pinned, point, phases, pi.FLIGHT_CAP_S, model.powder_friction)
    return pi.weighted_summary(model, w_r, impact_threshold_j(model), point, np.ones(point.size), table)


def _integrated(model: MillModel, w_r: np.ndarray, w_v: np.ndarray) -> dict[str, np.ndarray]:
    return pi.integrated_summary(model, w_r, w_v, impact_threshold_j(model), RTOL)


def test_a_window_between_the_first_samples_is_found(config: MillConfig) -> None:
    # two points of the benchmark's 100 × 100 map where nothing lands for 1.2–2 % of the cam phases, a window
    # narrower than the first intervals and beside the departure's lift-cycle jump, whose ends land alike in
    # power: refined only where the power's trapezoid moves, the window stays unseen
    model = MillModel.from_config(config)
    rotary, vibration = np.linspace(20.0, 300.0, 100), np.linspace(200.0, 1200.0, 100)
    w_r, w_v = _speeds((rotary[48], vibration[38]), (rotary[54], vibration[54]))
    fine, sixteen, out = _fixed(model, w_r, w_v, 4096), _fixed(model, w_r, w_v, 16), _integrated(model, w_r, w_v)
    assert np.all(sixteen["detach_fraction"] == 1.0) and np.all(fine["detach_fraction"] < 0.99)
    assert np.all(np.abs(out["detach_fraction"] - fine["detach_fraction"]) <= RTOL)
    error = np.abs(out["impact_power_w"] - fine["impact_power_w"]) / fine["impact_power_w"]
    assert np.all(error <= RTOL), error
    assert np.all(out["cam_phase_error"] <= RTOL) and np.all(out["cam_phases_used"] > 16)


def test_smooth_and_pinned_points_stop_early_and_meet_the_error(config: MillConfig) -> None:
    model = MillModel.from_config(config)
    w_r, w_v = _speeds((150.0, 800.0), (280.0, 300.0), (0.0, 800.0), (60.0, 1100.0))
    fine, out = _fixed(model, w_r, w_v, 2048), _integrated(model, w_r, w_v)
    pinned = pi.start_angles(model, w_r, w_v)[1]
    assert pinned.tolist() == [False, True, True, False]
    assert np.all(out["cam_phases_used"][pinned] == 16)  # nothing lands: the first 16 samples say all
    for name in ("detach_fraction", "slip_fraction"):
        assert np.all(np.abs(out[name] - fine[name]) <= RTOL), (name, out[name], fine[name])
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = out["impact_power_w"] / fine["impact_power_w"]
        error = np.where(fine["impact_power_w"] > 0.0, np.abs(ratio - 1.0), 0.0)
    assert np.all(error <= RTOL), error
    assert np.all(out["cam_phases_used"] <= pi.MAX_CAM_PHASES + 64)


def test_a_point_gets_the_same_numbers_alone_and_in_a_batch(config: MillConfig) -> None:
    model = MillModel.from_config(config)
    w_r, w_v = _speeds((201.010101010101, 977.7777777777777), (150.0, 800.0), (40.0, 1200.0), (280.0, 300.0))
    batch = _integrated(model, w_r, w_v)
    for i in range(w_r.size):
        alone = _integrated(model, w_r[i : i + 1], w_v[i : i + 1])
        for name, values in alone.items():
            assert np.array_equal(values, batch[name][i : i + 1], equal_nan=True), (i, name)


def test_unit_weights_at_even_phases_are_the_fixed_phase_summary(config: MillConfig) -> None:
    from millctl.studies.arrays import PointArrays

    model = MillModel.from_config(config)
    w_r, w_v = _speeds((201.010101010101, 977.7777777777777), (150.0, 800.0), (0.5, 300.0))
    fixed = PointArrays(config, model, w_r, w_v, cam_phases=8).summary()
    ours = _fixed(model, w_r, w_v, 8)
    for name, values in ours.items():
        assert np.array_equal(values, fixed[name], equal_nan=True), name


def test_a_tighter_tolerance_takes_more_samples_and_lands_closer(config: MillConfig) -> None:
    model = MillModel.from_config(config)
    w_r, w_v = _speeds((96.36363636363636, 775.7575757575758), (150.0, 800.0))
    threshold, fine = impact_threshold_j(model), _fixed(model, w_r, w_v, 4096)
    runs = {rtol: pi.integrated_summary(model, w_r, w_v, threshold, rtol) for rtol in (0.05, 0.002)}
    error = {rtol: np.abs(out["impact_power_w"] / fine["impact_power_w"] - 1.0) for rtol, out in runs.items()}
    for rtol, out in runs.items():
        assert np.all(out["cam_phase_error"] <= rtol) and np.all(error[rtol] <= rtol), (rtol, error[rtol])
    assert np.all(runs[0.002]["cam_phases_used"] > runs[0.05]["cam_phases_used"])


def test_no_points_give_empty_columns(config: MillConfig) -> None:
    model = MillModel.from_config(config)
    none = np.zeros(0)
    out = _integrated(model, none, none)
    assert out["cam_phases_used"].shape == (0,) and out["impact_power_w"].shape == (0,)


def test_the_rules_samples_are_a_periodic_trapezoid_of_their_phases(config: MillConfig) -> None:
    # each point's samples: distinct phases in [0, 2π) whose weights are half the gaps to both neighbours
    model = MillModel.from_config(config)
    w_r, w_v = _speeds((201.010101010101, 977.7777777777777), (150.0, 800.0), (280.0, 300.0), (96.4, 775.8))
    table, phase, weight, owner, used, error = pi.integral_samples(model, w_r, w_v, impact_threshold_j(model), RTOL)
    assert table.shape == (phase.size, 10) and np.all(np.diff(owner) >= 0)
    assert np.array_equal(np.bincount(owner, minlength=w_r.size), used) and np.all(error <= RTOL)
    for i in range(w_r.size):
        mine = owner == i
        order = np.argsort(phase[mine])
        nodes, weights = phase[mine][order], weight[mine][order]
        assert nodes[0] == 0.0 and nodes[-1] < 2.0 * math.pi and np.all(np.diff(nodes) > 0.0)
        gaps = np.diff(np.append(nodes, 2.0 * math.pi))
        assert np.allclose(weights, 0.5 * (gaps + np.roll(gaps, 1)), rtol=1e-12, atol=0.0)
    assert used[2] == 16 and used[0] > 16  # a pinned point stops at the first 16, a detaching one refines
