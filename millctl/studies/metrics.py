"""What a study can measure at a point, each metric at the cheapest level of detail that answers it.

Levels (docs/model.md#levels-of-detail-and-their-cost): (a) closed forms, (b)
the per-revolution summary, (c) the offline multi-rod simulation. A point
computes only the levels its metrics need.

Impact rates count every rod (eq. 18 corrected, n·p·ω_r/2π) in both variants,
so that the paper's and the corrected model compare like with like; the energy
of an impact is the variant's (eq. 19 printed, or ½ m_eff (1 − e²) v_n²). Names:
a quantity of one rod says ``per_rod``; every other rate, power and dose is the
whole mill's. A landing below :func:`~millctl.studies.loads.impact_threshold_j`
is a micro-hop, not an impact, at every level. Level (b) integrates over the cam
phase to a stated error (:func:`cam_phase_summary`) unless ``cam_phases`` fixes K.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from millctl.config.models import LimitLaw, MillConfig
from millctl.errors import InvalidInputError
from millctl.physics.cam import lift_phase_rad, lift_speed_rad_s
from millctl.physics.dose import dose_rate_j_g_s, milling_power_w, whole_mill_rate_hz
from millctl.physics.impact import carriage_shear_pa
from millctl.physics.limits import LimitParams, omega_r_max, vibration_intensity
from millctl.physics.model import MillModel, Scene
from millctl.physics.simulate import simulate_compiled
from millctl.physics.telemetry import MIN_OMEGA_R_RAD_S, RevolutionSummary, revolution_summary
from millctl.studies.loads import (
    carried_arc_slip,
    impact_loads,
    impact_threshold_j,
    slip_ride_metrics,
    structural_metrics,
)
from millctl.studies.phase_integral import MAX_CAM_PHASES, integrated_summary
from millctl.studies.schema import PARAMETER_NAMES, Parameter
from millctl.units import rad_s_to_rpm


@dataclass(frozen=True)
class Metric:
    """One metric: its identifier (with its unit), level of detail, the name people read, and what it is."""

    name: str
    level: str
    """"a" closed form, "b" per-revolution summary, "s" slip ride, "c" multi-rod simulation."""
    label: str
    """Its name in tables and figures, in words; a quantity of one rod says "per rod", of every rod "whole mill"."""
    unit: str
    """Its unit as printed, one word so that a header never wraps inside it ("–" a pure number)."""
    description: str


def _margin_name(law: LimitLaw) -> str:
    return f"margin_{law.value.replace('-', '_')}_rpm"


_LIST = [
    *(Metric(_margin_name(law), "a", f"margin to the {law.value} limit", "rpm",
             f"ω_r,max under {law.value} minus ω_r (rpm; < 0 outside)") for law in LimitLaw),
    Metric("gamma", "a", "cam intensity Γ, peak cam acceleration over g", "–",
           "cam intensity Γ = r_d (hω_v)²/g"),
    Metric("spring_force_amplitude_n", "a", "spring force amplitude, per rod", "N",
           "k·r_d of eqs 4–9, the per-rod spring term (N)"),
    Metric("paper_estimate_power_w", "a", "paper's power estimate, whole mill", "W",
           "the paper's estimate, whole mill: n × eq. 18 (p = 1) × eq. 19 at r0 ω_r"),
    Metric("paper_estimate_power_per_rod_w", "a", "paper's power estimate, per rod", "W",
           "the same for one rod, as eq. 18 is printed (W)"),
    Metric("platform_acceleration_peak_m_s2", "a", "peak platform acceleration", "m/s²",
           "peak platform and vial acceleration r_d (hω_v)² (m/s²)"),
    Metric("spring_force_peak_n", "a", "peak platform spring force", "N",
           "peak tension of the four platform springs K_s (δ0 + r_d) (N)"),
    Metric("cam_contact_force_min_n", "a", "least cam contact force", "N",
           "least cam–roller contact force over the cam phase (N; < 0: roller jumps)"),
    Metric("cam_contact_force_max_n", "a", "largest cam contact force", "N",
           "largest cam–roller contact force over the cam phase (N)"),
    Metric("follower_jump_margin_rpm", "a", "margin to the roller leaving the cam", "rpm",
           "cam speed at which the roller leaves the cam minus ω_v (rpm)"),
    Metric("cam_contact_pressure_pa", "a", "cam contact pressure", "Pa",
           "Hertz p_max of the cam–roller contact at the largest force (Pa)"),
    Metric("cam_fatigue_cycles", "a", "cycles to cam contact fatigue", "cycles",
           "cycles to contact fatigue at that pressure (inf below the endurance limit)"),
    Metric("shaft_load_peak_n", "a", "peak shaft bearing load", "N",
           "peak quasi-static load on the rotary shaft's bearings (N)"),
    Metric("bearing_life_h", "a", "shaft bearing L10 life", "h",
           "L10 life of one shaft bearing at that load and ω_r (h)"),
    Metric("impact_rate_hz", "b", "impact rate, whole mill", "Hz",
           "impacts per second, whole mill, n·p·ω_r/2π (eq. 18 corrected)"),
    Metric("impact_rate_per_rod_hz", "b", "impact rate, per rod", "Hz",
           "impacts per second and rod, p·ω_r/2π (eq. 18)"),
    Metric("impact_energy_mean_j", "b", "mean impact energy", "J",
           "mean energy of an impact (eq. 19, variant's form) (J)"),
    Metric("milling_power_w", "b", "milling power, whole mill", "W",
           "whole mill: impact rate × mean impact energy (W)"),
    Metric("dose_rate_j_g_s", "b", "dose rate, whole mill", "J/(g·s)",
           "whole mill's milling power per gram of powder (J/g/s)"),
    Metric("wall_shear_pa", "b", "wall shear stress, eq. 25", "Pa",
           "eq. 25, μ·p_av averaged over the pinned arc (Pa)"),
    Metric("detach_fraction", "b", "share of cam phases detaching", "–",
           "share of cam phases whose revolution has a counted impact"),
    Metric("theta_d_deg", "b", "mean detachment angle", "°",
           "mean detachment angle (degrees; nan when pinned)"),
    Metric("impact_force_peak_n", "b", "peak impact force", "N",
           "peak force of a wall impact at the mean impact energy (N)"),
    Metric("rod_rod_shear_pa", "b", "rod–rod shear stress, eq. 20", "Pa",
           "eq. 20 with the impact force: μ F / A(F), A the rod–rod Hertz strip (Pa)"),
    Metric("no_slip_violated", "b", "no-slip condition violated", "0/1",
           "1 when the carriage needs |F_t| > μN at some cam phase, else 0"),
    Metric("slip_fraction", "b", "share of cam phases slipping", "–",
           "share of cam phases whose carriage slips before the rod leaves"),
    Metric("micro_hop_fraction", "b", "share of cam phases micro-hopping", "–",
           "share of cam phases whose landing is below the impact threshold"),
    Metric("cam_phases_used", "b", "cam phases used", "count",
           "cam phases the level-(b) integral took"),
    Metric("cam_phase_error", "b", "cam-phase integral error", "–",
           "its error estimate: the larger of milling power's relative and the shares' absolute error"),
    Metric("slip_impact_fraction", "s", "share of cam phases impacting, with slip", "–",
           "with slip (spin locked): share of cam phases with a counted wall impact"),
    Metric("slip_impact_energy_mean_j", "s", "mean impact energy, with slip", "J",
           "with slip: mean wall impact energy (J)"),
    Metric("slip_milling_power_w", "s", "milling power with slip, whole mill", "W",
           "with slip: whole mill's impact power, n·fraction·ω_r/2π × energy (W)"),
    Metric("slip_unresolved_fraction", "s", "share of landings unresolved, with slip", "–",
           "with slip: share of cam phases whose landing the contact search failed"),
    Metric("impact_energy_p10_j", "c", "impact energy, 10th percentile", "J",
           "10th percentile of impact energy over the simulated impacts (J)"),
    Metric("impact_energy_p90_j", "c", "impact energy, 90th percentile", "J",
           "90th percentile of impact energy over the simulated impacts (J)"),
    Metric("sim_impact_rate_hz", "c", "simulated impact rate, whole mill", "Hz",
           "impacts per second in the multi-rod simulation, whole mill"),
    Metric("sim_impact_rate_per_rod_hz", "c", "simulated impact rate, per rod", "Hz",
           "impacts per second and rod in the multi-rod simulation"),
    Metric("sim_power_w", "c", "simulated milling power, whole mill", "W",
           "whole mill: simulated impact energy per second, counted impacts (W)"),
    Metric("sim_micro_hop_fraction", "c", "simulated share of landings micro-hopping", "–",
           "share of the simulation's landings below the impact threshold"),
    Metric("sim_slip_fraction", "c", "simulated share of carried arcs slipping", "–",
           "share of the simulation's carried arcs whose carriage needs |F_t| > μN"),
    Metric("sim_slip_lead_deg", "c", "simulated slip lead angle", "°",
           "mean wall angle before a departure over which the carriage slips (deg)"),
    Metric("slip_sim_impact_rate_hz", "c", "simulated impact rate with slip, whole mill", "Hz",
           "with the held rods' slip ride (spin locked, μ): counted impacts per second, whole mill"),
    Metric("slip_sim_power_w", "c", "simulated milling power with slip, whole mill", "W",
           "with the held rods' slip ride: counted impact energy per second, whole mill (W)"),
    Metric("slip_sim_slid_fraction", "c", "simulated share of departures after sliding", "–",
           "with the slip ride: share of the departures whose rod slid on the wall before it left"),
    Metric("slip_sim_slide_time_s", "c", "simulated time slid before a departure", "s",
           "with the slip ride: mean time a rod slid on the wall since it was put there, per departure (s)"),
    Metric("slip_sim_overlap_share", "c", "simulated share of sliding inside another rod", "–",
           "with the slip ride: share of the slide time a rod spent inside another held rod (held rods are not "
           "tested against each other; near 1 the slip_sim metrics describe rods heaped at the bottom)"),
    Metric("spin_shear_pa", "c", "spin shear stress, eqs 26–27", "Pa",
           "eqs 26–27 corrected at the wall impacts: min(|F_t|, μN)/(2 L b), mean (Pa)"),
]
METRICS: dict[str, Metric] = {m.name: m for m in _LIST}
"""Every metric by name."""

DEFAULT_METRICS = tuple(m.name for m in _LIST if m.level in ("a", "b"))
"""Metrics of a study that names none: every level-(a) and level-(b) metric."""


def quantity_label(name: str) -> str:
    """A metric's or parameter's name with its unit, for a table header or an axis: ``milling power, whole mill (W)``.

    The one place identifiers become words (the metrics above, the parameters in
    :data:`~millctl.studies.schema.PARAMETER_NAMES`); a leading ``-`` (a metric minimised in
    ``--pareto``) is not part of the quantity.
    """
    key = name.lstrip("-")
    if key in METRICS:
        label, unit = METRICS[key].label, METRICS[key].unit
    elif key in PARAMETER_NAMES:
        label, unit = PARAMETER_NAMES[Parameter(key)]
    else:
        known = ", ".join([*METRICS, *PARAMETER_NAMES])
        raise InvalidInputError(f"{name!r} is neither a metric nor a study parameter (known: {known})")
    return f"{label} ({unit})" if unit else label


@dataclass(frozen=True)
class PointSettings:
    """How hard to look at one point."""

    cam_phases: int = 0
    """Level (b): a fixed number of cam phases, or 0 to integrate to ``cam_phase_rtol``."""
    revolutions: float = 4.0
    cam_phase_rtol: float = 0.01
    slip_phases: int = 8
    """Level (s): cam phases ridden with slip."""


def _level_a(config: MillConfig, model: MillModel, w_r: float, w_v: float) -> dict[str, float]:
    p = LimitParams.from_config(config)
    out = {_margin_name(law): float(rad_s_to_rpm(omega_r_max(law, p, w_v) - w_r)) for law in LimitLaw}
    out["gamma"] = float(vibration_intensity(p, w_v))
    out["spring_force_amplitude_n"] = model.spring_n_per_m * model.eccentricity_m
    # the paper's reasoning: one impact per rod and revolution (eq. 18, p = 1) of ½ m |v|² at the wall speed (eq. 19)
    per_rod = w_r / (2.0 * math.pi) * 0.5 * model.rod_mass_kg * (model.r0_m * w_r) ** 2
    out["paper_estimate_power_per_rod_w"] = per_rod
    out["paper_estimate_power_w"] = model.n_rods * per_rod
    out |= {name: float(value) for name, value in structural_metrics(config, w_r, w_v).items()}
    return out


def cam_phase_summary(
    model: MillModel, w_r: float, w_v: float, settings: PointSettings, threshold_j: float
) -> tuple[RevolutionSummary, int, float]:
    """The level-(b) summary integrated over the cam phase: (summary, phases used, error estimate).

    With ``settings.cam_phases`` > 0, that many even phases and error nan. Otherwise the adaptive
    integral of :mod:`millctl.studies.phase_integral` to ``cam_phase_rtol`` (the array path's, for
    one point: the same samples, the same numbers).
    """
    if settings.cam_phases > 0:
        s = revolution_summary(model, w_r, w_v, cam_phases=settings.cam_phases, min_impact_energy_j=threshold_j)
        return s, settings.cam_phases, math.nan
    r, v = np.array([abs(w_r)]), np.array([abs(w_v)])
    out = integrated_summary(model, r, v, threshold_j, settings.cam_phase_rtol)
    fields = {name: float(values[0]) for name, values in out.items()}
    summary = RevolutionSummary(
        detached=fields["detached"] == 1.0,
        theta_d_rad=fields["theta_d_rad"],
        impact_rate_hz=fields["impact_rate_hz"],
        mean_impact_energy_j=fields["mean_impact_energy_j"],
        impact_power_w=fields["impact_power_w"],
        mean_shear_pa=fields["mean_shear_pa"],
        detach_fraction=fields["detach_fraction"],
        collisions_per_rod_rev=fields["collisions_per_rod_rev"],
        mean_flight_time_s=fields["mean_flight_time_s"],
        wall_impact_fraction=fields["wall_impact_fraction"],
        no_slip_violated=fields["no_slip_violated"] == 1.0,
        slip_onset_theta_rad=fields["slip_onset_theta_rad"],
        slip_fraction=fields["slip_fraction"],
        sub_threshold_fraction=fields["sub_threshold_fraction"],
    )
    return summary, int(fields["cam_phases_used"]), fields["cam_phase_error"]


def _level_b(
    config: MillConfig, model: MillModel, w_r: float, w_v: float, settings: PointSettings, threshold_j: float
) -> tuple[dict[str, float], int]:
    s, phases, error = cam_phase_summary(model, w_r, w_v, settings, threshold_j)
    total = whole_mill_rate_hz(model.variant, model.n_rods, s.impact_rate_hz) if s.detached else 0.0
    energy = s.mean_impact_energy_j if s.detached else math.nan
    loads = impact_loads(model, energy)
    return {
        "impact_rate_hz": total,
        "impact_rate_per_rod_hz": total / model.n_rods,
        "impact_energy_mean_j": energy,
        "milling_power_w": milling_power_w(model, s),
        "dose_rate_j_g_s": dose_rate_j_g_s(model, s, config.mill.powder.charge_g),
        "wall_shear_pa": s.mean_shear_pa,
        "detach_fraction": s.detach_fraction,
        "theta_d_deg": math.degrees(s.theta_d_rad),
        "impact_force_peak_n": float(loads["impact_force_peak_n"]) if s.detached else math.nan,
        "rod_rod_shear_pa": float(loads["rod_rod_shear_pa"]) if s.detached else math.nan,
        "no_slip_violated": 1.0 if s.no_slip_violated else 0.0,
        "slip_fraction": s.slip_fraction,
        "micro_hop_fraction": s.sub_threshold_fraction,
        "cam_phases_used": float(phases),
        "cam_phase_error": error,
    }, phases


SLIP_RUN_PREFIX = "slip_sim_"
"""Level-(c) metrics of the second simulation, the one with the held rods' slip ride."""


