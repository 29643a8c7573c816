"""Level (b) of many points: the per-revolution summary from weighted cam-phase samples, and its adaptive integral.

A level-(b) summary (:func:`millctl.physics.telemetry.revolution_summary`) is a mean over the cam's lift
phase α0 at the moment rod 0 reaches its start angle: sample s of point i is rod 0's one-rod event and
no-slip check from that phase (:func:`millctl.physics.kernels.telemetry_at`), and every mean of the
summary is Σ w_s x_s / Σ w_s over the point's samples. :func:`weighted_summary` computes them for any
weights: 1 at K even phases is the K-phase summary; the trapezoid weights of an adaptive set of phases
integrate over α0 (:func:`integrated_summary`).

The integrand is piecewise smooth in α0. It jumps where detaching starts or stops, where a landing
crosses the impact threshold or the slip check changes its verdict, and where the detachment moves to
the next lift cycle (the held path just grazes the region where N < 0). Even phases integrate a smooth
periodic function fast but a jump only to O(h), so doubling K everywhere spends the samples on the
smooth arcs and still misses the stated error near the jumps. The rule here refines where the samples
say the integrand does not yet follow its trapezoid:

1. K0 = 8 even phases, every interval bisected once: the 16 even phases' samples, bit for bit;
2. bisecting an interval of width h changes its trapezoid by Δ = (h/2π)(2 F_m − F_a − F_b)/4 in each
   of four means: the counted share A (landings at or above the impact threshold), B = mean of the
   counted p (collisions per revolution), C = mean of the counted energy, and the slipping share D.
   The milling power is ∝ B·C/A, so its relative error is at most |ΔA|/A + |ΔB|/B + |ΔC|/C; the
   shares' errors are absolute. The interval's score is
   ε = max(|ΔA|, |ΔD|, |ΔA|/A + |ΔB|/B + |ΔC|/C) / rtol, and each half takes ε/2: for a jump in the
   interval that is the largest error the halves' trapezoids can have (|jump|·h/4 between them); for a
   smooth integrand three times the trapezoid's error after the bisection;
3. a point whose scores sum to more than 1 bisects every interval scoring more than its equal share
   1/n of the budget (n its intervals), down to :data:`FINEST_PHASE_RAD`, until the sum is ≤ 1 or the
   point has taken :data:`MAX_CAM_PHASES` samples. ``cam_phase_error`` is rtol times that sum: the
   estimate of the larger of the power's relative and the shares' absolute error.

Every point is refined from its own samples only, so a point's answer does not depend on the others
in its batch: one point alone (:func:`millctl.studies.metrics.cam_phase_summary`) gets the same numbers.
The rule runs compiled, point by point, with the samples (:mod:`millctl.physics.kernels.phase_rule`);
the summary's weighted sums are numpy, here.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from millctl.config.models import ModelVariant
from millctl.physics import kernels
from millctl.physics.cam import strokes
from millctl.physics.impact import contact_radius_m, effective_modulus_pa
from millctl.physics.kernels.phase_rule import FINEST_PHASE_RAD, FIRST_PHASES, MAX_CAM_PHASES
from millctl.physics.model import MillModel, Scene
from millctl.physics.telemetry import MIN_OMEGA_R_RAD_S

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

FLIGHT_CAP_S = 2.0
"""Longest flight a level-(b) sample follows (s), as :mod:`millctl.physics.telemetry`."""
_TWO_PI = 2.0 * math.pi
_SHEAR_SINES = tuple(math.sin(2.0 * math.pi * (k + 0.5) / 16) for k in range(16))
_COLUMN = {name: k for k, name in enumerate(kernels.TELEMETRY)}


def start_angles(model: MillModel, w_r: FloatArray, w_v: FloatArray) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Where a rod carried from the bottom can first detach, and the points where none can (telemetry.py).

    N/m = A − g_eff sin θ with g_eff ∈ [g − c, g + c]: the sample starts at sin θ = A/(g + c) − 1e-9 rad,
    at the bottom when g − c < 0; pinned where A ≥ g + c.
    """
    m = model
    w_lift = strokes(m.cam) * w_v
    if m.variant is ModelVariant.CORRECTED:
        a, c = m.r0_m * w_r * w_r, np.abs(m.eccentricity_m * w_lift * w_lift)
    else:
        a = 2.0 * m.r0_m * w_r * w_r
        c = np.abs((w_lift * w_lift - m.spring_n_per_m / m.rod_mass_kg) * m.eccentricity_m)
    c = 2.0 * np.abs(0.5 * c)
    g_max, g_min = m.g_m_s2 + c, m.g_m_s2 - c
    pinned = ((g_min >= 0.0) & (a >= g_max)) | (w_r < MIN_OMEGA_R_RAD_S)  # standstill: telemetry.py's pinned
    with np.errstate(invalid="ignore"):
        start = np.where(g_min < 0.0, -0.5 * math.pi, np.arcsin(np.minimum(a / g_max, 1.0)) - 1e-9)
    return np.where(pinned, -0.5 * math.pi, start), pinned


