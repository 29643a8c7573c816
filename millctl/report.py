"""The report of one recipe run: figures and a self-contained HTML page, from the run record alone.

The run record (``<records_dir>/runs/<run_id>.jsonl``) holds the run's
``start`` (recipe, law, margin, furnace band, powder charge), its samples
(:mod:`millctl.recipes.samples`) and its events (steps, pauses, holds,
refusals, trips, the end). The report draws, against time since the start:

* the rotary speed (setpoint and measured) under the enforced limit at the
  present ω_v, the region above the limit shaded, and the vibration speed;
* the margin to the limit (rpm);
* the furnace temperature against its setpoint and the recipe's band;
* the specific energy dose accumulated (kJ per g of powder);
* the control loop's lateness (ms, the worst per sample) under the node's
  watchdog bound and its warning line: a trip of WATCHDOG or stale telemetry
  right after a late loop is named host starvation, with the figures, in the
  summary and on the figure (SAFETY 27);

with every event marked (trips and refusals red, pauses and holds orange,
step starts grey). ``millctl report RUN`` writes ``speeds.png``,
``margin.png``, ``furnace.png``, ``dose.png``, ``report.png`` (all four in
one) and ``report.html`` (the same, images embedded: one file to send).
"""

from __future__ import annotations

import base64
import html
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from millctl.errors import InvalidInputError
from millctl.looptime import HOST_CAUSES, WARN_FRACTION, starvation_message
from millctl.records import read_records

FIGURES = ("speeds", "host", "margin", "furnace", "dose")
"""The figure set, one PNG each, in the order of the page."""
MARKED = {"trip": "tab:red", "refusal": "tab:red", "fail": "tab:red", "abort": "tab:red", "pause": "tab:orange",
          "hold": "tab:orange", "resume": "tab:green", "step_start": "0.6"}
"""Events drawn on the time axes, and their colour."""


@dataclass
class RunRecord:
    """One run record, split into its start, its samples and its events (times in s since the start)."""

    path: Path
    start: dict[str, Any]
    samples: list[dict[str, Any]] = field(default_factory=list)
    events: list[dict[str, Any]] = field(default_factory=list)
    end: dict[str, Any] | None = None

    @property
    def run_id(self) -> str:
        """The run's id."""
        return str(self.start.get("run_id", self.path.stem))

    def series(self, key: str) -> tuple[list[float], list[float]]:
        """(t, value) of a sampled quantity, unknown values as NaN."""
        t = [float(s["t_s"]) for s in self.samples]
        values = [math.nan if s.get(key) is None else float(s[key]) for s in self.samples]
        return t, values


def load_run(path: str | Path) -> RunRecord:
    """Read a run record; an :class:`InvalidInputError` naming the file when it is not one."""
    path = Path(path)
    if not path.is_file():
        raise InvalidInputError(f"run record {path}: no such file")
    records = list(read_records(path))
    if not records or records[0].get("event") != "start":
        raise InvalidInputError(f"run record {path}: does not begin with a 'start' record (is it a run record?)")
    start = records[0]
    t0 = float(start.get("clock_s", 0.0))
    run = RunRecord(path, start)
    for record in records[1:]:
        record = {**record, "t_s": float(record.get("t_s", float(record.get("clock_s", t0)) - t0))}
        if record.get("event") == "sample":
            run.samples.append(record)
        else:
            run.events.append(record)
            if record.get("event") == "end":
                run.end = record
    if not run.samples:
        raise InvalidInputError(f"run record {path}: no samples (recorded by millctl ≥ 0.1 at service.run_sample_s)")
    return run


def find_run(run: str, records_dir: Path) -> Path:
    """A run record by path, or by run id under ``<records_dir>/runs``."""
    given = Path(run)
    if given.suffix == ".jsonl" or given.exists():
        return given
    candidate = records_dir / "runs" / f"{run}.jsonl"
    if not candidate.exists():
        raise InvalidInputError(f"run {run}: no record {candidate} (give the record's path, or the run id)")
    return candidate


def _mark_events(ax: Any, run: RunRecord) -> None:
    for event in run.events:
        colour = MARKED.get(str(event.get("event")))
        if colour is not None:
            ax.axvline(event["t_s"], color=colour, lw=0.8, ls="--" if colour == "0.6" else "-", alpha=0.8)


