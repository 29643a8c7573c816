"""Samples of a recipe run for its record: what the mill did, at a configurable rate (``service.run_sample_s``).

Each sample holds the setpoints and measured speeds, the enforced limit at
the measured ω_v and the margin of the measured ω_r to it, the furnace temperature and its setpoint, the node's impact
rate and energy, and the specific energy dose accumulated since the run
started (J/g; integrated every tick, not only at samples). ``millctl report``
draws them (:mod:`millctl.report`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from millctl.controller import Controller
from millctl.controller.status import build_status

DEFAULT_SAMPLE_S = 1.0
"""A sample a second: an 8 h run records ~29 000 lines (~10 MB)."""


class RunSampler:
    """Decides when a sample is due and integrates the dose between samples."""

    def __init__(self, period_s: float, dose_rate_j_g_s: Callable[[], float], start_s: float) -> None:
        if not period_s > 0.0:
            raise ValueError(f"sample period {period_s} s must be > 0 (service.run_sample_s)")
        self.period_s = period_s
        self.dose_rate_j_g_s = dose_rate_j_g_s
        self.start_s = start_s
        self.dose_j_g = 0.0
        """Specific energy dose since the run started (J per g of powder)."""
        self._last_s = start_s
        self._next_s = start_s
        self.extra: Callable[[], dict[str, Any]] | None = None
        """More fields for every sample (the service's loop lateness, SAFETY 27), or None."""

    def due(self, controller: Controller, now_s: float) -> dict[str, Any] | None:
        """Integrate the dose to ``now_s``; return a sample when one is due (else None)."""
        self.dose_j_g += self.dose_rate_j_g_s() * max(now_s - self._last_s, 0.0)
        self._last_s = now_s
        if now_s < self._next_s:
            return None
        self._next_s = max(self._next_s + self.period_s, now_s)  # never a burst to catch up after a stall
        row = sample(controller, now_s - self.start_s, self.dose_j_g)
        if self.extra is not None:
            row.update(self.extra())
        return row


def sample(controller: Controller, t_s: float, dose_j_g: float) -> dict[str, Any]:
    """One sample of the mill's state, ``t_s`` into the run."""
    s = build_status(controller)
    # the limit at the measured ω_v, as the measured-speed interlock sees it (the status's is at the commanded ω_v,
    # which drops to 0 at the first instant of a controlled stop while the drives are still turning)
    w_v = s.measured_vibration_rpm if s.measured_vibration_rpm is not None else s.setpoint_vibration_rpm
    w_r = s.measured_rotary_rpm if s.measured_rotary_rpm is not None else s.setpoint_rotary_rpm
    limit = float(controller.envelope.omega_r_limit_rpm(w_v))
    return {
        "t_s": t_s,
        "state": s.state,
        "setpoint_rotary_rpm": s.setpoint_rotary_rpm,
        "setpoint_vibration_rpm": s.setpoint_vibration_rpm,
        "measured_rotary_rpm": s.measured_rotary_rpm,
        "measured_vibration_rpm": s.measured_vibration_rpm,
        "limit_rotary_rpm": limit if math.isfinite(limit) else None,
        "margin_rpm": limit - w_r if math.isfinite(limit) else None,
        "furnace_temp_c": s.furnace_temp_c,
        "furnace_setpoint_c": s.furnace_setpoint_c,
        "impact_rate_hz": s.impact_rate_hz,
        "impact_energy_mj": s.impact_energy_mj,
        "dose_j_g": dose_j_g,
    }


__all__ = ["DEFAULT_SAMPLE_S", "RunSampler", "sample"]
