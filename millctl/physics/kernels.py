"""Compiled kernels (numba) of the exact engine: one first impact at a time, or many scenes at once.

The same algorithm as the readable numpy/scipy reference (:mod:`.detachment`,
:mod:`.events`, :mod:`.simulate`), written as scalar loops and compiled once per
machine (``cache=True``):

* N(t)/m as a constant plus three cosines (:func:`~.kinematics.normal_force_per_mass`),
  its certified first falling zero (Taylor bound, critical points, bisection), searched
  one revolution at a time (or one cam period with the vial at rest) and only when the
  event loop reaches the end of what has been searched (lazy);
* the wall gap of a departed rod with its triple root divided out (:func:`~.flight.departure_wall_gap`);
* the bracketing scan of every pair (separation, exact derivative, the second-order
  margin that lets a grazing minimum be skipped only when it provably stays apart), with
  held rods turned and flying rods' cam phases advanced by phasors on the scan's grid;
* a flight evaluated in its own time τ and its departure's cam phase (no absolute phase);
* Brent's bracketed root finder, a line-by-line port of scipy's ``brentq`` (same
  tolerances as the reference), so both engines stop on the same test.

No array is allocated per scene: a batch makes its work arrays once (:func:`_scratch`).

Event loop: every rod starts pinned at eq. 11's angle; rods detach at their own
times (``rods="all"``, :func:`first_impact_compiled`) or only rod 0 does, the others
held on the wall (``rods="one"``, the node telemetry's sample and a design study's
unit). The loop stops at the first impact: nothing is re-scheduled after it.

**Zero-length flight** (decided here, the same in every engine): a departure whose
wall gap, with the departure root divided out, is ≤ 0 at the departure instant
(its leading coefficient: the free path does not leave the wall — the paper's
detachment where the true N is still positive, or N touching zero with zero slope)
is not a flight and books no impact: the rod stays held through the current dip of
N and may detach again when N has risen above zero and falls again. Any other
flight, however short, is a flight, and its landing is an impact (of negligible
energy when the flight is tiny).

Cam: the single-acting circular cam of eqs 1–3 (lift r_d sin α). Scenes are given
as rows of parameters (:data:`PARAMS`, :func:`scene_row`).

One file, on purpose, though long: numba's cache (``cache=True``) is invalidated
only when the file that defines a function changes, not when a function it calls
from another file does ("Caching limitations" in numba's notes on caching). Split
across modules, an edit to a callee would leave its callers' compiled code stale.
:mod:`.legacy_kernel` does call these kernels from its own file: after editing this
one, delete its cache (``find millctl -name 'legacy_kernel.*.nb[ci]' -delete``;
a fresh clone, and CI, start without one).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from millctl.config.models import ModelVariant
from millctl.physics.flight import ZERO_FLIGHT_RTOL
from millctl.physics.model import Scene

FloatArray = NDArray[np.float64]

PARAMS = (
    "r0_m",
    "rod_radius_m",
    "eccentricity_m",
    "g_m_s2",
    "omega_r_rad_s",
    "omega_v_rad_s",
    "theta0_rad",
    "alpha0_rad",
    "n_rods",
    "paper",
    "spring_per_mass_s2",
    "rod_mass_kg",
    "restitution",
    "cam_to_vial_m",
)
"""Columns of a scene row: SI units; ``paper`` 1.0 for the paper variant, 0.0 corrected; k/m in 1/s².

