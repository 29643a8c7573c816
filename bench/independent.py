"""The independent reference first impact: a dense scan plus high-precision refinement (issue 17, item 5).

It never sees an engine's answer. From the scene alone:

1. each rod's detachment: N(t) (eqs 4–7, written out here in numpy) sampled on a grid
   400 × finer than the shortest time scale (cam period, revolution, √(2 r_r/g)); every
   falling sign change, and every local minimum (N' from − to +), is refined in mpmath
   at ``DIGITS`` digits (bracketed Anderson–Björk). The zero-length rule of docs/model.md
   is applied in mpmath (the wall gap's leading coefficient at 80 digits): such a rod is
   held until N has risen above zero and falls again;
2. every pair with a flying rod (wall, other rods, pinned or flying): its separation sampled
   on the same grid from the departure on (samples within 1e-9·r0² of zero re-evaluated in
   mpmath, and the first grid interval after a departure probed at 60 geometric steps in
   mpmath, where the triple root at departure swamps float64), candidates refined in mpmath;
3. the first impact is the earliest root over all pairs; its contact point, velocities and
   energy are evaluated in mpmath (:func:`millctl.physics.reference.impact_at`).

Cost: about a second per scene.
"""

from __future__ import annotations

import math
from typing import Any

import mpmath
import numpy as np
from numpy.typing import NDArray

from millctl.config import ModelVariant
from millctl.physics.flight import ZERO_FLIGHT_RTOL
from millctl.physics.methods import ImpactEvent
from millctl.physics.model import Scene
from millctl.physics.reference import _Mp, impact_at

DIGITS = 40
GRID_REFINEMENT = 400
T_END_S = 5.0
FloatArray = NDArray[np.float64]


def _grid_step_s(scene: Scene) -> float:
    m = scene.model
    scales = [math.sqrt(2.0 * m.rod_radius_m / m.g_m_s2)]
    for w in (scene.lift_omega_rad_s, scene.omega_r_rad_s):
        if w > 0.0:
            scales.append(2.0 * math.pi / w)
    return min(scales) / GRID_REFINEMENT


