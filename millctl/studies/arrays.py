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
  counted; with ``cam_phases`` 0 integrated over the cam phase by the adaptive rule of
  :mod:`millctl.studies.phase_integral` (all points at once, each refined from its own samples). The
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
from millctl.physics.limits import LimitParams, omega_r_max, vibration_intensity
from millctl.physics.model import MillModel
from millctl.studies.loads import impact_loads, impact_threshold_j, structural_metrics
from millctl.studies.phase_integral import (
    FLIGHT_CAP_S,
    integrated_summary,
    scene_rows,
    start_angles,
    weighted_summary,
)

FloatArray = NDArray[np.float64]
ArrayMetric = Callable[["PointArrays"], FloatArray]

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

    def rows(self, theta0_rad: FloatArray) -> FloatArray:
        """Kernel parameter rows (:data:`~millctl.physics.kernels.PARAMS`) of the points, rod 0 at θ0, α0 = 0."""
        return scene_rows(self.model, self.omega_r_rad_s, self.omega_v_rad_s, theta0_rad)

    def start_angles(self) -> tuple[FloatArray, NDArray[np.bool_]]:
        """Where a rod from the bottom can first detach, and where none can (:func:`.phase_integral.start_angles`)."""
        return start_angles(self.model, self.omega_r_rad_s, self.omega_v_rad_s)

    def telemetry(self) -> dict[str, FloatArray]:
        """The K samples of every point, one (P, K) array per :data:`~millctl.physics.kernels.TELEMETRY` column."""
        table = self.telemetry_table()
        return {name: table[:, :, k] for k, name in enumerate(kernels.TELEMETRY)}

    def telemetry_table(self) -> FloatArray:
        """The same samples as one (P, K, len(TELEMETRY)) array, the kernel's own (computed once)."""
        if self.cam_phases < 1:
            raise ValueError(f"telemetry needs cam_phases ≥ 1, got {self.cam_phases} (0 integrates: use summary())")
        cached = self._cache.get("telemetry")
        if cached is None:
            start, pinned = self.start_angles()
            cached = self._cache["telemetry"] = kernels.telemetry_batch(
                self.rows(start), start, pinned, self.cam_phases, FLIGHT_CAP_S, self.model.powder_friction
            )
        table: FloatArray = cached
        return table

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
                cached = integrated_summary(
                    self.model, self.omega_r_rad_s, self.omega_v_rad_s, self.impact_threshold_j, self.cam_phase_rtol
                )
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


def _summary(points: PointArrays) -> dict[str, FloatArray]:
    """revolution_summary over arrays: K samples a point, unit weights (:func:`.phase_integral.weighted_summary`)."""
    k = points.cam_phases
    table = points.telemetry_table().reshape(points.size * k, len(kernels.TELEMETRY))
    point = np.repeat(np.arange(points.size, dtype=np.int64), k)
    model, w_r, threshold = points.model, points.omega_r_rad_s, points.impact_threshold_j
    return weighted_summary(model, w_r, threshold, point, np.ones(point.size), table)


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
