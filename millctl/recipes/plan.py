"""Pre-flight a recipe: the timeline of every step, and every place it would leave the envelope.

The same :class:`~millctl.safety.ramps.RampPlanner` and
:class:`~millctl.safety.Envelope` that run the mill check the whole planned
trajectory here, ramps and the final stop included, so that a recipe that
passes ``millctl recipe check`` is one the controller will not refuse.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from millctl.config.models import MillConfig
from millctl.physics.dose import dose_rate_j_g_s
from millctl.physics.model import MillModel
from millctl.physics.telemetry import RevolutionSummary, revolution_summary
from millctl.recipes.schema import HoldStep, PauseStep, RampStep, Recipe, WaitFurnaceStep
from millctl.safety import InterlockRefused, Verdict
from millctl.safety.ramps import STANDSTILL, RampPlanner, SpeedPoint, Trajectory
from millctl.units import rpm_to_rad_s


@dataclass(frozen=True)
class Violation:
    """One place a recipe leaves the envelope: step, time, value, limit and law."""

    step: int
    """1-based step number; 0 for the final stop."""
    time_s: float
    """Time from the start of the recipe (s)."""
    quantity: str
    value: float
    limit: float
    message: str

    def __str__(self) -> str:
        where = "final stop" if self.step == 0 else f"step {self.step}"
        return f"{where} at t = {self.time_s:.1f} s: {self.message}"


@dataclass(frozen=True)
class StepPlan:
    """Where one step starts, how long it takes, and what it asks for."""

    index: int
    kind: str
    start_s: float
    duration_s: float
    open_ended: bool
    """True when the duration depends on the mill or the operator (pause, wait_furnace)."""
    target: SpeedPoint
    furnace_c: float | None
    min_margin_rpm: float
    trajectory: Trajectory | None = None
    note: str = ""
    physics: RevolutionSummary | None = None
    """What the physics model expects at the step's setpoints (level-(b) summary)."""
    dose_kj_g: float = 0.0
    """Expected specific energy dose of the step (kJ per g of powder)."""
    dose_target_kj_g: float | None = None
    """The dose the step mills to (a dose-targeted hold), else None."""


@dataclass(frozen=True)
class RecipePlan:
    """The whole pre-flighted recipe."""

    steps: tuple[StepPlan, ...]
    stop: Trajectory
    violations: tuple[Violation, ...]
    law: str
    margin: float
    notes: tuple[str, ...] = field(default=())
    powder_charge_g: float = math.nan
    """Powder in the vial (g) the doses are per gram of."""
    variant: str = "paper"
    """Physics variant of the steps' summaries: the paper's reports eq. 18 per rod, the corrected one per mill."""
    n_rods: int = 1
    """Rods in the mill: the whole mill's impact rate (the doses') is n × one rod's."""

    @property
    def ok(self) -> bool:
        """True when no step leaves the envelope."""
        return not self.violations

    @property
    def total_dose_kj_g(self) -> float:
        """Expected specific energy dose of the whole recipe (kJ/g)."""
        return sum(s.dose_kj_g for s in self.steps)

    @property
    def total_s(self) -> float:
        """Total planned time (s), the final stop included; open-ended steps count as 0."""
        return (self.steps[-1].start_s + self.steps[-1].duration_s if self.steps else 0.0) + self.stop.duration_s


def _violations(step: int, t_s: float, verdict: Verdict) -> list[Violation]:
    return [Violation(step, t_s, r.quantity, r.value, r.limit, r.reason) for r in verdict.refusals]