def scene_rows(model: MillModel, w_r: FloatArray, w_v: FloatArray, theta0_rad: FloatArray) -> FloatArray:
    """Kernel parameter rows (:data:`~millctl.physics.kernels.PARAMS`) of the points, rod 0 at θ0, α0 = 0."""
    rows = np.tile(kernels.scene_row(Scene(model, 0.0, 0.0)), (w_r.size, 1))
    rows[:, kernels.PARAMS.index("omega_r_rad_s")] = w_r
    rows[:, kernels.PARAMS.index("omega_v_rad_s")] = strokes(model.cam) * w_v
    rows[:, kernels.PARAMS.index("theta0_rad")] = theta0_rad
    return rows


def mean_shear_pa(model: MillModel, w_r: FloatArray) -> FloatArray:
    """Eq. 25 averaged over the pinned arc (telemetry._mean_shear_pa), τ = μ p_av, p_av = N/(2 L b); 0 at standstill."""
    e_star, r = effective_modulus_pa(model), contact_radius_m(model)
    factor = math.pi / 4.0 if model.variant is ModelVariant.PAPER else 4.0 / math.pi
    length = model.rod_length_m

    def shear(load: FloatArray) -> FloatArray:
        n = np.maximum(load, 0.0)
        b = np.sqrt(factor * n * r / (length * e_star))
        with np.errstate(invalid="ignore", divide="ignore"):
            pressure = np.where(b > 0.0, load / (2.0 * length * b), 0.0)
        result: FloatArray = model.powder_friction * pressure
        return result

    m = model.rod_mass_kg
    if model.variant is ModelVariant.PAPER:
        total = shear(m * w_r * w_r * model.r0_m)
    else:
        centripetal = model.r0_m * w_r * w_r
        total = np.zeros_like(w_r)
        for s in _SHEAR_SINES:
            total = total + shear(np.maximum(centripetal - model.g_m_s2 * s, 0.0) * m)
        total = total / len(_SHEAR_SINES)
    result: FloatArray = np.where(w_r < MIN_OMEGA_R_RAD_S, 0.0, total)
    return result


def _by_point(point: IntArray, weights: FloatArray, size: int) -> FloatArray:
    """Σ of ``weights`` by ``point`` (shape (size,)), each point's in their order."""
    return np.asarray(np.bincount(point, weights=weights, minlength=size), dtype=np.float64)


def _per_sample(w_r: FloatArray, threshold_j: float, t: FloatArray) -> dict[str, NDArray[Any]]:
    """Per sample (``w_r`` its point's): counted, landed, slipping (0/1) and collisions per revolution p."""
    moving = w_r >= MIN_OMEGA_R_RAD_S
    landed = (t[:, _COLUMN["found"]] == 1.0) & moving
    counted = landed & (t[:, _COLUMN["energy_j"]] >= threshold_j)  # below it: a micro-hop, not an impact
    theta_d, theta_c = t[:, _COLUMN["theta_d_rad"]], t[:, _COLUMN["theta_contact_rad"]]
    flight = t[:, _COLUMN["flight_time_s"]]
    with np.errstate(invalid="ignore", divide="ignore"):
        travel = np.mod(theta_d - theta_c, 2.0 * math.pi)
        cycle_s = flight + travel / w_r
        wall_rev = np.where(cycle_s > 0.0, 2.0 * math.pi / (w_r * cycle_s), 1.0)
    per_rev = np.where(t[:, _COLUMN["on_wall"]] == 1.0, wall_rev, 1.0)
    slipping = np.isfinite(t[:, _COLUMN["slip_theta_rad"]]) & moving
    return {"counted": counted, "landed": landed, "slipping": slipping, "per_rev": per_rev}


