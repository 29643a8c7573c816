"""Level (b), node telemetry: a per-revolution summary cheap enough to run live.

For K cam phases α0 (default 4, evenly spaced over one lift cycle) one rod starts pinned at the
lowest angle where it could possibly detach (sin θ = A/(g + c) for N/m = A − g_eff sin θ,
g_eff ∈ [g − c, g + c]; the bottom when g − c < 0), with cam phase α0 there, and is
followed with the exact engine through one revolution: detachment (eq. 7 or the
corrected law), free flight (eq. 10) and its
first contact with the wall or with one of the other n − 1 rods, which are held
on the wall at their eq. 11 positions (the level-(c) simulation lets them fly
too). From the K samples:

* ``detached``: any sample detaches; ``detach_fraction`` the share that do;
* ``theta_d_rad``: circular mean of θ_d over the detaching samples;
* collisions per rod and revolution p: detach_fraction × mean over detaching
  samples of 2π/(ω_r T), where T = flight time + the wall travel from the
  landing angle back to θ_d (1 per revolution when the rod lands on a rod);
* ``impact_rate_hz``: corrected n·p·ω_r/2π (whole mill); paper eq. 18 p·ω_r/2π
  as printed (per rod, the paper's number);
* ``mean_impact_energy_j``: corrected ½ m_eff (1 − e²) v_n²; paper eq. 19 ½ m |v|²;
* ``impact_power_w`` = rate × mean energy;
* ``mean_shear_pa``: eq. 25, μ·p_av, averaged over the pinned arc (corrected,
  N = m(r0 ω_r² − g sin θ) ≥ 0 at 16 angles) or at the paper's N_c = m ω_r² r0;
* ``no_slip_violated``: in some sample the carried rod needs a wall traction
  |F_t| > μN before it detaches (or within the revolution when it stays pinned),
  :func:`~millctl.physics.slip.no_slip_check`; ``slip_onset_theta_rad`` is the
  circular mean of where that starts.

Cost: about 0.1 ms per call with the compiled kernels (``engine="compiled"``,
the default: :func:`millctl.physics.kernels.telemetry_samples`, K one-rod events
and slip checks in one call), milliseconds with the numpy reference
(``engine="reference"``, the same numbers); measured by ``python -m bench``,
docs/benchmarks.md §2. The node computes every summary inside its tick;
:class:`SummaryCache` answers repeated queries on a 1 rpm grid. Below ``MIN_OMEGA_R_RAD_S`` (1 rpm) the vial is treated
as standing still: rods pinned, no impacts, no shear.

At a few rpm the model predicts micro-hops (the rod leaves just above the
horizontal and lands a hair further on): many impacts per revolution of
negligible energy. ``impact_power_w`` stays meaningful there; the rate alone
does not.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass

from millctl.config.models import ModelVariant
from millctl.errors import PhysicsInputError
from millctl.physics import kernels
from millctl.physics.cam import strokes
from millctl.physics.detachment import find_detachment
from millctl.physics.events import WALL, earliest_contact
from millctl.physics.flight import RodState, WallState, depart
from millctl.physics.impact import impact_energy_j, impact_rate_hz, wall_shear_pa
from millctl.physics.kinematics import normal_force_per_mass, true_normal_force_per_mass
from millctl.physics.model import MillModel, Scene
from millctl.physics.slip import NoSlipCheck, no_slip_check
from millctl.units import rpm_to_rad_s

MIN_OMEGA_R_RAD_S = 2.0 * math.pi / 60.0
"""Below 1 rpm the summary reports standstill (pinned, no impacts)."""

_SHEAR_THETAS = tuple(2.0 * math.pi * (k + 0.5) / 16 for k in range(16))
_FLIGHT_CAP_S = 2.0


@dataclass(frozen=True)
class RevolutionSummary:
    """What one revolution of the mill does, phase-averaged over the cam (level-(b) telemetry)."""

    detached: bool
    """False = rods stay pinned to the wall."""
    theta_d_rad: float
    """Detachment angle (circular mean), nan when pinned."""
    impact_rate_hz: float
    """Whole mill (corrected: n·p·ω_r/2π); paper variant: eq. 18 p·ω_r/2π as printed."""
    mean_impact_energy_j: float
    impact_power_w: float
    mean_shear_pa: float
    detach_fraction: float = 0.0
    """Share of the sampled cam phases in which the rod detaches within the revolution."""
    collisions_per_rod_rev: float = 0.0
    """p, the mean number of impacts per rod and revolution."""
    mean_flight_time_s: float = math.nan
    wall_impact_fraction: float = math.nan
    """Share of impacts on the wall (the rest hit another rod)."""
    no_slip_violated: bool = False
    """The paper's no-slip carriage needs more wall friction than μN somewhere (docs/model.md, slip)."""
    slip_onset_theta_rad: float = math.nan
    """Where that first happens on the carried arc (circular mean over the samples), nan when it never does."""
    slip_fraction: float = 0.0
    """Share of the sampled cam phases whose carriage needs |F_t| > μN before the rod leaves (or in the revolution)."""
    sub_threshold_fraction: float = 0.0
    """Share of the sampled cam phases whose landing dissipates less than ``min_impact_energy_j``: not counted."""