``omega_v_rad_s`` and ``alpha0_rad`` are the cam's *lift* speed and phase (h·ω_v, h·α0 for a cam of
h strokes per revolution, :mod:`millctl.physics.cam`), so ``alpha_d_rad`` in a result is a lift phase.
"""
(_R0, _RR, _RD, _G, _WR, _WV, _TH0, _A0, _N, _PAPER, _KM, _M, _E, _L) = range(len(PARAMS))

OUT = (
    "found",
    "time_s",
    "rod",
    "partner",
    "x_m",
    "y_m",
    "normal_velocity_m_s",
    "tangential_velocity_m_s",
    "speed_abs_m_s",
    "energy_j",
    "backed",
    "depart_time_s",
    "theta_d_rad",
    "alpha_d_rad",
    "first_detach_time_s",
    "zero_length_flights",
    "theta_contact_rad",
)
"""Columns of a kernel result row (lab frame; ``found`` 0.0 when nothing touches)."""
(
    _O_FOUND,
    _O_T,
    _O_ROD,
    _O_PARTNER,
    _O_X,
    _O_Y,
    _O_VN,
    _O_VT,
    _O_SPEED,
    _O_ENERGY,
    _O_BACKED,
    _O_TDEP,
    _O_THD,
    _O_ALD,
    _O_TD0,
    _O_ZERO,
    _O_THC,
) = range(len(OUT))

WALL = -1
_RTOL = 4.0 * 2.220446049250313e-16
_MAXITER = 200
_MAX_DEPTH = 80
_NEAR_ZERO = 1e-9
_RESYNC = 16  # the contact scan's phasors are recomputed from sin and cos every this many steps (a few ulp apart)
_TWO_PI = 2.0 * math.pi
# state columns of a rod: flying flag, t0, pinned angle at t0, x0, y0, ux0, uy0 (vial frame), n_d, sin α0, cos α0
(_S_FLY, _S_T0, _S_TH, _S_X, _S_Y, _S_UX, _S_UY, _S_ND, _S_SA, _S_CA) = range(10)
_STATE_COLUMNS = 10
# function codes for the root finder
_F_N, _F_DN, _F_NEG_N, _F_NEG_DN, _F_SIGN_SEP, _F_DSEP = range(6)


def scene_row(scene: Scene) -> FloatArray:
    """The parameter row (:data:`PARAMS`) of a scene."""
    m = scene.model
    return np.array(
        [
            m.r0_m,
            m.rod_radius_m,
            m.eccentricity_m,
            m.g_m_s2,
            scene.omega_r_rad_s,
            scene.lift_omega_rad_s,  # the cam's lift (millctl.physics.cam): h·ω_v, h·α0
            scene.theta0_rad,
            scene.lift_alpha0_rad,
            float(m.n_rods),
            1.0 if m.variant is ModelVariant.PAPER else 0.0,
            m.spring_n_per_m / m.rod_mass_kg,
            m.rod_mass_kg,
            m.restitution,
            m.cam_to_vial_m,
        ]
    )


# -- N(t)/m, eqs 4–7 --------------------------------------------------------------------------------


# a trig sum c + Σ a_k cos(w_k t + φ_k) as a row: [c, number of terms, a_0..a_5, w_0..w_5, φ_0..φ_5]
_T_COUNT, _TA, _TW, _TP = 1, 2, 8, 14
_TRIG_COLUMNS = 20


@njit(cache=True)
def _set_term(rows, i, k, amplitude, frequency, phase):  # type: ignore[no-untyped-def]
    rows[i, _TA + k], rows[i, _TW + k], rows[i, _TP + k] = amplitude, frequency, phase


@njit(cache=True)
def _trig_rows(p, n, out=None):  # type: ignore[no-untyped-def]
    """Row i: N/m of rod i (kinematics.normal_force_per_mass), three terms: g, and the cam's ±½ coupling.

    ``out``: an array of at least n rows to fill (its first n rows are returned), else a new one.
    """
    wr, wv, a0 = p[_WR], p[_WV], p[_A0]
    if p[_PAPER] != 0.0:
        constant = 2.0 * p[_R0] * wr * wr
        coupling = (wv * wv - p[_KM]) * p[_RD]
    else:
        constant = p[_R0] * wr * wr
        coupling = p[_RD] * wv * wv
    half = 0.5 * coupling
    rows = np.zeros((n, _TRIG_COLUMNS)) if out is None else out[:n]
    for i in range(n):
        th0 = p[_TH0] + i * 2.0 * math.pi / n
        rows[i, 0], rows[i, _T_COUNT] = constant, 3.0
        _set_term(rows, i, 0, p[_G], wr, th0 + 0.5 * math.pi)
        _set_term(rows, i, 1, half, wv - wr, a0 - th0)
        _set_term(rows, i, 2, -half, wv + wr, a0 + th0)
    return rows


@njit(cache=True)
def _trig(tr, i, t, order, sign):  # type: ignore[no-untyped-def]
    """Sign × the order-th time derivative of row i at t."""
    total = tr[i, 0] if order == 0 else 0.0
    shift = 0.5 * math.pi * order
    for k in range(int(tr[i, _T_COUNT])):
        w = tr[i, _TW + k]
        total += tr[i, _TA + k] * w**order * math.cos(w * t + tr[i, _TP + k] + shift)
    return sign * total


@njit(cache=True)
def _trig012(tr, i, t, sign):  # type: ignore[no-untyped-def]
    """Sign × (value, first, second derivative) of row i at t: one sine and cosine per term serve all three."""
    f0, f1, f2 = tr[i, 0], 0.0, 0.0
    for k in range(int(tr[i, _T_COUNT])):
        a, w = tr[i, _TA + k], tr[i, _TW + k]
        x = w * t + tr[i, _TP + k]
        c, s = math.cos(x), math.sin(x)
        f0 += a * c
        f1 -= a * w * s
        f2 -= a * w * w * c
    return sign * f0, sign * f1, sign * f2


@njit(cache=True)
def _trig_bound(tr, i, order):  # type: ignore[no-untyped-def]
    total = 0.0
    for k in range(int(tr[i, _T_COUNT])):
        total += abs(tr[i, _TA + k]) * abs(tr[i, _TW + k]) ** order
    return total


# -- rod states in the vial frame, eq. 10 -----------------------------------------------------------


@njit(cache=True)
def _rel(p, st, i, t):  # type: ignore[no-untyped-def]
    """(x, y, vx, vy) of rod i relative to the vial centre at t."""
    if st[i, _S_FLY] == 0.0:
        r0, w = p[_R0], p[_WR]
        th = st[i, _S_TH] + w * (t - st[i, _S_T0])
        c, s = math.cos(th), math.sin(th)
        return r0 * c, r0 * s, -r0 * w * s, r0 * w * c
    tau = t - st[i, _S_T0]
    x = p[_WV] * tau
    return _flying_rel(p, st, i, tau, math.cos(x), math.sin(x))


@njit(cache=True)
def _flying_rel(p, st, i, tau, c, s):  # type: ignore[no-untyped-def]
    """(x, y, vx, vy) of flying rod i, τ after its departure, given c, s = cos, sin of the cam's turn ω_v τ since.

    Eq. 10 in the flight's own time: sin(α_d + ω_vτ) − sin α_d = sin α_d (c − 1) + cos α_d s, so no absolute
    time or phase enters (a long run loses nothing to the size of ω_v t).
    """
    r_d, w, g = p[_RD], p[_WV], p[_G]
    sa, ca = st[i, _S_SA], st[i, _S_CA]
    h = -0.5 * g * tau * tau - r_d * (sa * (c - 1.0) + ca * (s - w * tau))
    dh = -g * tau - r_d * w * (ca * (c - 1.0) - sa * s)
    ux, uy = st[i, _S_UX], st[i, _S_UY]
    return st[i, _S_X] + ux * tau, st[i, _S_Y] + uy * tau + h, ux, uy + dh


# Taylor coefficients of the two small-x series below, in powers of x² (Horner's rule)
_C2_SERIES = np.array([(-1.0) ** k / math.factorial(2 * k) for k in range(2, 12)])
_S3_SERIES = np.array([(-1.0) ** k / math.factorial(2 * k + 1) for k in range(1, 12)])


@njit(cache=True)
def _horner(coefficients, y):  # type: ignore[no-untyped-def]
    total = 0.0
    for k in range(coefficients.size - 1, -1, -1):
        total = total * y + coefficients[k]
    return total


@njit(cache=True)
def _c2_plus_half_over_x(x):  # type: ignore[no-untyped-def]
    """((cos x − 1)/x² + ½)/x, stable at small x (flight.py): x·Σ_{k≥2} (−x²)^(k−2)/(2k)! for |x| < 1."""
    if abs(x) < 1.0:
        return x * _horner(_C2_SERIES, x * x)
    return ((math.cos(x) - 1.0) / (x * x) + 0.5) / x


@njit(cache=True)
def _s3(x):  # type: ignore[no-untyped-def]
    """(sin x − x)/x³, stable at small x (flight.py): Σ_{k≥1} (−x²)^(k−1)/(2k+1)! for |x| < 1."""
    if abs(x) < 1.0:
        return _horner(_S3_SERIES, x * x)
    return (math.sin(x) - x) / (x * x * x)


@njit(cache=True)
def _departure_gap(p, st, i, t):  # type: ignore[no-untyped-def]
    """(r0² − |d|²)/τ² of a rod that left the wall at t0, or /τ³ when n_d = 0 (flight.departure_wall_gap)."""
    t0 = st[i, _S_T0]
    tau = t - t0
    r0, w_r, w_v, r_d, g = p[_R0], p[_WR], p[_WV], p[_RD], p[_G]
    s_d, c_d = st[i, _S_Y] / r0, st[i, _S_X] / r0
    x = w_v * tau
    sa, ca = st[i, _S_SA], st[i, _S_CA]
    d_eta = -r_d * w_v**3 * (sa * _c2_plus_half_over_x(x) + ca * _s3(x))
    eta0 = -0.5 * g + 0.5 * r_d * w_v * w_v * sa
    eta = eta0 + d_eta * tau
    reduced = 2.0 * r0 * (d_eta * s_d + eta * w_r * c_d) + eta * eta * tau
    n_d = st[i, _S_ND]
    if n_d == 0.0:
        return -reduced
    return -(n_d + tau * reduced)


@njit(cache=True)
def _zero_length_departure(p, st, i):  # type: ignore[no-untyped-def]
    """The zero-length rule of flight.zero_length_departure: reduced gap at τ = 0 ≤ ZERO_FLIGHT_RTOL × its scale."""
    r0, w_r, w_v, r_d, g = p[_R0], p[_WR], p[_WV], p[_RD], p[_G]
    if st[i, _S_ND] == 0.0:
        scale = 2.0 * r0 * (r_d * w_v**3 + (g + r_d * w_v * w_v) * w_r)
    else:
        scale = r0 * (r0 * w_r * w_r + g + r_d * w_v * w_v)
    return _departure_gap(p, st, i, st[i, _S_T0]) <= ZERO_FLIGHT_RTOL * scale


@njit(cache=True)
def _pair(p, st, i, j, t):  # type: ignore[no-untyped-def]
    """Separation (> 0 apart), its derivative and the relative speed squared of rod i and j (WALL: the wall)."""
    x, y, vx, vy = _rel(p, st, i, t)
    if j == WALL:
        return p[_R0] * p[_R0] - (x * x + y * y), -2.0 * (x * vx + y * vy), vx * vx + vy * vy
    xb, yb, vxb, vyb = _rel(p, st, j, t)
    dx, dy, dvx, dvy = x - xb, y - yb, vx - vxb, vy - vyb
    c = 2.0 * p[_RR]
    return dx * dx + dy * dy - c * c, 2.0 * (dx * dvx + dy * dvy), dvx * dvx + dvy * dvy


@njit(cache=True)
def _f(code, p, st, tr, i, j, t):  # type: ignore[no-untyped-def]
    """The function the root finder works on (code: N, N', −N, −N', sign separation, d separation)."""
    if code == _F_N:
        return _trig(tr, i, t, 0, 1.0)
    if code == _F_DN:
        return _trig(tr, i, t, 1, 1.0)
    if code == _F_NEG_N:
        return _trig(tr, i, t, 0, -1.0)
    if code == _F_NEG_DN:
        return _trig(tr, i, t, 1, -1.0)
    if code == _F_SIGN_SEP and j == WALL and st[i, _S_FLY] != 0.0:
        return _departure_gap(p, st, i, t)
    s, ds, _ = _pair(p, st, i, j, t)
    return s if code == _F_SIGN_SEP else ds


@njit(cache=True)
def _brentq(code, p, st, tr, i, j, xa, xb, xtol, rtol):  # type: ignore[no-untyped-def]
    """Brent's method, scipy's brentq (Zeros/brentq.c), on _f; a bracket without a sign change returns its left end."""
    xpre, xcur = xa, xb
    xblk, fblk, spre, scur = 0.0, 0.0, 0.0, 0.0
    fpre = _f(code, p, st, tr, i, j, xpre)
    fcur = _f(code, p, st, tr, i, j, xcur)
    if fpre == 0.0:
        return xpre
    if fcur == 0.0:
        return xcur
    if (fpre < 0.0) == (fcur < 0.0):
        return xpre
    for _ in range(_MAXITER):
        if fpre != 0.0 and fcur != 0.0 and (fpre < 0.0) != (fcur < 0.0):
            xblk, fblk = xpre, fpre
            spre = scur = xcur - xpre
        if abs(fblk) < abs(fcur):
            xpre, xcur, xblk = xcur, xblk, xcur
            fpre, fcur, fblk = fcur, fblk, fcur
        delta = 0.5 * (xtol + rtol * abs(xcur))
        sbis = 0.5 * (xblk - xcur)
        if fcur == 0.0 or abs(sbis) < delta:
            return xcur
        if abs(spre) > delta and abs(fcur) < abs(fpre):
            if xpre == xblk:
                stry = -fcur * (xcur - xpre) / (fcur - fpre)
            else:
                dpre = (fpre - fcur) / (xpre - xcur)
                dblk = (fblk - fcur) / (xblk - xcur)
                stry = -fcur * (fblk * dblk - fpre * dpre) / (dblk * dpre * (fblk - fpre))
            if 2.0 * abs(stry) < min(abs(spre), 3.0 * abs(sbis) - delta):
                spre, scur = scur, stry
            else:
                spre, scur = sbis, sbis
        else:
            spre, scur = sbis, sbis
        xpre, fpre = xcur, fcur
        if abs(scur) > delta:
            xcur += scur
        else:
            xcur += delta if sbis > 0.0 else -delta
        fcur = _f(code, p, st, tr, i, j, xcur)
    return xcur


@njit(cache=True)
def _xtol(a, b, tol):  # type: ignore[no-untyped-def]
    return max(tol, _RTOL * max(abs(a), abs(b)), 1e-300)


# -- detachment, the first falling zero of N (detachment.py) ---------------------------------------


@njit(cache=True)
def _monotone_pieces_root(p, st, tr, i, sign, a, b):  # type: ignore[no-untyped-def]
    """On [a, b] f' is monotone: split at f's critical point and look for a falling zero (inf: none)."""
    f_code, df_code = (_F_N, _F_DN) if sign > 0.0 else (_F_NEG_N, _F_NEG_DN)
    fa, d1a, _ = _trig012(tr, i, a, sign)
    fb, d1b, _ = _trig012(tr, i, b, sign)
    if fa > 0.0 and fb < 0.0:  # f' monotone: exactly one falling zero in [a, b], no need for the critical point
        return _brentq(f_code, p, st, tr, i, 0, a, b, _xtol(a, b, 0.0), _RTOL)
    if fa > 0.0 and fb > 0.0 and d1a < 0.0 < d1b:
        # convex here: f lies above both end tangents; where they cross is a lower bound on min f
        t_x = (fb - fa + d1a * a - d1b * b) / (d1a - d1b)
        if fa + d1a * (t_x - a) > 1e-13 * (tr[i, 0] + _trig_bound(tr, i, 0)):
            return math.inf
    split = b  # f's critical point when f' changes sign in [a, b]: the two pieces [a, split], [split, b]
    if (d1a < 0.0 < d1b) or (d1a > 0.0 > d1b):
        split = _brentq(df_code, p, st, tr, i, 0, a, b, _xtol(a, b, 0.0), _RTOL)
    for s, e in ((a, split), (split, b)):
        if s >= e:
            continue
        fs, fe = _trig(tr, i, s, 0, sign), _trig(tr, i, e, 0, sign)
        if fs > 0.0 and fe < 0.0:
            return _brentq(f_code, p, st, tr, i, 0, s, e, _xtol(s, e, 0.0), _RTOL)
        if fs > 0.0 and fe == 0.0 and _trig(tr, i, e, 1, sign) < 0.0:
            return e
    return math.inf


@njit(cache=True)
def _falling_zero(p, st, tr, i, sign, t0, t1):  # type: ignore[no-untyped-def]
    """First t in (t0, t1] where sign·N falls through zero, given sign·N(t0) > 0; inf if it stays ≥ 0."""
    m2, m3 = _trig_bound(tr, i, 2), _trig_bound(tr, i, 3)
    w_max = 0.0
    for k in range(int(tr[i, _T_COUNT])):
        if tr[i, _TA + k] != 0.0:
            w_max = max(w_max, abs(tr[i, _TW + k]))
    cells = 1 if w_max == 0.0 else int(min(max(math.ceil((t1 - t0) * w_max * 2.0 / math.pi), 1), 4096))
    width = (t1 - t0) / cells
    stack = np.empty((2 * _MAX_DEPTH + 4, 3))  # (a, b, depth) of the intervals still to look at, leftmost on top
    for c in range(cells):
        a = t0 + c * width
        b = t1 if c == cells - 1 else t0 + (c + 1) * width
        stack[0, 0], stack[0, 1], stack[0, 2] = a, b, 0.0
        top = 1
        while top > 0:
            top -= 1
            a, b, depth = stack[top, 0], stack[top, 1], int(stack[top, 2])
            h = b - a
            mid = 0.5 * (a + b)
            f0, f1, f2 = _trig012(tr, i, mid, sign)
            if f0 - abs(f1) * 0.5 * h - m2 * h * h * 0.125 > 0.0:
                continue
            if abs(f2) > m3 * 0.5 * h or depth >= _MAX_DEPTH:
                root = _monotone_pieces_root(p, st, tr, i, sign, a, b)
                if root < math.inf:
                    return root
                continue
            stack[top, 0], stack[top, 1], stack[top, 2] = mid, b, depth + 1
            stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2] = a, mid, depth + 1
            top += 2
    return math.inf


@njit(cache=True)
def _revolution_s(p):  # type: ignore[no-untyped-def]
    """One revolution; one cam period with the vial at rest; 1 s when both stand still."""
    if p[_WR] > 0.0:
        return _TWO_PI / p[_WR]
    if p[_WV] > 0.0:
        return _TWO_PI / p[_WV]
    return 1.0


@njit(cache=True)
def _window_s(p):  # type: ignore[no-untyped-def]
    """The detachment search's window: the shorter of one revolution and one cam period."""
    w = _revolution_s(p)
    if p[_WV] > 0.0:
        w = min(w, _TWO_PI / p[_WV])
    return w


