"""The service's recipe slot: at most one :class:`~millctl.recipes.runner.RecipeRunner` at a time, in the loop.

A recipe arrives as its TOML text (a client may be on another machine: the
service never opens a path a request names). It is parsed and pre-flighted
against the service's own configuration in the request's thread, outside the
control loop; a plan with any violation is refused with every one of them.
Only the start itself, and every other method, run in the control loop.

An interrupted run (the service stopped or died under it) is found in the
records (:mod:`millctl.recipes.history`) and resumed by :meth:`RecipeSlot.resume_run`
after the operator's confirmation and a pre-flight from the mill's actual
state (:mod:`millctl.recipes.resume`); the record reading and locking happen
in the request's thread, the check and the start together in the loop, so no
command slips in between (docs/operations.md#resume).
"""

from __future__ import annotations

import logging
import os
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from millctl.api import RecipeCheckOut, RecipeOut, RecipeProgress, ResumeCheckOut, RunGapOut, RunState, UnfinishedRunOut
from millctl.clock import Clock
from millctl.config.models import MillConfig
from millctl.controller import CommandRefused, Controller
from millctl.errors import InterlockError, RecipeError
from millctl.recipes import LoadedRecipe, RecipePlan, parse_recipe, plan_recipe
from millctl.recipes.history import (
    RUNS_DIR,
    RunHistory,
    RunLock,
    RunNotResumable,
    is_live,
    read_history,
    record_path,
    repair_tail,
    unfinished_history,
)
from millctl.recipes.plan import Violation
from millctl.recipes.resume import ResumeCheck, ResumePoint, check_unchanged, preflight_resume, resume_point
from millctl.recipes.runner import RecipeRunner, new_run_id
from millctl.records import RecordQueue, RecordWriter
from millctl.service.journal import finite

log = logging.getLogger(__name__)


class RecipeRefused(InterlockError):
    """A recipe whose pre-flight plan leaves the envelope; it was not started."""

    def __init__(self, source: str, law: str, violations: tuple[Violation, ...]) -> None:
        self.violations = violations
        lines = "; ".join(str(v) for v in violations)
        super().__init__(f"recipe {source} refused by the pre-flight check under {law}: {lines}")


@dataclass
class PreparedResume:
    """A resume prepared in the request's thread: the run's history, its recipe and plan, and where it continues."""

    history: RunHistory
    loaded: LoadedRecipe
    plan: RecipePlan
    point: ResumePoint
    text: str


def unfinished_out(h: RunHistory) -> UnfinishedRunOut:
    """An interrupted run as the API shows it."""
    gaps = [*h.gaps, h.open_gap]
    return UnfinishedRunOut(
        run_id=h.run_id, recipe=h.recipe, recipe_file=str(h.start.get("recipe_file", "")),
        recipe_sha256=h.recipe_sha256, config_sha256=h.config_sha256, state=RunState.INTERRUPTED, step=h.step,
        steps=h.steps, kind=h.kind, step_elapsed_s=h.step_elapsed_s, step_dose_kj_g=h.step_dose_j_g * 1e-3,
        elapsed_s=h.run_s, started_unix=h.started_unix, interrupted_unix=h.last_unix, reason=h.reason,
        gaps=[RunGapOut(start_unix=g.start_unix, end_unix=g.end_unix, gap_s=g.gap_s, step=g.step, reason=g.reason)
              for g in gaps],
        record=str(h.path), recipe_in_record=h.recipe_text is not None,
    )