def _pinned(shear_pa: float, checks: list[NoSlipCheck] | None = None) -> RevolutionSummary:
    violated, onset = _slip_flag(checks or [])
    return RevolutionSummary(False, math.nan, 0.0, 0.0, 0.0, shear_pa, 0.0, 0.0, math.nan, math.nan, violated, onset)


def _circular_mean(angles: list[float]) -> float:
    return math.atan2(sum(math.sin(a) for a in angles), sum(math.cos(a) for a in angles)) if angles else math.nan


def _slip_flag(checks: list[NoSlipCheck]) -> tuple[bool, float]:
    onsets = [c.onset_theta_rad for c in checks if c.violated]
    return bool(onsets), _circular_mean(onsets)


def _mean_shear_pa(model: MillModel, omega_r: float) -> float:
    m = model.rod_mass_kg
    if model.variant is ModelVariant.PAPER:
        return wall_shear_pa(model, m * omega_r * omega_r * model.r0_m)
    centripetal = model.r0_m * omega_r * omega_r
    loads = (max(centripetal - model.g_m_s2 * math.sin(th), 0.0) * m for th in _SHEAR_THETAS)
    return sum(wall_shear_pa(model, n) for n in loads) / len(_SHEAR_THETAS)


def _start_angle_rad(model: MillModel, omega_r: float, omega_v: float) -> float | None:
    """Where a rod carried up from the bottom can first detach; None if it never can (pinned at every phase).

    N/m = A − g_eff sin θ with g_eff ∈ [g − c, g + c] over the cam phase: with g − c ≥ 0 nothing can
    detach below sin θ = A/(g + c), so the sample starts there (the rod is certainly pinned on the way).
    """
    f = normal_force_per_mass(Scene(model, omega_r, omega_v), 0.0)
    a, c = f.constant, 2.0 * abs(f.amplitudes[1])
    g_max, g_min = model.g_m_s2 + c, model.g_m_s2 - c
    if g_min < 0.0:
        return -0.5 * math.pi
    if a >= g_max:
        return None
    return math.asin(a / g_max) - 1e-9


def _carriage_from_bottom(scene: Scene, arc_end_s: float) -> NoSlipCheck:
    """The no-slip check of the sampled rod over its whole carried arc, from the bottom (θ = −π/2) on.

    The sample starts higher up (where it could first detach); the same ride from the
    bottom has the cam phase shifted back by ω_v·Δt, Δt = (θ_start + π/2)/ω_r.
    """
    lead_s = (scene.theta0_rad + 0.5 * math.pi) / scene.omega_r_rad_s
    bottom = Scene(
        scene.model,
        scene.omega_r_rad_s,
        scene.omega_v_rad_s,
        -0.5 * math.pi,
        scene.alpha0_rad - scene.omega_v_rad_s * lead_s,
    )
    return no_slip_check(bottom, arc_end_s=arc_end_s + lead_s)


def _sample(scene: Scene) -> tuple[tuple[float, float, float, float, bool] | None, NoSlipCheck]:
    """One cam phase: (θ_d, energy J, cycles per revolution, flight s, hit the wall) or None if pinned; slip check.

    A zero-length flight (flight.zero_length_departure) is no impact: the rod is held through the
    dip of N and the search goes on within the revolution (docs/model.md, zero-length flights).
    """
    model = scene.model
    det = find_detachment(scene)
    while True:
        if not det.detached:
            return None, _carriage_from_bottom(scene, det.horizon_s)
        wall0 = WallState(0.0, scene.theta0_rad)
        flight = depart(scene, wall0, det.time_s)
        states: list[RodState] = [flight]
        states += [WallState(0.0, scene.rod_theta0_rad(i)) for i in range(1, model.n_rods)]
        n_d = 0.0
        if model.variant is not ModelVariant.CORRECTED or det.at_start:
            n_d = model.r0_m * true_normal_force_per_mass(scene, det.time_s, det.theta_rad)
        contact = earliest_contact(scene, states, det.time_s, det.time_s + _FLIGHT_CAP_S, {0: n_d}, rods=[0])
        if contact is None or not (contact.partner == WALL and contact.flight_time_s == 0.0):
            break
        det = find_detachment(scene, t_start_s=det.time_s, horizon_s=det.horizon_s, rearm=True)
    check = _carriage_from_bottom(scene, det.time_s)
    if contact is None:
        return None, check
    t_f = contact.flight_time_s  # the root in the flight's own clock: no cancellation of t_contact − t_d
    _, _, vx, vy = flight.rel(scene, contact.time_s)
    w_lift = scene.lift_omega_rad_s
    vyc = model.eccentricity_m * w_lift * math.cos(scene.lift_alpha0_rad + w_lift * contact.time_s)
    speed_abs = math.hypot(vx, vy + vyc)
    on_wall = contact.partner == WALL
    energy = impact_energy_j(model, contact.normal_velocity_m_s, speed_abs, backed=True)  # partners are held
    x, y, _, _ = flight.rel(scene, contact.time_s)
    per_rev = _per_rev(scene.omega_r_rad_s, det.theta_rad, math.atan2(y, x), t_f, on_wall)
    return (det.theta_rad, energy, per_rev, t_f, on_wall), check


