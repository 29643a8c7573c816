"""Level (c), offline: the multi-rod event-driven simulation, returning numpy structured arrays.

Every rod has its own state (pinned to the wall, or in flight). The loop goes
from event to event: the next detachment of a pinned rod (exact, in time) or the
next contact among the current states (exact, :func:`~millctl.physics.events.earliest_contact`),
whichever comes first. Contact rules (a statistics tool, not a contact solver):

* wall: the impact is recorded, the rod is put back on the wall where it landed
  (no-slip capture, the paper's picture) and its next detachment is searched;
  a zero-length flight (the free rod would enter the wall at once: the paper's
  detachment where the true N is still positive, or sliding) is not an impact —
  the rod stays pinned until N has risen above zero again;
* rod on a pinned rod: the pinned rod is backed by the wall and does not move;
  the flying rod's relative normal velocity is reversed with restitution e;
* rod on a flying rod: equal masses, normal components exchanged with restitution e;
* after a rod–rod impact the pair is not tested again until it has separated
  (the rod rolls off its partner instead of resting on it);
* a rod that comes to rest on another rod — normal speed below
  ``SETTLE_SPEED_FACTOR``·√(g r_r), or more than ``MAX_BOUNCES`` rod–rod impacts in
  one flight — settles into the pile: it is put back on the wall at its angle; where
  the wall cannot hold it there (N ≤ 0) it rides the pile until N has risen above zero
  and detaches at the next falling zero (the zero-length rule's re-arming);
* with a finite ``friction`` μ a held rod rides with slip (:mod:`.wall_slide`): carried until the earlier
  of its detachment and the end of its stick, then slide steps along their chords until it regrips (carried
  again) or leaves at its own rate; each detachment records the time it slid (``slid_s``).

Cost: roughly 1 ms of CPython per event for Set A (scales with n for the pair
scans), i.e. seconds for thousands of events. This is the reference (the oracle);
:func:`simulate_compiled` runs the same algorithm compiled
(:mod:`millctl.physics.kernels.many_event`), the engine the studies use, and agrees with it
event for event (tests/unit/physics/test_many_event.py, ``python -m bench --only study``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from millctl.config.models import ModelVariant
from millctl.errors import PhysicsInputError
from millctl.physics.detachment import find_detachment
from millctl.physics.events import WALL, Contact, earliest_contact, scan_step_s
from millctl.physics.flight import FlightState, RodState, WallState, depart, depart_sliding
from millctl.physics.impact import impact_energy_j
from millctl.physics.kinematics import true_normal_force_per_mass, vial_centre_m
from millctl.physics.model import Scene
from millctl.physics.wall_slide import (
    DETACH,
    MAX_CHANGES,
    REGRIP,
    SLIDE_STEP,
    STEPS_PER_SCALE,
    slide_direction,
    slide_step,
    slide_step_s,
    stick_slip_onset,
)

IMPACT_DTYPE = np.dtype(
    [
        ("time_s", "f8"),
        ("rod", "i4"),
        ("partner", "i4"),  # −1 = wall
        ("x_m", "f8"),  # contact point, lab frame
        ("y_m", "f8"),
        ("theta_rad", "f8"),  # angle of the rod centre about the vial centre
        ("alpha_rad", "f8"),
        ("normal_velocity_m_s", "f8"),
        ("tangential_velocity_m_s", "f8"),
        ("speed_abs_m_s", "f8"),
        ("energy_j", "f8"),
        ("flight_time_s", "f8"),
    ]
)
"""One row per impact."""

DETACHMENT_DTYPE = np.dtype(
    [("time_s", "f8"), ("rod", "i4"), ("theta_rad", "f8"), ("alpha_rad", "f8"), ("slid_s", "f8")]
)
"""One row per detachment; ``slid_s`` the time the rod slid on the wall since it was last put there (0: no slip)."""

SETTLE_SPEED_FACTOR = 0.01
MAX_BOUNCES = 20
MIN_HOP_RTOL = 1e-6
"""A wall landing after a hop off the wall shorter than this × the contact scan's step (~1e-9 s) ends a Zeno
chain: the rod lands where N is about to dip again below zero, hop after ever shorter hop (each ~20× shorter,
down to 1e-12 s, where rounding alone decided which engine's chain had one hop more); it rides through the
dip. A short flight that began at a rod–rod bounce is an impact like any other."""
RELEASE_GAP_RTOL = 1e-9
"""An excluded pair is released when its separation |d|² − (2 r_r)² exceeds this × r0² (the search's near-zero)."""


@dataclass
class _Ride:
    """A held rod's slip ride (the kernel's ROD_BOOK columns ends … changes)."""

    ends: int = DETACH
    """What its next held event is: :data:`~.wall_slide.SLIDE_STEP`, REGRIP or DETACH."""
    direction: float = 0.0
    """The slide's s (0: carried)."""
    theta_rad: float = math.nan
    """φ at the next held event."""
    rate_rad_s: float = math.nan
    """φ̇ at the next held event."""
    slid_s: float = 0.0
    """Time slid since it was put on the wall."""
    changes: int = 0
    """Stick ↔ slide changes since."""


@dataclass
class _Run:
    scene: Scene
    t_end_s: float
    states: list[RodState]
    next_detach: list[float]
    tol_s: float = 0.0
    n_d: dict[int, float] = field(default_factory=dict)
    excluded: set[tuple[int, int]] = field(default_factory=set)
    bounces: dict[int, int] = field(default_factory=dict)
    unsupported: set[int] = field(default_factory=set)
    """Rods whose next detachment is at the start of their search with N < 0 (not a falling zero)."""
    slide_step_s: float = 0.0
    friction: float = math.inf
    """μ of the slip ride (:mod:`.wall_slide`); inf: the paper's carriage, no slip."""
    ride: dict[int, _Ride] = field(default_factory=dict)
    """A held rod's slip ride, from when it was put on the wall to its departure."""
    impacts: list[tuple[float, ...]] = field(default_factory=list)
    detachments: list[tuple[float, ...]] = field(default_factory=list)
    slide_s: float = 0.0
    overlap_s: float = 0.0


@dataclass(frozen=True)
class SimulationResult:
    """Per-event records of an offline run."""

    impacts: NDArray[np.void]
    """Structured array of :data:`IMPACT_DTYPE`."""
    detachments: NDArray[np.void]
    """Structured array of :data:`DETACHMENT_DTYPE`."""
    t_end_s: float
    slide_s: float = 0.0
    """Rod-seconds the held rods slid (the slip ride), departed or not."""
    overlap_s: float = 0.0
    """Of those, the rod-seconds whose slide step began with the rod inside another held rod (beyond rounding).

    Held rods are never tested against each other (docs/model.md, "What level (c) does not model"): carried
    at one rate they cannot meet, but sliding rods pass through each other to the bottom. A share
    ``overlap_s / slide_s`` well above 0 says that the run's slip ride describes rods heaped at one place.
    """


def _alpha_rad(scene: Scene, t_s: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.asarray((scene.alpha0_rad + scene.omega_v_rad_s * t_s) % (2.0 * math.pi), dtype=np.float64)


def simulate_compiled(
    scene: Scene,
    t_end_s: float,
    max_events: int = 100_000,
    tol_s: float = 0.0,
    threshold_j: float = 0.0,
    friction: float = math.inf,
    slide_steps: int = STEPS_PER_SCALE,
) -> tuple[SimulationResult, int]:
    """The same run as :func:`simulate`, compiled (:func:`~millctl.physics.kernels.many_event.many_events`).

    Returns the same records, and how many of the impacts reach ``threshold_j`` (J; the rest are micro-hops).
    """
    if not (math.isfinite(t_end_s) and t_end_s >= 0.0):
        raise PhysicsInputError(f"t_end_s = {t_end_s} must be a finite time ≥ 0")
    from millctl.physics.kernels import scene_row
    from millctl.physics.kernels.many_event import many_events

    rows, detached, _, totals = many_events(scene_row(scene), t_end_s, max_events, threshold_j, tol_s,
                                            _check_friction(friction), slide_steps)  # fmt: skip
    impacts = np.zeros(len(rows), dtype=IMPACT_DTYPE)
    columns = ("time_s", "rod", "partner", "x_m", "y_m", "theta_rad", "normal_velocity_m_s",
               "tangential_velocity_m_s", "speed_abs_m_s", "energy_j", "flight_time_s")  # fmt: skip
    for k, name in enumerate(columns):
        impacts[name] = rows[:, k]
    impacts["alpha_rad"] = _alpha_rad(scene, rows[:, 0])
    detachments = np.zeros(len(detached), dtype=DETACHMENT_DTYPE)
    detachments["time_s"], detachments["rod"], detachments["theta_rad"] = detached[:, 0], detached[:, 1], detached[:, 2]
    detachments["slid_s"] = detached[:, 3]
    detachments["alpha_rad"] = _alpha_rad(scene, detached[:, 0])
    result = SimulationResult(impacts, detachments, t_end_s, float(totals[0]), float(totals[1]))
    return result, int(np.count_nonzero(rows[:, 11]))


def _repin(run: _Run, rod: int, t_s: float, rearm: bool, settled: bool = False) -> None:
    """Put a rod back on the wall at its current angle; overlapping neighbours are excluded until apart.

    ``settled``: the rod came to rest on another rod; where the wall cannot hold it (N ≤ 0 at its
    angle) it rides the pile until N has risen above zero again, instead of falling back onto the same
    rod at once (a Zeno chain of ever shorter hops that ended only at rounding, 1e-15 s apart).
    """
    x, y, _, _ = run.states[rod].rel(run.scene, t_s)
    run.states[rod] = WallState(t_s, math.atan2(y, x))
    run.n_d.pop(rod, None)
    run.bounces.pop(rod, None)
    run.ride.pop(rod, None)
    for j in range(len(run.states)):
        if j != rod and _overlapping(run, (min(rod, j), max(rod, j)), t_s):
            run.excluded.add((min(rod, j), max(rod, j)))
    _schedule(run, rod, t_s, rearm, settled)


def _schedule(run: _Run, rod: int, t_s: float, rearm: bool = False, settled: bool = False) -> None:
    s = run.states[rod]
    assert isinstance(s, WallState)
    theta_at_zero = s.theta0_rad - run.scene.omega_r_rad_s * s.t0_s
    det = find_detachment(run.scene, theta_at_zero, t_s, run.t_end_s, rearm=rearm)
    if settled and det.detached and det.at_start:
        det = find_detachment(run.scene, theta_at_zero, t_s, run.t_end_s, rearm=True)
    run.next_detach[rod] = det.time_s if det.detached else math.inf
    if det.detached and det.at_start:
        run.unsupported.add(rod)
    else:
        run.unsupported.discard(rod)
    ride = run.ride.setdefault(rod, _Ride())
    ride.ends, ride.direction = DETACH, 0.0
    carried = not (det.detached and det.at_start) and math.isfinite(det.held_from_s)
    if math.isfinite(run.friction) and carried and ride.changes < MAX_CHANGES:
        start, stop = det.held_from_s, min(run.next_detach[rod], run.t_end_s)
        onset = stick_slip_onset(run.scene, theta_at_zero, start, stop, run.friction) if start <= stop else math.inf
        if onset < run.next_detach[rod] and onset <= run.t_end_s:
            theta = s.theta0_rad + s.rate_rad_s(run.scene) * (onset - s.t0_s)
            ride.ends, ride.direction = SLIDE_STEP, slide_direction(run.scene, onset, theta)
            ride.theta_rad, ride.rate_rad_s = theta, run.scene.omega_r_rad_s
            run.next_detach[rod] = onset


def _slide(run: _Run, rod: int, t_s: float) -> None:
    """One slide step of a held rod from t (:func:`~.wall_slide.slide_step`): it moves along the step's chord."""
    ride, w_r = run.ride[rod], run.scene.omega_r_rad_s
    h = min(run.slide_step_s, run.t_end_s - t_s)
    if not h > 0.0:
        run.next_detach[rod] = math.inf
        return
    step = slide_step(run.scene, t_s, ride.theta_rad, ride.rate_rad_s, ride.direction, run.friction, h)
    if step.h_s == 0.0:  # the true N ≤ 0 where the slide would begin: the rod leaves carried, unsupported
        ride.ends, ride.direction, run.next_detach[rod] = DETACH, 0.0, t_s
        run.unsupported.add(rod)
        return
    run.states[rod] = WallState(t_s, ride.theta_rad, (step.theta_rad - ride.theta_rad) / step.h_s - w_r)
    ride.ends, ride.theta_rad, ride.rate_rad_s = step.ends, step.theta_rad, step.rate_rad_s
    ride.slid_s += step.h_s
    run.slide_s += step.h_s
    inside = -RELEASE_GAP_RTOL * run.scene.model.r0_m**2
    held = (j for j, state in enumerate(run.states) if j != rod and isinstance(state, WallState))
    if any(_overlapping(run, (rod, j), t_s, inside) for j in held):
        run.overlap_s += step.h_s
    run.next_detach[rod] = t_s + step.h_s


def _regrip(run: _Run, rod: int, t_s: float) -> None:
    """The sliding rod has caught up with the wall at t: carried again from its angle, the stick tried anew."""
    ride = run.ride[rod]
    run.states[rod] = WallState(t_s, ride.theta_rad)
    ride.changes += 1
    _schedule(run, rod, t_s)


def _depart(run: _Run, rod: int, t_s: float) -> None:
    scene, wall = run.scene, run.states[rod]
    assert isinstance(wall, WallState)
    ride = run.ride.pop(rod, None)
    sliding = ride is not None and ride.direction != 0.0
    if ride is not None and sliding:
        flight = depart_sliding(scene, t_s, ride.theta_rad, ride.rate_rad_s)
    else:
        flight = depart(scene, wall, t_s)
    theta = math.atan2(flight.y0_m, flight.x0_m)
    run.states[rod] = flight
    run.next_detach[rod] = math.inf
    # corrected, at a falling zero of N: N(t_d) = 0 by construction, the departure root is triple (n_d = 0
    # exactly, whatever the root finder's residual); a rod that starts unsupported or the paper's law: r0·N_true/m;
    # a sliding rod leaves at the falling zero of its true n (either variant)
    exact = sliding or (scene.model.variant is ModelVariant.CORRECTED and rod not in run.unsupported)
    run.n_d[rod] = 0.0 if exact else scene.model.r0_m * true_normal_force_per_mass(scene, t_s, theta)
    run.unsupported.discard(rod)
    alpha = (scene.alpha0_rad + scene.omega_v_rad_s * t_s) % (2.0 * math.pi)
    run.detachments.append((t_s, rod, theta, alpha, 0.0 if ride is None else ride.slid_s))
    # a neighbour it leaves touching (a separation of rounding size) is not a contact: excluded until apart
    for j in range(len(run.states)):
        if j != rod and _overlapping(run, (min(rod, j), max(rod, j)), t_s, RELEASE_GAP_RTOL * scene.model.r0_m**2):
            run.excluded.add((min(rod, j), max(rod, j)))


def _record(run: _Run, c: Contact) -> None:
    scene, model = run.scene, run.scene.model
    s = run.states[c.rod]
    x, y, vx, vy = s.rel(scene, c.time_s)
    yc, vyc, _ = vial_centre_m(scene, c.time_s)
    r = model.rod_radius_m
    px, py = x + r * c.normal_x, yc + y + r * c.normal_y
    speed = math.hypot(vx, vy + vyc)
    backed = c.partner == WALL or isinstance(run.states[c.partner], WallState)
    energy = impact_energy_j(model, c.normal_velocity_m_s, speed, backed)
    alpha = (scene.alpha0_rad + scene.omega_v_rad_s * c.time_s) % (2.0 * math.pi)
    flight = c.flight_time_s  # located in the flight's own clock, not t_contact − t_0
    velocities = (c.normal_velocity_m_s, c.tangential_velocity_m_s, speed)
    run.impacts.append((c.time_s, c.rod, c.partner, px, py, math.atan2(y, x), alpha, *velocities, energy, flight))


def _bounce(run: _Run, c: Contact) -> None:
    scene, e = run.scene, run.scene.model.restitution
    a = run.states[c.rod]
    x, y, vx, vy = a.rel(scene, c.time_s)
    partner = run.states[c.partner]
    _, _, vbx, vby = partner.rel(scene, c.time_s)
    vn = c.normal_velocity_m_s
    if isinstance(partner, FlightState):
        dv = 0.5 * (1.0 + e) * vn
        xb, yb, _, _ = partner.rel(scene, c.time_s)
        run.states[c.partner] = FlightState(c.time_s, xb, yb, vbx + dv * c.normal_x, vby + dv * c.normal_y)
    else:
        dv = (1.0 + e) * vn
    run.states[c.rod] = FlightState(c.time_s, x, y, vx - dv * c.normal_x, vy - dv * c.normal_y)
    run.excluded.add((min(c.rod, c.partner), max(c.rod, c.partner)))


def _step(run: _Run, t_s: float, stop_after_first: bool) -> float | None:
    """Advance to the next event; return its time, or None when the run is over."""
    scene = run.scene
    t_det = min(run.next_detach, default=math.inf)
    seg_end = min(t_det, run.t_end_s)
    contact = None
    if any(isinstance(s, FlightState) for s in run.states):
        contact = earliest_contact(scene, run.states, t_s, seg_end, run.n_d, excluded=run.excluded, tol_s=run.tol_s)
    if contact is None:
        if t_det > run.t_end_s:
            return None
        rod = run.next_detach.index(t_det)
        ends = run.ride[rod].ends if rod in run.ride else DETACH
        if ends == SLIDE_STEP:
            _slide(run, rod, t_det)
        elif ends == REGRIP:
            _regrip(run, rod, t_det)
        else:
            _depart(run, rod, t_det)
        return t_det
    zero_length = contact.partner == WALL and contact.flight_time_s == 0.0
    if not zero_length:
        _record(run, contact)
        if stop_after_first:
            return None  # nothing after the first impact is needed: no re-scheduling
    if contact.partner == WALL:
        flight = run.states[contact.rod]
        hop = isinstance(flight, FlightState) and flight.from_wall  # a hop off the wall, not a bounce's landing
        hop = hop and contact.flight_time_s < MIN_HOP_RTOL * scan_step_s(scene)  # the end of a Zeno chain
        _repin(run, contact.rod, contact.time_s, rearm=zero_length or hop)
    else:
        run.bounces[contact.rod] = run.bounces.get(contact.rod, 0) + 1
        settle = SETTLE_SPEED_FACTOR * math.sqrt(scene.model.g_m_s2 * scene.model.rod_radius_m)
        if contact.normal_velocity_m_s < settle or run.bounces[contact.rod] > MAX_BOUNCES:
            _repin(run, contact.rod, contact.time_s, rearm=False, settled=True)
        else:
            _bounce(run, contact)
    return contact.time_s


def _check_friction(friction: float) -> float:
    if not friction >= 0.0:
        raise PhysicsInputError(f"friction μ = {friction} must be ≥ 0 (inf: the paper's carriage, no slip)")
    return float(friction)


def simulate(
    scene: Scene,
    t_end_s: float,
    max_events: int = 100_000,
    stop_after_first: bool = False,
    tol_s: float = 0.0,
    friction: float = math.inf,
    slide_steps: int = STEPS_PER_SCALE,
) -> SimulationResult:
    """Run the multi-rod event simulation from t = 0 (all rods pinned at eq. 11's angles) to t_end (s).

    ``tol_s`` is the contact root finder's time tolerance (0: ≈ 4 ulp). ``friction``: μ of the held rods'
    slip ride (:mod:`.wall_slide`; ``scene.model.powder_friction`` is the model's); inf (default) carries
    them as the paper does. ``slide_steps``: the slide's Runge–Kutta steps per shortest time scale
    (:func:`~.wall_slide.slide_step_s`; its error ∝ steps⁻⁴). Every slide step counts as an event of ``max_events``.
    """
    if not (math.isfinite(t_end_s) and t_end_s >= 0.0):
        raise PhysicsInputError(f"t_end_s = {t_end_s} must be a finite time ≥ 0")
    n = scene.model.n_rods
    run = _Run(scene, t_end_s, [WallState(0.0, scene.rod_theta0_rad(i)) for i in range(n)], [math.inf] * n, tol_s)
    run.friction, run.slide_step_s = _check_friction(friction), slide_step_s(scene, slide_steps)
    for i in range(n):
        _schedule(run, i, 0.0)
    t: float | None = 0.0
    events = 0
    while t is not None and events < max_events:
        t = _step(run, t, stop_after_first)
        events += 1
        if t is not None:
            run.excluded = {p for p in run.excluded if _still_touching(run, p, t)}
    return SimulationResult(
        np.array(run.impacts, dtype=IMPACT_DTYPE), np.array(run.detachments, dtype=DETACHMENT_DTYPE), t_end_s,
        run.slide_s, run.overlap_s,
    )


def _overlapping(run: _Run, pair: tuple[int, int], t_s: float, slack_m2: float = 0.0) -> bool:
    """Centres no further apart than the contact distance (a re-pinned rod resting on a neighbour).

    ``slack_m2``: a separation |d|² − (2 r_r)² up to this still counts (a departing rod: rounding's size).

    Only such pairs are excluded when a rod is put back on the wall: two rods that merely
    ride side by side on the wall are neither apart-and-separating nor touching, and must
    stay in the contact search once one of them flies.
    """
    xa, ya, _, _ = run.states[pair[0]].rel(run.scene, t_s)
    xb, yb, _, _ = run.states[pair[1]].rel(run.scene, t_s)
    return (xa - xb) ** 2 + (ya - yb) ** 2 - run.scene.model.contact_distance_m**2 <= slack_m2


def _still_touching(run: _Run, pair: tuple[int, int], t_s: float) -> bool:
    """A pair stays excluded until its centres are apart by more than the contact distance and separating.

    Apart means beyond rounding: the separation |d|² − (2 r_r)² above :data:`RELEASE_GAP_RTOL` · r0², the
    scale below which the contact search treats a pair as touching. Released at the instant of its bounce
    (apart by an ulp), a pair was found touching again a few 1e-14 s later at v_n ~ 1e-13 m/s, and the rod
    settled where it should have flown on (tests/unit/physics/test_many_event.py). Separating likewise
    means beyond rounding: the cosine between d and the relative velocity above RELEASE_GAP_RTOL (two
    rods held on the wall move at right angles to their offset, a dot product of ±1 ulp whose sign
    decided whether the pair was tested again).
    """
    scene = run.scene
    xa, ya, vxa, vya = run.states[pair[0]].rel(scene, t_s)
    xb, yb, vxb, vyb = run.states[pair[1]].rel(scene, t_s)
    dx, dy = xa - xb, ya - yb
    apart = dx * dx + dy * dy - scene.model.contact_distance_m**2 > RELEASE_GAP_RTOL * scene.model.r0_m**2
    dvx, dvy = vxa - vxb, vya - vyb
    separating = dx * dvx + dy * dvy > RELEASE_GAP_RTOL * math.hypot(dx, dy) * math.hypot(dvx, dvy)
    return not (apart and separating)


__all__ = ["DETACHMENT_DTYPE", "IMPACT_DTYPE", "SimulationResult", "simulate", "simulate_compiled"]
