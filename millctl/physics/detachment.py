"""Detachment as an event in time: the first falling zero of N(t) (eqs 4–7).

N(t)/m is a trig sum (:func:`~millctl.physics.kinematics.normal_force_per_mass`),
so bounds on its derivatives are exact. The search is certified, with no scan
step: an interval is discarded when a Taylor bound proves N > 0 on it (second
order with max|N''|, or third order with N'' at its midpoint and max|N'''|); where
N'' keeps one sign N' is monotone, so N has at most one critical point there, found
as a root of N' (Brent's method: :func:`.roots.brentq`, scipy's algorithm without
importing scipy) — this is how N's minima are tracked when N only grazes zero.
Otherwise the interval is bisected. A minimum at which N stays
≥ 0 is reported as no detachment (pinned), honestly.

Cost: a few dozen evaluations of a three-term cosine sum per revolution
(≈ 0.1 ms in CPython); grazing minima add ~½·log2(1/ε) bisections.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from millctl.config.models import ModelVariant
from millctl.physics.kinematics import TrigSum, normal_force_per_mass
from millctl.physics.model import Scene
from millctl.physics.roots import brentq

_MAX_DEPTH = 80
_RTOL = 4.0 * 2.220446049250313e-16
_MAXITER = 200


def _xtol(a: float, b: float) -> float:
    """Absolute time tolerance of a few ulps of the bracket (a root at t = 0 has no relative scale)."""
    return max(_RTOL * max(abs(a), abs(b)), 1e-300)


@dataclass(frozen=True)
class Detachment:
    """Where and when a pinned rod leaves the wall, or that it stays pinned up to the horizon."""

    detached: bool
    time_s: float
    """Detachment time t_d (s); nan when pinned."""
    theta_rad: float
    """θ_d (rad, in (−π, π]); nan when pinned."""
    alpha_rad: float
    """Cam phase α_d at detachment (rad, in [0, 2π)); nan when pinned."""
    horizon_s: float
    """The search covered [t_start, horizon_s]."""
    at_start: bool = False
    """N ≤ 0 already at t_start: the rod is never held."""
    held_from_s: float = math.nan
    """Where the search began: t_start, or with ``rearm`` the end of the dip it skipped (nan: N never rose)."""


def _wrap_pi(angle: float) -> float:
    return math.remainder(angle, 2.0 * math.pi)


def first_falling_zero(f: TrigSum, t_start_s: float, t_end_s: float) -> float | None:
    """First t in (t_start, t_end] where f falls through zero, given f(t_start) > 0; None if f stays ≥ 0."""
    m2, m3 = f.bound(2), f.bound(3)
    # Vectorised first pass: cells of a quarter of the fastest period, pruned by the Taylor bound.
    w_max = max((abs(w) for w in f.frequencies_rad_s), default=0.0)
    cells = 1 if w_max == 0.0 else int(min(max(math.ceil((t_end_s - t_start_s) * w_max * 2.0 / math.pi), 1), 4096))
    edges = np.linspace(t_start_s, t_end_s, cells + 1)
    mids, h = 0.5 * (edges[:-1] + edges[1:]), (t_end_s - t_start_s) / cells
    lower = f.on_grid(mids) - np.abs(f.on_grid(mids, 1)) * 0.5 * h - m2 * h * h * 0.125
    stack = [(float(edges[k]), float(edges[k + 1]), 0) for k in np.flatnonzero(lower <= 0.0)[::-1]]
    while stack:
        a, b, depth = stack.pop()
        h = b - a
        mid = 0.5 * (a + b)
        f0, f1, f2 = f(mid), f(mid, 1), f(mid, 2)
        linear = f0 - abs(f1) * 0.5 * h
        # Taylor about the midpoint, |u| ≤ h/2: f ≥ f0 − |f′|h/2 − max|f″| h²/8, or with f″ there and max|f‴|:
        # f ≥ f0 − |f′|h/2 + min(f″, 0) h²/8 − max|f‴| h³/48; either bound above zero clears the cell
        if linear - m2 * h * h * 0.125 > 0.0 or linear + min(f2, 0.0) * h * h * 0.125 - m3 * h * h * h / 48.0 > 0.0:
            continue
        if abs(f2) > m3 * 0.5 * h or depth >= _MAX_DEPTH:
            root = _monotone_pieces_root(f, a, b)
            if root is not None:
                return root
            continue
        stack.append((mid, b, depth + 1))
        stack.append((a, mid, depth + 1))
    return None


def _monotone_pieces_root(f: TrigSum, a: float, b: float) -> float | None:
    """On [a, b] f' is monotone: split at f's one critical point and look for a falling zero."""
    ends = [a, b]
    d1a, d1b = f(a, 1), f(b, 1)
    if d1a < 0.0 < d1b or d1a > 0.0 > d1b:  # a minimum of f inside: this is where grazing is decided
        t_c = brentq(lambda t: f(t, 1), a, b, xtol=_xtol(a, b), rtol=_RTOL, maxiter=_MAXITER)
        ends = [a, t_c, b]
    for s, e in itertools.pairwise(ends):
        fs, fe = f(s), f(e)
        if fs > 0.0 and fe < 0.0:
            return brentq(f, s, e, xtol=_xtol(s, e), rtol=_RTOL, maxiter=_MAXITER)
        if fs > 0.0 and fe == 0.0 and f(e, 1) < 0.0:
            return e
    return None


def _nudge(f: TrigSum, t: float, horizon_s: float, sign: float) -> float | None:
    """The first time from t on where sign·f > 0, stepping geometrically off a root."""
    step = max(abs(t), 1.0) * 1e-13
    while sign * f(t) <= 0.0:
        if t >= horizon_s:
            return None
        t, step = t + step, 2.0 * step
    return t


def _rearm(f: TrigSum, t_start_s: float, horizon_s: float) -> float | None:
    """Skip the current dip of f: the first time after t_start at which f is > 0 again after having been < 0."""
    t = t_start_s
    if f(t) >= 0.0:
        down = first_falling_zero(f, t, horizon_s) if f(t) > 0.0 else t
        if down is None:
            return None
        found = _nudge(f, down, horizon_s, -1.0)
        if found is None:
            return None
        t = found
    neg = TrigSum(-f.constant, tuple(-a for a in f.amplitudes), f.frequencies_rad_s, f.phases_rad)
    up = first_falling_zero(neg, t, horizon_s)
    return None if up is None else _nudge(f, up, horizon_s, 1.0)


def find_detachment(
    scene: Scene,
    theta0_rad: float | None = None,
    t_start_s: float = 0.0,
    horizon_s: float | None = None,
    variant: ModelVariant | None = None,
    rearm: bool = False,
) -> Detachment:
    """First detachment of a rod pinned at θ0 + ω_r t from t_start on (eq. 7 for ``paper``, N = 0 for ``corrected``).

    ``theta0_rad`` is the rod's angle at t = 0 (default: the scene's θ0). The
    horizon defaults to one revolution after t_start (2π/ω_r; one cam period at
    standstill of the vial, and 1 s when both speeds are zero).
    With ``rearm`` (a rod whose free flight would enter the wall at once) the
    rod stays pinned through the current dip of N: it waits for N to fall below
    zero (if it has not yet) and to rise above zero again.
    """
    theta0 = scene.theta0_rad if theta0_rad is None else theta0_rad
    f = normal_force_per_mass(scene, theta0, variant)
    if horizon_s is None:
        fastest = max(scene.omega_r_rad_s, 0.0)
        period = (
            2.0 * math.pi / fastest
            if fastest > 0
            else (2.0 * math.pi / scene.omega_v_rad_s if scene.omega_v_rad_s > 0 else 1.0)
        )
        horizon_s = t_start_s + period

    def _result(t: float, at_start: bool = False) -> Detachment:
        theta = _wrap_pi(theta0 + scene.omega_r_rad_s * t)
        alpha = (scene.alpha0_rad + scene.omega_v_rad_s * t) % (2.0 * math.pi)
        return Detachment(True, t, theta, alpha, horizon_s, at_start, t_start_s)

    if rearm:
        rearmed = _rearm(f, t_start_s, horizon_s)
        if rearmed is None:
            return Detachment(False, math.nan, math.nan, math.nan, horizon_s)
        t_start_s = rearmed
    if f(t_start_s) <= 0.0:
        return _result(t_start_s, at_start=True)
    root = first_falling_zero(f, t_start_s, horizon_s)
    if root is None:
        return Detachment(False, math.nan, math.nan, math.nan, horizon_s, held_from_s=t_start_s)
    return _result(root)


__all__ = ["Detachment", "find_detachment", "first_falling_zero"]
