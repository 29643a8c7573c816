"""Run a pre-flighted recipe on a controller, step by step, with pause, resume, abort and a run record.

The runner lives in the controller service's loop (hours-long runs survive a
closed terminal) and is stepped by :meth:`RecipeRunner.tick` after the
controller's own tick. It never talks to the bus: every move goes through the
:class:`~millctl.controller.Controller`, so the interlock applies to recipes
exactly as to an operator. Stop and abort are the controller's controlled
stop; a trip ends the run as failed with its cause.

Run states::

    STARTING → RUNNING ⇄ PAUSED / HELD → STOPPING → DONE | ABORTED
                  └──────────── trip ───────────────→ FAILED
    (any unfinished state) ── service stopping ──→ INTERRUPTED (resumable)

A run interrupted by a service stop, a crash or a reboot is resumed by a new
runner built with a :class:`~millctl.recipes.resume.ResumePoint`: it appends
to the same record, writes the ``gap``, brings the mill back to the step's
setpoints from the measured values (:class:`~millctl.recipes.resume.Restore`)
and continues the step with the time it had done (docs/operations.md#resume).
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any

from millctl import __version__
from millctl.api import RunState
from millctl.clock import Clock
from millctl.controller import CommandRefused, Controller, ControllerState
from millctl.errors import InterlockError
from millctl.recipes.history import RUNS_DIR, RunLock, new_run_id
from millctl.recipes.plan import RecipePlan, StepPlan
from millctl.recipes.resume import Restore, ResumePoint
from millctl.recipes.samples import DEFAULT_SAMPLE_S, RunSampler
from millctl.recipes.schema import HoldStep, LoadedRecipe, PauseStep, RampStep, Step, Tolerances, WaitFurnaceStep
from millctl.recipes.step_dose import SETTLE_TIMEOUT_S, StepDose
from millctl.records import RecordQueue, RecordWriter

log = logging.getLogger(__name__)

S = ControllerState

ARM_TIMEOUT_S = 5.0
"""How long the runner waits for the node to arm before the run fails (s)."""

STANDSTILL_RPM = 1.0


FINAL = frozenset(s for s in RunState if s.final)
"""The states a run ends in."""


class RecipeRunner:
    """One run of one recipe on one controller."""

    def __init__(
        self,
        controller: Controller,
        loaded: LoadedRecipe,
        plan: RecipePlan,
        clock: Clock,
        *,
        records_dir: Path,
        config_sha256: str,
        source: str = "recipe",
        records: RecordQueue | None = None,
        sample_s: float = DEFAULT_SAMPLE_S,
        run_id: str | None = None,
        text: str | None = None,
        lock: RunLock | None = None,
        resume: ResumePoint | None = None,
        torn_bytes: int = 0,
    ) -> None:
        if not plan.ok:
            raise InterlockError(f"recipe {loaded.source} does not pass its pre-flight: {plan.violations[0]}")
        self.controller = controller
        self.loaded = loaded
        self.plan = plan
        self.clock = clock
        self.source = source
        self.run_id = resume.run_id if resume is not None else run_id or new_run_id()
        self.lock = lock
        self.resumed = resume
        self._restore: Restore | None = None
        self._ramp_planned_s: float | None = None
        """The issued ramp's time from where the mill was (a resumed ramp starts from standstill: longer)."""
        self._run_s_before = 0.0 if resume is None else resume.run_s
        self._gap_s = 0.0 if resume is None else resume.gaps_before_s
        self._t_offset_s = 0.0 if resume is None else time.time() - resume.started_unix
        """Time from the run's first start to this segment's start, gaps included (s): ``t_s`` of its records."""
        self.state = RunState.STARTING
        self.reason = ""
        self.index = 0
        """0-based index of the current step; len(steps) once past the last."""
        self._started_s = clock.now()
        self._step_started_s = clock.now()
        self._step_elapsed_s = 0.0
        self._step_begun = False
        self._begun_index = -1
        """Index of the step whose start was recorded (a boundary pause defers it)."""
        self._pause_at_boundary = False
        self._arm_sent = False
        self._finish_as = RunState.DONE
        self.dose = StepDose(controller, plan.powder_charge_g, clock.now())
        """The current step's dose (J/g), from the node's physics telemetry."""
        self.sampler = RunSampler(sample_s, self.dose.rate_j_g_s, clock.now() - self._t_offset_s)
        self.record = RecordWriter(Path(records_dir) / RUNS_DIR, self.run_id, rotate_bytes=1 << 30, keep=1,
                                   queue=records)
        if resume is not None:
            self.sampler.dose_j_g = resume.run_dose_j_g
            self.index = min(resume.index, len(self.steps))
            gap, gap_s = resume.gap, self._gap_s_now()
            self._write("gap", start_t=gap.start_unix, end_t=gap.start_unix + gap_s, gap_s=gap_s,
                        reason=gap.reason, step=gap.step, credited_s=resume.credit_s,
                        credited_dose_j_g=resume.dose_j_g, torn_bytes=torn_bytes, source=source,
                        config_sha256=config_sha256)
            self._gap_s += gap_s
            return
        self._write(
            "start",
            recipe=loaded.recipe.recipe.name,
            recipe_file=loaded.source,
            recipe_sha256=loaded.sha256,
            config_sha256=config_sha256,
            version=__version__,
            law=plan.law,
            margin=plan.margin,
            steps=len(plan.steps),
            planned_s=plan.total_s,
            sample_s=sample_s,
            powder_charge_g=plan.powder_charge_g,
            furnace_band_c=loaded.recipe.defaults.tolerances.furnace_c,
            recipe_text=text,
        )

    # ------------------------------------------------------------------ record
    def _write(self, event: str, **data: Any) -> None:
        record = {"run_id": self.run_id, "event": event, "clock_s": self.clock.now()}
        if self.resumed is not None and "t_s" not in data:  # a new clock: place the record on the run's timeline
            record["t_s"] = self._t_offset_s + self.clock.now() - self._started_s
        self.record.write({**record, **data})

    def _gap_s_now(self) -> float:
        """The gap being closed (s): from the last record before it to this resume."""
        assert self.resumed is not None
        return max(time.time() - self.resumed.gap.start_unix, 0.0)

    def _step_elapsed_now(self) -> float:
        """Time of the current step that counts as done (s): running time at its setpoints."""
        running = self.state is RunState.RUNNING and self._restore is None
        return self._step_elapsed_s + (self.clock.now() - self._step_started_s if running else 0.0)

    def _run_s(self) -> float:
        """Time the run has been under way, its gaps excluded (s)."""
        return self._run_s_before + self.clock.now() - self._started_s

    def _where(self) -> dict[str, Any]:
        """What a resume needs to know, in each sample and pause: the step's time and dose done, the run's time."""
        return {"step_elapsed_s": self._step_elapsed_now(), "step_dose_j_g": self.dose.j_g, "run_s": self._run_s()}

    @property
    def steps(self) -> list[Step]:
        """The recipe's steps."""
        return self.loaded.recipe.steps

    @property
    def finished(self) -> bool:
        """True once the run reached DONE, ABORTED or FAILED, or was INTERRUPTED (by its service stopping)."""
        return self.state in FINAL or self.state is RunState.INTERRUPTED

    # ------------------------------------------------------------------ operator
    def pause(self, now: bool = False, source: str = "operator") -> None:
        """Pause now (hold the current setpoints) or at the next step boundary."""
        if self.state is not RunState.RUNNING:
            raise CommandRefused(f"cannot pause a run that is {self.state}")
        if not now:
            self._pause_at_boundary = True
            self._write("pause_requested", source=source, at="boundary")
            return
        self._freeze()
        self._enter(RunState.PAUSED, f"paused by {source}")
        self._write("pause", source=source, at="now", step=self.index + 1, **self._where())

    def resume(self, source: str = "operator") -> None:
        """Resume a paused or held run."""
        if self.state not in (RunState.PAUSED, RunState.HELD):
            raise CommandRefused(f"cannot resume a run that is {self.state}")
        self._pause_at_boundary = False
        self._step_started_s = self.dose.clock_s = self.clock.now()
        if self.index < len(self.steps) and isinstance(self.steps[self.index], RampStep):
            self._step_begun = False  # re-issue the ramp from where the mill is now
            self._step_elapsed_s = 0.0
        if self._restore is not None:  # paused on the way back to the step's setpoints: on again from here
            self._restore.begin(self.controller, source)
        self._enter(RunState.RUNNING, f"resumed by {source}")
        self._write("resume", source=source, step=self.index + 1)
        if self._begun_index != self.index:
            self._begin_step()

    def abort(self, source: str = "operator", reason: str = "") -> None:
        """Abort: a controlled stop inside the envelope, then ABORTED (``reason``: why, besides who)."""
        if self.finished or self.state is RunState.STOPPING:
            raise CommandRefused(f"cannot abort a run that is {self.state}")
        self._write("abort", source=source, step=self.index + 1, reason=reason)
        self._stop(RunState.ABORTED, f"aborted by {source}" + (f": {reason}" if reason else ""))

    def interrupt(self, reason: str) -> None:
        """The service is stopping under the run: record where it is, stop the mill, leave the run resumable."""
        if self.finished:
            return
        step = min(self.index + 1, len(self.steps))
        self._write("interrupt", reason=reason, step=step, run_state=str(self.state), **self._where())
        self._enter(RunState.INTERRUPTED, f"{reason}: `millctl recipe resume {self.run_id}` continues it")
        if self.controller.state in (S.ARMED, S.RUNNING, S.STOPPING):
            self.controller.stop(self.source, reason)
        self._release()

    def _release(self) -> None:
        """Close the record, then (after its queued writes) unlock it."""
        self.record.close()
        lock = self.lock
        if lock is None:
            return
        if self.record.queue is not None:
            self.record.queue.submit(lock.release)
        else:
            lock.release()

    # ------------------------------------------------------------------ internals
    def _enter(self, state: RunState, reason: str) -> None:
        log.info("run %s: %s → %s (%s)", self.run_id, self.state, state, reason)
        self.state, self.reason = state, reason

    def _freeze(self) -> None:
        if self._restore is None:  # a restore's time is not the step's
            self._step_elapsed_s += self.clock.now() - self._step_started_s
        commanded = self.controller.commanded
        if self.controller.trajectory is not None and self.controller.state in (S.ARMED, S.RUNNING):
            self.controller.set_speeds(commanded.omega_r_rpm, commanded.omega_v_rpm, source=self.source)

    def _stop(self, final: RunState, reason: str) -> None:
        self._finish_as = final
        self._enter(RunState.STOPPING, reason)
        if self.controller.state in (S.ARMED, S.RUNNING, S.STOPPING):
            self.controller.stop(self.source, reason)

    def _fail(self, reason: str) -> None:
        self._write("fail", reason=reason, step=self.index + 1)
        if self.controller.state is S.TRIPPED:
            self._enter(RunState.FAILED, reason)
            self._end()
        else:
            self._stop(RunState.FAILED, reason)

    def _end(self) -> None:
        self._write("end", status=str(self.state), reason=self.reason, elapsed_s=self._run_s(), run_s=self._run_s(),
                    gap_s=self._gap_s)
        self._release()

    def _tolerances(self, step: Step) -> Tolerances:
        own = getattr(step, "tolerances", None)
        return own if isinstance(own, Tolerances) else self.loaded.recipe.defaults.tolerances

    # ------------------------------------------------------------------ the loop
    def tick(self) -> None:
        """Advance the run; call after the controller's tick."""
        if self.finished:
            return
        c = self.controller
        due = self.sampler.due(c, self.clock.now())
        if due is not None:
            self._write("sample", step=min(self.index + 1, len(self.steps)), run_state=str(self.state), **due,
                        **self._where())
        if c.state is S.TRIPPED and self.state is not RunState.STOPPING:
            self._write("trip", cause=c.trip_cause, step=self.index + 1)
            self._enter(RunState.FAILED, f"interlock trip: {c.trip_cause}")
            self._end()
            return
        try:
            self._advance()
        except InterlockError as exc:  # a refusal mid-run: stop safely, report
            self._write("refusal", reason=str(exc), step=self.index + 1)
            self._fail(f"step {self.index + 1} refused: {exc}")

    def _advance(self) -> None:
        c = self.controller
        now = self.clock.now()
        if self.state is RunState.STARTING:
            if c.state is S.DISABLED and not self._arm_sent:
                c.arm(self.source)
                self._arm_sent = True
            if c.state in (S.ARMED, S.RUNNING):
                self._enter(RunState.RUNNING, "armed")
                if self.resumed is not None:
                    self._begin_resumed(self.resumed)
                else:
                    self._begin_step()
            elif c.state is S.TRIPPED or now - self._started_s > ARM_TIMEOUT_S:
                self._fail(f"the mill did not arm within {ARM_TIMEOUT_S:.0f} s (controller {c.state})")
            return
        if self.state is RunState.STOPPING:
            measured = c.measured
            still = measured is not None and max(measured.rotary_rpm, measured.vibration_rpm) < STANDSTILL_RPM
            if c.state is S.TRIPPED:  # a trip in the run's final stop: recorded, and the run is not DONE
                self._write("trip", cause=c.trip_cause, step=min(self.index + 1, len(self.steps)))
                if self._finish_as is RunState.DONE:
                    self._finish_as, self.reason = RunState.FAILED, f"interlock trip in the final stop: {c.trip_cause}"
                self._enter(self._finish_as, self.reason or "stopped")
                self._end()
            elif c.state is S.ARMED and still:
                self._enter(self._finish_as, self.reason or "stopped")
                self._end()
            return
        if self.state is not RunState.RUNNING:
            return
        if self._restore is not None:
            if not self._restore.done(c):
                return
            self._restored()
            if self.state is not RunState.RUNNING:
                return
        if self._step_done(now):
            self._write(
                "step_end", step=self.index + 1, kind=self.steps[self.index].kind, dose_kj_g=self.dose.j_g * 1e-3
            )
            self.index += 1
            if self.index >= len(self.steps):
                self._stop(RunState.DONE, "recipe complete")
                return
            if self._pause_at_boundary:
                self._pause_at_boundary = False
                self._enter(RunState.PAUSED, "paused at step boundary")
                self._write("pause", at="boundary", step=self.index + 1)
                return
            self._begin_step()

    def _begin_step(self) -> None:
        step = self.steps[self.index]
        self._begun_index = self.index
        self._step_started_s = self.clock.now()
        self._step_elapsed_s = 0.0
        self._step_begun = False
        self.dose.restart(self.clock.now())
        self._write("step_start", step=self.index + 1, kind=step.kind, planned_s=self.plan.steps[self.index].duration_s)
        if isinstance(step, PauseStep):
            self._enter(RunState.PAUSED, step.message)

    def _begin_resumed(self, point: ResumePoint) -> None:
        """Continue the interrupted step: restore its setpoints from the measured values, then run it on."""
        if self.index >= len(self.steps):
            self._stop(RunState.DONE, "recipe complete (resumed for its final stop)")
            return
        step = self.steps[self.index]
        self._begun_index = self.index
        self._step_begun = False
        self._write("step_start", step=self.index + 1, kind=step.kind, planned_s=self.plan.steps[self.index].duration_s,
                    resumed=True, credited_s=point.credit_s, credited_dose_j_g=point.dose_j_g)
        self._step_elapsed_s = point.credit_s
        self.dose.restart(self.clock.now(), point.dose_j_g)
        target = point.restore
        if isinstance(step, RampStep):  # the ramp itself runs again from standstill; first its furnace in force
            if step.furnace_c is None and target.furnace_c is not None:
                self.controller.set_furnace(target.furnace_c, rate_c_per_min=target.heating_rate_c_per_min,
                                            source=self.source)
            self._step_started_s = self.dose.clock_s = self.clock.now()
            return
        band = self._tolerances(step).furnace_c if isinstance(step, HoldStep) else None
        self._restore = Restore(target, self._tolerances(step).speed_rpm, band)
        self._restore.begin(self.controller, self.source)
        self.reason = f"resumed: back to step {self.index + 1}'s setpoints from the measured values first"
        self._write("restore", step=self.index + 1, rotary_rpm=target.rotary_rpm, vibration_rpm=target.vibration_rpm,
                    furnace_c=target.furnace_c)

    def _restored(self) -> None:
        """The mill is back at the step's setpoints: the step's clock runs again."""
        self._restore = None
        self.reason = "resumed"
        self._step_started_s = self.dose.clock_s = self.clock.now()
        self._write("restored", step=self.index + 1, credited_s=self._step_elapsed_s)
        step = self.steps[self.index]
        if isinstance(step, PauseStep):
            self._enter(RunState.PAUSED, step.message)

    def _issue_ramp(self, step: RampStep) -> None:
        defaults = self.loaded.recipe.defaults
        heating = None if step.furnace_c is None else step.heating_rate_c_per_min or defaults.heating_rate_c_per_min
        c = self.controller
        move = c.set_speeds(  # speeds and furnace checked whole: all or nothing
            step.rotary_rpm,
            step.vibration_rpm,
            rotary_rate_rpm_s=step.rotary_rate_rpm_s or defaults.rotary_rate_rpm_s,
            vibration_rate_rpm_s=step.vibration_rate_rpm_s or defaults.vibration_rate_rpm_s,
            linear=step.path == "linear",
            furnace_c=step.furnace_c,
            heating_rate_c_per_min=heating,
            source=self.source,
        )
        heat_s = 0.0
        if c.furnace_target_c is not None:
            heat_s = abs(c.furnace_target_c - c.furnace_setpoint_c) / c.heating_rate_c_per_min * 60.0
        self._ramp_planned_s = max(move.duration_s, heat_s)  # from where the mill is: after a pause or a gap, longer

    def _step_done(self, now: float) -> bool:
        step = self.steps[self.index]
        elapsed = self._step_elapsed_s + (now - self._step_started_s)
        c = self.controller
        if isinstance(step, RampStep):
            if not self._step_begun:
                self._issue_ramp(step)
                self._step_begun = True
                return False
            furnace_done = c.furnace_target_c is None or c.furnace_setpoint_c == c.furnace_target_c
            if c.trajectory is not None or not furnace_done:
                return False
            measured = c.measured
            tol = self._tolerances(step).speed_rpm
            settled = measured is not None and (
                abs(measured.rotary_rpm - step.rotary_rpm) <= tol
                and abs(measured.vibration_rpm - step.vibration_rpm) <= tol
            )
            planned = max(self.plan.steps[self.index].duration_s, self._ramp_planned_s or 0.0)
            if not settled and elapsed > planned + SETTLE_TIMEOUT_S:
                raise CommandRefused(f"drives did not settle within ±{tol} rpm of the ramp's target")
            return settled
        if isinstance(step, HoldStep):
            self._check_furnace_band(step)
            seconds = step.seconds
            if seconds is None:
                return self.dose.reached(step, now, elapsed, self.state is RunState.RUNNING,
                                         self.plan.steps[self.index].duration_s)
            return self.state is RunState.RUNNING and elapsed >= seconds
        if isinstance(step, WaitFurnaceStep):
            furnace = c.furnace
            target = c.furnace_target_c
            if furnace is not None and target is not None and abs(furnace.temp_c - target) <= step.band_c:
                return True
            if elapsed > step.timeout_min * 60.0:
                raise CommandRefused(
                    f"furnace did not reach ±{step.band_c} °C of {target} °C within {step.timeout_min:g} min"
                )
            return False
        return self.state is RunState.RUNNING  # a pause step ends when resumed

    def _check_furnace_band(self, step: HoldStep) -> None:
        c = self.controller
        furnace, target = c.furnace, c.furnace_target_c
        if furnace is None or target is None or c.furnace_setpoint_c != target:
            return
        band = self._tolerances(step).furnace_c
        if abs(furnace.temp_c - target) > band:
            self._step_elapsed_s += self.clock.now() - self._step_started_s
            self._step_started_s = self.clock.now()
            reason = f"furnace {furnace.temp_c:.1f} °C left its band {target:.1f} ± {band:.1f} °C: held"
            self._enter(RunState.HELD, reason)
            self._write("hold", reason=reason, step=self.index + 1)

    # ------------------------------------------------------------------ progress
    def progress(self) -> dict[str, Any]:
        """The run's progress as JSON-ready data."""
        current: StepPlan | None = self.plan.steps[self.index] if self.index < len(self.plan.steps) else None
        step_elapsed = self._step_elapsed_now()
        remaining = sum(s.duration_s for s in self.plan.steps[self.index + 1 :]) + self.plan.stop.duration_s
        if current is not None:
            remaining += max(current.duration_s - step_elapsed, 0.0)
        return {
            "run_id": self.run_id,
            "recipe": self.loaded.recipe.recipe.name,
            "recipe_file": self.loaded.source,
            "state": str(self.state),
            "reason": self.reason,
            "step": min(self.index + 1, len(self.steps)),
            "steps": len(self.steps),
            "kind": current.kind if current else None,
            "elapsed_s": self._run_s(),
            "step_elapsed_s": step_elapsed,
            "remaining_s": remaining if not self.finished else 0.0,
            "record": str(self.record.path),
            "gap_s": self._gap_s,
            "resumed": self.resumed is not None,
        }


__all__ = ["FINAL", "RecipeRunner", "RunState", "new_run_id"]
