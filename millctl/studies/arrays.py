"""Metrics as vectorised functions of arrays: many points of one mill in one compiled call (issue 40).

A :class:`PointArrays` holds P points of one mill design (one :class:`~millctl.config.MillConfig`,
one :class:`~millctl.physics.model.MillModel`) at P pairs of speeds, as arrays. An array metric
is a function ``PointArrays -> FloatArray`` of shape (P,), registered by name in
:data:`ARRAY_METRICS` (:func:`array_metric`). Levels of detail are computed once per
``PointArrays`` and shared by every metric that reads them:

* level (a): the closed forms, straight numpy over ω_v and ω_r;
* level (b): :meth:`PointArrays.telemetry` — the node telemetry's K cam-phase samples of
  every point from one call of :func:`millctl.physics.kernels.telemetry_batch`, shape (P, K)
  per column of :data:`~millctl.physics.kernels.TELEMETRY` — and :meth:`PointArrays.summary`,
  the per-revolution summary of :func:`millctl.physics.telemetry.revolution_summary` as arrays,
  landings below the impact threshold (:func:`millctl.studies.loads.impact_threshold_j`) not
  counted; with ``cam_phases`` 0 integrated over the cam phase as
  :func:`millctl.studies.metrics.cam_phase_summary` does it (K = 8, 16, ... for every point at
  once, each point kept at the first doubling that changes it by ≤ rtol, the rest refined). The
  same formulas, the same numbers to rounding (``tests/unit/studies/test_arrays.py``).

Nothing here builds a configuration, a model or a scene per point, and nothing validates per
point: a group's model was validated once when the group was made
(:func:`millctl.studies.engine.evaluate_arrays`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from millctl.config.models import LimitLaw, MillConfig, ModelVariant
from millctl.physics import kernels
from millctl.physics.cam import strokes
from millctl.physics.limits import LimitParams, omega_r_max, vibration_intensity
from millctl.physics.model import MillModel, Scene
from millctl.physics.telemetry import MIN_OMEGA_R_RAD_S
from millctl.studies.loads import impact_loads, impact_threshold_j, structural_metrics
from millctl.studies.metrics import MAX_CAM_PHASES

FloatArray = NDArray[np.float64]
ArrayMetric = Callable[["PointArrays"], FloatArray]

FLIGHT_CAP_S = 2.0
"""Longest flight a level-(b) sample follows (s), as :mod:`millctl.physics.telemetry`."""
_SHEAR_SINES = tuple(math.sin(2.0 * math.pi * (k + 0.5) / 16) for k in range(16))
_RPM_PER_RAD_S = 60.0 / (2.0 * math.pi)


@dataclass
class PointArrays:
    """P points of one mill: its configuration and model, and the speeds of each point (rad/s, shape (P,))."""

    config: MillConfig
    model: MillModel
    omega_r_rad_s: FloatArray
    """ω_r of every point (rad/s, ≥ 0)."""
    omega_v_rad_s: FloatArray
    """ω_v, the cam motor's speed, of every point (rad/s, ≥ 0)."""
    cam_phases: int = 4
    """K, the level-(b) samples over one lift cycle; 0: integrate over the phase to ``cam_phase_rtol``."""
    revolutions: float = 4.0
    """Length of a level-(c) simulation (revolutions)."""
    seeds: NDArray[np.uint64] | None = None
    """One seed per point for level (c) (:func:`millctl.studies.engine.point_seed`)."""
    cam_phase_rtol: float = 0.01
    """Level (b) with ``cam_phases`` 0: the relative change of milling power and detaching share to stop at."""
    _cache: dict[str, Any] = field(default_factory=dict, repr=False)

    @property
    def size(self) -> int:
        """P, the number of points."""
        return int(self.omega_r_rad_s.size)

    @property
    def limit_params(self) -> LimitParams:
        """The interlock's parameters of this mill (:meth:`LimitParams.from_config`)."""
        cached = self._cache.get("limit_params")
        if cached is None:
            cached = self._cache["limit_params"] = LimitParams.from_config(self.config)
        params: LimitParams = cached
        return params

    @property
    def impact_threshold_j(self) -> float:
        """Below this energy a landing is a micro-hop, not an impact (J; :func:`.loads.impact_threshold_j`)."""
        cached = self._cache.get("impact_threshold_j")
        if cached is None:
            cached = self._cache["impact_threshold_j"] = impact_threshold_j(self.model)
        threshold: float = cached
        return threshold

    def subset(self, index: NDArray[np.int64], cam_phases: int) -> PointArrays:
        """The points ``index`` of this mill, sampled at ``cam_phases`` fixed phases (its mill's caches shared)."""
        shared = {k: v for k, v in self._cache.items() if k in ("limit_params", "impact_threshold_j")}
        return PointArrays(
            self.config, self.model, self.omega_r_rad_s[index], self.omega_v_rad_s[index], cam_phases,
            self.revolutions, None if self.seeds is None else self.seeds[index], self.cam_phase_rtol, shared,
        )  # fmt: skip

    def rows(self, theta0_rad: FloatArray) -> FloatArray:
        """Kernel parameter rows (:data:`~millctl.physics.kernels.PARAMS`) of the points, rod 0 at θ0, α0 = 0."""
        rows = np.tile(kernels.scene_row(Scene(self.model, 0.0, 0.0)), (self.size, 1))
        rows[:, kernels.PARAMS.index("omega_r_rad_s")] = self.omega_r_rad_s
        rows[:, kernels.PARAMS.index("omega_v_rad_s")] = strokes(self.model.cam) * self.omega_v_rad_s
        rows[:, kernels.PARAMS.index("theta0_rad")] = theta0_rad
        return rows

    def start_angles(self) -> tuple[FloatArray, NDArray[np.bool_]]:
        """Where a rod carried from the bottom can first detach, and the points where none can (telemetry.py).

        N/m = A − g_eff sin θ with g_eff ∈ [g − c, g + c]: the sample starts at sin θ = A/(g + c) − 1e-9 rad,
        at the bottom when g − c < 0; pinned where A ≥ g + c.
        """
        m, w_r = self.model, self.omega_r_rad_s
        w_lift = strokes(m.cam) * self.omega_v_rad_s
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

    def telemetry(self) -> dict[str, FloatArray]:
        """The K samples of every point, one (P, K) array per :data:`~millctl.physics.kernels.TELEMETRY` column."""
        if self.cam_phases < 1:
            raise ValueError(f"telemetry needs cam_phases ≥ 1, got {self.cam_phases} (0 integrates: use summary())")
        cached = self._cache.get("telemetry")
        if cached is None:
            start, pinned = self.start_angles()
            table = kernels.telemetry_batch(
                self.rows(start), start, pinned, self.cam_phases, FLIGHT_CAP_S, self.model.powder_friction
            )
            cached = self._cache["telemetry"] = {name: table[:, :, k] for k, name in enumerate(kernels.TELEMETRY)}
        telemetry: dict[str, FloatArray] = cached
        return telemetry

    def summary(self) -> dict[str, FloatArray]:
        """:class:`~millctl.physics.telemetry.RevolutionSummary`'s fields as arrays (P,), the same formulas.

        Also ``cam_phases_used`` and ``cam_phase_error`` (nan at fixed phases), as
        :func:`millctl.studies.metrics.cam_phase_summary` returns them.
        """
        cached = self._cache.get("summary")
        if cached is None:
            if self.cam_phases >= 1:
                cached = _summary(self) | {
                    "cam_phases_used": np.full(self.size, float(self.cam_phases)),
                    "cam_phase_error": np.full(self.size, math.nan),
                }
            else:
                cached = _integrated(self)
            self._cache["summary"] = cached
        summary: dict[str, FloatArray] = cached
        return summary

    def structure(self) -> dict[str, FloatArray]:
        """The level-(a) structural loads of every point (:func:`~millctl.studies.loads.structural_metrics`)."""
        cached = self._cache.get("structure")
        if cached is None:
            cached = self._cache["structure"] = structural_metrics(self.config, self.omega_r_rad_s, self.omega_v_rad_s)
        loads: dict[str, FloatArray] = cached
        return loads