class _Walker:
    """Walks the steps, tracking setpoints and time, collecting violations."""

    def __init__(self, recipe: Recipe, config: MillConfig) -> None:
        self.recipe = recipe
        self.planner = RampPlanner.from_config(config)
        self.envelope = self.planner.envelope
        self.t_s = 0.0
        self.point = STANDSTILL
        self.furnace_c: float | None = None
        self.ambient_c = config.furnace.ambient_temp_c
        self.violations: list[Violation] = []
        self.steps: list[StepPlan] = []
        self.model = MillModel.from_config(config)
        self._physics: dict[SpeedPoint, RevolutionSummary] = {}
        self.powder_g = recipe.recipe.powder_charge_g or config.mill.powder.charge_g

    def physics(self, point: SpeedPoint) -> RevolutionSummary:
        """The expected per-revolution physics at a speed pair (cached per pair)."""
        if point not in self._physics:
            self._physics[point] = revolution_summary(
                self.model, rpm_to_rad_s(point.omega_r_rpm), rpm_to_rad_s(point.omega_v_rpm)
            )
        return self._physics[point]

    def dose_rate_j_g_s(self, point: SpeedPoint) -> float:
        """Expected specific energy dose rate at a speed pair (J/g/s)."""
        return dose_rate_j_g_s(self.model, self.physics(point), self.powder_g)

    def ramp(self, index: int, step: RampStep) -> None:
        defaults = self.recipe.defaults
        rate_r = step.rotary_rate_rpm_s or defaults.rotary_rate_rpm_s
        rate_v = step.vibration_rate_rpm_s or defaults.vibration_rate_rpm_s
        target = self.planner.snap(SpeedPoint(step.rotary_rpm, step.vibration_rpm))
        move: Trajectory | None = None
        try:
            if step.path == "linear":
                move = self.planner.plan_linear(self.point, target, rate_r, rate_v)
            else:
                move = self.planner.plan(self.point, target, rate_r, rate_v)
        except InterlockRefused as refused:
            self.violations.extend(_violations(index, self.t_s, refused.verdict))
            # report with the message that says where on a linear ramp it crossed
            if step.path == "linear" and refused.verdict.refusals:
                last = self.violations.pop()
                self.violations.append(Violation(index, self.t_s, last.quantity, last.value, last.limit, str(refused)))
        duration = move.duration_s if move is not None else 0.0
        if step.furnace_c is not None:
            duration = max(duration, self._furnace(index, step))
        margin = move.min_margin_rpm(self.envelope) if move is not None else -math.inf
        # the speeds move for the trajectory's time (trapezoid of the end rates), then sit at the target
        moving_s = move.duration_s if move is not None else 0.0
        rate_from, rate_to = self.dose_rate_j_g_s(self.point), self.dose_rate_j_g_s(target)
        dose_j_g = 0.5 * (rate_from + rate_to) * moving_s + rate_to * (duration - moving_s)
        self.steps.append(
            StepPlan(
                index,
                "ramp",
                self.t_s,
                duration,
                False,
                target,
                self.furnace_c,
                margin,
                move,
                step.note,
                self.physics(target),
                dose_j_g * 1e-3,
            )
        )
        self.t_s += duration
        self.point = target

    def _furnace(self, index: int, step: RampStep) -> float:
        assert step.furnace_c is not None
        rate = step.heating_rate_c_per_min or self.recipe.defaults.heating_rate_c_per_min
        rate = rate or self.envelope.max_heating_rate_c_per_min
        self.violations.extend(_violations(index, self.t_s, self.envelope.check(0.0, 0.0, step.furnace_c)))
        self.violations.extend(_violations(index, self.t_s, self.envelope.check_heating_rate(rate)))
        start_c = self.ambient_c if self.furnace_c is None else self.furnace_c
        self.furnace_c = step.furnace_c
        return abs(step.furnace_c - start_c) / rate * 60.0

    def dose_hold(self, index: int, step: HoldStep) -> None:
        """A hold that ends at a dose: its duration is the dose over the expected dose rate at the setpoints."""
        assert step.dose_kj_g is not None
        rate = self.dose_rate_j_g_s(self.point)
        if rate <= 0.0:
            at = f"{self.point.omega_r_rpm:.0f}/{self.point.omega_v_rpm:.0f} rpm"
            self.violations.append(
                Violation(
                    index,
                    self.t_s,
                    "dose",
                    0.0,
                    step.dose_kj_g,
                    f"mill until {step.dose_kj_g:g} kJ/g at {at}: the model expects no impacts there "
                    "(rods pinned or standing still), so the step would never end (docs/operations.md#dose-steps)",
                )
            )
            self.fixed(index, "hold", 0.0, True, step.note, step.dose_kj_g)
            return
        self.fixed(index, "hold", step.dose_kj_g * 1e3 / rate, False, step.note, step.dose_kj_g)

    def fixed(
        self, index: int, kind: str, duration_s: float, open_ended: bool, note: str, dose_target: float | None = None
    ) -> None:
        margin = float(self.envelope.check(self.point.omega_r_rpm, self.point.omega_v_rpm).margin_rpm)
        if self.point.omega_r_rpm == 0.0:
            margin = math.inf
        self.steps.append(
            StepPlan(
                index,
                kind,
                self.t_s,
                duration_s,
                open_ended,
                self.point,
                self.furnace_c,
                margin,
                None,
                note,
                self.physics(self.point),
                self.dose_rate_j_g_s(self.point) * duration_s * 1e-3,
                dose_target,
            )
        )
        self.t_s += duration_s

    def walk(self) -> RecipePlan:
        for index, step in enumerate(self.recipe.steps, start=1):
            if isinstance(step, RampStep):
                self.ramp(index, step)
            elif isinstance(step, HoldStep):
                seconds = step.seconds
                if seconds is None:
                    self.dose_hold(index, step)
                else:
                    self.fixed(index, "hold", seconds, False, step.note)
            elif isinstance(step, WaitFurnaceStep):
                if self.furnace_c is None:
                    self.violations.append(
                        Violation(
                            index,
                            self.t_s,
                            "furnace_temp",
                            math.nan,
                            math.nan,
                            "wait_furnace with no furnace setpoint: an earlier ramp must set furnace_c",
                        )
                    )
                self.fixed(index, "wait_furnace", 0.0, True, step.note or f"until within ±{step.band_c} °C")
            elif isinstance(step, PauseStep):
                self.fixed(index, "pause", 0.0, True, step.message)
        stop = self.planner.plan_stop(self.point)
        return RecipePlan(
            steps=tuple(self.steps),
            stop=stop,
            violations=tuple(self.violations),
            law=self.envelope.law.value,
            margin=self.envelope.margin,
            powder_charge_g=self.powder_g,
            variant=self.model.variant.value,
            n_rods=self.model.n_rods,
        )


def plan_recipe(recipe: Recipe, config: MillConfig) -> RecipePlan:
    """Pre-flight a recipe against a configured mill: timeline, margins and every violation."""
    return _Walker(recipe, config).walk()


__all__ = ["RecipePlan", "StepPlan", "Violation", "plan_recipe"]
