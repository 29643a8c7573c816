"""Resuming an interrupted run: where it continues, what counts as done, and the pre-flight from the mill's state.

A run interrupted by a crash, a kill, a power loss or a service stop
(:mod:`millctl.recipes.history`) continues at the step it was in
(docs/operations.md#resume):

* a **hold** keeps the time it had done at its setpoints (``step_elapsed_s``
  of its last record: at most one sample period, ``service.run_sample_s``, is
  repeated) and, if it ends at a dose, the dose it had reached. Only time at
  the setpoints counts: the mill first ramps back to the hold's setpoints from
  the speeds and temperature measured now (the *restore*), and the hold's clock
  runs again once the drives are within the step's speed tolerance and the
  furnace within its band;
* a **ramp** interrupted mid-way is planned again from the measured speeds
  (the controller's standstill) and the measured furnace temperature to its
  own targets at its own rates; its time before the gap is not credited, since
  a ramp ends on reaching its target, not on time;
* a **wait_furnace** waits again, with its full timeout; a **pause** step
  restores its setpoints and waits for the operator again.

Nothing moves before the operator confirms and :func:`preflight_resume` finds
the mill ready: node seen, not tripped, drives standing still, and the restore
ramp and furnace target inside the envelope under the configuration in force.
"""

from __future__ import annotations

from dataclasses import dataclass

from millctl.controller import STANDSTILL_RPM, CommandRefused, Controller, ControllerState
from millctl.recipes.history import Gap, RunHistory, RunNotResumable
from millctl.recipes.plan import RecipePlan
from millctl.recipes.schema import HoldStep, LoadedRecipe, RampStep, Recipe, WaitFurnaceStep
from millctl.safety import InterlockRefused
from millctl.safety.ramps import SpeedPoint, Trajectory

S = ControllerState

RESTORE_FURNACE_MARGIN_S = 1_800.0
"""A restore waits for the furnace's band at most its heating ramp's time plus this long (s), then fails."""
RESTORE_SETTLE_S = 30.0
"""A restore's drives may take this long past the ramp's planned end to settle within tolerance (s)."""


@dataclass(frozen=True)
class Setpoints:
    """What the steps before one step left in force: drive targets and rates, furnace target and rate."""

    rotary_rpm: float = 0.0
    vibration_rpm: float = 0.0
    rotary_rate_rpm_s: float | None = None
    vibration_rate_rpm_s: float | None = None
    linear: bool = False
    furnace_c: float | None = None
    heating_rate_c_per_min: float | None = None

    @property
    def point(self) -> SpeedPoint:
        """The drive targets as a speed pair."""
        return SpeedPoint(self.rotary_rpm, self.vibration_rpm)


def setpoints_before(recipe: Recipe, index: int) -> Setpoints:
    """The setpoints in force when step ``index`` (0-based) starts: those of the ramps before it."""
    d = recipe.defaults
    held = Setpoints()
    for step in recipe.steps[:index]:
        if not isinstance(step, RampStep):
            continue
        furnace_c, heating = held.furnace_c, held.heating_rate_c_per_min
        if step.furnace_c is not None:
            furnace_c, heating = step.furnace_c, step.heating_rate_c_per_min or d.heating_rate_c_per_min
        held = Setpoints(step.rotary_rpm, step.vibration_rpm, step.rotary_rate_rpm_s or d.rotary_rate_rpm_s,
                         step.vibration_rate_rpm_s or d.vibration_rate_rpm_s, step.path == "linear", furnace_c,
                         heating)
    return held


@dataclass(frozen=True)
class ResumePoint:
    """Where a resumed run continues and what of its interrupted step counts as done."""

    run_id: str
    index: int
    """The step to continue (0-based); ``len(steps)`` when only the final stop was left."""
    credit_s: float
    """Time of the step credited as done (s): a hold's time at its setpoints, 0 for the other kinds."""
    dose_j_g: float
    """Dose of the step credited as done (J/g), for a dose-targeted hold."""
    run_s: float
    """Time the run was under way before the gap (s)."""
    run_dose_j_g: float
    """Specific energy dose of the run before the gap (J/g)."""
    started_unix: float
    gaps_before_s: float
    """The run's earlier gaps (s)."""
    gap: Gap
    """The gap being closed (its end is the resume)."""
    restore: Setpoints
    """The setpoints to bring back before the step continues (a ramp step: its furnace target before it)."""


def resume_point(history: RunHistory, loaded: LoadedRecipe) -> ResumePoint:
    """Where ``history``'s run continues in its recipe; :class:`RunNotResumable` when it cannot."""
    if history.ended is not None:
        raise RunNotResumable(f"run {history.run_id} {history.reason}: only an interrupted run can be resumed")
    steps = loaded.recipe.steps
    if len(steps) != history.steps:
        raise RunNotResumable(f"run {history.run_id}: its record names {history.steps} steps, the recipe has "
                              f"{len(steps)}")
    index = min(history.step - 1, len(steps))
    credit_s = dose_j_g = 0.0
    if index < len(steps) and history.step_started and isinstance(steps[index], HoldStep):
        credit_s, dose_j_g = history.step_elapsed_s, history.step_dose_j_g
    return ResumePoint(history.run_id, index, credit_s, dose_j_g, history.run_s, history.run_dose_j_g,
                       history.started_unix, history.gap_s, history.open_gap, setpoints_before(loaded.recipe, index))