@njit(cache=True)
def _held_until(tr, i, t):  # type: ignore[no-untyped-def]
    """A time up to which f > 0 is certified from t on by its first term alone, else t.

    f = c + a_0 cos(w_0 t + φ_0) + (other terms, ≤ Σ|a_k| together) > 0 while
    cos(w_0 t + φ_0) > q = (Σ_{k≥1}|a_k| − c)/a_0; for N/m, a_0 cos(…) = g cos(θ + π/2) is the slow
    part, so this is the arc of the wall where no cam phase can detach the rod.
    """
    w, g = tr[i, _TW], tr[i, _TA]
    if w <= 0.0 or g <= 0.0:
        return t
    rest = 0.0
    for k in range(1, int(tr[i, _T_COUNT])):
        rest += abs(tr[i, _TA + k])
    q = (rest - tr[i, 0]) / g
    if q >= 1.0:
        return t
    if q < -1.0:
        return math.inf
    edge = math.acos(q)
    r = (w * t + tr[i, _TP] + math.pi) % _TWO_PI - math.pi
    if -edge < r < edge:
        return t + (edge - r) / w * (1.0 - 1e-9)
    return t


@njit(cache=True)
def _falling_zero_windowed(p, st, tr, i, sign, t0, t1):  # type: ignore[no-untyped-def]
    """_falling_zero over [t0, t1], one window at a time from where N can first vanish, stopping at the first root."""
    w = _window_s(p)
    a = t0
    while a < t1:
        if sign > 0.0:
            a = max(a, _held_until(tr, i, a))
            if a >= t1:
                return math.inf
        b = min(a + w, t1)
        if _trig(tr, i, a, 0, sign) <= 0.0:
            return a
        root = _falling_zero(p, st, tr, i, sign, a, b)
        if root < math.inf:
            return root
        a = b
    return math.inf


