"""The results file: one row per point with every parameter and metric, Parquet (pyarrow) or CSV.

The file carries the study's fingerprint (a hash of the study and its base
configuration), so that a rerun resumes only the study that wrote it: finished
points are read back and not recomputed. CSV rows are appended and flushed as
points finish (a cut-off last line is dropped on resume); Parquet is rewritten
atomically after each batch, so an interruption leaves the last complete file.

One run at a time per file: :meth:`ResultsStore.lock` takes an exclusive ``fcntl`` lock on
``FILE.lock`` (next to it, holding the runner's PID) for as long as the run lasts; a second run
on the same file is refused with the holder's PID. The kernel drops the lock when the holder
exits, however it exits (SIGKILL included), so a stale lock file never blocks.
"""

from __future__ import annotations

import csv
import fcntl
import io
import json
import math
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from millctl.cli.output import write_atomically
from millctl.errors import InvalidInputError

FINGERPRINT_KEY = "millctl.study.fingerprint"
CSV_MARK = "# millctl study fingerprint="
TEXT_COLUMNS = frozenset({"key", "violations", "cam_shape", "rod_material", "vial_material", "variant"})
BOOL_COLUMNS = frozenset({"feasible"})
INT_COLUMNS = frozenset({"point", "events", "n_rods"})


def _typed(column: str, text: str) -> Any:
    if column in TEXT_COLUMNS:
        return text
    if column in BOOL_COLUMNS:
        return text == "True"
    if column in INT_COLUMNS:
        return int(text)
    return float(text) if text else math.nan


def _pyarrow() -> Any:
    try:
        import pyarrow
        import pyarrow.parquet
    except ImportError:
        raise InvalidInputError(
            "Parquet results need pyarrow: pip install 'millctl[study]', or write CSV with --csv"
        ) from None
    return pyarrow


class ResultsStore:
    """Rows of one study in one file, keyed by the point's parameters; ``path`` None keeps them in memory only."""

    def __init__(self, path: Path | None, fingerprint: str) -> None:
        self.path = None if path is None else Path(path)
        if self.path is not None and self.path.exists() and not self.path.is_file():
            # the file is replaced atomically (rename over it): never over a device, a pipe or a directory
            raise InvalidInputError(f"results file {self.path} exists and is not a regular file; give another --out")
        self.fingerprint = fingerprint
        self.csv = self.path is not None and self.path.suffix.lower() == ".csv"
        self.rows: dict[str, dict[str, Any]] = {}
        self._columns: list[str] | None = None
        self._lock_fd: int | None = None

    # ------------------------------------------------------------------ one run per file
    @property
    def lock_path(self) -> Path | None:
        """``FILE.lock`` beside the results file (None in memory)."""
        return None if self.path is None else self.path.with_name(self.path.name + ".lock")

    def lock(self) -> None:
        """Hold the results file for this process; refuse, naming the holder's PID, while another run holds it."""
        where = self.lock_path
        if where is None or self._lock_fd is not None:
            return
        try:
            fd = os.open(where, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as exc:
            raise InvalidInputError(f"cannot lock results file {self.path} ({where}: {exc.strerror})") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 64, 0).decode(errors="replace").strip() or "unknown"
            os.close(fd)
            raise InvalidInputError(
                f"results file {self.path} is in use by another study run (PID {holder}, lock {where}): "
                "wait for it to finish or stop it, or give another --out"
            ) from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        self._lock_fd = fd

    def unlock(self) -> None:
        """Let the results file go (the lock file stays; an unheld lock blocks nobody)."""
        if self._lock_fd is not None:
            os.ftruncate(self._lock_fd, 0)
            os.close(self._lock_fd)
            self._lock_fd = None

    # ------------------------------------------------------------------ reading
    def resume(self) -> int:
        """Read the rows already in the file (same study only); return how many."""
        if self.path is None or not self.path.exists():
            return 0
        rows, fingerprint = self._read_csv() if self.csv else self._read_parquet()
        if fingerprint != self.fingerprint:
            raise InvalidInputError(
                f"{self.path} holds results of another study or base configuration (fingerprint "
                f"{fingerprint or 'none'} ≠ {self.fingerprint}): give another --out, or --fresh to overwrite it"
            )
        for row in rows:
            self.rows[row["key"]] = row
        self._columns = list(rows[0]) if rows else None
        return len(rows)

    def _file(self) -> Path:
        if self.path is None:
            raise AssertionError("an in-memory store has no file")
        return self.path

    def _read_csv(self) -> tuple[list[dict[str, Any]], str | None]:
        text = self._file().read_text(encoding="utf-8")
        first, _, body = text.partition("\n")
        fingerprint = first.removeprefix(CSV_MARK) if first.startswith(CSV_MARK) else None
        complete = body if body.endswith("\n") else body[: body.rfind("\n") + 1]  # a cut-off last row is dropped
        reader = csv.DictReader(io.StringIO(complete))
        rows = [{k: _typed(k, v) for k, v in r.items()} for r in reader if None not in r.values()]
        return rows, fingerprint

    def _read_parquet(self) -> tuple[list[dict[str, Any]], str | None]:
        pa = _pyarrow()
        try:
            table = pa.parquet.read_table(self.path)
        except (OSError, pa.ArrowInvalid) as exc:
            raise InvalidInputError(f"{self.path}: not a readable Parquet results file ({exc}); use --fresh") from None
        meta = table.schema.metadata or {}
        fingerprint = meta.get(FINGERPRINT_KEY.encode(), b"").decode() or None
        return table.to_pylist(), fingerprint

    # ------------------------------------------------------------------ writing
    def add(self, rows: Iterable[dict[str, Any]]) -> None:
        """Keep finished rows and write them out (append for CSV, atomic rewrite for Parquet)."""
        fresh = [r for r in rows if r["key"] not in self.rows]
        for row in fresh:
            self.rows[row["key"]] = row
        if not fresh or self.path is None:
            return
        if self.csv:
            self._append_csv(fresh)
        else:
            self._write_parquet()

    def _append_csv(self, rows: list[dict[str, Any]]) -> None:
        path = self._file()
        new_file = not path.exists() or self._columns is None
        if new_file:
            self._columns = list(rows[0])
        assert self._columns is not None
        with path.open("w" if new_file else "a", encoding="utf-8", newline="") as f:
            if new_file:
                f.write(f"{CSV_MARK}{self.fingerprint}\n")
            writer = csv.DictWriter(f, fieldnames=self._columns, extrasaction="ignore", lineterminator="\n")
            if new_file:
                writer.writeheader()
            for row in rows:
                writer.writerow({k: repr(v) if isinstance(v, float) else v for k, v in row.items()})
            f.flush()

    def _write_parquet(self) -> None:
        pa = _pyarrow()
        table = pa.Table.from_pylist(self.ordered())
        table = table.replace_schema_metadata({FINGERPRINT_KEY: self.fingerprint})
        write_atomically(self._file(), lambda tmp: pa.parquet.write_table(table, tmp))

    def reset(self) -> None:
        """Forget every row and remove the file (``--fresh``)."""
        self.rows.clear()
        self._columns = None
        if self.path is not None:
            self.path.unlink(missing_ok=True)

    def ordered(self) -> list[dict[str, Any]]:
        """Every row, by point number."""
        return sorted(self.rows.values(), key=lambda r: int(r["point"]))


def fingerprint_of(*parts: Any) -> str:
    """A short stable hash of JSON-able parts."""
    import hashlib

    text = json.dumps(parts, sort_keys=True, default=str, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


__all__ = ["ResultsStore", "fingerprint_of"]
