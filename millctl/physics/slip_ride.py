"""A rod on the wall with Coulomb friction and its own spin: stick → slip → detach (level of detail "slip").

The paper's carriage (θ = θ0 + ω_r t) assumes the wall never lets go tangentially;
:mod:`millctl.physics.slip` shows that it always does before detachment. Here the rod
is a rigid cylinder in the vial-centred frame (gravity g_eff = g − r_d ω_v² sin α), with
centre angle φ on the circle r0, spin ω_s (counter-clockwise), wall turning at ω_r,
and per unit mass

    n = N/m = r0 φ̇² − g_eff sin φ,         r0 φ̈ = f − g_eff cos φ,        ω̇_s = j f / r_r,

where f = F/m is the wall's friction along the wall's motion and j = m r_r²/I. The
contact point slides at v_s = r0 φ̇ + r_r ω_s − r_v ω_r.

* stick (v_s = 0 held): f = g_eff cos φ/(1 + j), valid while |f| ≤ μ n;
* slip: f = s μ n, s = ±1 the direction of the wall's pull, until v_s returns to 0;
* detach: n falls through 0; the rod leaves with φ̇ and ω_s, and flies (eq. 10).

``spin="locked"`` (j = 0) is the paper's premise: the rod does not roll, its spin stays
the wall's, and stick is the carriage itself (f = g_eff cos φ, φ̇ = ω_r); slipping, it
is a block sliding on the wall. ``spin="free"`` (j = 2, a solid cylinder, I = ½ m r_r²)
lets it roll: a rolling rod obeys r0 φ̈ = −j g_eff cos φ/(1 + j), which does not involve
ω_r at all — a lone free rod is not carried by the wall, it rocks about the bottom.
Both start from the paper's state: carried (φ̇ = ω_r, ω_s = ω_r, v_s = 0).

Numerics: scipy ``solve_ivp`` (DOP853, rtol 1e-11) with the mode changes as terminal
events. Cost: milliseconds per ride; this is an offline level of detail, not telemetry.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from scipy.integrate import solve_ivp

from millctl.config.models import ModelVariant
from millctl.errors import PhysicsInputError
from millctl.physics.detachment import find_detachment
from millctl.physics.events import earliest_contact
from millctl.physics.flight import FlightState, RodState
from millctl.physics.impact import impact_energy_j
from millctl.physics.model import MillModel, Scene

Spin = Literal["free", "locked"]
_RTOL, _ATOL = 1e-11, 1e-13
_MAX_PHASES = 2000


def spin_ratio(spin: Spin) -> float:
    """The ratio j = m r_r²/I: 2 for a free solid cylinder, 0 for a spin locked to the wall."""
    if spin == "free":
        return 2.0
    if spin == "locked":
        return 0.0
    raise PhysicsInputError(f"spin = {spin!r} must be 'free' or 'locked'")


@dataclass(frozen=True)
class SlipPhase:
    """One stretch of the ride in one contact mode."""

    mode: str
    """"stick" or "slip"."""
    t_start_s: float
    t_end_s: float
    theta_start_rad: float


@dataclass(frozen=True)
class WallRide:
    """A rod's ride on the wall until it detaches (or the horizon), with its stick/slip history."""

    detached: bool
    time_s: float
    """Detachment time (s), nan when it stays on the wall."""
    theta_rad: float
    """φ_d (rad, in (−π, π]), nan when it stays."""
    theta_rate_rad_s: float
    """φ̇ at detachment (rad/s): ω_r for the paper's carriage."""
    spin_rad_s: float
    """ω_s at detachment (rad/s)."""
    phases: tuple[SlipPhase, ...]
    slip_time_s: float
    """Time spent sliding before detachment (or the horizon)."""


def _g_eff(scene: Scene, t: float) -> float:
    m = scene.model
    w_lift = scene.lift_omega_rad_s  # the cam's lift (millctl.physics.cam)
    return m.g_m_s2 - m.eccentricity_m * w_lift**2 * math.sin(scene.lift_alpha0_rad + w_lift * t)