def _integrated(points: PointArrays) -> dict[str, FloatArray]:
    """The summary integrated over the cam phase, every point as :func:`~millctl.studies.metrics.cam_phase_summary`.

    K = 8, then 16, 32, ... for the points not yet settled: a point settles at the first doubling
    that changes its milling power (relative) and its detaching share by ≤ rtol, or at
    :data:`MAX_CAM_PHASES`; its summary is the finer one, its error that last change.
    """
    size = points.size
    out: dict[str, FloatArray] = {}
    active = np.arange(size, dtype=np.int64)
    k = 8
    first = points.subset(active, k)
    coarse, samples = _summary(first), first.telemetry()
    while active.size:
        fine = points.subset(active, 2 * k)
        fine._cache["telemetry"] = samples = _doubled(fine, samples)
        finer = _summary(fine)
        k *= 2
        new, old = finer["impact_power_w"], coarse["impact_power_w"]
        scale = np.maximum(np.abs(new), np.abs(old))
        with np.errstate(invalid="ignore", divide="ignore"):
            error = np.where(scale > 0.0, np.abs(new - old) / np.where(scale > 0.0, scale, 1.0), 0.0)
        share = np.abs(finer["detach_fraction"] - coarse["detach_fraction"])
        done = ((error <= points.cam_phase_rtol) & (share <= points.cam_phase_rtol)) | (k >= MAX_CAM_PHASES)
        settled = active[done]
        for name, values in finer.items():
            out.setdefault(name, np.full(size, math.nan))[settled] = values[done]
        out.setdefault("cam_phases_used", np.zeros(size))[settled] = float(k)
        out.setdefault("cam_phase_error", np.full(size, math.nan))[settled] = error[done]
        active = active[~done]
        coarse = {name: values[~done] for name, values in finer.items()}
        samples = {name: values[~done] for name, values in samples.items()}
    return out


