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

The slip ride is not integrated here: a rod held on the wall is carried (θ = θ_pin + ω_r t). Slip enters
the studies' level (c) through the carried arcs of this run (:func:`millctl.studies.loads.carried_arc_slip`).
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
    _S_FLY,
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
    _TWO_PI,
    _WR,
    _WV,
    OUT,
    PARAMS,
    WALL,
    FloatArray,
)
from millctl.physics.kernels.many_layout import (
    _B_BOUNCES,
    _B_DET,
    _B_FROM_WALL,
    _B_UNSUP,
    _D_ROD,
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
    DETACHMENT,
    IMPACT,
    MAX_BOUNCES,
    ROD_BOOK,
    SCAN_SAMPLES,
    SETTLE_SPEED_FACTOR,
)
from millctl.physics.kernels.many_roots import _gap_tau, _resolve
from millctl.physics.kernels.motion import _flying_rel, _rel, _zero_length_departure
from millctl.physics.kernels.trig import _set_term, _trig

_NEAR_ZERO = 1e-9


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
def _schedule(p, st, tr, book, i, t, t_end, rearm, settled=False):  # type: ignore[no-untyped-def]
    """The next detachment of held rod i from t (detachment.find_detachment up to t_end, ``rearm``: skip the dip).

    ``settled``: the rod came to rest on another rod; with N ≤ 0 at its angle it rides the pile (re-armed).
    """
    _held_row(p, tr, i, st[i, _S_TH] - p[_WR] * st[i, _S_T0])
    book[i, _B_DET], book[i, _B_UNSUP] = math.inf, 0.0
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
    elif not _never_detaches(tr, i):
        book[i, _B_DET] = _falling_zero_windowed(p, st, tr, i, 1.0, start, t_end)


@njit(cache=True)
def _scan_step_s(p):  # type: ignore[no-untyped-def]
    """events.scan_step_s: 1/16 of the shortest of the cam period, the revolution and the fall time √(2 r_r/g)."""
    shortest = math.sqrt(2.0 * p[_RR] / p[_G])
    for w in (p[_WV], p[_WR]):
        if w > 0.0:
            shortest = min(shortest, _TWO_PI / w)
    return shortest / 16.0


@njit(cache=True)
def _pair_now(p, pos, i, j):  # type: ignore[no-untyped-def]
    """(separation, its derivative, relative speed²) of a pair from the rods' positions (vial frame)."""
    x, y, vx, vy = pos[i, 0], pos[i, 1], pos[i, 2], pos[i, 3]
    if j == WALL:
        return p[_R0] * p[_R0] - (x * x + y * y), -2.0 * (x * vx + y * vy), vx * vx + vy * vy
    dx, dy, dvx, dvy = x - pos[j, 0], y - pos[j, 1], vx - pos[j, 2], vy - pos[j, 3]
    return dx * dx + dy * dy - 4.0 * p[_RR] * p[_RR], 2.0 * (dx * dvx + dy * dvy), dvx * dvx + dvy * dvy