class _Float:
    """The scene's kinematics in float64 numpy (vectorised over time), written out from eqs 1–10."""

    def __init__(self, scene: Scene) -> None:
        m = scene.model
        self.scene, self.m = scene, m
        self.wr, self.wv, self.a0 = scene.omega_r_rad_s, scene.lift_omega_rad_s, scene.lift_alpha0_rad

    def normal(self, rod: int, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        """N/m and its time derivative."""
        m, wr, wv = self.m, self.wr, self.wv
        th = self.scene.rod_theta0_rad(rod) + wr * t
        al = self.a0 + wv * t
        if m.variant is ModelVariant.CORRECTED:
            c, amp = m.r0_m * wr * wr, -m.eccentricity_m * wv * wv
        else:
            c, amp = 2.0 * m.r0_m * wr * wr, (m.spring_n_per_m / m.rod_mass_kg - wv * wv) * m.eccentricity_m
        g_eff = m.g_m_s2 + amp * np.sin(al)
        value = c - g_eff * np.sin(th)
        return value, -amp * wv * np.cos(al) * np.sin(th) - g_eff * wr * np.cos(th)

    def rel(self, rod: int, t_d: float | None, t: FloatArray) -> tuple[FloatArray, ...]:
        m, wr, wv = self.m, self.wr, self.wv
        r0 = m.r0_m

        def pinned(tt: FloatArray) -> tuple[FloatArray, ...]:
            th = self.scene.rod_theta0_rad(rod) + wr * tt
            c, s = np.cos(th), np.sin(th)
            return r0 * c, r0 * s, -r0 * wr * s, r0 * wr * c

        if t_d is None:
            return pinned(t)
        x0, y0, ux, uy = (float(v[0]) for v in pinned(np.array([t_d])))
        tau = np.maximum(t - t_d, 0.0)
        ad, rd, g = self.a0 + wv * t_d, m.eccentricity_m, m.g_m_s2
        h = -0.5 * g * tau * tau - rd * (np.sin(ad + wv * tau) - math.sin(ad) - wv * tau * math.cos(ad))
        dh = -g * tau - rd * wv * (np.cos(ad + wv * tau) - math.cos(ad))
        fly = t > t_d
        px, py, pvx, pvy = pinned(t)
        return (
            np.where(fly, x0 + ux * tau, px),
            np.where(fly, y0 + uy * tau + h, py),
            np.where(fly, ux, pvx),
            np.where(fly, uy + dh, pvy),
        )


def _bisect(f: Any, a: Any, b: Any) -> Any:
    """A sign change of f in [a, b] by bisection in mpmath, to 1e-32 s (robust where f is flat or noisy)."""
    fa = f(a)
    while b - a > mpmath.mpf("1e-32"):
        mid = (a + b) / 2
        fm = f(mid)
        if fm == 0:
            return mid
        if (fm > 0) == (fa > 0):
            a, fa = mid, fm
        else:
            b = mid
    return b


def _refine(f: Any, df: Any, a: float, b: float, fa: float, fb: float, dfa: float, dfb: float) -> Any | None:
    """The first falling zero of f in [a, b] in mpmath, or None (f stays > 0)."""
    mpf = mpmath.mpf
    if fa <= 0.0:
        return mpf(a)
    if fb <= 0.0:
        return _bisect(f, mpf(a), mpf(b))
    if dfa < 0.0 < dfb:
        t_m = _bisect(df, mpf(a), mpf(b))
        if f(t_m) <= 0:
            return _bisect(f, mpf(a), t_m)
    return None


def _first_zero(values: FloatArray, slopes: FloatArray, ts: FloatArray, f: Any, df: Any) -> Any | None:
    """First falling zero of f on the grid ts (samples and slopes in float64), refined in mpmath."""
    low = (values[1:] <= 0.0) | ((slopes[:-1] < 0.0) & (slopes[1:] > 0.0))
    for k in np.flatnonzero(low):
        root = _refine(f, df, ts[k], ts[k + 1], values[k], values[k + 1], slopes[k], slopes[k + 1])
        if root is not None:
            return root
    return None


def _zero_length(mp: _Mp, scene: Scene, rod: int, t_d: Any, unsupported: bool) -> bool:
    """docs/model.md's rule, in mpmath: the wall gap's leading coefficient ≤ ZERO_FLIGHT_RTOL × its scale."""
    m = scene.model
    w_r, w_v, r_d, g, r0 = scene.omega_r_rad_s, scene.lift_omega_rad_s, m.eccentricity_m, m.g_m_s2, m.r0_m
    exact = m.variant is ModelVariant.CORRECTED and not unsupported
    with mpmath.workdps(80):
        eps = mpmath.mpf("1e-25")
        x, y, _, _ = mp.rel(rod, t_d, t_d + eps)
        gap = mp.r0**2 - x * x - y * y
        lead = gap / eps**3 if exact else gap / eps**2
    if exact:
        scale = 2.0 * r0 * (r_d * w_v**3 + (g + r_d * w_v * w_v) * w_r)
    else:
        scale = r0 * (r0 * w_r * w_r + g + r_d * w_v * w_v)
    return bool(lead <= ZERO_FLIGHT_RTOL * scale)


def _detachment(fl: _Float, mp: _Mp, scene: Scene, rod: int, ts: FloatArray) -> Any | None:
    """The rod's departure (mpmath), zero-length departures skipped; None: pinned up to T_END_S."""
    values, slopes = fl.normal(rod, ts)

    def f(t: Any) -> Any:
        return mp.normal(rod, t)

    def df(t: Any) -> Any:
        return mpmath.diff(f, t)

    unsupported = bool(values[0] <= 0.0)
    start = 0
    while True:
        sub = slice(start, None)
        if values[start] <= 0.0:
            t_d = mpmath.mpf(float(ts[start]))
        else:
            t_d = _first_zero(values[sub], slopes[sub], ts[sub], f, df)
        if t_d is None:
            return None
        if not _zero_length(mp, scene, rod, t_d, unsupported and start == 0):
            return t_d
        # held through the dip: the next rise of N above zero, then its next fall
        k = int(np.searchsorted(ts, float(t_d)))
        rise = np.flatnonzero(values[k:] > 0.0)
        if rise.size == 0:
            return None
        start = k + int(rise[0])
        unsupported = False


def _pair_zero(fl: _Float, mp: _Mp, i: int, j: int, t_d: dict[int, Any], ts: FloatArray) -> Any | None:
    """The first contact of flying rod i with j (−1: wall) on the grid from i's departure, refined in mpmath."""
    m = fl.m
    ti = float(t_d[i])
    tj = float(t_d[j]) if j in t_d else None
    grid = np.concatenate(([ti], ts[ts > ti]))
    x, y, vx, vy = fl.rel(i, ti, grid)
    if j < 0:
        s, ds = m.r0_m**2 - (x * x + y * y), -2.0 * (x * vx + y * vy)
    else:
        xb, yb, vxb, vyb = fl.rel(j, tj, grid)
        dx, dy = x - xb, y - yb
        s, ds = dx * dx + dy * dy - 4.0 * m.rod_radius_m**2, 2.0 * (dx * (vx - vxb) + dy * (vy - vyb))

    def sep(t: Any) -> Any:
        xa, ya, _, _ = mp.rel(i, t_d[i], t)
        if j < 0:
            return mp.r0**2 - xa * xa - ya * ya
        xb_, yb_, _, _ = mp.rel(j, t_d.get(j), t)
        return (xa - xb_) ** 2 + (ya - yb_) ** 2 - 4 * mp.rr**2

    def dsep(t: Any) -> Any:
        return mpmath.diff(sep, t)

    near = np.flatnonzero(np.abs(s) < 1e-9 * m.r0_m**2)
    for k in near:
        if k > 0:
            s[k] = float(sep(mpmath.mpf(float(grid[k]))))
    if j < 0 and grid.size > 1:  # the first interval after departure: geometric probes in mpmath
        with mpmath.workdps(110):  # the gap is ~τ³ here: 2^-40 of a grid step needs ~60 digits
            t0 = t_d[i]
            h = mpmath.mpf(float(grid[1])) - t0
            probes = [t0 + h * mpmath.mpf(2) ** (-k) for k in range(40, -1, -1)]
            values = [sep(p) for p in probes]
            for a, b, fa, fb in zip(probes, probes[1:], values, values[1:], strict=False):
                if fa > 0 and fb == 0:
                    return b
                if fa > 0 and fb < 0:
                    return _bisect(sep, a, b)
        # the first interval is settled by the probes (the departure itself is no contact: the zero-length
        # rule has been applied); the float scan starts at the first grid point after it
        return _first_zero(s[1:], ds[1:], grid[1:], sep, dsep)
    return _first_zero(s, ds, grid, sep, dsep)


def independent_first_impact(scene: Scene, digits: int = DIGITS, t_end_s: float = T_END_S) -> ImpactEvent | None:
    """The scene's first impact from the scene alone (see module docstring); None if nothing touches."""
    with mpmath.workdps(digits):
        mp = _Mp(scene)
        fl = _Float(scene)
        ts = np.arange(0.0, t_end_s, _grid_step_s(scene))
        departures: dict[int, Any] = {}
        for rod in range(scene.model.n_rods):
            t_d = _detachment(fl, mp, scene, rod, ts)
            if t_d is not None:
                departures[rod] = t_d
        best: tuple[Any, int, int] | None = None
        order = sorted(departures, key=lambda r: departures[r])
        for n, i in enumerate(order):
            # rod i meets the wall, the rods that are still pinned at its departure, and the rods that leave later
            partners = [-1] + [j for j in range(scene.model.n_rods) if j != i and j not in order[:n]]
            for j in partners:
                seen = {r: departures[r] for r in order[: n + 1]}
                if j in departures:
                    seen[j] = departures[j]
                root = _pair_zero(fl, mp, i, j, seen, ts)
                if root is not None and root <= t_end_s and (best is None or root < best[0]):
                    best = (root, i, j)
        if best is None:
            return None
        t_c, i, j = best
        return impact_at(mp, i, j, {r: t for r, t in departures.items() if t < t_c}, t_c, f"independent-{digits}")


__all__ = ["independent_first_impact"]
