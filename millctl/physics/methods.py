"""One entry point per first-impact method, for the benchmark (issue 11) and the CLI.

``first_impact(scene, method, ...)`` answers the same question with each scheme:
from t = 0, every rod pinned at eq. 11's angles, each rod detaching at its own
exact detachment time, which is the first contact (rod–wall or rod–rod)?

=============== ==================================================== ============
method          scheme                                                knob
=============== ==================================================== ============
``exact``       bracket + brentq, compiled (:mod:`.kernels`)          ``tol`` (s)
``exact-reference`` the same in numpy/scipy (:mod:`.simulate`)         ``tol`` (s)
``legacy``      paper: fixed dt, end-point check, averaging; circle   ``dt`` (s)
``legacy-interp`` as ``legacy``, time by linear interpolation          ``dt`` (s)
``legacy-arcs`` paper: fixed dt, wall as q arcs (eqs 15–17)           ``dt``, ``q``
``legacy-compiled`` ``legacy`` compiled like ``exact`` (:mod:`.legacy_kernel`) ``dt`` (s)
``ivp``         scipy solve_ivp (DOP853) with terminal events          ``tol`` (rtol)
=============== ==================================================== ============

The reference is :func:`millctl.physics.reference.reference_first_impact`
(closed form for r_d = 0 and one rod, mpmath otherwise).

Many events of one model, fast: ``call = EventCall(model)`` checks the model and the settings once;
``call(omega_r_rad_s, omega_v_rad_s, theta0_rad, alpha0_rad)`` is then one rod's event (``rods="one"``;
``EventCall(model, rods="all")`` the whole scene, as ``exact``) as the kernel's result row
(:data:`~millctl.physics.kernels.OUT` columns, reused by the next call) or None, with nothing built per call.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from millctl.errors import PhysicsInputError
from millctl.physics import kernels
from millctl.physics.events import ContactRow
from millctl.physics.impact import impact_energy_j
from millctl.physics.ivp import ivp_first_contact
from millctl.physics.kernels.scene_call import EventCall, SceneCall
from millctl.physics.legacy import legacy_first_contact
from millctl.physics.legacy_kernel import legacy_first_contact_compiled
from millctl.physics.model import Scene
from millctl.physics.simulate import simulate

Method = Literal["exact", "exact-reference", "legacy", "legacy-interp", "legacy-arcs", "legacy-compiled", "ivp"]
METHODS: tuple[Method, ...] = (
    "exact",
    "exact-reference",
    "legacy",
    "legacy-interp",
    "legacy-arcs",
    "legacy-compiled",
    "ivp",
)


@dataclass(frozen=True)
class ImpactEvent:
    """The first impact of a scene (SI units, lab frame)."""

    time_s: float
    rod: int
    partner: int
    """Other rod's index, or −1 for the wall."""
    x_m: float
    y_m: float
    """Contact point (lab frame: origin at the cam rotor)."""
    normal_velocity_m_s: float
    """Relative normal approach speed."""
    speed_abs_m_s: float
    """The rod's absolute speed (eq. 19's |v|)."""
    energy_j: float
    """Impact energy in the scene's variant (eq. 19 or ½ m_eff (1 − e²) v_n²)."""
    method: str
    tangential_velocity_m_s: float = math.nan
    """Sliding speed of the rod's surface against the partner's (m/s)."""
    flight_time_s: float = math.nan
    """Time since the rod's flight began (s), carried as its own number by ``exact``; nan for the others."""


def _event(scene: Scene, method: str, row: ContactRow) -> ImpactEvent:
    energy = impact_energy_j(scene.model, row.normal_velocity_m_s, row.speed_abs_m_s, row.backed)
    return ImpactEvent(
        row.time_s,
        row.rod,
        row.partner,
        row.x_m,
        row.y_m,
        row.normal_velocity_m_s,
        row.speed_abs_m_s,
        energy,
        method,
        row.tangential_velocity_m_s,
    )