def ride(scene: Scene, spin: Spin = "free", horizon_s: float | None = None, friction: float | None = None) -> WallRide:
    """Follow rod 0 from the paper's carried state at θ0 (t = 0) with Coulomb friction (μ = ``friction``).

    ``friction=math.inf`` is a grip that never fails: with ``spin="locked"`` that is the paper's
    carriage, with ``spin="free"`` pure rolling.
    """
    m = scene.model
    mu = m.powder_friction if friction is None else friction
    if math.isnan(mu) or mu < 0.0:
        raise PhysicsInputError(f"friction μ = {mu} must be ≥ 0 (inf: a grip that never fails)")
    j = spin_ratio(spin)
    r0, r_r, w_r = m.r0_m, m.rod_radius_m, scene.omega_r_rad_s
    horizon = horizon_s if horizon_s is not None else (2.0 * math.pi / w_r if w_r > 0 else 1.0)

    def normal(t: float, y: Any) -> float:
        return float(r0 * y[1] ** 2 - _g_eff(scene, t) * math.sin(y[0]))

    def stick_force(t: float, y: Any) -> float:
        return _g_eff(scene, t) * math.cos(y[0]) / (1.0 + j)

    def rhs(t: float, y: Any, mode: int) -> list[float]:
        g_eff = _g_eff(scene, t)
        f = stick_force(t, y) if mode == 0 else mode * mu * normal(t, y)
        return [y[1], (f - g_eff * math.cos(y[0])) / r0, j * f / r_r]

    def detach(t: float, y: Any, mode: int) -> float:
        return normal(t, y)

    detach.terminal, detach.direction = True, -1  # type: ignore[attr-defined]

    def lose_grip_up(t: float, y: Any, mode: int) -> float:
        return mu * normal(t, y) - stick_force(t, y)

    def lose_grip_down(t: float, y: Any, mode: int) -> float:
        return mu * normal(t, y) + stick_force(t, y)

    def regrip(t: float, y: Any, mode: int) -> float:
        return float(r0 * y[1] + r_r * y[2] - m.vial_radius_m * w_r)

    for event in (lose_grip_up, lose_grip_down, regrip):
        event.terminal = True  # type: ignore[attr-defined]
    lose_grip_up.direction = lose_grip_down.direction = -1  # type: ignore[attr-defined]

    def choose(t: float, y: Any) -> int:
        """0 = stick if the grip holds, else the slip direction (the sign of the needed traction)."""
        f = stick_force(t, y)
        return 0 if abs(f) <= mu * normal(t, y) else (1 if f > 0.0 else -1)

    # Events are seen only as sign changes between steps: keep steps well below every time scale
    # (the carriage is linear in time, so the integrator alone would take huge steps over the cam's wiggles).
    scales = [math.sqrt(2.0 * r_r / m.g_m_s2)] + [2.0 * math.pi / w for w in (w_r, scene.lift_omega_rad_s) if w > 0.0]
    max_step = min(scales) / 32.0
    t, y = 0.0, np.array([scene.theta0_rad, w_r, w_r])
    phases: list[SlipPhase] = []
    slip_time = 0.0
    mode = choose(t, y)
    while t < horizon and len(phases) < _MAX_PHASES:
        if normal(t, y) <= 0.0:
            return _ride(True, t, y, phases, slip_time)
        grip_events = [lose_grip_up, lose_grip_down] if math.isfinite(mu) else []
        events = [detach, *grip_events] if mode == 0 else [detach, regrip]
        if mode != 0:
            regrip.direction = mode  # type: ignore[attr-defined]
        sol = solve_ivp(
            rhs,
            (t, horizon),
            y,
            method="DOP853",
            rtol=_RTOL,
            atol=_ATOL,
            events=events,
            args=(mode,),
            max_step=max_step,
        )
        if sol.status < 0:
            raise PhysicsInputError(f"slip ride failed at t = {t} s: {sol.message}")
        phases.append(SlipPhase("stick" if mode == 0 else "slip", t, float(sol.t[-1]), float(y[0])))
        if mode != 0:
            slip_time += float(sol.t[-1]) - t
        t, y = float(sol.t[-1]), sol.y[:, -1].copy()
        if sol.status != 1:
            break
        if sol.t_events[0].size:
            return _ride(True, t, y, phases, slip_time)
        if mode == 0:  # the grip is lost: slide the way the needed traction points
            mode = 1 if sol.t_events[1].size else -1
        else:  # the contact point has caught up with the wall
            if j > 0.0:
                y[2] = (m.vial_radius_m * w_r - r0 * y[1]) / r_r  # land exactly on v_s = 0
            else:
                y[1] = w_r
            mode = choose(t, y)
    if t < horizon and len(phases) >= _MAX_PHASES:
        raise PhysicsInputError(
            f"slip ride chattered: {_MAX_PHASES} stick/slip changes by t = {t:.6g} s of {horizon:.6g} s "
            f"(μ = {mu}, spin {spin}); shorten the horizon or see docs/model.md, slip"
        )
    return WallRide(False, math.nan, math.nan, math.nan, math.nan, tuple(phases), slip_time)


