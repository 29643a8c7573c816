"""The specific energy dose: impact energy delivered per gram of powder (J/g), and its rate (J/g/s).

The dose rate is the milling power per gram, n·p·ω_r/2π × Ē / m_powder, with
the whole mill's impact rate (eq. 18 corrected: every rod impacts) and the
mean impact energy Ē of the model's variant (eq. 19 printed, or the corrected
½ m_eff (1 − e²) v_n²). The paper's variant reports eq. 18 per rod as
printed, so its rate is multiplied by n here: both variants count the same
impacts. Recipes plan with it (``recipe plan``) and the runner integrates it
from the node's physics telemetry to end a step at its dose.
"""

from __future__ import annotations

import math

from millctl.config.models import ModelVariant
from millctl.physics.model import MillModel
from millctl.physics.telemetry import RevolutionSummary


def whole_mill_rate_hz(variant: ModelVariant, n_rods: int, reported_rate_hz: float) -> float:
    """The whole mill's impact rate (Hz) from a rate reported by a summary or the node in ``variant``."""
    return reported_rate_hz * n_rods if variant is ModelVariant.PAPER else reported_rate_hz


def milling_power_w(model: MillModel, summary: RevolutionSummary) -> float:
    """Impact energy delivered per second by the whole mill (W)."""
    if not summary.detached:
        return 0.0
    rate = whole_mill_rate_hz(model.variant, model.n_rods, summary.impact_rate_hz)
    return rate * summary.mean_impact_energy_j


def dose_rate_j_g_s(model: MillModel, summary: RevolutionSummary, powder_g: float) -> float:
    """Specific energy dose rate (J per g of powder per s)."""
    power = milling_power_w(model, summary)
    return power / powder_g if math.isfinite(power) else 0.0


__all__ = ["dose_rate_j_g_s", "milling_power_w", "whole_mill_rate_hz"]