def check_unchanged(history: RunHistory, loaded: LoadedRecipe, config_sha256: str) -> None:
    """Refuse a recipe text whose hash differs from the record's, or a configuration that changed since."""
    if loaded.sha256 != history.recipe_sha256:
        raise RunNotResumable(
            f"run {history.run_id}: the recipe changed (sha256 {loaded.sha256[:12]}… now, "
            f"{history.recipe_sha256[:12]}… when the run started): a run resumes only with the recipe it started "
            "with; start the changed recipe as a new run"
        )
    if config_sha256 != history.config_sha256:
        raise RunNotResumable(
            f"run {history.run_id}: the configuration changed (sha256 {config_sha256[:12]}… now, "
            f"{history.config_sha256[:12]}… when the run started): its envelope may differ; restore that "
            "configuration to resume, or start the recipe as a new run"
        )


class Restore:
    """Brings the mill back to a step's setpoints after a gap, from the measured values; the step waits for it.

    Done once the ramp has ended, both drives are within ``speed_tol_rpm`` of
    their targets and, with a furnace target and a ``furnace_band_c``, the
    furnace's setpoint has reached the target and its measured temperature is
    within the band. Past its deadline it raises :class:`CommandRefused` (the
    run then fails with a controlled stop).
    """

    def __init__(self, target: Setpoints, speed_tol_rpm: float, furnace_band_c: float | None) -> None:
        self.target = target
        self.speed_tol_rpm = speed_tol_rpm
        self.furnace_band_c = furnace_band_c if target.furnace_c is not None else None
        self.deadline_s = 0.0

    def begin(self, c: Controller, source: str) -> None:
        """Plan the ramp from the controller's standstill and the furnace from its measured temperature; start both."""
        t = self.target
        rate = t.heating_rate_c_per_min or c.config.furnace.max_heating_rate_c_per_min
        move = c.set_speeds(t.rotary_rpm, t.vibration_rpm, rotary_rate_rpm_s=t.rotary_rate_rpm_s,
                            vibration_rate_rpm_s=t.vibration_rate_rpm_s, linear=t.linear, furnace_c=t.furnace_c,
                            heating_rate_c_per_min=None if t.furnace_c is None else rate, source=source)
        bound_s = move.duration_s + RESTORE_SETTLE_S
        if t.furnace_c is not None and self.furnace_band_c is not None:
            heat_s = abs(t.furnace_c - c.furnace_setpoint_c) / rate * 60.0
            bound_s = max(bound_s, heat_s + RESTORE_FURNACE_MARGIN_S)
        self.deadline_s = c.clock.now() + bound_s

    def done(self, c: Controller) -> bool:
        """True once the mill is back at the setpoints; :class:`CommandRefused` past the deadline."""
        t = self.target
        measured, furnace = c.measured, c.furnace
        speeds = (c.trajectory is None and measured is not None
                  and abs(measured.rotary_rpm - t.rotary_rpm) <= self.speed_tol_rpm
                  and abs(measured.vibration_rpm - t.vibration_rpm) <= self.speed_tol_rpm)
        heat = (t.furnace_c is None or self.furnace_band_c is None
                or (c.furnace_setpoint_c == t.furnace_c and furnace is not None
                    and abs(furnace.temp_c - t.furnace_c) <= self.furnace_band_c))
        if speeds and heat:
            return True
        if c.clock.now() > self.deadline_s:
            shown = "none" if measured is None else f"{measured.rotary_rpm:.1f} / {measured.vibration_rpm:.1f} rpm"
            temp = "" if t.furnace_c is None or furnace is None else f", furnace {furnace.temp_c:.1f} °C"
            raise CommandRefused(f"the mill did not come back to the step's setpoints ({t.rotary_rpm:.1f} / "
                                 f"{t.vibration_rpm:.1f} rpm" + ("" if t.furnace_c is None else
                                 f", {t.furnace_c:.1f} ± {self.furnace_band_c} °C") +
                                 f") in time after the resume: measured {shown}{temp}")
        return False


@dataclass(frozen=True)
class ResumeCheck:
    """The pre-flight of a resume from the mill's state now: what would happen first, and what stops it."""

    problems: tuple[str, ...]
    restore: str
    """The restore in words: from the measured values to the step's setpoints."""
    restore_s: float
    """Expected time of the restore ramps (s)."""

    @property
    def ok(self) -> bool:
        """True when nothing stops the resume."""
        return not self.problems


