"""N(t)/m as a trig sum c + Σ a_k cos(w_k t + φ_k), eqs 4–7: its rows, values, derivatives and bounds.

N/m = r0 ω_r² − g_eff sin θ (corrected) or the paper's eq. 7 form 2 r0 ω_r² − (g − (ω_v² − k/m) r_d sin α) sin θ,
with sin α sin θ = ½[cos(α − θ) − cos(α + θ)] and −g sin θ = g cos(θ + π/2): three terms per rod
(:func:`~millctl.physics.kinematics.normal_force_per_mass`, the reference's form). A rod's N row is marked
(``_T_N_FORM``) and evaluated in the product form instead (:func:`_n_form012`): two sine–cosine pairs, not three.
The no-slip margins μN/m ∓ F_t/m of :mod:`.telemetry` are the same product with u sin θ + v cos θ in place of
sin θ (:func:`_margin_form012`, :func:`_set_margin_form`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from millctl.physics.kernels.layout import (
    _A0,
    _FORM_MARGIN,
    _FORM_N,
    _G,
    _KM,
    _PAPER,
    _R0,
    _RD,
    _T_A0,
    _T_COUNT,
    _T_G,
    _T_KAPPA,
    _T_N_FORM,
    _T_TH0,
    _T_U,
    _T_V,
    _T_WV,
    _TA,
    _TH0,
    _TP,
    _TRIG_COLUMNS,
    _TW,
    _WR,
    _WV,
    leaf_kernel,
)


@leaf_kernel
def _set_term(rows, i, k, amplitude, frequency, phase):  # type: ignore[no-untyped-def]
    rows[i, _TA + k], rows[i, _TW + k], rows[i, _TP + k] = amplitude, frequency, phase


@leaf_kernel
def _set_margin_form(rows, i, kappa, theta0, w_v, alpha0, g, u, v):  # type: ignore[no-untyped-def]
    """Mark row i as a no-slip margin c − (g − κ sin α)(u sin θ + v cos θ), θ = ω_r t + θ0 (ω_r its term 0's)."""
    rows[i, _T_N_FORM], rows[i, _T_KAPPA], rows[i, _T_TH0] = _FORM_MARGIN, kappa, theta0
    rows[i, _T_WV], rows[i, _T_A0], rows[i, _T_G] = w_v, alpha0, g
    rows[i, _T_U], rows[i, _T_V] = u, v


@leaf_kernel
def _fill_trig_rows(p, n, rows):  # type: ignore[no-untyped-def]
    """Fill rows 0..n−1 of ``rows``: N/m of rod i (kinematics.normal_force_per_mass), three terms each.

    The terms: g, and the cam's ±½ coupling. Returns nothing, so that leaf kernels (no reference counting) can
    call it.
    """
    _fill_first_trig_rows(p, n, n, rows)


@leaf_kernel
def _fill_first_trig_rows(p, n, count, rows):  # type: ignore[no-untyped-def]
    """:func:`_fill_trig_rows` for rods 0..count−1 of the scene's n only (one rod's event needs rod 0's alone)."""
    wr, wv, a0 = p[_WR], p[_WV], p[_A0]
    if p[_PAPER] != 0.0:
        constant = 2.0 * p[_R0] * wr * wr
        coupling = (wv * wv - p[_KM]) * p[_RD]
    else:
        constant = p[_R0] * wr * wr
        coupling = p[_RD] * wv * wv
    half = 0.5 * coupling
    for i in range(count):
        th0 = p[_TH0] + i * 2.0 * math.pi / n
        rows[i, 0], rows[i, _T_COUNT] = constant, 3.0
        _set_term(rows, i, 0, p[_G], wr, th0 + 0.5 * math.pi)
        _set_term(rows, i, 1, half, wv - wr, a0 - th0)
        _set_term(rows, i, 2, -half, wv + wr, a0 + th0)
        rows[i, _T_N_FORM], rows[i, _T_KAPPA], rows[i, _T_TH0] = _FORM_N, coupling, th0
        rows[i, _T_WV], rows[i, _T_A0] = wv, a0


@njit(cache=True, error_model="numpy")
def _trig_rows(p, n, out=None):  # type: ignore[no-untyped-def]
    """The trig rows of :func:`_fill_trig_rows` in ``out`` (at least n rows; its first n are returned), or new ones."""
    rows = np.zeros((n, _TRIG_COLUMNS)) if out is None else out[:n]
    _fill_trig_rows(p, n, rows)
    return rows


@leaf_kernel
def _n_form012(tr, i, t):  # type: ignore[no-untyped-def]
    """N/m of an N row and its first two time derivatives in eq. 7's form: two sine–cosine pairs, not three.

    N/m = c − G sin θ with G = g − κ sin α, θ = ω_r t + θ0, α = ω_v t + α0 (the three cosines of the row
    are this by sin α sin θ = ½[cos(α − θ) − cos(α + θ)]); G′ = −κ ω_v cos α, G″ = κ ω_v² sin α.
    """
    w_r, w_v, kappa = tr[i, _TW], tr[i, _T_WV], tr[i, _T_KAPPA]
    theta = w_r * t + tr[i, _T_TH0]
    alpha = w_v * t + tr[i, _T_A0]
    s_th, c_th = math.sin(theta), math.cos(theta)
    s_al, c_al = math.sin(alpha), math.cos(alpha)
    g_eff = tr[i, _TA] - kappa * s_al
    d_g = -kappa * w_v * c_al
    d2_g = kappa * w_v * w_v * s_al
    f0 = tr[i, 0] - g_eff * s_th
    f1 = -d_g * s_th - g_eff * w_r * c_th
    f2 = -d2_g * s_th - 2.0 * d_g * w_r * c_th + g_eff * w_r * w_r * s_th
    return f0, f1, f2


@leaf_kernel
def _n_form01(tr, i, t, order):  # type: ignore[no-untyped-def]
    """N/m of an N row (order 0) or its time derivative (order 1), as :func:`_n_form012`."""
    w_r, w_v, kappa = tr[i, _TW], tr[i, _T_WV], tr[i, _T_KAPPA]
    theta = w_r * t + tr[i, _T_TH0]
    alpha = w_v * t + tr[i, _T_A0]
    s_th, s_al = math.sin(theta), math.sin(alpha)
    g_eff = tr[i, _TA] - kappa * s_al
    if order == 0:
        return tr[i, 0] - g_eff * s_th
    return kappa * w_v * math.cos(alpha) * s_th - g_eff * w_r * math.cos(theta)


@leaf_kernel
def _margin_form012(tr, i, t):  # type: ignore[no-untyped-def]
    """A no-slip margin row and its first two time derivatives in the product form (``_FORM_MARGIN``).

    m = c − G S with G = g − κ sin α as in N (:func:`_n_form012`) and S = u sin θ + v cos θ, S′ = ω_r (u cos θ −
    v sin θ), S″ = −ω_r² S: μN/m ∓ F_t/m of :func:`.telemetry._slip_rows` (u = μ, v = ±1), two sine–cosine
    pairs where its three cosines take three.
    """
    w_r, w_v, kappa, u, v = tr[i, _TW], tr[i, _T_WV], tr[i, _T_KAPPA], tr[i, _T_U], tr[i, _T_V]
    theta = w_r * t + tr[i, _T_TH0]
    alpha = w_v * t + tr[i, _T_A0]
    s_th, c_th = math.sin(theta), math.cos(theta)
    s_al, c_al = math.sin(alpha), math.cos(alpha)
    g_eff = tr[i, _T_G] - kappa * s_al
    d_g = -kappa * w_v * c_al
    d2_g = kappa * w_v * w_v * s_al
    s_0 = u * s_th + v * c_th
    s_1 = w_r * (u * c_th - v * s_th)
    f0 = tr[i, 0] - g_eff * s_0
    f1 = -d_g * s_0 - g_eff * s_1
    f2 = -d2_g * s_0 - 2.0 * d_g * s_1 + g_eff * w_r * w_r * s_0
    return f0, f1, f2


@leaf_kernel
def _trig(tr, i, t, order, sign):  # type: ignore[no-untyped-def]
    """Sign × the order-th time derivative of row i at t."""
    form = tr[i, _T_N_FORM]
    if order <= 1 and form == _FORM_N:
        return sign * _n_form01(tr, i, t, order)
    if order == 0 and form == _FORM_MARGIN:
        theta = tr[i, _TW] * t + tr[i, _T_TH0]
        g_eff = tr[i, _T_G] - tr[i, _T_KAPPA] * math.sin(tr[i, _T_WV] * t + tr[i, _T_A0])
        return sign * (tr[i, 0] - g_eff * (tr[i, _T_U] * math.sin(theta) + tr[i, _T_V] * math.cos(theta)))
    if order == 1 and form == _FORM_MARGIN:
        return sign * _margin_form012(tr, i, t)[1]
    total = tr[i, 0] if order == 0 else 0.0
    shift = 0.5 * math.pi * order
    for k in range(int(tr[i, _T_COUNT])):
        w = tr[i, _TW + k]
        total += tr[i, _TA + k] * w**order * math.cos(w * t + tr[i, _TP + k] + shift)
    return sign * total


@leaf_kernel
def _trig012(tr, i, t, sign):  # type: ignore[no-untyped-def]
    """Sign × (value, first, second derivative) of row i at t: one sine and cosine per term serve all three."""
    form = tr[i, _T_N_FORM]
    if form == _FORM_N:
        f0, f1, f2 = _n_form012(tr, i, t)
        return sign * f0, sign * f1, sign * f2
    if form == _FORM_MARGIN:
        f0, f1, f2 = _margin_form012(tr, i, t)
        return sign * f0, sign * f1, sign * f2
    f0, f1, f2 = tr[i, 0], 0.0, 0.0
    for k in range(int(tr[i, _T_COUNT])):
        a, w = tr[i, _TA + k], tr[i, _TW + k]
        x = w * t + tr[i, _TP + k]
        c, s = math.cos(x), math.sin(x)
        f0 += a * c
        f1 -= a * w * s
        f2 -= a * w * w * c
    return sign * f0, sign * f1, sign * f2


@leaf_kernel
def _trig_bound(tr, i, order):  # type: ignore[no-untyped-def]
    total = 0.0
    for k in range(int(tr[i, _T_COUNT])):
        total += abs(tr[i, _TA + k]) * abs(tr[i, _TW + k]) ** order
    return total
