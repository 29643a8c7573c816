"""What a run record says about its run: finished or not, where it stopped, what of it is done, and its gaps.

A run record (``<records_dir>/runs/<run_id>.jsonl``, :mod:`millctl.records`) is
append-only, one JSON line per ``write`` and ``fsync``: after a SIGKILL or a
power loss it is readable up to its last complete line; a torn last line is
cut off (:func:`repair_tail`) before a resumed run appends to it. A run whose
record has no ``end`` and that no process runs (:class:`RunLock`) was
interrupted: :func:`read_history` says at which step, how much of that step
counts as done (``step_elapsed_s`` of the last record of the step), and why it
stopped; :func:`unfinished_runs` finds every such run (docs/operations.md#resume).

A live runner holds an exclusive ``flock`` on its record for as long as it
runs; the lock goes with its process, so a crashed service leaves no lock
behind, while another service sharing the records directory never takes a
live run for an interrupted one.
"""

from __future__ import annotations

import fcntl
import json
import os
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from millctl.errors import InterlockError, InvalidInputError
from millctl.records import RECORD_MODE

RUNS_DIR = "runs"
"""Run records live in ``<records_dir>/runs``."""

RUN_ID_PATTERN = r"^[0-9]{8}T[0-9]{6}Z-[0-9a-f]{6}$"
"""A run id: the UTC start time and six hex digits (``20260101T120000Z-1a2b3c``)."""


def clock_stamp() -> str:
    """A sortable UTC timestamp for run ids."""
    return time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())


def new_run_id() -> str:
    """A new run id: the UTC start time and six random hex digits (RUN_ID_PATTERN)."""
    return f"{clock_stamp()}-{uuid.uuid4().hex[:6]}"


LOCK_TRIES = 20
LOCK_RETRY_S = 0.01


class RunNotFound(InvalidInputError):
    """No run record with this id under the records directory (HTTP 404, exit 1)."""


class RunNotResumable(InterlockError):
    """The run cannot be resumed: it ended, it runs, its recipe or configuration changed (HTTP 409, exit 2)."""


@dataclass(frozen=True)
class Gap:
    """A time the run did not run: from the last record before it to the resume (Unix times, s)."""

    start_unix: float
    end_unix: float | None
    """None while the run is still interrupted."""
    step: int
    """The step (from 1) the run was in."""
    reason: str

    @property
    def gap_s(self) -> float | None:
        """How long the gap lasted (s); None while open."""
        return None if self.end_unix is None else self.end_unix - self.start_unix


@dataclass
class RunHistory:
    """A run as its record tells it."""

    run_id: str
    path: Path
    start: dict[str, Any]
    steps: int
    started_unix: float
    last_unix: float
    """Unix time of the last complete record."""
    step: int = 1
    """The step (from 1) in progress at the last record; ``steps + 1`` once every step ended."""
    kind: str | None = None
    """Kind of that step, None before it started."""
    step_started: bool = False
    step_elapsed_s: float = 0.0
    """Time of the step that counts as done (running time; a ramp's time is never credited: it ends on target)."""
    step_dose_j_g: float = 0.0
    """Specific energy dose of the step so far (J/g): a dose-targeted hold continues from it."""
    run_s: float = 0.0
    """Time the run was under way, its gaps excluded (s)."""
    run_dose_j_g: float = 0.0
    """Specific energy dose of the run so far (J/g), from its last sample."""
    paused: bool = False
    ended: str | None = None
    """The end status (DONE, ABORTED, FAILED), None while unfinished."""
    end_reason: str = ""
    interrupt_reason: str = ""
    """Why the service stopped the run (its ``interrupt`` record), empty after a crash."""
    gaps: list[Gap] = field(default_factory=list)
    records: int = 0

    @property
    def recipe(self) -> str:
        """The recipe's name."""
        return str(self.start.get("recipe", "?"))

    @property
    def recipe_sha256(self) -> str:
        """The hash of the recipe's text the run started with."""
        return str(self.start.get("recipe_sha256", ""))

    @property
    def recipe_text(self) -> str | None:
        """The recipe's TOML text kept in the record (None in records of millctl before resume)."""
        text = self.start.get("recipe_text")
        return text if isinstance(text, str) else None

    @property
    def config_sha256(self) -> str:
        """The hash of the configuration the run started under."""
        return str(self.start.get("config_sha256", ""))

    @property
    def reason(self) -> str:
        """Why the run stopped, in words."""
        if self.ended is not None:
            return f"ended {self.ended}" + (f": {self.end_reason}" if self.end_reason else "")
        if self.interrupt_reason:
            return f"interrupted: {self.interrupt_reason}"
        stamp = time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime(self.last_unix))
        return f"the service ended without closing the run (a crash, a kill or a power loss); last record {stamp}"

    @property
    def open_gap(self) -> Gap:
        """The gap the run is in now (open: no end yet)."""
        return Gap(self.last_unix, None, min(self.step, self.steps), self.reason)

    @property
    def gap_s(self) -> float:
        """The total of the closed gaps (s)."""
        return sum(g.gap_s or 0.0 for g in self.gaps)


