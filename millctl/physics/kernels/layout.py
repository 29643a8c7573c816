"""Array layouts of the compiled kernels, named: scene rows, result rows, rod states, trig sums, function codes.

A scene travels through the kernels as one row of :data:`PARAMS` (SI units), a result as one row of
:data:`OUT` (or :data:`TELEMETRY` for a level-(b) sample); each column has a named index (``_WR`` is
ω_r, ``_O_T`` the impact time, ...). A rod's state is a row of the ``_S_*`` columns; N(t)/m and the
slip margins are trig sums, rows of the ``_T*`` columns (:mod:`.trig`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

from millctl.config.models import ModelVariant
from millctl.physics.model import Scene

FloatArray = NDArray[np.float64]


def leaf_kernel(fn: Callable[..., Any]) -> Any:
    """``njit`` for a kernel that makes no array: cached, numpy's error model, no reference counting.

    Without numba's reference counting (``_nrt=False``) a call with array arguments, or a view taken of one,
    does not increment and decrement the array's count atomically (the package docstring). Such a kernel must
    not make an array, nor return one, nor call a kernel that returns one (that reference would never be
    released): it fills arrays it is given. Numba refuses to compile one that allocates.
    """
    return njit(cache=True, error_model="numpy", _nrt=False)(fn)  # type: ignore[call-overload]


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


# state columns of a rod: flying flag, t0, pinned angle at t0, x0, y0, ux0, uy0 (vial frame), n_d, sin α0, cos α0,
# of a held rod cos, sin of its angle carried back to t = 0, θ_pin − ω_r t0 (the contact scan turns it to any t),
# and its rate's offset from ω_r (0 carried; a sliding rod's slide step's mean rate − ω_r, physics.wall_slide),
# which a flight from the wall keeps as its departure rate's (the wall gap's triple root, motion._departure_gap)
(_S_FLY, _S_T0, _S_TH, _S_X, _S_Y, _S_UX, _S_UY, _S_ND, _S_SA, _S_CA, _S_PC, _S_PS, _S_DW) = range(13)


_STATE_COLUMNS = 13


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


# a trig sum c + Σ a_k cos(w_k t + φ_k) as a row: [c, number of terms, a_0..a_5, w_0..w_5, φ_0..φ_5], then
# its product form, if it has one (:func:`.trig._fill_trig_rows`, :func:`.telemetry._slip_rows`): _T_N_FORM 1.0 if
# the row is N/m = c − (g − κ sin α) sin θ, θ = ω_r t + θ0 and α = ω_v t + α0 (eq. 7's form, two sines and cosines
# an evaluation instead of three), 2.0 if it is a no-slip margin c − (g − κ sin α)(u sin θ + v cos θ) (the same
# G = g_eff = g − κ sin α, its g in _T_G), then κ, θ0, ω_v, α0, g, u, v
_T_COUNT, _TA, _TW, _TP = 1, 2, 8, 14
_T_N_FORM, _T_KAPPA, _T_TH0, _T_WV, _T_A0, _T_G, _T_U, _T_V = 20, 21, 22, 23, 24, 25, 26, 27
_FORM_N, _FORM_MARGIN = 1.0, 2.0


_TRIG_COLUMNS = 28


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


def scene_rows(scenes: list[Scene]) -> FloatArray:
    """Parameter rows of many scenes (shape (len(scenes), len(PARAMS)))."""
    return np.array([scene_row(s) for s in scenes]).reshape(len(scenes), len(PARAMS))


__all__ = ["OUT", "PARAMS", "TELEMETRY", "WALL", "FloatArray", "scene_row", "scene_rows"]