def draw(run: RunRecord, name: str, ax: Any) -> None:
    """Draw figure ``name`` of :data:`FIGURES` on ``ax``."""
    if name == "speeds":
        t, limit = run.series("limit_rotary_rpm")
        top = max([v for v in limit if math.isfinite(v)] + [1.0]) * 1.15
        ax.fill_between(t, [min(v, top) if math.isfinite(v) else top for v in limit], top, color="tab:red",
                        alpha=0.12, label="above the enforced limit (refused)")
        ax.plot(t, limit, color="tab:red", lw=1.2, label=f"enforced ω_r limit ({run.start.get('law', '?')})")
        ax.plot(*run.series("setpoint_rotary_rpm"), color="tab:blue", ls="--", lw=1, label="ω_r setpoint")
        ax.plot(*run.series("measured_rotary_rpm"), color="tab:blue", lw=1.5, label="ω_r measured")
        ax.set(ylabel="rotary speed ω_r (rpm)", ylim=(0, top))
        twin = ax.twinx()
        twin.plot(*run.series("measured_vibration_rpm"), color="tab:purple", lw=1, alpha=0.5)
        twin.set_ylabel("vibration speed ω_v (rpm, purple)", color="tab:purple")
    elif name == "host":
        t, lateness = run.series("loop_lateness_ms")
        bound_ms = next((float(s["watchdog_bound_ms"]) for s in run.samples if s.get("watchdog_bound_ms")), None)
        ax.plot(t, lateness, color="tab:gray", lw=1.2, label="control loop lateness (worst per sample)")
        if bound_ms is not None:
            ax.axhline(bound_ms, color="tab:red", lw=1, label=f"the node's watchdog bound ({bound_ms:.0f} ms)")
            ax.axhline(WARN_FRACTION * bound_ms, color="tab:orange", lw=1, ls="--", label="warning")
        else:
            ax.text(0.5, 0.5, "no loop lateness in this record (a service before SAFETY 27)", transform=ax.transAxes,
                    ha="center", va="center", color="0.4")
        for t_s, named in host_starvation(run):
            ax.annotate(named, (t_s, 0.0), xytext=(4, 24), textcoords="offset points", fontsize=7, color="tab:red")
        ax.set(ylabel="loop lateness (ms)")
    elif name == "margin":
        ax.plot(*run.series("margin_rpm"), color="tab:green", lw=1.5, label="margin to the limit (limit − ω_r)")
        ax.axhline(0.0, color="tab:red", lw=1, label="the limit")
        ax.set(ylabel="margin (rpm)")
    elif name == "furnace":
        t, setpoint = run.series("furnace_setpoint_c")
        band = float(run.start.get("furnace_band_c") or 0.0)
        ax.fill_between(t, [v - band for v in setpoint], [v + band for v in setpoint], color="tab:orange",
                        alpha=0.15, label=f"setpoint ± {band:g} °C (the recipe's band)")
        ax.plot(t, setpoint, color="tab:orange", ls="--", lw=1, label="furnace setpoint")
        ax.plot(*run.series("furnace_temp_c"), color="tab:red", lw=1.5, label="furnace measured")
        ax.set(ylabel="temperature (°C)")
    elif name == "dose":
        t, dose = run.series("dose_j_g")
        ax.plot(t, [v / 1e3 for v in dose], color="tab:brown", lw=1.5, label="specific energy dose")
        ax.set(ylabel="dose (kJ/g)")
    else:
        raise ValueError(f"unknown figure {name!r}; one of {', '.join(FIGURES)}")
    _mark_events(ax, run)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")


def host_starvation(run: RunRecord) -> list[tuple[float, str]]:
    """Trips whose cause was a late control loop: (time, the named cause with its figures), from the samples.

    A WATCHDOG or stale-telemetry trip with a sample of lateness at the warning line or past it in the
    trip's sample or the one before it.
    """
    named = []
    for event in run.events:
        cause = str(event.get("cause", ""))
        if event.get("event") != "trip" or not any(word in cause for word in HOST_CAUSES):
            continue
        before = [s for s in run.samples if s["t_s"] <= event["t_s"] + 1e-9][-2:]
        late = [(float(s["loop_lateness_ms"]), float(s["watchdog_bound_ms"])) for s in before
                if s.get("loop_lateness_ms") is not None and s.get("watchdog_bound_ms")]
        worst = max(late, default=None)
        if worst is not None and worst[0] >= WARN_FRACTION * worst[1]:
            message = starvation_message(worst[0] / 1e3, worst[1] / 1e3)
            named.append((float(event["t_s"]), f"host starvation: {message}"))
    return named


def _title(run: RunRecord) -> str:
    status = run.end.get("status", "?") if run.end else "unfinished"
    return f"{run.start.get('recipe', '?')} — run {run.run_id}: {status}"