@njit(cache=True)
def _nudge(tr, i, t, horizon, sign):  # type: ignore[no-untyped-def]
    """The first time from t on where sign·N > 0, stepping geometrically off a root (inf: none)."""
    step = max(abs(t), 1.0) * 1e-13
    while _trig(tr, i, t, 0, sign) <= 0.0:
        if t >= horizon:
            return math.inf
        t, step = t + step, 2.0 * step
    return t


@njit(cache=True)
def _rearm(p, st, tr, i, t_start, horizon):  # type: ignore[no-untyped-def]
    """Skip the current dip of N: the first time after t_start at which N > 0 again after having been < 0."""
    t = t_start
    if _trig(tr, i, t, 0, 1.0) >= 0.0:
        down = _falling_zero_windowed(p, st, tr, i, 1.0, t, horizon) if _trig(tr, i, t, 0, 1.0) > 0.0 else t
        if down == math.inf:
            return math.inf
        t = _nudge(tr, i, down, horizon, -1.0)
        if t == math.inf:
            return math.inf
    up = _falling_zero_windowed(p, st, tr, i, -1.0, t, horizon)
    return math.inf if up == math.inf else _nudge(tr, i, up, horizon, 1.0)


@njit(cache=True)
def _never_detaches(tr, i):  # type: ignore[no-untyped-def]
    """Certified: N ≥ c − Σ|a_k| > 0 at every time."""
    return tr[i, 0] - _trig_bound(tr, i, 0) > 0.0


# -- contacts (events.py) ---------------------------------------------------------------------------


@njit(cache=True)
def _scan_step_s(p):  # type: ignore[no-untyped-def]
    """1/8 of the shortest of the cam period, the revolution and the fall time √(2 r_r/g).

    The reference (events.scan_step_s) samples at 1/16; the minimum check's margin grows with the step
    (h²/8 × a bound on the separation's second derivative), so either step brackets the same contacts, and the
    coarser one halves the samples (issue 17's throughput; the same answers on 10⁴ random scenes).
    """
    shortest = math.sqrt(2.0 * p[_RR] / p[_G])
    if p[_WV] > 0.0:
        shortest = min(shortest, _TWO_PI / p[_WV])
    if p[_WR] > 0.0:
        shortest = min(shortest, _TWO_PI / p[_WR])
    return shortest / 8.0


@njit(cache=True)
def _resolve(p, st, tr, i, j, a, b, tol):  # type: ignore[no-untyped-def]
    """Exact contact time in [a, b] of one candidate interval, or inf (a minimum that stays apart)."""
    if _f(_F_SIGN_SEP, p, st, tr, i, j, b) <= 0.0:
        return _brentq(_F_SIGN_SEP, p, st, tr, i, j, a, b, _xtol(a, b, tol), _RTOL)
    da, db = _f(_F_DSEP, p, st, tr, i, j, a), _f(_F_DSEP, p, st, tr, i, j, b)
    if da < 0.0 < db:
        t_m = _brentq(_F_DSEP, p, st, tr, i, j, a, b, _xtol(a, b, 0.0), _RTOL)
        if _f(_F_SIGN_SEP, p, st, tr, i, j, t_m) <= 0.0:
            return _brentq(_F_SIGN_SEP, p, st, tr, i, j, a, t_m, _xtol(a, t_m, tol), _RTOL)
    return math.inf


@njit(cache=True)
def _turned(c, s, c_step, s_step):  # type: ignore[no-untyped-def]
    """cos, sin of φ + δ from those of φ and δ."""
    return c * c_step - s * s_step, s * c_step + c * s_step