def read_history(path: Path) -> RunHistory:
    """Read a run record; a :class:`RunNotFound` naming the file when it is not one, or not readable."""
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise RunNotFound(f"run record {path}: cannot read it: {exc}") from None
    lines = raw.split(b"\n")
    if lines and lines[-1] != b"":
        lines = lines[:-1]  # a torn last line: the write a kill cut short
    history: RunHistory | None = None
    for number, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        try:
            record = json.loads(line)
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise RunNotFound(f"run record {path}: line {number} is not JSON ({exc}): the record is damaged") from None
        if not isinstance(record, dict):
            raise RunNotFound(f"run record {path}: line {number} is not a JSON object")
        if history is None:
            if record.get("event") != "start":
                raise RunNotFound(f"run record {path}: does not begin with a 'start' record (is it a run record?)")
            history = RunHistory(str(record.get("run_id", path.stem)), path, record, int(record.get("steps", 0)),
                                 float(record.get("t", 0.0)), float(record.get("t", 0.0)))
        _apply(history, record)
    if history is None:
        raise RunNotFound(f"run record {path}: empty")
    return history


def _apply(h: RunHistory, record: dict[str, Any]) -> None:
    """Fold one record into the history."""
    h.records += 1
    h.last_unix = float(record.get("t", h.last_unix))
    event = record.get("event")
    if "run_s" in record:
        h.run_s = float(record["run_s"])
    if event == "sample" and "dose_j_g" in record:
        h.run_dose_j_g = float(record["dose_j_g"])
    if event == "step_start":
        h.step, h.kind, h.step_started = int(record["step"]), str(record.get("kind")), True
        h.step_elapsed_s = float(record.get("credited_s", 0.0))
        h.step_dose_j_g = float(record.get("credited_dose_j_g", 0.0))
    elif event == "step_end":
        h.step, h.kind, h.step_started = int(record["step"]) + 1, None, False
        h.step_elapsed_s = h.step_dose_j_g = 0.0
    elif h.step_started and record.get("step") == h.step and "step_elapsed_s" in record:
        h.step_elapsed_s = float(record["step_elapsed_s"])
        h.step_dose_j_g = float(record.get("step_dose_j_g", h.step_dose_j_g))
    if event == "pause":
        h.paused = True
    elif event in ("resume", "gap"):
        h.paused = False
    if event == "interrupt":
        h.interrupt_reason = str(record.get("reason", ""))
    elif event == "gap":
        h.gaps.append(Gap(float(record["start_t"]), float(record["end_t"]), int(record["step"]),
                          str(record.get("reason", ""))))
        h.interrupt_reason = ""
    elif event == "end":
        h.ended, h.end_reason = str(record.get("status", "?")), str(record.get("reason", ""))


def record_path(records_dir: Path, run_id: str) -> Path:
    """The record of run ``run_id``; a :class:`RunNotFound` when there is none."""
    path = Path(records_dir) / RUNS_DIR / f"{run_id}.jsonl"
    if not path.is_file():
        raise RunNotFound(f"run {run_id}: no record {path} (`millctl recipe list` shows the unfinished runs)")
    return path


