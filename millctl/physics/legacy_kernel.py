"""The paper's fixed-step collision scheme compiled the same way as the exact engine (numba, issue 17).

:mod:`.legacy` is the scheme as the paper writes it, in numpy: fixed step dt from the
first detachment, after every step the check in absolute (lab) coordinates, and on the
first step that passes it the collision at the average of the step's end points
(time, contact point, velocities; first order in dt). This module is the same scheme,
line for line, as scalar loops compiled with numba (``cache=True``), on the kernels'
own detachment search and flight formulas (:mod:`.kernels`): the like-for-like
baseline of the benchmark ("the same algorithms compiled the same way"), beside the
numpy one a user would run today. Method ``legacy-compiled`` of
:func:`millctl.physics.methods.first_impact`.

Checks per step (the same order as :mod:`.legacy`, the first pair that passes wins):
for every rod with a detachment, its wall gap r0² − |p − c|² ≤ 0 once it has left
(the exact circle, c the vial centre in the lab), then (x_i − x_j)² + (y_i − y_j)² ≤ (2 r_r)²
for every other rod, once either of the two has left (eq. 14 with the corrected contact distance).

Its compiled code includes the kernels it calls, but numba invalidates this module's
cache only when this file changes: after an edit to :mod:`.kernels`, delete it
(``find millctl -name 'legacy_kernel.*.nb[ci]' -delete``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from millctl.errors import PhysicsInputError
from millctl.physics import kernels as k
from millctl.physics.events import ContactRow
from millctl.physics.model import Scene

FloatArray = NDArray[np.float64]
_LAB = 6  # columns of a rod's lab state: x, y, vx, vy, y of the vial centre, its vy


@njit(cache=True)
def _lab(p, pinned, flying, t0, i, t, out):  # type: ignore[no-untyped-def]
    """Lab (x, y, vx, vy, y_c, vy_c) of rod i at t: pinned before its departure t0[i], flying from it on."""
    if t >= t0[i]:
        x, y, vx, vy = k._rel(p, flying, i, t)
    else:
        x, y, vx, vy = k._rel(p, pinned, i, t)
    alpha = p[k._A0] + p[k._WV] * t
    yc = p[k._L] - p[k._RD] + p[k._RD] * math.sin(alpha)
    vyc = p[k._RD] * p[k._WV] * math.cos(alpha)
    out[i, 0], out[i, 1], out[i, 2], out[i, 3], out[i, 4], out[i, 5] = x, yc + y, vx, vyc + vy, yc, vyc


@njit(cache=True)
def _first_touch(p, lab, t0, t):  # type: ignore[no-untyped-def]
    """The first pair (rod, partner; −1 the wall) that passes the paper's check at t, or (−1, −1)."""
    n = lab.shape[0]
    r0, c = p[k._R0], 2.0 * p[k._RR]
    for i in range(n):
        if t0[i] == math.inf:
            continue
        x, y, yc = lab[i, 0], lab[i, 1], lab[i, 4]
        if t > t0[i] and r0 * r0 - (x * x + (y - yc) ** 2) <= 0.0:
            return i, -1
        for j in range(n):
            if j == i or (j < i and t0[j] < math.inf) or not (t > t0[i] or t > t0[j]):
                continue
            dx, dy = x - lab[j, 0], y - lab[j, 1]
            if dx * dx + dy * dy - c * c <= 0.0:
                return i, j
    return -1, -1


@njit(cache=True)
def _legacy(p, dt, t_end, out):  # type: ignore[no-untyped-def]
    """The paper's first contact into ``out`` (t, rod, partner, x, y, v_n, v_t, |v|, backed); out[0] nan: none."""
    n = int(p[k._N])
    tr = k._trig_rows(p, n)
    pinned = np.zeros((n, k._STATE_COLUMNS))
    for i in range(n):
        pinned[i, k._S_TH] = p[k._TH0] + i * 2.0 * math.pi / n
    flying = pinned.copy()
    t0 = np.full(n, math.inf)
    for i in range(n):
        unsupported = k._trig(tr, i, 0.0, 0, 1.0) <= 0.0
        if unsupported:
            t0[i] = 0.0
        elif not k._never_detaches(tr, i):
            t0[i] = k._falling_zero_windowed(p, pinned, tr, i, 1.0, 0.0, t_end)
        if t0[i] < math.inf:
            k._depart(p, flying, tr, i, t0[i], unsupported)
    out[:] = math.nan
    start = t0.min()
    if start == math.inf:
        return
    before, after = np.empty((n, _LAB)), np.empty((n, _LAB))
    for i in range(n):
        _lab(p, pinned, flying, t0, i, start, before)
    step = 1
    while start + (step - 1) * dt < t_end:
        t = start + dt * step
        for i in range(n):
            _lab(p, pinned, flying, t0, i, t, after)
        i, j = _first_touch(p, after, t0, t)
        if i >= 0:
            _averaged(p, before, after, t0, i, j, start + dt * (step - 1), t, out)
            return
        before, after = after, before
        step += 1


@njit(cache=True)
def _averaged(p, before, after, t0, i, j, t_prev, t, out):  # type: ignore[no-untyped-def]
    """The paper's answer: every quantity at the average of the step's end points (legacy._averaged, w = ½)."""
    mid = 0.5 * (before + after)
    x, y, vx, vy, yc, vyc = mid[i, 0], mid[i, 1], mid[i, 2], mid[i, 3], mid[i, 4], mid[i, 5]
    w_r = p[k._WR]
    if j < 0:
        dx, dy = x, y - yc
        rvx, rvy = vx + w_r * dy, vy - (vyc + w_r * dx)
    else:
        dx, dy, rvx, rvy = mid[j, 0] - x, mid[j, 1] - y, vx - mid[j, 2], vy - mid[j, 3]
    norm = math.hypot(dx, dy)
    nx, ny = dx / norm, dy / norm
    t_mid = t_prev + 0.5 * (t - t_prev)
    backed = j < 0 or not (t0[i] < t_mid and t0[j] < t_mid)
    out[0], out[1], out[2] = t_mid, i, j
    out[3], out[4] = x + p[k._RR] * nx, y + p[k._RR] * ny
    out[5], out[6], out[7] = rvx * nx + rvy * ny, rvy * nx - rvx * ny, math.hypot(vx, vy)
    out[8] = 1.0 if backed else 0.0


def legacy_first_contact_compiled(scene: Scene, dt_s: float, t_end_s: float = 5.0) -> ContactRow | None:
    """The first contact by the paper's scheme (exact circle, end-point average), compiled; None if none."""
    if not (math.isfinite(dt_s) and dt_s > 0.0):
        raise PhysicsInputError(f"dt = {dt_s} s must be a finite step > 0")
    out = np.empty(9)
    _legacy(k.scene_row(scene), float(dt_s), float(t_end_s), out)
    if math.isnan(out[0]):
        return None
    t, i, j, x, y, v_n, v_t, speed, backed = (float(v) for v in out)
    return ContactRow(t, int(i), int(j), x, y, v_n, v_t, speed, backed == 1.0)


__all__ = ["legacy_first_contact_compiled"]