class RecipeSlot:
    """Holds the current (or last finished) recipe run of the service."""

    def __init__(
        self, controller: Controller, clock: Clock, records_dir: Path, config_sha256: str,
        records: RecordQueue | None = None,
    ) -> None:
        self.controller = controller
        self.clock = clock
        self.records_dir = records_dir
        self.config_sha256 = config_sha256
        self.records = records
        self.sample_extra: Callable[[], dict[str, Any]] | None = None
        """More fields for every run sample (the service sets its loop lateness here; SAFETY 27)."""
        self.runner: RecipeRunner | None = None
        self._scanned: dict[str, tuple[tuple[int, int], RunHistory | None]] = {}
        """Each run record's (mtime, size) and its history when unfinished: re-read only when it changed."""
        self._scan_lock = threading.Lock()

    @property
    def active(self) -> bool:
        """True while a run is in progress (not yet finished)."""
        return self.runner is not None and not self.runner.finished

    def require_idle(self, what: str) -> None:
        """Refuse a manual command while a recipe drives the mill (stop and E-stop are never refused)."""
        if self.runner is not None and self.active:
            raise CommandRefused(
                f"{what} refused: recipe run {self.runner.run_id} is {self.runner.state}; pause or abort it first"
            )

    @staticmethod
    def prepare(name: str, text: str, config: MillConfig) -> tuple[LoadedRecipe, RecipePlan]:
        """Parse and pre-flight a recipe's text (outside the loop); refuse it with every violation."""
        loaded = parse_recipe(text, name)
        plan = plan_recipe(loaded.recipe, config)
        if not plan.ok:
            raise RecipeRefused(loaded.source, plan.law, plan.violations)
        return loaded, plan

    @staticmethod
    def check(name: str, text: str, config: MillConfig) -> RecipeCheckOut:
        """Pre-flight a recipe's text without starting it: every violation or invalid field, or its plan."""
        law = config.interlock.law.value
        try:
            loaded = parse_recipe(text, name)
        except RecipeError as exc:
            return RecipeCheckOut(source=name, recipe=None, ok=False, steps=0, planned_s=None, open_ended=False,
                                  dose_kj_g=None, law=law, problems=exc.problems)
        plan = plan_recipe(loaded.recipe, config)
        return RecipeCheckOut(
            source=name, recipe=loaded.recipe.recipe.name, ok=plan.ok, steps=len(plan.steps),
            planned_s=plan.total_s, open_ended=any(step.open_ended for step in plan.steps),
            dose_kj_g=plan.total_dose_kj_g, law=plan.law, problems=[str(v) for v in plan.violations],
        )

    def lock_new_run(self) -> tuple[str, RunLock]:
        """A new run's id and its record's lock (in the request's thread: the loop never waits for the disk)."""
        run_id = new_run_id()
        return run_id, RunLock.acquire(Path(self.records_dir) / RUNS_DIR / f"{run_id}.jsonl")

    def start(self, loaded: LoadedRecipe, plan: RecipePlan, source: str, *, run_id: str | None = None,
              lock: RunLock | None = None, text: str | None = None) -> dict[str, Any]:
        """Start a prepared run (in the loop); return its progress."""
        if self.runner is not None and self.active:
            raise CommandRefused(f"recipe run {self.runner.run_id} is still {self.runner.state}: one run at a time")
        self.runner = RecipeRunner(
            self.controller,
            loaded,
            plan,
            self.clock,
            records_dir=self.records_dir,
            config_sha256=self.config_sha256,
            source=source,
            records=self.records,
            sample_s=self.controller.config.service.run_sample_s,
            run_id=run_id,
            lock=lock,
            text=text,
        )
        self.runner.sampler.extra = self.sample_extra
        return self.runner.progress()

    # ------------------------------------------------------------------ interrupted runs
    def unfinished(self) -> list[RunHistory]:
        """The interrupted runs in the records, oldest first (request threads; a record is re-read once it changed)."""
        runs = Path(self.records_dir) / RUNS_DIR
        found = []
        with self._scan_lock:
            try:
                entries = sorted((e for e in os.scandir(runs) if e.name.endswith(".jsonl")), key=lambda e: e.name)
            except OSError:
                entries = []
            seen: dict[str, tuple[tuple[int, int], RunHistory | None]] = {}
            for entry in entries:
                try:
                    stat = entry.stat()
                except OSError:
                    continue
                key = (stat.st_mtime_ns, stat.st_size)
                cached = self._scanned.get(entry.name)
                history = cached[1] if cached is not None and cached[0] == key else unfinished_history(Path(entry.path))
                seen[entry.name] = (key, history)
                if history is not None and not is_live(Path(entry.path)):
                    found.append(history)
            self._scanned = seen
        mine = self.runner  # this service's own run, live or ended, is never offered: it knows its state best
        return [h for h in found if mine is None or h.run_id != mine.run_id or mine.state is RunState.INTERRUPTED]

    def prepare_resume(self, run_id: str, text: str | None, config_sha256: str, config: MillConfig) -> PreparedResume:
        """Read the run's record, check its recipe and configuration are unchanged, and plan (request thread)."""
        history = read_history(record_path(self.records_dir, run_id))
        if history.ended is not None:
            raise RunNotResumable(f"run {run_id} {history.reason}: only an interrupted run can be resumed")
        mine = self.runner
        if mine is not None and mine.run_id == run_id and mine.state is not RunState.INTERRUPTED:
            hint = ("" if mine.finished else
                    ": `millctl recipe resume` without a run id continues a paused run")
            raise RunNotResumable(f"run {run_id} is {mine.state} in this service{hint}")
        if text is None:
            text = history.recipe_text
            if text is None:
                raise RunNotResumable(f"run {run_id}: its record keeps no recipe text (recorded before resume "
                                      "existed): send the recipe (`millctl recipe resume RUN --recipe FILE`)")
        loaded = parse_recipe(text, str(history.start.get("recipe_file", run_id)))
        check_unchanged(history, loaded, config_sha256)
        plan = plan_recipe(loaded.recipe, config)
        return PreparedResume(history, loaded, plan, resume_point(history, loaded), text)

    def check_resume(self, prepared: PreparedResume) -> ResumeCheck:
        """The pre-flight from the mill's state now (in the loop); a run already active is a problem too."""
        check = preflight_resume(prepared.point, prepared.loaded, prepared.plan, self.controller)
        if self.runner is not None and self.active:
            busy = f"recipe run {self.runner.run_id} is {self.runner.state}: one run at a time"
            return ResumeCheck((busy, *check.problems), check.restore, check.restore_s)
        return check

    def resume_run(self, prepared: PreparedResume, lock: RunLock, torn_bytes: int, source: str) -> dict[str, Any]:
        """Check again and start the resumed run (in the loop, so nothing moves between the check and the start)."""
        check = self.check_resume(prepared)
        if not check.ok:
            raise RunNotResumable(f"run {prepared.history.run_id} not resumed: " + "; ".join(check.problems))
        self.runner = RecipeRunner(
            self.controller, prepared.loaded, prepared.plan, self.clock, records_dir=self.records_dir,
            config_sha256=self.config_sha256, source=source, records=self.records,
            sample_s=self.controller.config.service.run_sample_s, lock=lock, resume=prepared.point,
            torn_bytes=torn_bytes,
        )
        self.runner.sampler.extra = self.sample_extra
        return self.runner.progress()

    def check_out(self, check: ResumeCheck) -> ResumeCheckOut:
        """The check with the mill's measured values, as the API shows it (in the loop)."""
        c = self.controller
        measured, furnace = c.measured, c.furnace
        return ResumeCheckOut(
            ok=check.ok, problems=list(check.problems), restore=check.restore, restore_s=check.restore_s,
            controller_state=c.state, measured_rotary_rpm=None if measured is None else measured.rotary_rpm,
            measured_vibration_rpm=None if measured is None else measured.vibration_rpm,
            furnace_temp_c=None if furnace is None else furnace.temp_c,
        )

    def recipe_out(self) -> RecipeOut:
        """The current run's progress as the API shows it."""
        progress = self.progress()
        shown = RecipeProgress.model_validate(finite(progress)) if progress is not None else None
        return RecipeOut(active=self.active, progress=shown)

    def close_interrupted(self, run_id: str, source: str) -> RunHistory:
        """Close an interrupted run for good: its record gets ``abort`` and ``end`` (ABORTED); never resumable."""
        path = record_path(self.records_dir, run_id)
        lock = RunLock.acquire(path)
        try:
            history = read_history(path)
            if history.ended is not None:
                raise RunNotResumable(f"run {run_id} {history.reason}: nothing to close")
            torn = repair_tail(path)
            writer = RecordWriter(path.parent, run_id, rotate_bytes=1 << 30, keep=1)
            reason = f"closed by {source} after an interruption ({history.reason})"
            base = {"run_id": run_id, "step": min(history.step, history.steps)}
            writer.write({**base, "event": "abort", "source": source, "reason": reason, "torn_bytes": torn})
            writer.write({"run_id": run_id, "event": "end", "status": str(RunState.ABORTED), "reason": reason,
                          "elapsed_s": history.run_s, "run_s": history.run_s, "gap_s": history.gap_s})
            writer.close()
            return read_history(path)
        finally:
            lock.release()

    def _require_runner(self) -> RecipeRunner:
        if self.runner is None:
            raise CommandRefused("no recipe run: start one first (POST /v1/recipe/run)")
        return self.runner

    def pause(self, now: bool, source: str) -> dict[str, Any]:
        """Pause the run (now, or at the next step boundary)."""
        runner = self._require_runner()
        runner.pause(now=now, source=source)
        return runner.progress()

    def resume(self, source: str) -> dict[str, Any]:
        """Resume a paused or held run."""
        runner = self._require_runner()
        runner.resume(source=source)
        return runner.progress()

    def abort(self, source: str) -> dict[str, Any]:
        """Abort the run with a controlled stop."""
        runner = self._require_runner()
        runner.abort(source=source)
        return runner.progress()

    def interrupt_if_active(self, reason: str) -> None:
        """The service is stopping: stop the mill under an active run and leave the run resumable (never raises)."""
        if self.runner is not None and self.active:
            self.runner.interrupt(reason)

    def abort_if_active(self, source: str, reason: str = "") -> None:
        """Abort an active run before a stop, an E-stop or a shutdown (never raises)."""
        if self.runner is not None and self.active:
            try:
                self.runner.abort(source=source, reason=reason)
            except InterlockError as exc:
                log.warning("recipe abort by %s: %s", source, exc)

    def close(self) -> None:
        """Close the run record of an unfinished run (its queued records are written first)."""
        if self.runner is not None and not self.runner.finished:
            self.runner.record.close()
            if self.runner.lock is not None:
                self.runner.lock.release()

    def progress(self) -> dict[str, Any] | None:
        """Progress of the current or last run, or None before the first."""
        return self.runner.progress() if self.runner is not None else None

    def tick(self) -> None:
        """Step the runner (after the controller's tick)."""
        if self.runner is not None and not self.runner.finished:
            self.runner.tick()


__all__ = ["PreparedResume", "RecipeRefused", "RecipeSlot", "unfinished_out"]