def write_report(run: RunRecord, out_dir: Path) -> list[Path]:
    """Write the figure set, the overview and the HTML page into ``out_dir``; return the files written."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise InvalidInputError("millctl report needs matplotlib: pip install 'millctl[plot]'") from None
    from millctl.cli.output import write_atomically

    out_dir.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    images: dict[str, bytes] = {}
    for name in FIGURES:
        fig, ax = plt.subplots(figsize=(10, 3.2), layout="constrained")
        draw(run, name, ax)
        ax.set(xlabel="time since the start (s)", title=f"{name}: {_title(run)}")
        path = out_dir / f"{name}.png"
        _save(fig, path, 110)
        plt.close(fig)
        images[name] = path.read_bytes()
        written.append(path)
    fig, axes = plt.subplots(len(FIGURES), 1, figsize=(10, 13), sharex=True, layout="constrained")
    for name, ax in zip(FIGURES, axes, strict=True):
        draw(run, name, ax)
    axes[-1].set(xlabel="time since the start (s)")
    fig.suptitle(_title(run))
    overview = out_dir / "report.png"
    _save(fig, overview, 100)
    plt.close(fig)
    written.append(overview)
    page = out_dir / "report.html"
    text = render_html(run, images)
    write_atomically(page, lambda tmp: _write_text(tmp, text))
    written.append(page)
    return written


def _save(fig: Any, path: Path, dpi: int) -> None:
    from millctl.cli.output import write_atomically

    def save(tmp: Path) -> None:
        fig.savefig(tmp, dpi=dpi, format="png")

    write_atomically(path, save)


def _write_text(path: Path, text: str) -> None:
    path.write_text(text, encoding="utf-8")


def summary(run: RunRecord) -> dict[str, Any]:
    """The run in figures: state, duration, speeds, least margin, temperatures, dose, trips and refusals."""
    def finite(key: str) -> list[float]:
        return [v for v in run.series(key)[1] if math.isfinite(v)]

    margins, temps = finite("margin_rpm"), finite("furnace_temp_c")
    return {
        "run_id": run.run_id,
        "recipe": run.start.get("recipe"),
        "status": run.end.get("status") if run.end else None,
        "reason": run.end.get("reason") if run.end else None,
        "law": run.start.get("law"),
        "margin": run.start.get("margin"),
        "elapsed_s": run.end.get("elapsed_s") if run.end else run.samples[-1]["t_s"],
        "samples": len(run.samples),
        "max_measured_rotary_rpm": max(finite("measured_rotary_rpm"), default=None),
        "min_margin_rpm": min(margins, default=None),
        "max_furnace_temp_c": max(temps, default=None),
        "dose_kj_g": run.samples[-1].get("dose_j_g", 0.0) / 1e3,
        "trips": sum(1 for e in run.events if e.get("event") == "trip"),
        "refusals": sum(1 for e in run.events if e.get("event") == "refusal"),
        "max_loop_lateness_ms": max(finite("loop_lateness_ms"), default=None),
        "host_starvation": "; ".join(named for _, named in host_starvation(run)) or None,
    }


def render_html(run: RunRecord, images: dict[str, bytes]) -> str:
    """One HTML file: the summary, every figure (embedded PNG) and the events."""
    esc = html.escape
    rows = "".join(f"<tr><th>{esc(k)}</th><td>{esc(_shown(v))}</td></tr>" for k, v in summary(run).items())
    figures = "".join(
        f'<figure><img alt="{esc(name)}" src="data:image/png;base64,{base64.b64encode(data).decode()}">'
        f"<figcaption>{esc(name)}</figcaption></figure>"
        for name, data in images.items()
    )
    events = "".join(
        f"<tr><td>{e['t_s']:.1f}</td><td>{esc(str(e.get('event')))}</td><td>{esc(str(e.get('step', '')))}</td>"
        f"<td>{esc(_details(e))}</td></tr>"
        for e in run.events
    )
    return (
        "<!doctype html><html lang=en><meta charset=utf-8>"
        f"<title>{esc(_title(run))}</title>"
        "<style>body{font-family:sans-serif;max-width:1100px;margin:auto}img{width:100%}"
        "table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:2px 8px;text-align:left}</style>"
        f"<h1>{esc(_title(run))}</h1><p>record: {esc(str(run.path))}</p>"
        f"<h2>Summary</h2><table>{rows}</table><h2>Figures</h2>{figures}"
        f"<h2>Events</h2><table><tr><th>t (s)</th><th>event</th><th>step</th><th>details</th></tr>{events}</table>"
        "</html>\n"
    )


def _shown(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return "—" if value is None else str(value)


def _details(event: dict[str, Any]) -> str:
    skip = {"run_id", "event", "clock_s", "t_s", "step"}
    return ", ".join(f"{k} = {_shown(v)}" for k, v in event.items() if k not in skip)


__all__ = ["FIGURES", "RunRecord", "draw", "find_run", "load_run", "render_html", "summary", "write_report"]