def preflight_resume(point: ResumePoint, loaded: LoadedRecipe, plan: RecipePlan, c: Controller) -> ResumeCheck:
    """Check the mill's actual state for a resume (in the control loop): every problem, and the restore planned."""
    problems: list[str] = []
    if not plan.ok:
        problems.extend(f"pre-flight: {v}" for v in plan.violations)
    state = c.state
    if state is S.DISCONNECTED:
        problems.append("the node is not seen on the bus: nothing can be commanded")
    elif state is S.TRIPPED:
        problems.append(f"the controller is TRIPPED ({c.trip_cause}): find the cause, `millctl reset`, then resume")
    elif state not in (S.DISABLED, S.ARMED):
        problems.append(f"the mill is {state}: stop it (`millctl stop`) and resume at standstill")
    measured = c.measured
    if measured is None:
        problems.append("no drive telemetry yet: the restore must start from measured speeds")
    elif max(abs(measured.rotary_rpm), abs(measured.vibration_rpm)) > STANDSTILL_RPM:
        problems.append(f"the drives are turning (measured ω_r {measured.rotary_rpm:.1f} rpm, ω_v "
                        f"{measured.vibration_rpm:.1f} rpm; standstill is ≤ {STANDSTILL_RPM:g} rpm): stop the mill")
    steps = loaded.recipe.steps
    step = steps[point.index] if point.index < len(steps) else None
    target = point.restore
    move: Trajectory | None = None
    words = []
    if isinstance(step, RampStep):
        d = loaded.recipe.defaults
        target = Setpoints(step.rotary_rpm, step.vibration_rpm, step.rotary_rate_rpm_s or d.rotary_rate_rpm_s,
                           step.vibration_rate_rpm_s or d.vibration_rate_rpm_s, step.path == "linear",
                           step.furnace_c if step.furnace_c is not None else target.furnace_c,
                           (step.heating_rate_c_per_min or d.heating_rate_c_per_min)
                           if step.furnace_c is not None else target.heating_rate_c_per_min)
    if step is not None:
        try:
            plan_move = c.planner.plan_linear if target.linear else c.planner.plan
            move = plan_move(c.commanded, target.point, target.rotary_rate_rpm_s, target.vibration_rate_rpm_s)
        except InterlockRefused as refused:
            problems.append(f"the ramp back to step {point.index + 1}'s setpoints is refused: {refused}")
    restore_s = move.duration_s if move is not None else 0.0
    from_r = measured.rotary_rpm if measured is not None else 0.0
    from_v = measured.vibration_rpm if measured is not None else 0.0
    if move is not None:
        words.append(f"ramp from the measured ω_r {from_r:.1f} / ω_v {from_v:.1f} rpm to "
                     f"{target.rotary_rpm:.1f} / {target.vibration_rpm:.1f} rpm ({move.duration_s:.1f} s)")
    if step is not None and target.furnace_c is not None:
        rate = target.heating_rate_c_per_min or c.config.furnace.max_heating_rate_c_per_min
        for verdict in (c.envelope.check(0.0, 0.0, target.furnace_c), c.envelope.check_heating_rate(rate)):
            if not verdict.ok:
                problems.append(f"furnace target {target.furnace_c:.1f} °C at {rate:.1f} °C/min: {verdict.reason()}")
        furnace = c.furnace
        if furnace is None:
            problems.append("no furnace telemetry yet: the furnace ramp must start from the measured temperature")
        else:
            heat_s = abs(target.furnace_c - furnace.temp_c) / rate * 60.0
            restore_s = max(restore_s, heat_s)
            words.append(f"furnace from the measured {furnace.temp_c:.1f} °C to {target.furnace_c:.1f} °C at "
                         f"{rate:.1f} °C/min ({heat_s:.0f} s)")
    if step is None:
        then = "then the final stop (every step had ended)"
    elif isinstance(step, HoldStep):
        done = (f"{point.dose_j_g * 1e-3:.4g} of {step.dose_kj_g:g} kJ/g" if step.dose_kj_g is not None
                else f"{point.credit_s:.1f} of {step.seconds:.1f} s")
        then = f"then step {point.index + 1} (hold) continues with {done} done, counted at its setpoints"
    elif isinstance(step, RampStep):
        then = f"step {point.index + 1} (ramp) runs again from there"
    elif isinstance(step, WaitFurnaceStep):
        then = f"then step {point.index + 1} (wait_furnace) waits again, full timeout"
    else:
        then = f"then step {point.index + 1} (pause) waits for the operator again"
    return ResumeCheck(tuple(problems), "; ".join([*words, then]), restore_s)


__all__ = [
    "RESTORE_FURNACE_MARGIN_S",
    "RESTORE_SETTLE_S",
    "Restore",
    "ResumeCheck",
    "ResumePoint",
    "Setpoints",
    "check_unchanged",
    "preflight_resume",
    "resume_point",
    "setpoints_before",
]
