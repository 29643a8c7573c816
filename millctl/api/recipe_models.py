"""The service API's models of recipe runs: start, check, progress, pause, resume, interrupted runs.

Split from :mod:`millctl.api.models` by concern (the controller's status and commands stay there); the same
rules hold: unknown fields are refused, keys end in their unit.
"""

from __future__ import annotations

from pydantic import Field

from millctl.api.enums import ControllerState, RunState
from millctl.api.models import Strict


class RecipeRunRequest(Strict):
    """Run a recipe sent by content: its TOML ``text``, and a ``name`` for the record (e.g. the client's file name).

    The service opens no path a request names: a client may be on another machine.
    """

    name: str = Field(min_length=1, max_length=255, pattern=r"^[^\x00-\x1f\x7f]+$",
                      description="where the recipe came from, for the run record (no control characters)")
    text: str = Field(min_length=1, max_length=512 * 1024, description="the recipe file's TOML text")


class RecipeCheckOut(Strict):
    """A recipe's pre-flight against the service's own envelope: nothing is started, no control needed."""

    source: str = Field(description="the name the recipe was sent under (its file name)")
    recipe: str | None = Field(description="the recipe's own name; null when its text is not a valid recipe")
    ok: bool = Field(description="true when it is a valid recipe whose whole plan stays inside the envelope")
    steps: int = Field(description="number of steps (0 when invalid)")
    planned_s: float | None = Field(description="planned time with the final stop (s); open-ended steps count 0")
    open_ended: bool = Field(description="true when some step waits for the furnace or the operator")
    dose_kj_g: float | None = Field(description="expected specific energy dose (kJ per g of powder)")
    law: str = Field(description="the limit law it was checked under")
    problems: list[str] = Field(description="why it would be refused: every envelope violation (step, time, "
                                "value, limit) or every invalid field; empty when ok")


class RecipePauseRequest(Strict):
    """Pause the running recipe: at the end of the step, or ``now``."""

    now: bool = Field(default=False, description="pause now, holding the current setpoints")


class RecipeProgress(Strict):
    """Where a recipe run is."""

    run_id: str = Field(description="the run's id (its record is runs/<run_id>.jsonl in the records folder)")
    recipe: str = Field(description="the recipe's name")
    recipe_file: str = Field(description="the recipe file the run was started from")
    state: RunState = Field(description="the run's state")
    reason: str | None = Field(description="why it ended, paused or held")
    step: int = Field(description="the current step, from 1")
    steps: int = Field(description="number of steps")
    kind: str | None = Field(description="kind of the current step (ramp, hold, wait_furnace, pause)")
    elapsed_s: float | None = Field(description="time since the run started (s)")
    step_elapsed_s: float | None = Field(description="time spent in the current step (s)")
    remaining_s: float | None = Field(description="planned time left, including the final stop (s)")
    record: str = Field(description="the run record (JSON lines)")
    gap_s: float = Field(default=0.0, description="time the run stood interrupted (service stopped or died), "
                         "not counted in elapsed_s (s)")
    resumed: bool = Field(default=False, description="true for a run resumed after an interruption")


class RunGapOut(Strict):
    """A time a run did not run: from its last record before the gap to its resume (Unix times)."""

    start_unix: float = Field(description="the last record before the gap (s)")
    end_unix: float | None = Field(description="the resume (s); null while the run is still interrupted")
    gap_s: float | None = Field(description="the gap's length (s); null while open")
    step: int = Field(description="the step the run was in, from 1")
    reason: str = Field(description="why the run stopped")


class UnfinishedRunOut(Strict):
    """A run its record shows unfinished (no end) and no service runs: it can be resumed or closed."""

    run_id: str = Field(description="the interrupted run's id")
    recipe: str = Field(description="the recipe's name")
    recipe_file: str = Field(description="the recipe file the run was started from")
    recipe_sha256: str = Field(description="hash of the recipe text the run started with; a resume needs the same")
    config_sha256: str = Field(description="hash of the configuration the run started under")
    state: RunState = Field(description="INTERRUPTED")
    step: int = Field(description="the step it was in, from 1 (steps + 1: only the final stop was left)")
    steps: int = Field(description="the recipe's number of steps")
    kind: str | None = Field(description="kind of that step; null when it had not started")
    step_elapsed_s: float = Field(description="time of that step done at its setpoints (s); a hold resumes with it")
    step_dose_kj_g: float = Field(description="dose of that step so far (kJ/g); a dose hold resumes with it")
    elapsed_s: float = Field(description="time the run was under way, gaps excluded (s)")
    started_unix: float = Field(description="Unix time the run started (s)")
    interrupted_unix: float = Field(description="the last record before the gap (s)")
    reason: str = Field(description="why it stopped: the service's stop, or a crash, kill or power loss")
    gaps: list[RunGapOut] = Field(description="the run's gaps so far, the open one last")
    record: str = Field(description="the run record (JSON lines)")
    recipe_in_record: bool = Field(description="the record keeps the recipe's text (else send it to resume)")


class UnfinishedRunsOut(Strict):
    """Every interrupted run in the service's records, oldest first."""

    runs: list[UnfinishedRunOut] = Field(description="every run a stop, crash or reboot interrupted, oldest first")


class RecipeResumeRequest(Strict):
    """Resume an interrupted run: ``confirm`` false only checks (nothing moves); true starts it after the check."""

    confirm: bool = Field(description="the operator's confirmation: true resumes, false only shows the check")
    text: str | None = Field(default=None, min_length=1, max_length=512 * 1024,
                             description="the recipe's TOML text; must hash to the run's recipe_sha256 "
                             "(default: the text kept in the run record)")


class ResumeCheckOut(Strict):
    """The pre-flight of a resume, from the mill's state now."""

    ok: bool = Field(description="nothing stops the resume")
    problems: list[str] = Field(description="what stops it, each with the value and what to do")
    restore: str = Field(description="what happens first, in words: from the measured values to the setpoints")
    restore_s: float = Field(description="expected time of the restore ramps (s)")
    controller_state: ControllerState = Field(description="the controller's state now")
    measured_rotary_rpm: float | None = Field(description="measured ω_r now (rpm); null before telemetry")
    measured_vibration_rpm: float | None = Field(description="measured ω_v now (rpm); null before telemetry")
    furnace_temp_c: float | None = Field(description="furnace temperature now (°C); null before telemetry")


class RecipeOut(Strict):
    """The current (or last) recipe run; ``active`` false when none runs, ``progress`` null before the first."""

    active: bool = Field(description="true while a recipe run is in progress (running, paused or stopping)")
    progress: RecipeProgress | None = Field(description="the current or last run's progress; null before any run")


class RecipeResumeOut(Strict):
    """The run, the check and, once confirmed and started, its progress."""

    run: UnfinishedRunOut = Field(description="the interrupted run that is resumed")
    check: ResumeCheckOut = Field(description="the mill's state now, which the resume was checked against")
    started: bool = Field(description="true once the run continues")
    recipe: RecipeOut | None = Field(description="the run's progress once started")


__all__ = [
    "RecipeCheckOut",
    "RecipeOut",
    "RecipePauseRequest",
    "RecipeProgress",
    "RecipeResumeOut",
    "RecipeResumeRequest",
    "RecipeRunRequest",
    "ResumeCheckOut",
    "RunGapOut",
    "UnfinishedRunOut",
    "UnfinishedRunsOut",
]