def _doubled(fine: PointArrays, coarse: dict[str, FloatArray]) -> dict[str, FloatArray]:
    """The 2K samples of ``fine`` from its points' K samples and one kernel call for the K odd phases.

    Phase j of 2K is 2πj/(2K): the even ones are the K phases' (bit for bit), the odd ones new.
    """
    start, pinned = fine.start_angles()
    half = fine.cam_phases // 2
    odd = kernels.telemetry_batch(
        fine.rows(start), start, pinned, half, FLIGHT_CAP_S, fine.model.powder_friction, odd_of_double=True
    )
    both: dict[str, FloatArray] = {}
    for column, name in enumerate(kernels.TELEMETRY):
        table = np.empty((fine.size, fine.cam_phases))
        table[:, 0::2], table[:, 1::2] = coarse[name], odd[:, :, column]
        both[name] = table
    return both


def _mean_shear_pa(model: MillModel, w_r: FloatArray) -> FloatArray:
    """Eq. 25 averaged over the pinned arc (telemetry._mean_shear_pa), τ = μ p_av, p_av = N/(2 L b)."""
    from millctl.physics.impact import contact_radius_m, effective_modulus_pa

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
        return shear(m * w_r * w_r * model.r0_m)
    centripetal = model.r0_m * w_r * w_r
    total = np.zeros_like(w_r)
    for s in _SHEAR_SINES:
        total = total + shear(np.maximum(centripetal - model.g_m_s2 * s, 0.0) * m)
    result: FloatArray = total / len(_SHEAR_SINES)
    return result