def _ride(detached: bool, t: float, y: Any, phases: list[SlipPhase], slip_time: float) -> WallRide:
    return WallRide(
        detached, t, math.remainder(float(y[0]), 2 * math.pi), float(y[1]), float(y[2]), tuple(phases), slip_time
    )


@dataclass(frozen=True)
class WallLanding:
    """The free flight from a detachment to the wall (single rod) and its impact."""

    flight_time_s: float
    landing_theta_rad: float
    normal_velocity_m_s: float
    energy_j: float
    """Corrected ½ m (1 − e²) v_n² on the wall."""


def fly_to_wall(scene: Scene, time_s: float, theta_rad: float, theta_rate_rad_s: float) -> WallLanding | None:
    """Eq. 10 from a departure at φ_d with rate φ̇_d (N = 0) to the first wall contact; None within 2 s."""
    mirror = theta_rate_rad_s < 0.0  # fly the mirror image (x → −x), which has φ̇ ≥ 0
    phi = math.pi - theta_rad if mirror else theta_rad
    rate = abs(theta_rate_rad_s)
    flying = dataclasses.replace(scene, omega_r_rad_s=rate)  # the departure's own rate sets u_0 = r0 φ̇ θ̂
    r0 = scene.model.r0_m
    c, s = math.cos(phi), math.sin(phi)
    flight = FlightState(time_s, r0 * c, r0 * s, -r0 * rate * s, r0 * rate * c, from_wall=True)
    states: list[RodState] = [flight]
    contact = earliest_contact(flying, states, time_s, time_s + 2.0, {0: 0.0}, rods=[0])
    if contact is None:
        return None
    x, y, _, _ = flight.rel_tau(flying, contact.flight_time_s)
    landing = math.atan2(y, -x if mirror else x)
    energy = impact_energy_j(
        dataclasses.replace(scene.model, variant=ModelVariant.CORRECTED), contact.normal_velocity_m_s, 0.0, True
    )
    return WallLanding(contact.flight_time_s, landing, contact.normal_velocity_m_s, energy)


def slip_effect(
    model: MillModel, omega_r_rad_s: float, omega_v_rad_s: float, phases: int = 16, friction: float | None = None
) -> dict[str, Any]:
    """No-slip carriage against slip (locked and free spin), one rod from the bottom, K cam phases.

    For each model: the share of phases that detach within one revolution, and over those the
    mean θ_d (deg), flight time (ms), wall impact energy (mJ) and time spent sliding (ms).
    ``friction`` overrides μ (default ``model.powder_friction``).
    """
    corrected = dataclasses.replace(model, variant=ModelVariant.CORRECTED)
    if friction is not None:
        corrected = dataclasses.replace(corrected, powder_friction=friction)
    rows = []
    for label in ("no-slip", "slip, spin locked", "slip, spin free"):
        thetas, flights, energies, slides, count = [], [], [], [], 0
        for k in range(phases):
            scene = Scene(corrected, omega_r_rad_s, omega_v_rad_s, -0.5 * math.pi, 2.0 * math.pi * (k + 0.5) / phases)
            if label == "no-slip":
                det = find_detachment(scene)
                start = (det.detached, det.time_s, det.theta_rad, omega_r_rad_s, 0.0)
            else:
                r = ride(scene, "locked" if "locked" in label else "free")
                start = (r.detached, r.time_s, r.theta_rad, r.theta_rate_rad_s, r.slip_time_s)
            if not start[0]:
                continue
            landing = fly_to_wall(scene, start[1], start[2], start[3])
            if landing is None:
                continue
            count += 1
            thetas.append(math.degrees(start[2]))
            flights.append(landing.flight_time_s * 1e3)
            energies.append(landing.energy_j * 1e3)
            slides.append(start[4] * 1e3)

        def mean(values: list[float]) -> float:
            return float(np.mean(values)) if values else math.nan

        rows.append(
            {
                "model": label,
                "detach_fraction": count / phases,
                "theta_d_deg": mean(thetas),
                "flight_ms": mean(flights),
                "energy_mj": mean(energies),
                "sliding_ms": mean(slides),
            }
        )
    return {"phases": phases, "friction": corrected.powder_friction, "rows": rows}


__all__ = ["SlipPhase", "Spin", "WallLanding", "WallRide", "fly_to_wall", "ride", "slip_effect", "spin_ratio"]