def needs_slip_run(names: Iterable[str]) -> bool:
    """Whether these metrics need level (c)'s second run, with the slip ride (about twice a point's cost)."""
    return any(n.startswith(SLIP_RUN_PREFIX) for n in names)


def _slip_ride_run(scene: Scene, t_end: float, threshold: float) -> tuple[dict[str, float], int]:
    """The ``slip_sim_*`` metrics: the same scene simulated with the held rods' slip ride (μ of the model)."""
    result, n_counted = simulate_compiled(scene, t_end, threshold_j=threshold, friction=scene.model.powder_friction)
    energies = result.impacts["energy_j"][result.impacts["energy_j"] >= threshold]
    slid = result.detachments["slid_s"]
    return {
        "slip_sim_impact_rate_hz": n_counted / t_end,
        "slip_sim_power_w": float(np.sum(energies)) / t_end,
        "slip_sim_slid_fraction": float(np.mean(slid > 0.0)) if slid.size else math.nan,
        "slip_sim_slide_time_s": float(np.mean(slid)) if slid.size else math.nan,
        "slip_sim_overlap_share": result.overlap_s / result.slide_s if result.slide_s > 0.0 else math.nan,
    }, int(result.impacts.size + result.detachments.size)


def _level_c(
    model: MillModel, w_r: float, w_v: float, revolutions: float, seed: int, slip: bool = True
) -> tuple[dict[str, float], int]:
    """Metrics of the multi-rod simulation from seeded random phases, and its event count.

    The compiled many-event kernel (:func:`~millctl.physics.simulate.simulate_compiled`, event for event the
    reference :func:`~millctl.physics.simulate.simulate`); a landing below the impact threshold is a micro-hop.
    The held rods are carried (the paper's picture); with ``slip`` the same scene is simulated again with their
    slip ride (the ``slip_sim_*`` metrics).
    """
    nan = math.nan
    if w_r < MIN_OMEGA_R_RAD_S:
        return {
            "slip_sim_impact_rate_hz": 0.0,
            "slip_sim_power_w": 0.0,
            "slip_sim_slid_fraction": nan,
            "slip_sim_slide_time_s": nan,
            "slip_sim_overlap_share": nan,
            "impact_energy_p10_j": nan,
            "impact_energy_p90_j": nan,
            "sim_impact_rate_hz": 0.0,
            "sim_impact_rate_per_rod_hz": 0.0,
            "sim_power_w": 0.0,
            "sim_micro_hop_fraction": nan,
            "spin_shear_pa": nan,
            "sim_slip_fraction": nan,
            "sim_slip_lead_deg": nan,
        }, 0
    theta0, alpha0 = np.random.default_rng(seed).uniform(0.0, 2.0 * math.pi, size=2)
    t_end = revolutions * 2.0 * math.pi / w_r
    scene = Scene(model, w_r, w_v, float(theta0), float(alpha0))
    threshold = impact_threshold_j(model)
    result, n_counted = simulate_compiled(scene, t_end, threshold_j=threshold)
    slip_share, slip_lead = carried_arc_slip(scene, result.impacts, result.detachments)
    counted = result.impacts[result.impacts["energy_j"] >= threshold]
    landings = int(result.impacts.size)
    energies = counted["energy_j"]
    wall = counted[counted["partner"] == -1]
    spins = []
    w_lift = lift_speed_rad_s(model.cam, w_v)
    for theta, alpha in zip(wall["theta_rad"], wall["alpha_rad"], strict=True):
        # eqs 26–27 corrected: the traction the wall gives the re-pinned rod, capped at μN
        _, capped = carriage_shear_pa(model, w_r, w_lift, float(theta), lift_phase_rad(model.cam, float(alpha)))
        if capped > 0.0:
            spins.append(capped)
    out = {
        "impact_energy_p10_j": float(np.percentile(energies, 10)) if energies.size else nan,
        "impact_energy_p90_j": float(np.percentile(energies, 90)) if energies.size else nan,
        "sim_impact_rate_hz": n_counted / t_end,
        "sim_impact_rate_per_rod_hz": n_counted / t_end / model.n_rods,
        "sim_power_w": float(np.sum(energies)) / t_end,
        "sim_micro_hop_fraction": (landings - n_counted) / landings if landings else nan,
        "spin_shear_pa": float(np.mean(spins)) if spins else nan,
        "sim_slip_fraction": slip_share,
        "sim_slip_lead_deg": slip_lead,
    }
    events = int(result.impacts.size + result.detachments.size)
    if slip:
        ridden, more = _slip_ride_run(scene, t_end, threshold)
        out.update(ridden)
        events += more
    return out, events


