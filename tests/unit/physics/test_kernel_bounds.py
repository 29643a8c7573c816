"""The compiled kernels' certified bounds and root starts, each against the functions it is a statement about.

:func:`.contacts._tangent_bound` (a lower bound on a separation over a step), :func:`.telemetry._local_safe_step`
(a step over which a margin provably stays positive), :func:`.detach._product_until` (the arcs where a row in
product form provably stays positive at every cam phase) and :func:`.roots._hermite_start` (the root of the cubic
through both ends' values and slopes) are otherwise exercised only through the engines' agreement tests.
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from millctl.physics.kernels.contacts import _tangent_bound
from millctl.physics.kernels.detach import _product_arcs, _product_until
from millctl.physics.kernels.layout import _T_G, _T_KAPPA, _T_TH0, _T_U, _T_V, _TA, _TRIG_COLUMNS, _TW, PARAMS
from millctl.physics.kernels.roots import _hermite_start
from millctl.physics.kernels.telemetry import _local_safe_step, _slip_rows
from millctl.physics.kernels.trig import _fill_trig_rows, _trig

_GRID = np.linspace(0.0, 1.0, 2001)
finite = st.floats(-10.0, 10.0, allow_nan=False)


@given(
    a=finite, b=finite, amp=st.floats(0.0, 5.0), w=st.floats(0.1, 6.0), phase=finite,
    width=st.floats(0.01, 2.0), slack=st.floats(0.0, 3.0),
)  # fmt: skip
def test_the_tangent_bound_is_below_the_function_over_the_step(
    a: float, b: float, amp: float, w: float, phase: float, width: float, slack: float
) -> None:
    # s(u) = a + b u + amp sin(w u + φ): |s″| ≤ amp w², any larger bound too
    def s(u: np.ndarray) -> np.ndarray:
        return a + b * u + amp * np.sin(w * u + phase)

    def ds(u: float) -> float:
        return b + amp * w * math.cos(w * u + phase)

    curvature = amp * w * w + slack
    u = _GRID * width
    bound = _tangent_bound(float(s(u[0])), ds(0.0), float(s(u[-1])), ds(width), width, curvature)
    lowest = float(s(u).min())
    assert bound <= lowest + 1e-9 * (1.0 + abs(lowest))
    # and no looser than the two end parabolas allow: at least the lower end value minus ½ C w²
    assert bound >= min(float(s(u[0])), float(s(u[-1]))) - 0.5 * curvature * width * width - abs(b) * width - 1e-9


def test_the_tangent_bound_where_its_parabolas_cross_and_where_it_is_exact() -> None:
    # s = u² − u on [0, 1], C = 2: the end parabolas −u − u² and −(1 − u) − (1 − u)² cross at u = ½, at −¾
    assert _tangent_bound(0.0, -1.0, 0.0, 1.0, 1.0, 2.0) == -0.75
    # s = u − u², C = 2: the parabolas are s itself, concave, least at the ends: the bound is s's minimum
    assert _tangent_bound(0.0, 1.0, 0.0, -1.0, 1.0, 2.0) == 0.0
    assert _tangent_bound(1.0, 0.5, 2.0, 0.5, 1.0, 0.0) == 1.0  # rising: the least value is at the start


@given(
    m=st.floats(1e-6, 5.0), dm=finite, d2m=finite, d3m=st.floats(-20.0, 20.0),
    extra_jerk=st.floats(0.0, 5.0), extra_curvature=st.floats(0.0, 5.0), reach=st.floats(1e-3, 3.0),
)  # fmt: skip
def test_a_local_safe_step_keeps_the_margin_positive(
    m: float, dm: float, d2m: float, d3m: float, extra_jerk: float, extra_curvature: float, reach: float
) -> None:
    # the cubic m + m′t + m″t²/2 + m‴t³/6 has |m‴| ≤ J and m″ ≥ −C on [0, reach] for J, C as below
    jerk = abs(d3m) + extra_jerk
    curvature = max(0.0, -min(d2m, d2m + d3m * reach)) + extra_curvature
    h = _local_safe_step(m, dm, d2m, curvature, jerk, reach)
    assert 0.0 < h <= reach
    t = _GRID[:-1] * h  # [0, h)
    values = m + dm * t + 0.5 * d2m * t * t + d3m * t**3 / 6.0
    assert values.min() > -1e-12 * (1.0 + m)


def test_a_local_safe_step_is_the_whole_reach_when_nothing_bends_down() -> None:
    assert _local_safe_step(1.0, 0.5, 2.0, 0.0, 0.0, 7.0) == 7.0
    # falling at 1 with no curvature: the step ends at the tangent's zero, m/|m′|
    assert _local_safe_step(2.0, -1.0, 0.0, 0.0, 0.0, 10.0) == 2.0


outside = st.one_of(st.floats(-5.0, -2.0), st.floats(3.0, 6.0))


@given(
    r1=st.floats(0.05, 0.95), r2=outside, r3=outside, scale=st.floats(0.5, 4.0),
    xa=st.floats(-5.0, 5.0), width=st.floats(1e-3, 10.0),
)  # fmt: skip
def test_the_hermite_start_is_the_root_of_a_cubic(
    r1: float, r2: float, r3: float, scale: float, xa: float, width: float
) -> None:
    # a cubic with one root at xa + r1·width inside the bracket, the others two widths away from it or more
    # (closer, a double root one width away, four steps from the secant are not yet the root: a start only)
    root = xa + r1 * width

    def f(x: float) -> float:
        u = (x - xa) / width
        return scale * (u - r1) * (u - r2) * (u - r3)

    def df(x: float) -> float:
        u = (x - xa) / width
        return scale * ((u - r2) * (u - r3) + (u - r1) * (u - r3) + (u - r1) * (u - r2)) / width

    xb = xa + width
    start = _hermite_start(xa, xb, f(xa), df(xa), f(xb), df(xb))
    assert xa < start < xb  # four Newton steps on the cubic from the secant's root: the root to rounding
    assert abs(start - root) <= 1e-10 * width


def test_the_hermite_start_lands_near_the_root_of_a_smooth_function() -> None:
    # sin on a bracket of its root at π: the cubic's root is within O(width⁴) of it
    for width in (0.5, 0.1, 0.02):
        xa, xb = math.pi - 0.3 * width, math.pi + 0.7 * width
        start = _hermite_start(xa, xb, math.sin(xa), math.cos(xa), math.sin(xb), math.cos(xb))
        assert abs(start - math.pi) <= 0.01 * width**4 + 1e-15
    assert math.isnan(_hermite_start(0.0, 1.0, 1.0, 0.0, 2.0, 0.0))  # no sign change: no root found


def _product_rows(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A random scene's N row (either law) and its two no-slip margins: rows in product form, and the scene row."""
    p = np.zeros(len(PARAMS))
    values = {
        "r0_m": 0.02, "rod_radius_m": 0.004, "eccentricity_m": rng.uniform(0.0005, 0.004), "g_m_s2": 9.81,
        "omega_r_rad_s": rng.uniform(2.0, 40.0), "omega_v_rad_s": rng.uniform(5.0, 150.0),
        "theta0_rad": rng.uniform(-math.pi, math.pi), "alpha0_rad": rng.uniform(0.0, 2.0 * math.pi), "n_rods": 1.0,
        "paper": float(rng.integers(0, 2)), "spring_per_mass_s2": rng.uniform(0.0, 4000.0), "rod_mass_kg": 0.05,
        "restitution": 0.5, "cam_to_vial_m": 0.05,
    }  # fmt: skip
    for name, value in values.items():
        p[PARAMS.index(name)] = value
    n_row = np.zeros((1, _TRIG_COLUMNS))
    _fill_trig_rows(p, 1, n_row)
    margins = _slip_rows(p, float(p[PARAMS.index("theta0_rad")]), rng.uniform(0.05, 2.0), np.zeros((2, _TRIG_COLUMNS)))
    return np.vstack([n_row, margins]), p