@njit(cache=True)
def _apart_for(wall, gap, dist, radial, v2, accel_fly, accel_held, st, j):  # type: ignore[no-untyped-def]
    """How long a pair at ``gap`` > 0 provably stays apart (s).

    d: the rod's position (wall) or the pair's relative position, |d| = ``dist``, v = d′, ``radial`` = d̂·v,
    A ≥ |d″| (g + r_d ω_v² for a flying rod in the vial frame, plus r0 ω_r² for a held partner).
    Rod pair: |d + vΔ + R| ≥ d̂·(d + vΔ) − |R| = |d| + Δ·radial − |R|, |R| ≤ ½AΔ², so the gap shrinks by
    at most u Δ + ½AΔ² with u = max(−radial, 0), the approach speed.
    Wall (gap r0 − |d|): |d + vΔ| ≤ |d| + Δ·radial + Δ²|v|²/(2|d|) (√(a² + x) ≤ a + x/2a), so the gap
    shrinks by at most uΔ + ½BΔ² with u = max(radial, 0) and B = A + |v|²/|d|.
    The first Δ at which the bound reaches zero: 2 gap / (u + √(u² + 2 B gap)).
    """
    if wall:
        approach, bound = max(radial, 0.0), accel_fly + v2 / dist
    else:
        approach = max(-radial, 0.0)
        bound = accel_fly + accel_held if st[j, _S_FLY] == 0.0 else 2.0 * accel_fly
    return 2.0 * gap / (approach + math.sqrt(approach * approach + 2.0 * bound * gap))


@njit(cache=True)
def _earliest_contact(p, st, tr, n, t_start, t_end, tol, scratch):  # type: ignore[no-untyped-def]
    """(time, rod, partner) of the first contact of a flying rod in [t_start, t_end]; time inf if none."""
    pairs, pair_ids, rods, rod_ids = scratch[0], scratch[1], scratch[2], scratch[3]
    pi, pj = pair_ids[:, 0], pair_ids[:, 1]
    count = 0
    for i in range(n):
        if st[i, _S_FLY] != 0.0:
            pi[count], pj[count] = i, WALL
            count += 1
    for i in range(n):
        if st[i, _S_FLY] == 0.0:
            continue
        for j in range(n):
            if j == i or (st[j, _S_FLY] != 0.0 and j < i):
                continue
            pi[count], pj[count] = i, j
            count += 1
    # every rod's vial-frame position at t_start; a held rod's later position is this one turned by ω_r(t − t_start)
    # a held rod's position later is its position at t_start turned by ω_r(t − t_start); a flying rod's needs
    # cos, sin of ω_v(t − t0): both are phasors advanced by one step's turn, recomputed every _RESYNC steps
    pos, phasor = rods[:, 0:4], rods[:, 4:6]
    for r in range(n):
        pos[r, 0], pos[r, 1], pos[r, 2], pos[r, 3] = _rel(p, st, r, t_start)
        if st[r, _S_FLY] == 0.0:
            phasor[r, 0], phasor[r, 1] = pos[r, 0], pos[r, 1]
    r0 = p[_R0]
    c2 = 4.0 * p[_RR] * p[_RR]
    s_prev, ds_prev, v2_prev, safe_until, stale = pairs[:, 0], pairs[:, 1], pairs[:, 2], pairs[:, 3], pairs[:, 4]
    for k in range(count):
        i, j = pi[k], pj[k]
        x, y, vx, vy = pos[i, 0], pos[i, 1], pos[i, 2], pos[i, 3]
        if j == WALL:
            s, ds = r0 * r0 - (x * x + y * y), -2.0 * (x * vx + y * vy)
            if t_start == st[i, _S_T0]:
                touching = _zero_length_departure(p, st, i)
            else:
                touching = _departure_gap(p, st, i, t_start) <= 0.0
        else:
            x, y, vx, vy = x - pos[j, 0], y - pos[j, 1], vx - pos[j, 2], vy - pos[j, 3]
            s, ds = x * x + y * y - c2, 2.0 * (x * vx + y * vy)
            touching = s <= 0.0
        if touching:
            return t_start, i, j
        s_prev[k], ds_prev[k], v2_prev[k] = s, ds, vx * vx + vy * vy
    h = _scan_step_s(p)
    accel = 2.0 * max(p[_G] + p[_RD] * p[_WV] * p[_WV], p[_R0] * p[_WR] * p[_WR])
    # bounds on the relative acceleration of a pair in the vial frame (the wall is at rest there)
    accel_fly, accel_held = p[_G] + p[_RD] * p[_WV] * p[_WV], p[_R0] * p[_WR] * p[_WR]
    near = _NEAR_ZERO * r0 * r0
    w_r, w_v = p[_WR], p[_WV]
    cos_step_r, sin_step_r = math.cos(w_r * h), math.sin(w_r * h)
    cos_step_v, sin_step_v = math.cos(w_v * h), math.sin(w_v * h)
    cos_turn, sin_turn = 1.0, 0.0
    for r in range(n):
        if st[r, _S_FLY] != 0.0:
            x = w_v * (t_start - st[r, _S_T0])
            phasor[r, 0], phasor[r, 1] = math.cos(x), math.sin(x)
    safe_until[:count] = t_start
    stale[:count] = 0.0
    filled_at = rod_ids
    filled_at[:n] = 0
    t_prev = t_start
    step = 0
    while t_prev < t_end:
        step += 1
        t_k = min(t_start + h * step, t_end)
        t_next = min(t_start + h * (step + 1), t_end)
        exact = step % _RESYNC == 0 or t_k == t_end
        if exact:
            cos_turn, sin_turn = math.cos(w_r * (t_k - t_start)), math.sin(w_r * (t_k - t_start))
        else:
            cos_turn, sin_turn = _turned(cos_turn, sin_turn, cos_step_r, sin_step_r)
        for r in range(n):
            if st[r, _S_FLY] == 0.0:
                continue
            if exact:
                x = w_v * (t_k - st[r, _S_T0])
                phasor[r, 0], phasor[r, 1] = math.cos(x), math.sin(x)
            else:
                phasor[r, 0], phasor[r, 1] = _turned(phasor[r, 0], phasor[r, 1], cos_step_v, sin_step_v)
        best, best_k, best_exact = math.inf, -1, False
        for k in range(count):
            if t_next <= safe_until[k] and t_k < t_end:
                stale[k] = 1.0  # provably apart up to the next sample: not evaluated
                continue
            i, j = pi[k], pj[k]
            for r in (i, j):
                if r == WALL or filled_at[r] == step:
                    continue
                filled_at[r] = step
                if st[r, _S_FLY] != 0.0:
                    pos[r, 0], pos[r, 1], pos[r, 2], pos[r, 3] = _flying_rel(
                        p, st, r, t_k - st[r, _S_T0], phasor[r, 0], phasor[r, 1]
                    )
                    continue
                xh = phasor[r, 0] * cos_turn - phasor[r, 1] * sin_turn
                yh = phasor[r, 0] * sin_turn + phasor[r, 1] * cos_turn
                pos[r, 0], pos[r, 1], pos[r, 2], pos[r, 3] = xh, yh, -w_r * yh, w_r * xh
            x, y, vx, vy = pos[i, 0], pos[i, 1], pos[i, 2], pos[i, 3]
            if j == WALL:
                s, ds = r0 * r0 - (x * x + y * y), -2.0 * (x * vx + y * vy)
                dist = math.sqrt(max(x * x + y * y, 0.0))
                gap = r0 - dist
            else:
                x, y, vx, vy = x - pos[j, 0], y - pos[j, 1], vx - pos[j, 2], vy - pos[j, 3]
                s, ds = x * x + y * y - c2, 2.0 * (x * vx + y * vy)
                dist = math.sqrt(x * x + y * y)
                gap = dist - 2.0 * p[_RR]
            v2 = vx * vx + vy * vy
            if stale[k] != 0.0:
                stale[k] = 0.0  # the interval since the last sample lies where the pair is provably apart
            else:
                v = math.sqrt(max(v2, v2_prev[k]))
                margin = 2.0 * ((v + 2.0 * accel * h) ** 2 + 4.0 * r0 * accel) * h * h / 8.0
                hit = s <= 0.0 or abs(s) < near or (ds_prev[k] < 0.0 < ds and min(s_prev[k], s) <= margin)
                if hit and t_k > t_prev:
                    t_hit = _resolve(p, st, tr, i, j, t_prev, t_k, tol)
                    if tol > 0.0 and best_k >= 0 and abs(t_hit - best) <= 2.0 * tol:
                        # two contacts closer than the tolerance: which is first is decided at full precision
                        t_hit = _resolve(p, st, tr, i, j, t_prev, t_k, 0.0)
                        if not best_exact:
                            best = _resolve(p, st, tr, pi[best_k], pj[best_k], t_prev, t_k, 0.0)
                            best_exact = True
                    elif t_hit < best:
                        best_exact = False
                    if t_hit < best:
                        best, best_k = t_hit, k
            s_prev[k], ds_prev[k], v2_prev[k] = s, ds, v2
            if gap > 0.0 and dist > 0.0:
                radial = (x * vx + y * vy) / dist
                safe_until[k] = t_k + _apart_for(j == WALL, gap, dist, radial, v2, accel_fly, accel_held, st, j)
        if best_k >= 0:
            return best, pi[best_k], pj[best_k]
        t_prev = t_k
    return math.inf, -1, -1


