"""Where a rod is, in the vial frame: held on the wall (eq. 11) or flying (eq. 10), and the gaps between them.

* :func:`_rel`: position and velocity of a rod, held (θ = θ_pin + ω_r t) or in flight (eq. 10 in the
  flight's own time τ and its departure's cam phase, :func:`_flying_rel`);
* :func:`_departure_gap`: the wall gap r0² − |d|² of a departed rod with its triple root at the
  departure divided out (:func:`millctl.physics.flight.departure_wall_gap`);
* :func:`_pair`: the separation of two rods, |d|² − (2 r_r)², eq. 13 with its contact distance
  corrected (printed: 2 r_d), or of a rod and the wall.
"""

from __future__ import annotations

import math

import numpy as np

from millctl.physics.flight import ZERO_FLIGHT_RTOL
from millctl.physics.kernels.layout import (
    _G,
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
    _WR,
    _WV,
    WALL,
    leaf_kernel,
)


@leaf_kernel
def _rel(p, st, i, t):  # type: ignore[no-untyped-def]
    """(x, y, vx, vy) of rod i relative to the vial centre at t."""
    if st[i, _S_FLY] == 0.0:
        r0, w = p[_R0], p[_WR] + st[i, _S_DW]  # carried: ω_r; sliding: the slide step's mean rate
        th = st[i, _S_TH] + w * (t - st[i, _S_T0])
        c, s = math.cos(th), math.sin(th)
        return r0 * c, r0 * s, -r0 * w * s, r0 * w * c
    tau = t - st[i, _S_T0]
    x = p[_WV] * tau
    return _flying_rel(p, st, i, tau, math.cos(x), math.sin(x))


@leaf_kernel
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


@leaf_kernel
def _horner(coefficients, y):  # type: ignore[no-untyped-def]
    total = 0.0
    for k in range(coefficients.size - 1, -1, -1):
        total = total * y + coefficients[k]
    return total


@leaf_kernel
def _c2_plus_half_over_x(x):  # type: ignore[no-untyped-def]
    """((cos x − 1)/x² + ½)/x, stable at small x (flight.py): x·Σ_{k≥2} (−x²)^(k−2)/(2k)! for |x| < 1."""
    if abs(x) < 1.0:
        return x * _horner(_C2_SERIES, x * x)
    return ((math.cos(x) - 1.0) / (x * x) + 0.5) / x


@leaf_kernel
def _s3(x):  # type: ignore[no-untyped-def]
    """(sin x − x)/x³, stable at small x (flight.py): Σ_{k≥1} (−x²)^(k−1)/(2k+1)! for |x| < 1."""
    if abs(x) < 1.0:
        return _horner(_S3_SERIES, x * x)
    return (math.sin(x) - x) / (x * x * x)


@leaf_kernel
def _departure_gap(p, st, i, t):  # type: ignore[no-untyped-def]
    """(r0² − |d|²)/τ² of a rod that left the wall at t0, or /τ³ when n_d = 0 (flight.departure_wall_gap)."""
    t0 = st[i, _S_T0]
    tau = t - t0
    r0, w_r, w_v, r_d, g = p[_R0], p[_WR] + st[i, _S_DW], p[_WV], p[_RD], p[_G]  # w_r: the departure rate
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


@leaf_kernel
def _zero_length_departure(p, st, i):  # type: ignore[no-untyped-def]
    """The zero-length rule of flight.zero_length_departure: reduced gap at τ = 0 ≤ ZERO_FLIGHT_RTOL × its scale."""
    r0, w_r, w_v, r_d, g = p[_R0], p[_WR] + st[i, _S_DW], p[_WV], p[_RD], p[_G]
    if st[i, _S_ND] == 0.0:
        scale = 2.0 * r0 * (r_d * w_v**3 + (g + r_d * w_v * w_v) * w_r)
    else:
        scale = r0 * (r0 * w_r * w_r + g + r_d * w_v * w_v)
    return _departure_gap(p, st, i, st[i, _S_T0]) <= ZERO_FLIGHT_RTOL * scale


@leaf_kernel
def _pair(p, st, i, j, t):  # type: ignore[no-untyped-def]
    """Separation (> 0 apart), its derivative and the relative speed squared of rod i and j (WALL: the wall)."""
    x, y, vx, vy = _rel(p, st, i, t)
    if j == WALL:
        return p[_R0] * p[_R0] - (x * x + y * y), -2.0 * (x * vx + y * vy), vx * vx + vy * vy
    xb, yb, vxb, vyb = _rel(p, st, j, t)
    dx, dy, dvx, dvy = x - xb, y - yb, vx - vxb, vy - vyb
    c = 2.0 * p[_RR]
    return dx * dx + dy * dy - c * c, 2.0 * (dx * dvx + dy * dvy), dvx * dvx + dvy * dvy