@njit(cache=True)
def _fill(p, st, n, count, pi, pj, pos, ts, sep, dsep, prev, start, stop, turn, h):  # type: ignore[no-untyped-def]
    """Samples start..stop−1 of a chunk: every pair's separation and derivative, the largest relative speed².

    Rods move by phasors (``turn``: the cos, sin of a held rod's angle θ or of a flying rod's cam turn ω_v τ
    at the last filled sample, turned by one step's ω h; the last row the steps' cos ω_r h, sin ω_r h, cos ω_v h,
    sin ω_v h), evaluated afresh at a sample the end clamped: a few ulp from the reference's cos and sin,
    which only decide which intervals are resolved (the roots come from :func:`_g`, exactly).
    """
    cr, sr, cv, sv = turn[n, 0], turn[n, 1], turn[n, 2], turn[n, 3]
    r0, w_r = p[_R0], p[_WR]
    for s_ in range(start, stop):
        t = ts[s_ + 1]
        exact = t != ts[0] + h * (s_ + 1)
        for r in range(n):
            held = st[r, _S_FLY] == 0.0
            if exact:
                x = st[r, _S_TH] + w_r * (t - st[r, _S_T0]) if held else p[_WV] * (t - st[r, _S_T0])
                turn[r, 0], turn[r, 1] = math.cos(x), math.sin(x)
            elif held:
                turn[r, 0], turn[r, 1] = turn[r, 0] * cr - turn[r, 1] * sr, turn[r, 1] * cr + turn[r, 0] * sr
            else:
                turn[r, 0], turn[r, 1] = turn[r, 0] * cv - turn[r, 1] * sv, turn[r, 1] * cv + turn[r, 0] * sv
            c, sn = turn[r, 0], turn[r, 1]
            if held:
                pos[r, 0], pos[r, 1], pos[r, 2], pos[r, 3] = r0 * c, r0 * sn, -r0 * w_r * sn, r0 * w_r * c
            else:
                pos[r, 0], pos[r, 1], pos[r, 2], pos[r, 3] = _flying_rel(p, st, r, t - st[r, _S_T0], c, sn)
        for k in range(count):
            s, ds, v2 = _pair_now(p, pos, pi[k], pj[k])
            sep[k, s_], dsep[k, s_] = s, ds
            prev[k, 2] = max(prev[k, 2], v2)
    return stop