def _summary(points: PointArrays) -> dict[str, FloatArray]:
    """revolution_summary over arrays: the samples' circular mean θ_d, p, rate, energy, slip flag."""
    model, w_r = points.model, points.omega_r_rad_s
    t = points.telemetry()
    moving = w_r >= MIN_OMEGA_R_RAD_S
    landed = (t["found"] == 1.0) & moving[:, None]
    found = landed & (t["energy_j"] >= points.impact_threshold_j)  # below it: a micro-hop, not an impact
    count = found.sum(axis=1)
    theta_d, theta_c, flight = t["theta_d_rad"], t["theta_contact_rad"], t["flight_time_s"]
    on_wall = t["on_wall"] == 1.0
    with np.errstate(invalid="ignore", divide="ignore"):
        travel = np.mod(theta_d - theta_c, 2.0 * math.pi)
        cycle_s = flight + travel / w_r[:, None]
        wall_rev = np.where(cycle_s > 0.0, 2.0 * math.pi / (w_r[:, None] * cycle_s), 1.0)
    per_rev = np.where(on_wall, wall_rev, 1.0)
    zero = np.zeros(points.size)
    sums = {"sin": zero.copy(), "cos": zero.copy(), "per_rev": zero.copy(), "energy": zero.copy()}
    sums |= {"flight": zero.copy(), "wall": zero.copy()}
    for k in range(points.cam_phases):  # in the samples' order, as the scalar summary sums them
        f = found[:, k]
        sums["sin"] = np.where(f, sums["sin"] + np.sin(theta_d[:, k]), sums["sin"])
        sums["cos"] = np.where(f, sums["cos"] + np.cos(theta_d[:, k]), sums["cos"])
        sums["per_rev"] = np.where(f, sums["per_rev"] + per_rev[:, k], sums["per_rev"])
        sums["energy"] = np.where(f, sums["energy"] + t["energy_j"][:, k], sums["energy"])
        sums["flight"] = np.where(f, sums["flight"] + flight[:, k], sums["flight"])
        sums["wall"] = np.where(f & on_wall[:, k], sums["wall"] + 1.0, sums["wall"])
    detached = (count > 0) & (w_r >= MIN_OMEGA_R_RAD_S)
    with np.errstate(invalid="ignore", divide="ignore"):
        fraction = np.where(detached, count / points.cam_phases, 0.0)
        p = np.where(detached, fraction * sums["per_rev"] / count, 0.0)
        per_rod = p * w_r / (2.0 * math.pi)
        rate = per_rod if model.variant is ModelVariant.PAPER else model.n_rods * per_rod
        energy = np.where(detached, sums["energy"] / count, 0.0)
        theta = np.where(detached, np.arctan2(sums["sin"], sums["cos"]), math.nan)
        flight_mean = np.where(detached, sums["flight"] / count, math.nan)
        wall_share = np.where(detached, sums["wall"] / count, math.nan)
    slipping = np.isfinite(t["slip_theta_rad"]) & moving[:, None]
    slip_sin = np.where(slipping, np.sin(t["slip_theta_rad"]), 0.0).sum(axis=1)
    slip_cos = np.where(slipping, np.cos(t["slip_theta_rad"]), 0.0).sum(axis=1)
    violated = slipping.any(axis=1)
    standing = w_r < MIN_OMEGA_R_RAD_S
    return {
        "detached": detached.astype(float),
        "theta_d_rad": theta,
        "impact_rate_hz": np.where(detached, rate, 0.0),
        "mean_impact_energy_j": energy,
        "impact_power_w": np.where(detached, rate * energy, 0.0),
        "mean_shear_pa": np.where(standing, 0.0, _mean_shear_pa(model, w_r)),
        "detach_fraction": fraction,
        "collisions_per_rod_rev": p,
        "mean_flight_time_s": flight_mean,
        "wall_impact_fraction": wall_share,
        "no_slip_violated": violated.astype(float),
        "slip_onset_theta_rad": np.where(violated, np.arctan2(slip_sin, slip_cos), math.nan),
        "slip_fraction": slipping.sum(axis=1) / points.cam_phases,
        "sub_threshold_fraction": (landed & ~found).sum(axis=1) / points.cam_phases,
    }


ARRAY_METRICS: dict[str, ArrayMetric] = {}
"""Every metric with an array form, by name (the same names as :data:`millctl.studies.metrics.METRICS`)."""


def array_metric(name: str) -> Callable[[ArrayMetric], ArrayMetric]:
    """Register ``function(points) -> (P,) array`` as the array form of metric ``name`` (a later one replaces)."""

    def register(function: ArrayMetric) -> ArrayMetric:
        ARRAY_METRICS[name] = function
        return function

    return register


def _margin(law: LimitLaw) -> ArrayMetric:
    def margin(points: PointArrays) -> FloatArray:
        limit = omega_r_max(law, points.limit_params, points.omega_v_rad_s)
        result: FloatArray = (limit - points.omega_r_rad_s) * _RPM_PER_RAD_S
        return result

    return margin


for _law in LimitLaw:
    array_metric(f"margin_{_law.value.replace('-', '_')}_rpm")(_margin(_law))


@array_metric("gamma")
def _gamma(points: PointArrays) -> FloatArray:
    return np.asarray(vibration_intensity(points.limit_params, points.omega_v_rad_s), dtype=float)


@array_metric("spring_force_amplitude_n")
def _spring_force(points: PointArrays) -> FloatArray:
    return np.full(points.size, points.model.spring_n_per_m * points.model.eccentricity_m)


def _paper_estimate_per_rod(points: PointArrays) -> FloatArray:
    """The paper's reasoning: one impact per rod and revolution (eq. 18, p = 1) of ½ m |v|² at r0 ω_r (eq. 19)."""
    m, w_r = points.model, points.omega_r_rad_s
    result: FloatArray = w_r / (2.0 * math.pi) * 0.5 * m.rod_mass_kg * (m.r0_m * w_r) ** 2
    return result