def test_the_product_certificate_holds_at_every_time_it_covers() -> None:
    rng = np.random.default_rng(40)
    covered = ends = 0
    for _ in range(300):
        tr, _ = _product_rows(rng)
        for i in range(3):
            arcs = _product_arcs(tr, i)
            t = rng.uniform(0.0, 2.0)
            until = _product_until(tr, i, t, arcs)
            if until <= t:
                continue
            covered += 1
            span = min(until, t + 4.0 * math.pi / tr[i, _TW]) - t  # two revolutions at most
            for tau in t + span * _GRID:
                assert _trig(tr, i, tau, 0, 1.0) > 0.0, (i, t, until, tau)
            if until < math.inf:
                ends += 1
    assert covered > 300 and ends > 200  # arcs certified, and most of them end


def test_the_product_certificate_ends_where_the_worst_cam_phase_reaches_zero() -> None:
    # at the end of a certified arc c − G·S is zero for the worst G: g + |κ| where S > 0, g − |κ| < 0 where S < 0
    rng = np.random.default_rng(41)
    tight = 0
    for _ in range(200):
        tr, _ = _product_rows(rng)
        for i in (0, 1):
            arcs = _product_arcs(tr, i)
            until = _product_until(tr, i, 0.0, arcs)
            if not 0.0 < until < math.inf:
                continue
            w, th0 = tr[i, _TW], tr[i, _T_TH0]
            u, v, g = (1.0, 0.0, tr[i, _TA]) if i == 0 else (tr[i, _T_U], tr[i, _T_V], tr[i, _T_G])
            theta = w * until + th0
            s = u * math.sin(theta) + v * math.cos(theta)
            worst = (g + abs(tr[i, _T_KAPPA])) * s if s > 0.0 else (g - abs(tr[i, _T_KAPPA])) * s
            assert abs(tr[i, 0] - worst) <= 1e-6 * tr[i, 0], (i, until)
            tight += 1
    assert tight > 50
