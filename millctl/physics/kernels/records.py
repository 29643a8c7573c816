"""Kernel result rows (:data:`.layout.OUT`) into the batch API's records (:data:`millctl.physics.batch.BATCH_DTYPE`).

One compiled pass, field by field and row by row, instead of numpy's per-field copies into a packed
structured array with their masks and casts (``python -m bench``'s batch figures go through this).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from millctl.physics.kernels.layout import (
    _O_ALD,
    _O_BACKED,
    _O_ENERGY,
    _O_FOUND,
    _O_PARTNER,
    _O_ROD,
    _O_SPEED,
    _O_T,
    _O_TD0,
    _O_TDEP,
    _O_THD,
    _O_VN,
    _O_VT,
    _O_X,
    _O_Y,
    _O_ZERO,
)


@njit(cache=True, error_model="numpy")
def _count(value):  # type: ignore[no-untyped-def]
    """A rod index or a count as int32, −1 where the kernel left nan (no impact)."""
    return np.int32(value) if math.isfinite(value) else np.int32(-1)


@njit(cache=True, error_model="numpy")
def records_into(raw, out):  # type: ignore[no-untyped-def]
    """Row k of ``raw`` (kernel columns) into record k of ``out`` (BATCH_DTYPE); flight time = impact − departure."""
    for k in range(raw.shape[0]):
        r, o = raw[k], out[k]
        o["found"] = r[_O_FOUND] == 1.0
        o["time_s"] = r[_O_T]
        o["rod"] = _count(r[_O_ROD])
        o["partner"] = _count(r[_O_PARTNER])
        o["x_m"], o["y_m"] = r[_O_X], r[_O_Y]
        o["normal_velocity_m_s"], o["tangential_velocity_m_s"] = r[_O_VN], r[_O_VT]
        o["speed_abs_m_s"], o["energy_j"] = r[_O_SPEED], r[_O_ENERGY]
        o["backed"] = r[_O_BACKED] == 1.0
        o["depart_time_s"] = r[_O_TDEP]
        o["flight_time_s"] = r[_O_T] - r[_O_TDEP]
        o["theta_d_rad"], o["alpha_d_rad"] = r[_O_THD], r[_O_ALD]
        o["first_detach_time_s"] = r[_O_TD0]
        o["zero_length_flights"] = _count(r[_O_ZERO])


__all__ = ["records_into"]
