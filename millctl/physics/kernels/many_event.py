"""Level (c) compiled: the multi-rod event loop with re-scheduling after every impact (reference: :mod:`..simulate`).

Line by line the algorithm of :func:`millctl.physics.simulate.simulate`, so that both engines see the same
events in the same order (the agreement test compares them event for event):

* every rod starts held on the wall at eq. 11's angle; a held rod's next detachment is the first falling
  zero of N(t)/m (eqs 4–7, :mod:`.detach`, with its trig row rebuilt for the angle it was put back at);
* between events the contacts of every flying rod with the wall and with every other rod are bracketed on
  the reference's grid (1/16 of the shortest time scale, chunks of :data:`~.many_layout.SCAN_SAMPLES`,
  the second-order margin over the chunk's largest relative speed) and resolved by Brent's method in the
  mover's own clock τ (eq. 10 for the flight, eq. 13 with 2 r_r for two rods; the wall gap of a rod that
  has just left the wall with the departure's triple root divided out);
* a wall landing is an impact (eq. 19, the variant's energy) unless its flight has zero length; the rod is
  put back on the wall where it landed and its next detachment is searched (after the current dip of N
  when the flight had zero length); a landing below the impact threshold is a micro-hop: recorded, not
  counted (``counted`` 0);
* two rods: restitution e along the normal (equal masses; a held partner is backed by the wall); the pair
  is skipped until it separates; a rod slower than ``SETTLE_SPEED_FACTOR``·√(g r_r) or past ``MAX_BOUNCES``
  settles on the wall.

* with a finite friction μ the held rods ride with slip (:mod:`.slide`, :mod:`millctl.physics.wall_slide`): a
  carried rod's next event is the earlier of its detachment and the end of its stick; a sliding rod's is the
  end of its slide step (a Runge–Kutta step, cut at a regrip or a detachment inside it), along whose chord it
  moves; at a regrip it is carried again and its stick tried anew; it leaves at its own rate φ̇_d.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from millctl.physics.kernels.detach import _falling_zero_windowed, _never_detaches, _rearm
from millctl.physics.kernels.events import _contact, _depart
from millctl.physics.kernels.layout import (
    _A0,
    _E,
    _G,
    _KM,
    _N,
    _NEAR_ZERO,
    _O_ENERGY,
    _O_SPEED,
    _O_THC,
    _O_VN,
    _O_VT,
    _O_X,
    _O_Y,
    _PAPER,
    _R0,
    _RD,
    _RR,
    _S_CA,
    _S_DW,
    _S_FLY,
    _S_ND,
    _S_SA,
    _S_T0,
    _S_TH,
    _S_UX,
    _S_UY,
    _S_X,
    _S_Y,
    _STATE_COLUMNS,
    _TH0,
    _TRIG_COLUMNS,
    _WR,
    _WV,
    OUT,
    PARAMS,
    WALL,
    FloatArray,
)
from millctl.physics.kernels.many_contacts import _earliest, _scan_step_s, _work
from millctl.physics.kernels.many_layout import (
    _B_BOUNCES,
    _B_CHANGES,
    _B_DET,
    _B_DIR,
    _B_ENDS,
    _B_FROM_WALL,
    _B_PHI,
    _B_RATE,
    _B_SLID,
    _B_UNSUP,
    _D_ROD,
    _D_SLID,
    _D_T,
    _D_TH,
    _I_COUNTED,
    _I_ENERGY,
    _I_FLIGHT,
    _I_PARTNER,
    _I_ROD,
    _I_SPEED,
    _I_T,
    _I_TH,
    _I_VN,
    _I_VT,
    _I_X,
    _I_Y,
    _T_OVERLAP,
    _T_SLIDE,
    DETACHMENT,
    IMPACT,
    MAX_BOUNCES,
    MIN_HOP_RTOL,
    ROD_BOOK,
    SETTLE_SPEED_FACTOR,
    TOTALS,
)
from millctl.physics.kernels.motion import _rel
from millctl.physics.kernels.slide import _slide_direction, _slide_step, _slip_work, _stick_onset
from millctl.physics.kernels.trig import _set_term, _trig
from millctl.physics.wall_slide import DETACH, MAX_CHANGES, REGRIP, SLIDE_STEP, STEPS_PER_SCALE, check_slide_steps


@njit(cache=True)
def _held_row(p, tr, i, theta_at_zero):  # type: ignore[no-untyped-def]
    """Trig row i: N/m of a rod held at θ(t) = θ_z + ω_r t (kinematics.normal_force_per_mass, corrected/paper)."""
    wr, wv, a0 = p[_WR], p[_WV], p[_A0]
    if p[_PAPER] != 0.0:  # eq. 7 as printed: 2 r0 ω_r² and the spring term
        constant, coupling = 2.0 * p[_R0] * wr * wr, (wv * wv - p[_KM]) * p[_RD]
    else:
        constant, coupling = p[_R0] * wr * wr, p[_RD] * wv * wv
    tr[i, 0], tr[i, 1] = constant, 3.0
    _set_term(tr, i, 0, p[_G], wr, theta_at_zero + 0.5 * math.pi)
    _set_term(tr, i, 1, 0.5 * coupling, wv - wr, a0 - theta_at_zero)
    _set_term(tr, i, 2, -0.5 * coupling, wv + wr, a0 + theta_at_zero)


@njit(cache=True)
def _schedule(p, st, tr, book, i, t, t_end, rearm, settled, slip):  # type: ignore[no-untyped-def]
    """The next event of carried rod i from t: its detachment, or with slip the end of its stick if earlier.

    The detachment is detachment.find_detachment's up to t_end (``rearm``: skip the dip); the stick's end
    the first |F_t| > μN after it is held (simulate._schedule).

    ``settled``: the rod came to rest on another rod; with N ≤ 0 at its angle it rides the pile (re-armed).
    """
    _held_row(p, tr, i, st[i, _S_TH] - p[_WR] * st[i, _S_T0])
    book[i, _B_DET], book[i, _B_UNSUP] = math.inf, 0.0
    book[i, _B_ENDS], book[i, _B_DIR] = DETACH, 0.0
    start = t
    if rearm:
        start = _rearm(p, st, tr, i, t, t_end)
        if start == math.inf:
            return
    if settled and not rearm and _trig(tr, i, start, 0, 1.0) <= 0.0:
        start = _rearm(p, st, tr, i, t, t_end)
        if start == math.inf:
            return
    if _trig(tr, i, start, 0, 1.0) <= 0.0:
        book[i, _B_DET], book[i, _B_UNSUP] = start, 1.0
        return
    if not _never_detaches(tr, i):
        book[i, _B_DET] = _falling_zero_windowed(p, st, tr, i, 1.0, start, t_end)
    stop = min(book[i, _B_DET], t_end)
    if slip[0] == math.inf or book[i, _B_CHANGES] >= MAX_CHANGES or not start <= stop:
        return
    rate = p[_WR] + st[i, _S_DW]
    onset = _stick_onset(p, st[i, _S_TH] + rate * (start - st[i, _S_T0]), start, stop, slip)
    if onset < book[i, _B_DET] and onset <= t_end:
        theta = st[i, _S_TH] + rate * (onset - st[i, _S_T0])
        book[i, _B_ENDS], book[i, _B_DIR] = SLIDE_STEP, _slide_direction(p, onset, theta)
        book[i, _B_PHI], book[i, _B_RATE], book[i, _B_DET] = theta, p[_WR], onset


@njit(cache=True)
def _slide(p, st, book, i, t, t_end, slip, totals):  # type: ignore[no-untyped-def]
    """simulate._slide: one slide step of held rod i from t; it moves along the step's chord.

    ``totals`` (:data:`TOTALS`) gains the step's length, and again when the rod began it inside another held rod.
    """
    h = min(slip[4], t_end - t)
    if not h > 0.0:
        book[i, _B_DET] = math.inf
        return
    phi = book[i, _B_PHI]
    ends, h_s, phi_end, rate_end = _slide_step(p, t, phi, book[i, _B_RATE], book[i, _B_DIR], slip[0], h)
    if h_s == 0.0:  # the true N ≤ 0 where the slide would begin: the rod leaves carried, unsupported
        book[i, _B_ENDS], book[i, _B_DIR], book[i, _B_DET], book[i, _B_UNSUP] = DETACH, 0.0, t, 1.0
        return
    st[i, _S_T0], st[i, _S_TH], st[i, _S_DW] = t, phi, (phi_end - phi) / h_s - p[_WR]
    book[i, _B_ENDS], book[i, _B_PHI], book[i, _B_RATE] = ends, phi_end, rate_end
    book[i, _B_SLID] += h_s
    book[i, _B_DET] = t + h_s
    totals[_T_SLIDE] += h_s
    inside = -_NEAR_ZERO * p[_R0] * p[_R0]
    for j in range(int(p[_N])):
        if j != i and st[j, _S_FLY] == 0.0 and _overlapping(p, st, i, j, t, inside):
            totals[_T_OVERLAP] += h_s
            break


@njit(cache=True)
def _regrip(p, st, tr, book, i, t, t_end, slip):  # type: ignore[no-untyped-def]
    """simulate._regrip: carried again from its angle at t, the stick tried anew."""
    st[i, _S_T0], st[i, _S_TH], st[i, _S_DW] = t, book[i, _B_PHI], 0.0
    book[i, _B_CHANGES] += 1.0
    _schedule(p, st, tr, book, i, t, t_end, False, False, slip)


@njit(cache=True)
def _depart_sliding(p, st, i, t, theta, rate):  # type: ignore[no-untyped-def]
    """flight.depart_sliding: rod i leaves the wall at t from φ_d at its own rate φ̇_d, n_d = 0."""
    r0, offset = p[_R0], rate - p[_WR]
    w = p[_WR] + offset
    c, s = math.cos(theta), math.sin(theta)
    st[i, _S_FLY], st[i, _S_T0] = 1.0, t
    st[i, _S_X], st[i, _S_Y], st[i, _S_UX], st[i, _S_UY] = r0 * c, r0 * s, -r0 * w * s, r0 * w * c
    alpha = p[_A0] + p[_WV] * t
    st[i, _S_SA], st[i, _S_CA] = math.sin(alpha), math.cos(alpha)
    st[i, _S_ND], st[i, _S_DW] = 0.0, offset


@njit(cache=True)
def _overlapping(p, st, a, b, t, slack):  # type: ignore[no-untyped-def]
    """simulate._overlapping: |d|² − (2 r_r)² ≤ ``slack`` (m²)."""
    xa, ya, _, _ = _rel(p, st, a, t)
    xb, yb, _, _ = _rel(p, st, b, t)
    return (xa - xb) ** 2 + (ya - yb) ** 2 - 4.0 * p[_RR] * p[_RR] <= slack


@njit(cache=True)
def _still_touching(p, st, a, b, t):  # type: ignore[no-untyped-def]
    """simulate._still_touching: excluded until apart and separating, both beyond rounding (RELEASE_GAP_RTOL)."""
    xa, ya, vxa, vya = _rel(p, st, a, t)
    xb, yb, vxb, vyb = _rel(p, st, b, t)
    dx, dy = xa - xb, ya - yb
    apart = dx * dx + dy * dy - 4.0 * p[_RR] * p[_RR] > _NEAR_ZERO * p[_R0] * p[_R0]
    dvx, dvy = vxa - vxb, vya - vyb
    separating = dx * dvx + dy * dvy > _NEAR_ZERO * math.hypot(dx, dy) * math.hypot(dvx, dvy)
    return not (apart and separating)


@njit(cache=True)
def _repin(p, st, tr, book, excluded, i, t, t_end, rearm, settled, slip):  # type: ignore[no-untyped-def]
    """Put rod i back on the wall at its angle at t, exclude the neighbours it overlaps, search its detachment."""
    x, y, _, _ = _rel(p, st, i, t)
    st[i, _S_FLY], st[i, _S_T0], st[i, _S_TH], st[i, _S_DW] = 0.0, t, math.atan2(y, x), 0.0
    book[i, _B_BOUNCES], book[i, _B_FROM_WALL] = 0.0, 0.0
    book[i, _B_SLID], book[i, _B_CHANGES] = 0.0, 0.0
    for j in range(int(p[_N])):
        if j != i and _overlapping(p, st, i, j, t, 0.0):
            excluded[min(i, j), max(i, j)] = 1
    _schedule(p, st, tr, book, i, t, t_end, rearm, settled, slip)


@njit(cache=True)
def _fly(p, st, book, i, t, x, y, vx, vy):  # type: ignore[no-untyped-def]
    """Rod i starts a free flight at t from (x, y) with (vx, vy), vial frame (not from the wall)."""
    st[i, _S_FLY], st[i, _S_T0] = 1.0, t
    st[i, _S_X], st[i, _S_Y], st[i, _S_UX], st[i, _S_UY] = x, y, vx, vy
    alpha = p[_A0] + p[_WV] * t
    st[i, _S_SA], st[i, _S_CA], st[i, _S_DW] = math.sin(alpha), math.cos(alpha), 0.0
    book[i, _B_FROM_WALL] = 0.0


@njit(cache=True)
def _bounce(p, st, book, excluded, i, j, t):  # type: ignore[no-untyped-def]
    """Rod–rod impact: the normal velocity reversed with restitution e (a flying partner takes half, equal masses)."""
    x, y, vx, vy = _rel(p, st, i, t)
    xb, yb, vxb, vyb = _rel(p, st, j, t)
    dx, dy = xb - x, yb - y
    r = math.hypot(dx, dy)
    nx, ny = dx / r, dy / r
    vn = (vx - vxb) * nx + (vy - vyb) * ny
    e = p[_E]
    if st[j, _S_FLY] != 0.0:
        dv = 0.5 * (1.0 + e) * vn
        _fly(p, st, book, j, t, xb, yb, vxb + dv * nx, vyb + dv * ny)
    else:
        dv = (1.0 + e) * vn
    _fly(p, st, book, i, t, x, y, vx - dv * nx, vy - dv * ny)
    excluded[min(i, j), max(i, j)] = 1


@njit(cache=True)
def _detach(p, st, tr, book, excluded, i, t, d):  # type: ignore[no-untyped-def]
    """simulate._depart: held rod i leaves the wall at t (carried, or sliding at its own rate); its row ``d``."""
    if book[i, _B_DIR] != 0.0:
        _depart_sliding(p, st, i, t, book[i, _B_PHI], book[i, _B_RATE])
    else:
        _depart(p, st, tr, i, t, book[i, _B_UNSUP] != 0.0)
    book[i, _B_UNSUP], book[i, _B_DET], book[i, _B_FROM_WALL] = 0.0, math.inf, 1.0
    d[_D_T], d[_D_ROD], d[_D_TH] = t, i, math.atan2(st[i, _S_Y], st[i, _S_X])
    d[_D_SLID] = book[i, _B_SLID]
    book[i, _B_ENDS], book[i, _B_DIR], book[i, _B_SLID], book[i, _B_CHANGES] = DETACH, 0.0, 0.0, 0.0
    for j in range(int(p[_N])):  # a neighbour it leaves touching at rounding's size: excluded until apart
        if j != i and _overlapping(p, st, i, j, t, _NEAR_ZERO * p[_R0] * p[_R0]):
            excluded[min(i, j), max(i, j)] = 1


@njit(cache=True)
def _run(p, t_end, max_events, threshold_j, tol, mu, slide_steps, impacts, detachments, totals):  # type: ignore[no-untyped-def]
    """The event loop of simulate.simulate into its rows and ``totals`` (:data:`TOTALS`, zeroed here).

    ``impacts`` (:data:`IMPACT`) and ``detachments`` (:data:`DETACHMENT`) are filled from row 0; ``mu``: the
    slip ride's friction (inf: carried), ``slide_steps`` its steps a time scale. Returns (impacts written,
    detachments written, events stepped, 1 when a table filled before the end).
    """
    slip = _slip_work(p, mu, slide_steps)
    totals[:] = 0.0
    n = int(p[_N])
    st = np.zeros((n, _STATE_COLUMNS))
    tr = np.zeros((n, _TRIG_COLUMNS))
    book = np.zeros((n, len(ROD_BOOK)))
    excluded = np.zeros((n, n), dtype=np.uint8)
    w = _work(n)
    row = np.empty(len(OUT))
    settle = SETTLE_SPEED_FACTOR * math.sqrt(p[_G] * p[_RR])
    for i in range(n):
        st[i, _S_TH] = p[_TH0] + i * 2.0 * math.pi / n
        _schedule(p, st, tr, book, i, 0.0, t_end, False, False, slip)
    n_imp, n_det, steps = 0, 0, 0
    t = 0.0
    while steps < max_events:
        t_det, rod_det, flying = math.inf, -1, False
        for i in range(n):
            if book[i, _B_DET] < t_det:
                t_det, rod_det = book[i, _B_DET], i
            flying = flying or st[i, _S_FLY] != 0.0
        t_hit, rod, partner, tau = math.inf, -1, -1, 0.0
        if flying:
            t_hit, rod, partner, tau = _earliest(p, st, book, excluded, t, min(t_det, t_end), tol, w)
        steps += 1
        if t_hit == math.inf:
            if t_det > t_end:
                return n_imp, n_det, steps, 0
            t = t_det
            if book[rod_det, _B_ENDS] == SLIDE_STEP:
                _slide(p, st, book, rod_det, t_det, t_end, slip, totals)
            elif book[rod_det, _B_ENDS] == REGRIP:
                _regrip(p, st, tr, book, rod_det, t_det, t_end, slip)
            elif n_det == detachments.shape[0]:
                return n_imp, n_det, steps, 1
            else:
                _detach(p, st, tr, book, excluded, rod_det, t_det, detachments[n_det])
                n_det += 1
        else:
            zero_length = partner == WALL and tau == 0.0
            vn = 0.0
            if not zero_length:
                if n_imp == impacts.shape[0]:
                    return n_imp, n_det, steps, 1
                _contact(p, st, rod, partner, t_hit, row)
                out = impacts[n_imp]
                out[_I_T], out[_I_ROD], out[_I_PARTNER] = t_hit, rod, partner
                out[_I_X], out[_I_Y], out[_I_TH] = row[_O_X], row[_O_Y], row[_O_THC]
                out[_I_VN], out[_I_VT], out[_I_SPEED] = row[_O_VN], row[_O_VT], row[_O_SPEED]
                out[_I_ENERGY], out[_I_FLIGHT] = row[_O_ENERGY], tau
                out[_I_COUNTED] = 1.0 if row[_O_ENERGY] >= threshold_j else 0.0
                vn = row[_O_VN]
                n_imp += 1
            if partner == WALL:
                # simulate.MIN_HOP_RTOL: a hop off the wall (not a bounce's landing) this short ends a Zeno chain
                hop = book[rod, _B_FROM_WALL] != 0.0 and tau < MIN_HOP_RTOL * _scan_step_s(p)
                _repin(p, st, tr, book, excluded, rod, t_hit, t_end, zero_length or hop, False, slip)
            else:
                book[rod, _B_BOUNCES] += 1.0
                if vn < settle or book[rod, _B_BOUNCES] > MAX_BOUNCES:
                    _repin(p, st, tr, book, excluded, rod, t_hit, t_end, False, True, slip)
                else:
                    _bounce(p, st, book, excluded, rod, partner, t_hit)
            t = t_hit
        for a in range(n):
            for b in range(a + 1, n):
                if excluded[a, b] != 0 and not _still_touching(p, st, a, b, t):
                    excluded[a, b] = 0
    return n_imp, n_det, steps, 0


def many_events(
    row: FloatArray,
    t_end_s: float,
    max_events: int = 100_000,
    threshold_j: float = 0.0,
    tol_s: float = 0.0,
    friction: float = math.inf,
    slide_steps: int = STEPS_PER_SCALE,
) -> tuple[FloatArray, FloatArray, int, FloatArray]:
    """Every impact and detachment of one scene row (:data:`PARAMS`) from t = 0 to ``t_end_s``, compiled.

    Returns (impact rows :data:`IMPACT`, detachment rows :data:`DETACHMENT`, events stepped, the run's
    :data:`TOTALS`). An impact
    below ``threshold_j`` (J) is recorded with ``counted`` 0. ``max_events`` bounds the loop's steps as in
    :func:`millctl.physics.simulate.simulate`; ``tol_s`` is the contact root finder's time tolerance;
    ``friction`` the held rods' μ of the slip ride (inf: carried, no slip), ``slide_steps`` its Runge–Kutta
    steps per shortest time scale (:func:`millctl.physics.wall_slide.slide_step_s`).
    """
    p = np.ascontiguousarray(row, dtype=np.float64)
    if p.shape != (len(PARAMS),):
        raise ValueError(f"row must have {len(PARAMS)} columns ({', '.join(PARAMS)}), got shape {p.shape}")
    if not (math.isfinite(t_end_s) and t_end_s >= 0.0):
        raise ValueError(f"t_end_s = {t_end_s} must be a finite time ≥ 0")
    if not friction >= 0.0:
        raise ValueError(f"friction μ = {friction} must be ≥ 0 (inf: carried, no slip)")
    per_scale = check_slide_steps(slide_steps)
    capacity = min(max(max_events, 1), 4096)
    totals = np.zeros(len(TOTALS))
    while True:
        impacts, detachments = np.empty((capacity, len(IMPACT))), np.empty((capacity, len(DETACHMENT)))
        n_imp, n_det, steps, full = _run(p, float(t_end_s), int(max_events), float(threshold_j), float(tol_s),
                                         float(friction), per_scale, impacts, detachments, totals)  # fmt: skip
        if not full:
            return impacts[:n_imp], detachments[:n_det], int(steps), totals
        capacity *= 4  # the run is deterministic: start again with room for every event


__all__ = ["DETACHMENT", "IMPACT", "TOTALS", "many_events"]