Sample = tuple[float, float, float, float, bool]
"""(θ_d, energy J, cycles per revolution, flight s, hit the wall) of one cam phase."""


def _per_rev(omega_r: float, theta_d: float, theta_contact: float, flight_s: float, on_wall: bool) -> float:
    """Impacts per rod and revolution of one sample: 2π/(ω_r T), T = flight + wall travel back to θ_d."""
    if not on_wall:
        return 1.0
    travel = (theta_d - theta_contact) % (2.0 * math.pi)
    cycle_s = flight_s + travel / omega_r
    return 2.0 * math.pi / (omega_r * cycle_s) if cycle_s > 0.0 else 1.0


def _compiled_samples(
    model: MillModel, w_r: float, w_v: float, theta_start: float | None, cam_phases: int
) -> tuple[list[Sample], list[float]]:
    """The K samples and the slip onsets (wall angles) from the compiled kernel (:func:`kernels.telemetry_samples`)."""
    pinned = theta_start is None
    start = -0.5 * math.pi if theta_start is None else theta_start
    row = kernels.scene_row(Scene(model, w_r, w_v, start, 0.0))
    table = kernels.telemetry_samples(row, start, cam_phases, _FLIGHT_CAP_S, model.powder_friction, pinned)
    col = {name: table[:, k] for k, name in enumerate(kernels.TELEMETRY)}
    samples: list[Sample] = []
    for k in range(cam_phases):
        if col["found"][k] == 1.0:
            theta_d, flight, on_wall = (
                float(col["theta_d_rad"][k]),
                float(col["flight_time_s"][k]),
                col["on_wall"][k] == 1.0,
            )
            per_rev = _per_rev(w_r, theta_d, float(col["theta_contact_rad"][k]), flight, on_wall)
            samples.append((theta_d, float(col["energy_j"][k]), per_rev, flight, on_wall))
    onsets = [float(x) for x in col["slip_theta_rad"] if math.isfinite(x)]
    return samples, onsets


def _reference_samples(
    model: MillModel, w_r: float, w_v: float, theta_start: float | None, cam_phases: int
) -> tuple[list[Sample], list[float]]:
    """The same from the numpy/scipy reference engine."""
    if theta_start is None:  # pinned at every phase: check the carriage over a revolution from the bottom
        lift_cycle = 2.0 * math.pi / strokes(model.cam)
        bottom = [Scene(model, w_r, w_v, -0.5 * math.pi, lift_cycle * k / cam_phases) for k in range(cam_phases)]
        checks = [no_slip_check(s, horizon_s=2.0 * math.pi / w_r) for s in bottom]
        return [], [c.onset_theta_rad for c in checks if c.violated]
    samples: list[Sample] = []
    checks = []
    for k in range(cam_phases):
        # evenly spaced lift phases: a double-acting cam repeats its lift twice per cam revolution
        scene = Scene(model, w_r, w_v, theta_start, 2.0 * math.pi * k / (cam_phases * strokes(model.cam)))
        result, check = _sample(scene)
        checks.append(check)
        if result is not None:
            samples.append(result)
    return samples, [c.onset_theta_rad for c in checks if c.violated]