def compute_metrics(
    config: MillConfig, w_r: float, w_v: float, names: tuple[str, ...], settings: PointSettings, seed: int
) -> tuple[dict[str, float], int]:
    """The named metrics at speeds (rad/s) on a configured mill, and the number of events it took."""
    model = MillModel.from_config(config)
    levels = {METRICS[n].level for n in names}
    values: dict[str, float] = {}
    events = 0
    if "a" in levels:
        values.update(_level_a(config, model, w_r, w_v))
    threshold = impact_threshold_j(model)
    if "b" in levels:
        summary, phases = _level_b(config, model, w_r, w_v, settings, threshold)
        values.update(summary)
        events += phases
    if "s" in levels:
        if w_r < MIN_OMEGA_R_RAD_S:
            ridden: dict[str, float] = {
                "slip_impact_fraction": 0.0,
                "slip_impact_energy_mean_j": math.nan,
                "slip_milling_power_w": 0.0,
                "slip_unresolved_fraction": 0.0,
            }
        else:
            ridden, n_events = slip_ride_metrics(model, w_r, w_v, settings.slip_phases, threshold)
            events += n_events
        values.update(ridden)
    if "c" in levels:
        sim, n_events = _level_c(model, w_r, w_v, settings.revolutions, seed, needs_slip_run(names))
        values.update(sim)
        events += n_events
    return {n: float(values[n]) for n in names}, events


__all__ = [
    "DEFAULT_METRICS",
    "MAX_CAM_PHASES",
    "METRICS",
    "Metric",
    "PointSettings",
    "cam_phase_summary",
    "compute_metrics",
    "needs_slip_run",
    "quantity_label",
]