# -- the event loop up to the first impact (simulate.py with stop_after_first) ---------------------


@njit(cache=True)
def _depart(p, st, tr, i, t, unsupported):  # type: ignore[no-untyped-def]
    """Rod i leaves the wall at t: its flight state (eq. 2's velocity relative to the vial) and n_d.

    Corrected variant at a falling zero of N: n_d = 0 exactly (the departure root is triple by construction);
    a rod that starts unsupported (N < 0 at the start) or the paper's law: n_d = r0·N_true/m.
    """
    x, y, vx, vy = _rel(p, st, i, t)
    st[i, _S_FLY], st[i, _S_T0] = 1.0, t
    st[i, _S_X], st[i, _S_Y], st[i, _S_UX], st[i, _S_UY] = x, y, vx, vy
    alpha = p[_A0] + p[_WV] * t
    st[i, _S_SA], st[i, _S_CA] = math.sin(alpha), math.cos(alpha)
    theta = math.atan2(y, x)
    g_eff = p[_G] - p[_RD] * p[_WV] ** 2 * math.sin(p[_A0] + p[_WV] * t)
    true_n = p[_R0] * p[_WR] ** 2 - g_eff * math.sin(theta)
    exact = p[_PAPER] == 0.0 and not unsupported
    st[i, _S_ND] = 0.0 if exact else p[_R0] * true_n


@njit(cache=True)
def _repin(p, st, i, t):  # type: ignore[no-untyped-def]
    x, y, _, _ = _rel(p, st, i, t)
    st[i, _S_FLY], st[i, _S_T0], st[i, _S_TH] = 0.0, t, math.atan2(y, x)


@njit(cache=True)
def _scratch(n_max):  # type: ignore[no-untyped-def]
    """Work arrays of _event for up to n_max rods, made once per batch (no allocation per scene).

    (pair columns, pair rod ids, rod columns, rod ids, trig rows, rod states, rod detachment columns)
    """
    pairs = n_max * (n_max + 1)
    return (
        np.empty((pairs, 5)),
        np.empty((pairs, 2), dtype=np.int64),
        np.empty((n_max, 6)),
        np.empty(n_max, dtype=np.int64),
        np.zeros((n_max, _TRIG_COLUMNS)),
        np.empty((n_max, _STATE_COLUMNS)),
        np.empty((n_max, 3)),
    )


@njit(cache=True)
def _event(p, all_rods, horizon, flight_cap, tol, out, scratch):  # type: ignore[no-untyped-def]
    """The first impact of one scene into ``out`` (:data:`OUT`); see the module docstring.

    ``scratch``: :func:`_scratch` for at least this scene's number of rods.
    """
    n = int(p[_N])
    tr = _trig_rows(p, n, scratch[4])
    st = scratch[5][:n]
    st[:, :] = 0.0
    det_columns = scratch[6]
    det_t, det_lb, unsupported = det_columns[:n, 0], det_columns[:n, 1], det_columns[:n, 2]
    det_t[:] = math.inf
    det_lb[:] = horizon
    unsupported[:] = 0.0
    window = _window_s(p)
    for i in range(n):
        st[i, _S_TH] = p[_TH0] + i * 2.0 * math.pi / n
        if i > 0 and not all_rods:
            continue
        if _trig(tr, i, 0.0, 0, 1.0) <= 0.0:
            det_t[i] = 0.0
            unsupported[i] = 1.0
        elif not _never_detaches(tr, i):
            det_lb[i] = 0.0
    det_end = horizon if all_rods else min(horizon, _revolution_s(p))
    out[:] = math.nan
    out[_O_FOUND], out[_O_ZERO] = 0.0, 0.0
    t = 0.0
    first_departure = math.inf
    while True:
        # the earliest known detachment, and the earliest end of a detachment search not yet extended
        t_det, rod_det = math.inf, -1
        lb, rod_lb = math.inf, -1
        t_fly = math.inf
        for i in range(n):
            if det_t[i] < t_det:
                t_det, rod_det = det_t[i], i
            if det_t[i] == math.inf and det_lb[i] < min(det_end, lb):
                lb, rod_lb = det_lb[i], i
            if st[i, _S_FLY] != 0.0:
                t_fly = min(t_fly, st[i, _S_T0])
        contact_end = min(horizon, t_fly + flight_cap)
        seg_end = min(t_det, lb, contact_end)
        t_hit, rod, partner = math.inf, -1, -1
        if t_fly < math.inf:
            t_hit, rod, partner = _earliest_contact(p, st, tr, n, t, seg_end, tol, scratch)
        if t_hit < math.inf:
            if partner == WALL and t_hit == st[rod, _S_T0]:
                # a zero-length flight is no impact: the rod stays held through this dip of N
                _repin(p, st, rod, t_hit)
                out[_O_ZERO] += 1.0
                up = _rearm(p, st, tr, rod, t_hit, det_end)
                det_t[rod] = _falling_zero_windowed(p, st, tr, rod, 1.0, up, det_end) if up < det_end else math.inf
                det_lb[rod] = det_end
                t = t_hit
                continue
            _contact(p, st, rod, partner, t_hit, out)
            out[_O_TD0] = first_departure if first_departure < math.inf else math.nan
            return
        if seg_end >= contact_end and contact_end < min(t_det, lb):
            out[_O_TD0] = first_departure if first_departure < math.inf else math.nan
            return
        if lb <= t_det and rod_lb >= 0:
            a = det_lb[rod_lb]
            b = min(a + window, det_end)
            det_t[rod_lb] = _falling_zero_windowed(p, st, tr, rod_lb, 1.0, a, b)
            det_lb[rod_lb] = b
            t = max(t, a)
            continue
        if rod_det < 0:
            out[_O_TD0] = first_departure if first_departure < math.inf else math.nan
            return
        _depart(p, st, tr, rod_det, t_det, unsupported[rod_det] != 0.0)
        unsupported[rod_det] = 0.0
        first_departure = min(first_departure, t_det)
        det_t[rod_det] = math.inf
        det_lb[rod_det] = det_end
        t = t_det