def unfinished_runs(records_dir: Path) -> list[RunHistory]:
    """Every run under ``records_dir`` whose record has no end and that no process runs, oldest first."""
    runs = Path(records_dir) / RUNS_DIR
    paths = sorted(runs.glob("*.jsonl")) if runs.is_dir() else []
    return [h for path in paths if not is_live(path) and (h := unfinished_history(path)) is not None]


def unfinished_history(path: Path) -> RunHistory | None:
    """The history of a record with no end, else None (ended, or not a readable run record: never fatal).

    Reads only the tail of a record that ended (most of them); is_live() says whether a process runs it.
    """
    if not _may_be_open(path):
        return None
    try:
        history = read_history(path)
    except RunNotFound:
        return None
    return history if history.ended is None else None


def _may_be_open(path: Path) -> bool:
    """False when the record's last line is its ``end`` (reads only the tail): most records, skipped cheaply."""
    try:
        with path.open("rb") as handle:
            handle.seek(0, os.SEEK_END)
            size = handle.tell()
            handle.seek(max(size - 4096, 0))
            tail = handle.read().rstrip(b"\n").rsplit(b"\n", 1)[-1]
    except OSError:
        return False
    try:
        last = json.loads(tail)
    except (json.JSONDecodeError, UnicodeDecodeError):
        return True
    return not (isinstance(last, dict) and last.get("event") == "end")


def is_live(path: Path) -> bool:
    """True while a runner (in this or another process) holds the record's lock."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_CLOEXEC)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    finally:
        os.close(fd)
    return False


class RunLock:
    """An exclusive ``flock`` on a run record, held while its run is live (released with the process)."""

    def __init__(self, path: Path, fd: int) -> None:
        self.path = path
        self._fd: int | None = fd

    @classmethod
    def acquire(cls, path: Path) -> RunLock:
        """Create the record if needed and lock it; :class:`RunNotResumable` when another runner holds it."""
        try:
            path.parent.mkdir(mode=0o750, parents=True, exist_ok=True)
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_APPEND | os.O_CLOEXEC, RECORD_MODE)
        except OSError as exc:
            raise RunNotResumable(f"run record {path}: cannot open it: {exc}") from None
        for _ in range(LOCK_TRIES):  # a reader's shared lock lasts microseconds
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                return cls(path, fd)
            except BlockingIOError:
                time.sleep(LOCK_RETRY_S)
        os.close(fd)
        raise RunNotResumable(f"run {path.stem} is running (or being resumed) now, in this service or another "
                              f"sharing {path.parent}: one runner per run")

    def release(self, *, remove_if_empty: bool = False) -> None:
        """Unlock (idempotent); ``remove_if_empty``: delete a record no run wrote to (a start that was refused)."""
        if self._fd is None:
            return
        if remove_if_empty and os.fstat(self._fd).st_size == 0:
            self.path.unlink(missing_ok=True)
        os.close(self._fd)
        self._fd = None


def repair_tail(path: Path) -> int:
    """Cut a torn last line (no newline: a write a kill or power loss cut short) off a record; return the bytes cut."""
    with path.open("rb+") as handle:
        handle.seek(0, os.SEEK_END)
        size = handle.tell()
        if size == 0:
            return 0
        handle.seek(max(size - 65_536, 0))
        tail = handle.read()
        if tail.endswith(b"\n"):
            return 0
        cut_at = size - len(tail) + tail.rfind(b"\n") + 1 if b"\n" in tail else 0
        handle.truncate(cut_at)
        handle.flush()
        os.fsync(handle.fileno())
        return size - cut_at


__all__ = [
    "RUNS_DIR",
    "RUN_ID_PATTERN",
    "Gap",
    "RunHistory",
    "RunLock",
    "RunNotFound",
    "RunNotResumable",
    "clock_stamp",
    "is_live",
    "new_run_id",
    "read_history",
    "record_path",
    "repair_tail",
    "unfinished_history",
    "unfinished_runs",
]
