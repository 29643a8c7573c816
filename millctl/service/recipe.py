"""The service's recipe slot: at most one :class:`~millctl.recipes.runner.RecipeRunner` at a time, in the loop.

A recipe arrives as its TOML text (a client may be on another machine: the
service never opens a path a request names). It is parsed and pre-flighted
against the service's own configuration in the request's thread, outside the
control loop; a plan with any violation is refused with every one of them.
Only the start itself, and every other method, run in the control loop.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from millctl.api import RecipeCheckOut
from millctl.clock import Clock
from millctl.config.models import MillConfig
from millctl.controller import CommandRefused, Controller
from millctl.errors import InterlockError, RecipeError
from millctl.recipes import LoadedRecipe, RecipePlan, parse_recipe, plan_recipe
from millctl.recipes.plan import Violation
from millctl.recipes.runner import RecipeRunner
from millctl.records import RecordQueue

log = logging.getLogger(__name__)


class RecipeRefused(InterlockError):
    """A recipe whose pre-flight plan leaves the envelope; it was not started."""

    def __init__(self, source: str, law: str, violations: tuple[Violation, ...]) -> None:
        self.violations = violations
        lines = "; ".join(str(v) for v in violations)
        super().__init__(f"recipe {source} refused by the pre-flight check under {law}: {lines}")


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
        self.runner: RecipeRunner | None = None

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

    def start(self, loaded: LoadedRecipe, plan: RecipePlan, source: str) -> dict[str, Any]:
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
        )
        return self.runner.progress()

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

    def progress(self) -> dict[str, Any] | None:
        """Progress of the current or last run, or None before the first."""
        return self.runner.progress() if self.runner is not None else None

    def tick(self) -> None:
        """Step the runner (after the controller's tick)."""
        if self.runner is not None and not self.runner.finished:
            self.runner.tick()


__all__ = ["RecipeRefused", "RecipeSlot"]