@njit(cache=True)
def _earliest(p, st, book, excluded, t_start, t_end, tol, w):  # type: ignore[no-untyped-def]
    """events.earliest_contact: (t, rod, partner, τ) of the first contact of a flying rod in [t_start, t_end]."""
    n = int(p[_N])
    pi, pj, reduced = w[0], w[1], w[2]
    sep, dsep, prev, pos, ts, turn = w[3], w[4], w[5], w[6], w[7], w[8]
    count = 0
    for i in range(n):
        if st[i, _S_FLY] != 0.0:
            pi[count], pj[count] = i, WALL
            reduced[count] = 1 if book[i, _B_FROM_WALL] != 0.0 else 0
            count += 1
    for i in range(n):
        if st[i, _S_FLY] == 0.0:
            continue
        for j in range(n):
            if j == i or (st[j, _S_FLY] != 0.0 and j < i) or excluded[min(i, j), max(i, j)] != 0:
                continue
            pi[count], pj[count], reduced[count] = i, j, 0
            count += 1
    for r in range(n):
        pos[r, 0], pos[r, 1], pos[r, 2], pos[r, 3] = _rel(p, st, r, t_start)
    for k in range(count):
        i, j = pi[k], pj[k]
        s, ds, _ = _pair_now(p, pos, i, j)
        if reduced[k] != 0 and st[i, _S_T0] == t_start:
            touching = _zero_length_departure(p, st, i)
        elif reduced[k] != 0:
            touching = _gap_tau(p, st, i, t_start - st[i, _S_T0]) <= 0.0
        else:
            touching = s <= 0.0
        if touching:
            return t_start, i, j, t_start - st[i, _S_T0]
        prev[k, 0], prev[k, 1] = s, ds
    h = _scan_step_s(p)
    accel = 2.0 * max(p[_G] + p[_RD] * p[_WV] * p[_WV], p[_R0] * p[_WR] * p[_WR])
    r0 = p[_R0]
    near = _NEAR_ZERO * r0 * r0
    turn[n, 0], turn[n, 1] = math.cos(p[_WR] * h), math.sin(p[_WR] * h)
    turn[n, 2], turn[n, 3] = math.cos(p[_WV] * h), math.sin(p[_WV] * h)
    t_prev = t_start
    while t_prev < t_end:
        ts[0] = t_prev
        for s_ in range(1, SCAN_SAMPLES + 1):
            ts[s_] = min(t_prev + h * s_, t_end)
        for r in range(n):
            held = st[r, _S_FLY] == 0.0
            x = st[r, _S_TH] + p[_WR] * (t_prev - st[r, _S_T0]) if held else p[_WV] * (t_prev - st[r, _S_T0])
            turn[r, 0], turn[r, 1] = math.cos(x), math.sin(x)
        for k in range(count):
            prev[k, 2] = 0.0
        # samples are filled as the candidates need them; the margin of a minimum needs the chunk's largest
        # relative speed (the reference's), so the first minimum fills the whole chunk: the same test, lazily
        filled = 0
        best, best_k, best_tau = math.inf, -1, 0.0
        for s_ in range(SCAN_SAMPLES):
            t_a, t_b = ts[s_], ts[s_ + 1]
            if best_k >= 0 and t_a >= best:
                break
            if filled <= s_:
                filled = _fill(p, st, n, count, pi, pj, pos, ts, sep, dsep, prev, filled, s_ + 1, turn, h)
            if not t_b > t_a:
                continue
            for k in range(count):
                s_before = prev[k, 0] if s_ == 0 else sep[k, s_ - 1]
                ds_before = prev[k, 1] if s_ == 0 else dsep[k, s_ - 1]
                s, ds = sep[k, s_], dsep[k, s_]
                hit = s <= 0.0 or abs(s) < near
                if not hit and ds_before < 0.0 < ds:
                    if filled < SCAN_SAMPLES:
                        filled = _fill(
                            p, st, n, count, pi, pj, pos, ts, sep, dsep, prev, filled, SCAN_SAMPLES, turn, h
                        )
                    margin = 2.0 * ((math.sqrt(prev[k, 2]) + 2.0 * accel * h) ** 2 + 4.0 * r0 * accel) * h * h / 8.0
                    hit = min(s_before, s) <= margin
                if not hit:
                    continue
                i, j = pi[k], pj[k]
                ref = st[i, _S_T0]
                tau = _resolve(p, st, i, j, reduced[k] != 0, t_a - ref, t_b - ref, tol)
                if tau < math.inf and ref + tau < best:
                    best, best_k, best_tau = ref + tau, k, tau
        if best_k >= 0:
            return best, pi[best_k], pj[best_k], best_tau
        last = SCAN_SAMPLES - 1
        for k in range(count):
            prev[k, 0], prev[k, 1] = sep[k, last], dsep[k, last]
        t_prev = ts[SCAN_SAMPLES]
    return math.inf, -1, -1, 0.0


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
def _repin(p, st, tr, book, excluded, i, t, t_end, rearm, settled=False):  # type: ignore[no-untyped-def]
    """Put rod i back on the wall at its angle at t, exclude the neighbours it overlaps, search its detachment."""
    x, y, _, _ = _rel(p, st, i, t)
    st[i, _S_FLY], st[i, _S_T0], st[i, _S_TH] = 0.0, t, math.atan2(y, x)
    book[i, _B_BOUNCES], book[i, _B_FROM_WALL] = 0.0, 0.0
    for j in range(int(p[_N])):
        if j != i and _overlapping(p, st, i, j, t, 0.0):
            excluded[min(i, j), max(i, j)] = 1
    _schedule(p, st, tr, book, i, t, t_end, rearm, settled)


@njit(cache=True)
def _fly(p, st, book, i, t, x, y, vx, vy):  # type: ignore[no-untyped-def]
    """Rod i starts a free flight at t from (x, y) with (vx, vy), vial frame (not from the wall)."""
    st[i, _S_FLY], st[i, _S_T0] = 1.0, t
    st[i, _S_X], st[i, _S_Y], st[i, _S_UX], st[i, _S_UY] = x, y, vx, vy
    alpha = p[_A0] + p[_WV] * t
    st[i, _S_SA], st[i, _S_CA] = math.sin(alpha), math.cos(alpha)
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
def _work(n):  # type: ignore[no-untyped-def]
    """Work arrays of the contact search for n rods: pair ids, reduced flags, chunk samples, positions, phasors."""
    pairs = n * n + 1
    return (
        np.empty(pairs, dtype=np.int64),
        np.empty(pairs, dtype=np.int64),
        np.empty(pairs, dtype=np.int64),
        np.empty((pairs, SCAN_SAMPLES)),
        np.empty((pairs, SCAN_SAMPLES)),
        np.empty((pairs, 3)),
        np.empty((n, 4)),
        np.empty(SCAN_SAMPLES + 1),
        np.empty((n + 1, 4)),
    )