def first_impact(
    scene: Scene,
    method: Method = "exact",
    *,
    tol: float | None = None,
    dt: float | None = None,
    q: int | None = None,
    t_end_s: float = 5.0,
) -> ImpactEvent | None:
    """The first impact of ``scene`` by the named method; None if nothing touches before t_end (s).

    ``tol``: exact — brentq time tolerance in s (default ≈ 4 ulp); ivp — rtol (default 1e-10).
    ``dt``: legacy step (s), required for the legacy methods. ``q``: arcs of ``legacy-arcs`` (default 360).
    """
    if method == "exact":
        return _compiled(scene, tol or 0.0, t_end_s)
    if method == "exact-reference":
        result = simulate(scene, t_end_s, stop_after_first=True, tol_s=tol or 0.0)
        if len(result.impacts) == 0:
            return None
        r = result.impacts[0]
        return ImpactEvent(
            float(r["time_s"]),
            int(r["rod"]),
            int(r["partner"]),
            float(r["x_m"]),
            float(r["y_m"]),
            float(r["normal_velocity_m_s"]),
            float(r["speed_abs_m_s"]),
            float(r["energy_j"]),
            method,
            float(r["tangential_velocity_m_s"]),
            float(r["flight_time_s"]),
        )
    if method == "ivp":
        row = ivp_first_contact(scene, 1e-10 if tol is None else tol, t_end_s)
        return None if row is None else _event(scene, method, row)
    if method in ("legacy", "legacy-interp", "legacy-arcs"):
        if dt is None:
            raise PhysicsInputError(f"method {method!r} needs a time step dt (s)")
        arcs = (360 if q is None else q) if method == "legacy-arcs" else None
        row = legacy_first_contact(scene, dt, arcs, t_end_s, interpolate=method == "legacy-interp")
        return None if row is None else _event(scene, method, row)
    if method == "legacy-compiled":
        if dt is None:
            raise PhysicsInputError(f"method {method!r} needs a time step dt (s)")
        row = legacy_first_contact_compiled(scene, dt, t_end_s)
        return None if row is None else _event(scene, method, row)
    raise PhysicsInputError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")


_SCENE_CALL = SceneCall()
"""The reused compiled call path of ``exact`` (per-thread arrays, nothing built per call)."""

(_T, _ROD, _PARTNER, _X, _Y, _VN, _SPEED, _ENERGY, _VT) = (
    kernels.OUT.index(name)
    for name in (
        "time_s",
        "rod",
        "partner",
        "x_m",
        "y_m",
        "normal_velocity_m_s",
        "speed_abs_m_s",
        "energy_j",
        "tangential_velocity_m_s",
    )
)


def _compiled(scene: Scene, tol_s: float, t_end_s: float) -> ImpactEvent | None:
    """The compiled kernel's first impact (every rod detaching at its own time)."""
    row = _SCENE_CALL.first_impact(scene, horizon_s=float(t_end_s), tol_s=float(tol_s))
    if row is None:
        return None
    return ImpactEvent(
        row[_T],
        int(row[_ROD]),
        int(row[_PARTNER]),
        row[_X],
        row[_Y],
        row[_VN],
        row[_SPEED],
        row[_ENERGY],
        "exact",
        row[_VT],
    )


def wall_angle_rad(scene: Scene, event: ImpactEvent) -> float:
    """Angle of the contact point about the vial centre at the event (rad)."""
    m = scene.model
    alpha = scene.lift_alpha0_rad + scene.lift_omega_rad_s * event.time_s
    yc = m.cam_to_vial_m - m.eccentricity_m + m.eccentricity_m * math.sin(alpha)
    return math.atan2(event.y_m - yc, event.x_m)


__all__ = ["METHODS", "EventCall", "ImpactEvent", "Method", "first_impact", "wall_angle_rad"]