@array_metric("paper_estimate_power_per_rod_w")
def _paper_estimate_rod(points: PointArrays) -> FloatArray:
    return _paper_estimate_per_rod(points)


@array_metric("paper_estimate_power_w")
def _paper_estimate(points: PointArrays) -> FloatArray:
    result: FloatArray = points.model.n_rods * _paper_estimate_per_rod(points)
    return result


def _structural(name: str) -> ArrayMetric:
    def load(points: PointArrays) -> FloatArray:
        return np.asarray(points.structure()[name], dtype=float)

    return load


for _name in (
    "platform_acceleration_peak_m_s2", "spring_force_peak_n", "cam_contact_force_min_n", "cam_contact_force_max_n",
    "follower_jump_margin_rpm", "cam_contact_pressure_pa", "cam_fatigue_cycles", "shaft_load_peak_n", "bearing_life_h",
):  # fmt: skip
    array_metric(_name)(_structural(_name))


def _impact_loads(points: PointArrays) -> dict[str, FloatArray]:
    """Eq. 20 with the impact force at each point's mean impact energy (nan where nothing detaches)."""
    cached = points._cache.get("impact_loads")
    if cached is None:
        s = points.summary()
        detached = s["detached"] == 1.0
        loads = impact_loads(points.model, np.where(detached, s["mean_impact_energy_j"], math.nan))
        cached = points._cache["impact_loads"] = {k: np.where(detached, v, math.nan) for k, v in loads.items()}
    result: dict[str, FloatArray] = cached
    return result


@array_metric("impact_force_peak_n")
def _impact_force(points: PointArrays) -> FloatArray:
    return _impact_loads(points)["impact_force_peak_n"]


@array_metric("rod_rod_shear_pa")
def _rod_rod_shear(points: PointArrays) -> FloatArray:
    return _impact_loads(points)["rod_rod_shear_pa"]


def _whole_mill_rate(points: PointArrays) -> FloatArray:
    s = points.summary()
    n = points.model.n_rods if points.model.variant is ModelVariant.PAPER else 1
    return np.where(s["detached"] == 1.0, s["impact_rate_hz"] * n, 0.0)


@array_metric("impact_rate_hz")
def _impact_rate(points: PointArrays) -> FloatArray:
    return _whole_mill_rate(points)


@array_metric("impact_rate_per_rod_hz")
def _impact_rate_per_rod(points: PointArrays) -> FloatArray:
    result: FloatArray = _whole_mill_rate(points) / points.model.n_rods
    return result


@array_metric("impact_energy_mean_j")
def _impact_energy(points: PointArrays) -> FloatArray:
    s = points.summary()
    return np.where(s["detached"] == 1.0, s["mean_impact_energy_j"], math.nan)


@array_metric("milling_power_w")
def _milling_power(points: PointArrays) -> FloatArray:
    s = points.summary()
    return np.where(s["detached"] == 1.0, _whole_mill_rate(points) * s["mean_impact_energy_j"], 0.0)


@array_metric("dose_rate_j_g_s")
def _dose_rate(points: PointArrays) -> FloatArray:
    power = _milling_power(points)
    return np.where(np.isfinite(power), power / points.config.mill.powder.charge_g, 0.0)


@array_metric("wall_shear_pa")
def _wall_shear(points: PointArrays) -> FloatArray:
    return points.summary()["mean_shear_pa"]


@array_metric("detach_fraction")
def _detach_fraction(points: PointArrays) -> FloatArray:
    return points.summary()["detach_fraction"]


@array_metric("theta_d_deg")
def _theta_d(points: PointArrays) -> FloatArray:
    return np.degrees(points.summary()["theta_d_rad"])


def _summary_field(name: str) -> ArrayMetric:
    def field_of(points: PointArrays) -> FloatArray:
        return points.summary()[name]

    return field_of


for _metric, _field in (
    ("no_slip_violated", "no_slip_violated"), ("slip_fraction", "slip_fraction"),
    ("micro_hop_fraction", "sub_threshold_fraction"), ("cam_phases_used", "cam_phases_used"),
    ("cam_phase_error", "cam_phase_error"),
):  # fmt: skip
    array_metric(_metric)(_summary_field(_field))


__all__ = ["ARRAY_METRICS", "FLIGHT_CAP_S", "ArrayMetric", "PointArrays", "array_metric"]