@njit(cache=True)
def _run(p, t_end, max_events, threshold_j, tol, impacts, detachments):  # type: ignore[no-untyped-def]
    """The event loop of simulate.simulate into ``impacts`` (:data:`IMPACT`) and ``detachments`` (:data:`DETACHMENT`).

    Returns (impacts written, detachments written, events stepped, 1 when a table filled before the end).
    """
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
        _schedule(p, st, tr, book, i, 0.0, t_end, False)
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
            if n_det == detachments.shape[0]:
                return n_imp, n_det, steps, 1
            _depart(p, st, tr, rod_det, t_det, book[rod_det, _B_UNSUP] != 0.0)
            book[rod_det, _B_UNSUP], book[rod_det, _B_DET], book[rod_det, _B_FROM_WALL] = 0.0, math.inf, 1.0
            d = detachments[n_det]
            d[_D_T], d[_D_ROD], d[_D_TH] = t_det, rod_det, math.atan2(st[rod_det, _S_Y], st[rod_det, _S_X])
            n_det += 1
            for j in range(n):  # a neighbour it leaves touching at rounding's size: excluded until apart
                if j != rod_det and _overlapping(p, st, rod_det, j, t_det, _NEAR_ZERO * p[_R0] * p[_R0]):
                    excluded[min(rod_det, j), max(rod_det, j)] = 1
            t = t_det
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
                _repin(p, st, tr, book, excluded, rod, t_hit, t_end, zero_length)
            else:
                book[rod, _B_BOUNCES] += 1.0
                if vn < settle or book[rod, _B_BOUNCES] > MAX_BOUNCES:
                    _repin(p, st, tr, book, excluded, rod, t_hit, t_end, False, True)
                else:
                    _bounce(p, st, book, excluded, rod, partner, t_hit)
            t = t_hit
        for a in range(n):
            for b in range(a + 1, n):
                if excluded[a, b] != 0 and not _still_touching(p, st, a, b, t):
                    excluded[a, b] = 0
    return n_imp, n_det, steps, 0


def many_events(
    row: FloatArray, t_end_s: float, max_events: int = 100_000, threshold_j: float = 0.0, tol_s: float = 0.0
) -> tuple[FloatArray, FloatArray, int]:
    """Every impact and detachment of one scene row (:data:`PARAMS`) from t = 0 to ``t_end_s``, compiled.

    Returns (impact rows :data:`IMPACT`, detachment rows :data:`DETACHMENT`, events stepped). An impact
    below ``threshold_j`` (J) is recorded with ``counted`` 0. ``max_events`` bounds the loop's steps as in
    :func:`millctl.physics.simulate.simulate`; ``tol_s`` is the contact root finder's time tolerance.
    """
    p = np.ascontiguousarray(row, dtype=np.float64)
    if p.shape != (len(PARAMS),):
        raise ValueError(f"row must have {len(PARAMS)} columns ({', '.join(PARAMS)}), got shape {p.shape}")
    if not (math.isfinite(t_end_s) and t_end_s >= 0.0):
        raise ValueError(f"t_end_s = {t_end_s} must be a finite time ≥ 0")
    capacity = min(max(max_events, 1), 4096)
    while True:
        impacts, detachments = np.empty((capacity, len(IMPACT))), np.empty((capacity, len(DETACHMENT)))
        n_imp, n_det, steps, full = _run(p, float(t_end_s), int(max_events), float(threshold_j), float(tol_s), impacts,
                                         detachments)  # fmt: skip
        if not full:
            return impacts[:n_imp], detachments[:n_det], int(steps)
        capacity *= 4  # the run is deterministic: start again with room for every event


__all__ = ["DETACHMENT", "IMPACT", "many_events"]
