"""A dose step's specific energy (J/g): integrated from the node's physics telemetry while the run runs.

The whole mill's impact rate (:func:`~millctl.physics.dose.whole_mill_rate_hz`:
the node reports one rod's) times the energy per impact, per gram of powder
charged, integrated over the step's running time; a step whose dose does not
come within twice its planned time fails (the node may not be reporting
impacts). docs/operations.md#dose-steps.
"""

from __future__ import annotations

from millctl.config.models import ModelVariant
from millctl.controller import CommandRefused, Controller
from millctl.physics.dose import whole_mill_rate_hz
from millctl.protocol import PhysicsTelemetry
from millctl.recipes.schema import HoldStep

SETTLE_TIMEOUT_S = 30.0
"""How long after its planned end a step may take to settle within tolerance, or to reach its dose (s)."""


class StepDose:
    """The current step's dose so far (J/g), and the instant it was last integrated to (s)."""

    def __init__(self, controller: Controller, powder_charge_g: float, now_s: float) -> None:
        self.controller = controller
        self.powder_charge_g = powder_charge_g
        self.j_g = 0.0
        """Specific energy dose of the current step so far (J/g)."""
        self.clock_s = now_s
        """Integrated up to here (s); moved on without integrating while the run is paused."""

    def restart(self, now_s: float, j_g: float = 0.0) -> None:
        """A step begins (or resumes with ``j_g`` credited): integrate from ``now_s``."""
        self.j_g, self.clock_s = j_g, now_s

    def rate_j_g_s(self) -> float:
        """The node's current specific energy dose rate (J/g/s): its impact rate × energy per gram of powder."""
        last = self.controller.tracker.tracks[PhysicsTelemetry].last
        if not isinstance(last, PhysicsTelemetry) or not last.detached:
            return 0.0
        config = self.controller.config
        rate = whole_mill_rate_hz(ModelVariant(config.model.variant), config.mill.rods.count, last.impact_rate_hz)
        return rate * last.impact_energy_mj * 1e-3 / self.powder_charge_g

    def reached(self, step: HoldStep, now_s: float, elapsed_s: float, running: bool, planned_s: float) -> bool:
        """Integrate while ``running``; True at the step's dose. Raises past twice the planned time."""
        assert step.dose_kj_g is not None
        if running:
            self.j_g += self.rate_j_g_s() * max(now_s - self.clock_s, 0.0)
        self.clock_s = now_s
        if self.j_g >= step.dose_kj_g * 1e3:
            return running
        if elapsed_s > 2.0 * planned_s + SETTLE_TIMEOUT_S:
            raise CommandRefused(
                f"dose step: {self.j_g * 1e-3:.4g} of {step.dose_kj_g:g} kJ/g after {elapsed_s:.0f} s, "
                f"more than twice the planned {planned_s:.0f} s (is the node reporting impacts?)"
            )
        return False


__all__ = ["SETTLE_TIMEOUT_S", "StepDose"]