@njit(cache=True)
def _contact(p, st, i, j, t, out):  # type: ignore[no-untyped-def]
    """Contact kinematics, lab contact point, absolute speed and energy (events.contact_kinematics, eq. 19)."""
    x, y, vx, vy = _rel(p, st, i, t)
    if j == WALL:
        r = math.hypot(x, y)
        nx, ny = x / r, y / r
        rvx, rvy = vx + p[_WR] * y, vy - p[_WR] * x
        backed = True
    else:
        xb, yb, vxb, vyb = _rel(p, st, j, t)
        dx, dy = xb - x, yb - y
        r = math.hypot(dx, dy)
        nx, ny = dx / r, dy / r
        rvx, rvy = vx - vxb, vy - vyb
        backed = st[j, _S_FLY] == 0.0
    v_n = rvx * nx + rvy * ny
    alpha = p[_A0] + p[_WV] * t
    yc = p[_L] - p[_RD] + p[_RD] * math.sin(alpha)
    vyc = p[_RD] * p[_WV] * math.cos(alpha)
    speed = math.hypot(vx, vy + vyc)
    m = p[_M]
    if p[_PAPER] != 0.0:
        energy = 0.5 * m * speed * speed
    else:
        energy = 0.5 * (m if backed else 0.5 * m) * (1.0 - p[_E] ** 2) * v_n * v_n
    out[_O_FOUND], out[_O_T], out[_O_ROD], out[_O_PARTNER] = 1.0, t, i, j
    out[_O_X], out[_O_Y] = x + p[_RR] * nx, yc + y + p[_RR] * ny
    out[_O_VN], out[_O_VT] = v_n, -rvx * ny + rvy * nx
    out[_O_SPEED], out[_O_ENERGY], out[_O_BACKED] = speed, energy, 1.0 if backed else 0.0
    t0 = st[i, _S_T0]
    out[_O_TDEP] = t0
    out[_O_THD] = math.atan2(st[i, _S_Y], st[i, _S_X])
    out[_O_THC] = math.atan2(y, x)
    out[_O_ALD] = (p[_A0] + p[_WV] * t0) % _TWO_PI


# -- level (b): the node telemetry's samples, with the no-slip check (telemetry.py, slip.py) -------


@njit(cache=True)
def _slip_rows(p, theta0, mu, rows):  # type: ignore[no-untyped-def]
    """Rows 0, 1 of ``rows``: μN/m − F_t/m and μN/m + F_t/m of a rod carried at θ0 + ω_r t (slip.no_slip_check).

    N is the corrected law in both variants; F_t/m = g_eff cos θ (slip.traction_per_mass).
    """
    wr, wv, a0, g = p[_WR], p[_WV], p[_A0], p[_G]
    half = 0.5 * p[_RD] * wv * wv
    for r in range(2):
        sign = -1.0 if r == 0 else 1.0
        rows[r, 0], rows[r, _T_COUNT] = mu * p[_R0] * wr * wr, 6.0
        _set_term(rows, r, 0, mu * g, wr, theta0 + 0.5 * math.pi)
        _set_term(rows, r, 1, mu * half, wv - wr, a0 - theta0)
        _set_term(rows, r, 2, mu * -half, wv + wr, a0 + theta0)
        _set_term(rows, r, 3, sign * g, wr, theta0)
        _set_term(rows, r, 4, sign * -half, wv + wr, a0 + theta0 - 0.5 * math.pi)
        _set_term(rows, r, 5, sign * -half, wv - wr, a0 - theta0 - 0.5 * math.pi)
    return rows


@njit(cache=True)
def _slip_onset(p, theta0, mu, t_end, rows, st):  # type: ignore[no-untyped-def]
    """First time in [0, t_end] at which the carried rod needs |F_t| > μN (0: at once; inf: never).

    ``rows``: a (2, trig columns) work array; ``st``: a zeroed (1, state columns) one (unused by the search).
    """
    tr = _slip_rows(p, theta0, mu, rows)
    onset = math.inf
    for r in range(2):
        if _trig(tr, r, 0.0, 0, 1.0) <= 0.0:
            return 0.0
        if t_end > 0.0:
            onset = min(onset, _falling_zero_windowed(p, st, tr, r, 1.0, 0.0, t_end))
    return onset


TELEMETRY = (
    "found",
    "detached",
    "depart_time_s",
    "theta_d_rad",
    "energy_j",
    "flight_time_s",
    "on_wall",
    "theta_contact_rad",
    "slip_onset_s",
    "slip_theta_rad",
)
"""Columns of a telemetry sample row (:func:`telemetry_samples`)."""


@njit(cache=True)
def _telemetry_into(p_base, theta_start, phases, flight_cap, mu, pinned, out, work):  # type: ignore[no-untyped-def]
    """The K telemetry samples of one scene into ``out`` (K rows of :data:`TELEMETRY`), no allocation.

    ``work``: (event row, _scratch, scene row, bottom scene row, slip rows, slip state) from :func:`_telemetry_work`.
    """
    ev, scratch, p, pb, slip_tr, slip_st = work
    out[:, :] = math.nan
    rev = _revolution_s(p_base)
    lead = (theta_start + 0.5 * math.pi) / p_base[_WR] if not pinned else 0.0
    for k in range(phases):
        p[:] = p_base
        p[_TH0], p[_A0] = theta_start, _TWO_PI * k / phases
        arc_end = rev
        if pinned:
            out[k, 0], out[k, 1] = 0.0, 0.0
        else:
            _event(p, False, math.inf, flight_cap, 0.0, ev, scratch)
            detached = ev[_O_TD0] == ev[_O_TD0]  # not nan
            out[k, 0], out[k, 1] = ev[_O_FOUND], 1.0 if detached else 0.0
            if ev[_O_FOUND] == 1.0:
                arc_end = ev[_O_TDEP]
                out[k, 2], out[k, 3], out[k, 4] = ev[_O_TDEP], ev[_O_THD], ev[_O_ENERGY]
                out[k, 5], out[k, 6] = ev[_O_T] - ev[_O_TDEP], 1.0 if ev[_O_PARTNER] == WALL else 0.0
                out[k, 7] = ev[_O_THC]
            elif detached:
                arc_end = ev[_O_TD0]
        # the carriage from the bottom: the same ride with the cam phase shifted back by ω_v·lead
        pb[:] = p
        pb[_TH0], pb[_A0] = -0.5 * math.pi, p[_A0] - p[_WV] * lead
        onset = _slip_onset(pb, -0.5 * math.pi, mu, arc_end + lead, slip_tr, slip_st)
        if onset < math.inf:
            out[k, 8] = onset
            out[k, 9] = (-0.5 * math.pi + p[_WR] * onset + math.pi) % _TWO_PI - math.pi