def weighted_summary(
    model: MillModel, w_r: FloatArray, threshold_j: float, point: IntArray, weight: FloatArray, t: FloatArray
) -> dict[str, FloatArray]:
    """revolution_summary's fields for P points (``w_r`` shape (P,)) from weighted samples.

    Entry s: point ``point[s]``, weight ``weight[s]`` > 0, telemetry row ``t[s]``; a point's entries
    are summed in their order. Unit weights at K even phases give the K-phase summary's formulas.
    """
    size = w_r.size
    x = _per_sample(w_r[point], threshold_j, t)
    counted = x["counted"]

    def total(values: NDArray[Any], where: NDArray[np.bool_] | None = None) -> FloatArray:
        v = weight * values if where is None else np.where(where, weight * values, 0.0)
        return _by_point(point, v, size)

    sum_w, count = total(np.ones_like(weight)), total(counted.astype(float))
    theta_d = t[:, _COLUMN["theta_d_rad"]]
    sin_d, cos_d = total(np.sin(theta_d), counted), total(np.cos(theta_d), counted)
    per_rev, energy = total(x["per_rev"], counted), total(t[:, _COLUMN["energy_j"]], counted)
    flight = total(t[:, _COLUMN["flight_time_s"]], counted)
    wall = total(np.ones_like(weight), counted & (t[:, _COLUMN["on_wall"]] == 1.0))
    slip = t[:, _COLUMN["slip_theta_rad"]]
    slipping = x["slipping"]
    slip_sin, slip_cos, slip_w = total(np.sin(slip), slipping), total(np.cos(slip), slipping), total(slipping * 1.0)
    below = total(np.ones_like(weight), x["landed"] & ~counted)
    detached = (count > 0.0) & (w_r >= MIN_OMEGA_R_RAD_S)
    violated = slip_w > 0.0
    with np.errstate(invalid="ignore", divide="ignore"):
        fraction = np.where(detached, count / sum_w, 0.0)
        p = np.where(detached, fraction * per_rev / count, 0.0)
        per_rod = p * w_r / (2.0 * math.pi)
        rate = per_rod if model.variant is ModelVariant.PAPER else model.n_rods * per_rod
        mean_energy = np.where(detached, energy / count, 0.0)
        return {
            "detached": detached.astype(float),
            "theta_d_rad": np.where(detached, np.arctan2(sin_d, cos_d), math.nan),
            "impact_rate_hz": np.where(detached, rate, 0.0),
            "mean_impact_energy_j": mean_energy,
            "impact_power_w": np.where(detached, rate * mean_energy, 0.0),
            "mean_shear_pa": mean_shear_pa(model, w_r),
            "detach_fraction": fraction,
            "collisions_per_rod_rev": p,
            "mean_flight_time_s": np.where(detached, flight / count, math.nan),
            "wall_impact_fraction": np.where(detached, wall / count, math.nan),
            "no_slip_violated": violated.astype(float),
            "slip_onset_theta_rad": np.where(violated, np.arctan2(slip_sin, slip_cos), math.nan),
            "slip_fraction": slip_w / sum_w,
            "sub_threshold_fraction": below / sum_w,
        }


def integrated_summary(
    model: MillModel, w_r: FloatArray, w_v: FloatArray, threshold_j: float, rtol: float
) -> dict[str, FloatArray]:
    """:func:`weighted_summary` integrated over the lift phase to ``rtol`` (the module docstring's rule).

    Also ``cam_phases_used`` (samples a point took) and ``cam_phase_error`` (its error estimate). The rule
    runs compiled, point by point (:func:`millctl.physics.kernels.phase_integral`); the summary's sums here.
    """
    table, _, weight, owner, used, error = integral_samples(model, w_r, w_v, threshold_j, rtol)
    out = weighted_summary(model, w_r, threshold_j, owner, weight, table)
    out["cam_phases_used"], out["cam_phase_error"] = used, error
    return out


def integral_samples(
    model: MillModel, w_r: FloatArray, w_v: FloatArray, threshold_j: float, rtol: float
) -> tuple[FloatArray, FloatArray, FloatArray, IntArray, FloatArray, FloatArray]:
    """The rule's samples of every point: (telemetry rows, lift phases, trapezoid weights, owners, used, error)."""
    start, pinned = start_angles(model, w_r, w_v)
    with np.errstate(divide="ignore"):
        lift = _TWO_PI / (strokes(model.cam) * w_v)
    return kernels.phase_integral(
        scene_rows(model, w_r, w_v, start), start, pinned, lift, MIN_OMEGA_R_RAD_S, threshold_j, rtol,
        FLIGHT_CAP_S, model.powder_friction,
    )  # fmt: skip


__all__ = [
    "FINEST_PHASE_RAD",
    "FIRST_PHASES",
    "FLIGHT_CAP_S",
    "MAX_CAM_PHASES",
    "integral_samples",
    "integrated_summary",
    "mean_shear_pa",
    "scene_rows",
    "start_angles",
    "weighted_summary",
]