def revolution_summary(
    model: MillModel,
    omega_r_rad_s: float,
    omega_v_rad_s: float,
    cam_phases: int = 4,
    engine: str = "compiled",
    min_impact_energy_j: float = 0.0,
) -> RevolutionSummary:
    """Level-(b) summary of one revolution at constant speeds (rad/s); never raises at standstill.

    Negative speeds are mirror images and are taken by magnitude. ``engine``:
    ``"compiled"`` (:mod:`.kernels`, the node's) or ``"reference"`` (numpy/scipy), same answers.
    A landing that dissipates less than ``min_impact_energy_j`` is not an impact (a micro-hop: the
    studies' threshold, :func:`millctl.physics.structure.resting_contact_energy_j`); 0 counts every one.
    """
    if not (math.isfinite(omega_r_rad_s) and math.isfinite(omega_v_rad_s)):
        raise PhysicsInputError(f"speeds must be finite, got ω_r = {omega_r_rad_s}, ω_v = {omega_v_rad_s} rad/s")
    if cam_phases < 1:
        raise PhysicsInputError(f"cam_phases = {cam_phases} must be ≥ 1")
    if engine not in ("compiled", "reference"):
        raise PhysicsInputError(f"engine = {engine!r}: choose 'compiled' or 'reference'")
    w_r, w_v = abs(omega_r_rad_s), abs(omega_v_rad_s)
    if w_r < MIN_OMEGA_R_RAD_S:
        return _pinned(0.0)
    shear = _mean_shear_pa(model, w_r)
    theta_start = _start_angle_rad(model, w_r, w_v)
    sampler = _compiled_samples if engine == "compiled" else _reference_samples
    found, onsets = sampler(model, w_r, w_v, theta_start, cam_phases)
    violated, onset = bool(onsets), _circular_mean(onsets)
    slipping = len(onsets) / cam_phases
    samples = [s for s in found if s[1] >= min_impact_energy_j]
    below = (len(found) - len(samples)) / cam_phases
    if not samples:
        return RevolutionSummary(
            False, math.nan, 0.0, 0.0, 0.0, shear, 0.0, 0.0, math.nan, math.nan, violated, onset, slipping, below
        )
    count = len(samples)
    fraction = count / cam_phases
    theta_d = _circular_mean([s[0] for s in samples])
    p = fraction * sum(s[2] for s in samples) / count
    rate = impact_rate_hz(model, p, w_r)
    energy = sum(s[1] for s in samples) / count
    return RevolutionSummary(
        detached=True,
        theta_d_rad=theta_d,
        impact_rate_hz=rate,
        mean_impact_energy_j=energy,
        impact_power_w=rate * energy,
        mean_shear_pa=shear,
        detach_fraction=fraction,
        collisions_per_rod_rev=p,
        mean_flight_time_s=sum(s[3] for s in samples) / count,
        wall_impact_fraction=sum(1.0 for s in samples if s[4]) / count,
        no_slip_violated=violated,
        slip_onset_theta_rad=onset,
        slip_fraction=slipping,
        sub_threshold_fraction=below,
    )


class SummaryCache:
    """Level-(b) summaries memoised on a speed grid, for a node that asks often at steady speeds.

    Speeds are rounded to the nearest ``step_rpm`` (default 1 rpm) and the summary
    of that grid point is computed once (``revolution_summary``) and kept, least
    recently used first out. A hit costs a few microseconds; a miss one full call.
    """

    def __init__(self, model: MillModel, step_rpm: float = 1.0, cam_phases: int = 4, maxsize: int = 4096) -> None:
        if not (math.isfinite(step_rpm) and step_rpm > 0.0) or maxsize < 1:
            raise PhysicsInputError(f"step_rpm = {step_rpm} must be > 0 and maxsize = {maxsize} ≥ 1")
        self.model, self.cam_phases, self.maxsize = model, cam_phases, maxsize
        self._step_rpm = step_rpm
        self._step_rad_s = rpm_to_rad_s(step_rpm)
        self._cache: OrderedDict[tuple[int, int], RevolutionSummary] = OrderedDict()

    def __call__(self, omega_r_rad_s: float, omega_v_rad_s: float) -> RevolutionSummary:
        """The summary at the grid point nearest to (|ω_r|, |ω_v|) (rad/s)."""
        if not (math.isfinite(omega_r_rad_s) and math.isfinite(omega_v_rad_s)):
            raise PhysicsInputError(f"speeds must be finite, got ω_r = {omega_r_rad_s}, ω_v = {omega_v_rad_s} rad/s")
        key = (round(abs(omega_r_rad_s) / self._step_rad_s), round(abs(omega_v_rad_s) / self._step_rad_s))
        hit = self._cache.get(key)
        if hit is not None:
            self._cache.move_to_end(key)
            return hit
        w_r, w_v = rpm_to_rad_s(key[0] * self._step_rpm), rpm_to_rad_s(key[1] * self._step_rpm)
        result = revolution_summary(self.model, w_r, w_v, cam_phases=self.cam_phases)
        self._cache[key] = result
        if len(self._cache) > self.maxsize:
            self._cache.popitem(last=False)
        return result


__all__ = ["MIN_OMEGA_R_RAD_S", "RevolutionSummary", "SummaryCache", "revolution_summary"]