@njit(cache=True)
def _telemetry_work(n_max):  # type: ignore[no-untyped-def]
    """The work arrays of :func:`_telemetry_into` for scenes of up to n_max rods (made once per batch)."""
    return (
        np.empty(len(OUT)),
        _scratch(n_max),
        np.empty(len(PARAMS)),
        np.empty(len(PARAMS)),
        np.zeros((2, _TRIG_COLUMNS)),
        np.zeros((1, _STATE_COLUMNS)),
    )


@njit(cache=True)
def _telemetry(p_base, theta_start, phases, flight_cap, mu, pinned):  # type: ignore[no-untyped-def]
    out = np.empty((phases, len(TELEMETRY)))
    _telemetry_into(p_base, theta_start, phases, flight_cap, mu, pinned, out, _telemetry_work(int(p_base[_N])))
    return out


def telemetry_samples(
    scene_row_: FloatArray, theta_start_rad: float, cam_phases: int, flight_cap_s: float, friction: float, pinned: bool
) -> FloatArray:
    """The node telemetry's K samples in one compiled call (columns :data:`TELEMETRY`).

    Sample k: rod 0 pinned at ``theta_start_rad`` with cam phase 2πk/K, its one-rod event
    (:func:`first_impacts`, ``rods="one"``) and the no-slip check of the same ride from the
    bottom (slip.no_slip_check); ``pinned``: no phase can detach, only the check, over one revolution.
    """
    result: FloatArray = _telemetry(
        np.ascontiguousarray(scene_row_, dtype=np.float64),
        float(theta_start_rad),
        int(cam_phases),
        float(flight_cap_s),
        float(friction),
        bool(pinned),
    )
    return result


@njit(cache=True)
def _telemetry_batch(rows, theta_start, pinned, phases, flight_cap, mu):  # type: ignore[no-untyped-def]
    out = np.empty((rows.shape[0], phases, len(TELEMETRY)))
    work = _telemetry_work(int(rows[:, _N].max()) if rows.shape[0] > 0 else 1)
    for s in range(rows.shape[0]):
        _telemetry_into(rows[s], theta_start[s], phases, flight_cap, mu, pinned[s], out[s], work)
    return out


def telemetry_batch(
    rows: FloatArray,
    theta_start_rad: FloatArray,
    pinned: NDArray[np.bool_],
    cam_phases: int,
    flight_cap_s: float,
    friction: float,
) -> FloatArray:
    """:func:`telemetry_samples` of many scenes in one compiled call: shape (scenes, K, len(TELEMETRY)).

    ``rows`` (scenes, len(PARAMS)); ``theta_start_rad`` and ``pinned`` one per scene. The
    design studies' level (b) (:mod:`millctl.studies.arrays`): no Python per scene.
    """
    table = np.ascontiguousarray(rows, dtype=np.float64)
    if table.ndim != 2 or table.shape[1] != len(PARAMS):
        raise ValueError(f"rows must have shape (scenes, {len(PARAMS)}), got {table.shape}")
    start = np.ascontiguousarray(theta_start_rad, dtype=np.float64).reshape(table.shape[0])
    flags = np.ascontiguousarray(pinned, dtype=np.bool_).reshape(table.shape[0])
    result: FloatArray = _telemetry_batch(table, start, flags, int(cam_phases), float(flight_cap_s), float(friction))
    return result


@njit(cache=True)
def _detachment_times(p, horizon):  # type: ignore[no-untyped-def]
    n = int(p[_N])
    tr = _trig_rows(p, n)
    st = np.zeros((n, _STATE_COLUMNS))
    out = np.full(n, math.inf)
    for i in range(n):
        if _trig(tr, i, 0.0, 0, 1.0) <= 0.0:
            out[i] = 0.0
        elif not _never_detaches(tr, i):
            out[i] = _falling_zero_windowed(p, st, tr, i, 1.0, 0.0, horizon)
    return out


def detachment_times(row: FloatArray, horizon_s: float) -> FloatArray:
    """Every rod's first detachment in [0, horizon] (s; inf: pinned), compiled.

    The shared search the benchmark times on its own (zero-length departures are not resolved here).
    """
    result: FloatArray = _detachment_times(np.ascontiguousarray(row, dtype=np.float64), float(horizon_s))
    return result


@njit(cache=True)
def _batch(rows, all_rods, horizon, flight_cap, tol):  # type: ignore[no-untyped-def]
    out = np.empty((rows.shape[0], len(OUT)))
    scratch = _scratch(int(rows[:, _N].max()) if rows.shape[0] > 0 else 1)
    for k in range(rows.shape[0]):
        _event(rows[k], all_rods, horizon, flight_cap, tol, out[k], scratch)
    return out


def first_impacts(
    rows: FloatArray,
    *,
    rods: str = "all",
    horizon_s: float = 5.0,
    flight_cap_s: float = math.inf,
    tol_s: float = 0.0,
) -> FloatArray:
    """The batch entry point: the first impact of every scene row, one result row each (:data:`OUT` columns).

    ``rows``: shape (scenes, len(PARAMS)) (:func:`scene_row`, :func:`scene_rows`).
    ``rods``: ``"all"`` — every rod detaches at its own time (the same question as
    ``methods.first_impact(scene, "exact")``); ``"one"`` — only rod 0 detaches, within
    one revolution, the others are held on the wall (the node telemetry's sample).
    ``horizon_s``: last time searched (s); ``flight_cap_s``: longest flight followed (s);
    ``tol_s``: root finder's time tolerance (s; 0 ≈ 4 ulp). One core, scenes in order.
    """
    if rods not in ("all", "one"):
        raise ValueError(f"rods = {rods!r}: choose 'all' or 'one'")
    table = np.ascontiguousarray(rows, dtype=np.float64)
    if table.ndim != 2 or table.shape[1] != len(PARAMS):
        columns = ", ".join(PARAMS)
        raise ValueError(f"rows must have shape (scenes, {len(PARAMS)}) (columns: {columns}), got {table.shape}")
    result: FloatArray = _batch(table, rods == "all", float(horizon_s), float(flight_cap_s), float(tol_s))
    return result


def scene_rows(scenes: list[Scene]) -> FloatArray:
    """Parameter rows of many scenes (shape (len(scenes), len(PARAMS)))."""
    return np.array([scene_row(s) for s in scenes]).reshape(len(scenes), len(PARAMS))


__all__ = [
    "OUT",
    "PARAMS",
    "TELEMETRY",
    "WALL",
    "detachment_times",
    "first_impacts",
    "scene_row",
    "scene_rows",
    "telemetry_batch",
    "telemetry_samples",
]
