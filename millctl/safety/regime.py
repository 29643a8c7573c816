"""Where the configured law stops being the every-cycle detachment bound: one answer, said once.

Printed eq. 9 takes sin α = −1 as the worst cam phase. That holds only while
k ≥ m(hω_v)²; above the switch speed ω_v = √(k/m)/h the worst phase is
sin α = +1 and eq. 9 becomes the paper's *most permissive* phase: rods may
stay pinned to the wall for many cycles even under the limit (docs/model.md,
errata of eq. 9). The best-phase law is never the every-cycle bound.

:func:`regime_warning` is the one function that says so, with the number:
``millctl limits`` (table and ``--plot``), the service's ``GET /v1/envelope``
and the TUI all take it from here, so they cannot disagree (they did: the TUI
showed the first point of its 7.5 rpm grid, 315 rpm, where ``limits`` said
307.8 rpm).
"""

from __future__ import annotations

from dataclasses import dataclass

from millctl.config.models import LimitLaw
from millctl.physics.limits import not_every_cycle_above_rad_s
from millctl.safety.envelope import Envelope
from millctl.units import rad_s_to_rpm

DOC_REF = "docs/model.md#eq-9"
EVERY_CYCLE_INSTEAD = LimitLaw.PAPER_EVERY_CYCLE
"""The law that is the every-cycle bound of the paper's own model everywhere (name it as the alternative)."""


@dataclass(frozen=True)
class RegimeWarning:
    """The configured law is not the every-cycle bound for ω_v above ``above_vibration_rpm``."""

    law: LimitLaw
    above_vibration_rpm: float
    """From this vibration speed up (rpm; 0: everywhere) the law is not the every-cycle bound."""
    vibration_max_rpm: float

    @property
    def summary(self) -> str:
        """One short line for a panel or a legend."""
        if self.above_vibration_rpm <= 0.0:
            return f"{self.law.value} is never the every-cycle bound"
        return f"above ω_v = {self.above_vibration_rpm:.1f} rpm {self.law.value} is not the every-cycle bound"

    @property
    def message(self) -> str:
        """The warning in full: where, why, what it means and what to read."""
        if self.above_vibration_rpm <= 0.0:
            where, why = "at every ω_v", "it bounds the most favourable cam phase only"
        else:
            where = f"above ω_v = {self.above_vibration_rpm:.1f} rpm (up to the drive's {self.vibration_max_rpm:.0f})"
            why = "there k < mω_v², so sin α = −1 is the most permissive cam phase, not the worst"
        return (
            f"the configured law {self.law.value} is not the every-cycle detachment bound {where}: {why}; "
            f"rods may stay pinned to the wall for many cycles there, even under the limit "
            f"({EVERY_CYCLE_INSTEAD.value} is the every-cycle bound). See {DOC_REF}."
        )

    def applies_at(self, omega_v_rpm: float) -> bool:
        """True where the warning applies (ω_v above the switch speed)."""
        return omega_v_rpm > self.above_vibration_rpm or self.above_vibration_rpm <= 0.0


def regime_warning(envelope: Envelope) -> RegimeWarning | None:
    """The warning for an envelope's law over the vibration drive's range, or None when there is nothing to say."""
    above_rad_s = not_every_cycle_above_rad_s(envelope.law, envelope.params)
    if above_rad_s is None:
        return None
    above_rpm = float(rad_s_to_rpm(above_rad_s))
    if above_rpm >= envelope.vibration_max_rpm:
        return None
    return RegimeWarning(envelope.law, above_rpm, envelope.vibration_max_rpm)


__all__ = ["DOC_REF", "RegimeWarning", "regime_warning"]
