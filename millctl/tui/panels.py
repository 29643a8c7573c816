"""The main screen's panels: drives, furnace, envelope, physics, link health, controller and recipe.

Each panel takes the service's status (:class:`millctl.api.StatusOut`) in
:meth:`show`; none of them talks to the service itself.
"""

from __future__ import annotations

from collections import deque

from rich.text import Text
from textual.app import ComposeResult
from textual.containers import Vertical
from textual.widgets import Sparkline, Static

from millctl.api import BusCondition, ControlOut, EnvelopeOut, RecipeOut, StatusOut
from millctl.client import describe_bus_health
from millctl.tui.format import duration, e2e_errors, num, state_style
from millctl.tui.plot import Curve, operating_points, render_plot
from millctl.tui.styles import NARROW_BELOW_COLUMNS

TREND_SAMPLES = 120
"""Samples kept in each trend sparkline (the service streams a status every 0.25 s: 30 s)."""
DEAD_FACTOR = 3.0
"""A link is shown dead (red) when its frames are older than this many stale bounds, or never arrived."""


class TrendPanel(Vertical):
    """A bordered panel with a text block above a sparkline of one measured quantity."""

    def __init__(self, title: str, *, id: str) -> None:
        super().__init__(id=id, classes="panel")
        self.border_title = title
        self.history: deque[float] = deque(maxlen=TREND_SAMPLES)

    def compose(self) -> ComposeResult:
        """A text block and the trend."""
        yield Static(id=f"{self.id}-text", classes="panel-text")
        yield Sparkline([], id=f"{self.id}-trend", classes="trend")

    @property
    def compact(self) -> bool:
        """A narrow terminal (80 columns: 26 of text) has no room for "setpoint 180.0 → target 180.0 rpm"."""
        return self.app.size.width < NARROW_BELOW_COLUMNS

    @property
    def setpoint_label(self) -> str:
        """The label before the ramped setpoint."""
        return "set " if self.compact else "setpoint "

    @property
    def target_label(self) -> str:
        """The label between the ramped setpoint and the ramp's target (never cut off: its value follows)."""
        return " → " if self.compact else " → target "

    def set_content(self, text: Text, sample: float | None) -> None:
        """Show ``text`` and append ``sample`` (skipped when unknown) to the trend."""
        self.query_one(f"#{self.id}-text", Static).update(text, layout=False)
        if sample is not None:
            self.history.append(sample)
            self.query_one(f"#{self.id}-trend", Sparkline).data = list(self.history)


class DrivePanel(TrendPanel):
    """One drive: commanded setpoint, ramp target, measured speed and torque, with a trend of the measured speed."""

    def __init__(self, axis: str, title: str, *, id: str) -> None:
        super().__init__(title, id=id)
        self.axis = axis

    def show(self, status: StatusOut) -> None:
        """Update from a status."""
        a = self.axis
        measured = getattr(status, f"measured_{a}_rpm")
        text = Text.assemble(
            ("measured ", "dim"), (num(measured, ".1f", " rpm"), "bold"), "\n",
            (self.setpoint_label, "dim"), num(getattr(status, f"setpoint_{a}_rpm"), ".1f"),
            (self.target_label, "dim"), num(getattr(status, f"target_{a}_rpm"), ".1f", " rpm"), "\n",
            ("torque ", "dim"), num(getattr(status, f"{a}_torque_nm"), ".2f", " N·m"),
        )
        self.set_content(text, measured)


class FurnacePanel(TrendPanel):
    """The furnace: temperature, ramped setpoint and target, heater duty, with a temperature trend."""

    def show(self, status: StatusOut) -> None:
        """Update from a status."""
        temp = status.furnace_temp_c
        target = status.furnace_target_c
        heater = status.heater_pct
        on = status.heater_on
        text = Text.assemble(
            ("measured ", "dim"), (num(temp, ".1f", " °C"), "bold"), "\n",
            (self.setpoint_label, "dim"), num(status.furnace_setpoint_c, ".1f"),
            (self.target_label, "dim"),
            num(target, ".1f", " °C") if target is not None else ("heater off", "dim"), "\n",
            ("heater ", "dim"), num(heater, ".0f", " %"), ("" if on is None else (" on" if on else " off"), "dim"),
        )
        self.set_content(text, temp)


NARROW_SUMMARY_BELOW = 60
"""Envelope panels narrower than this (columns) say the summary in fewer words."""


class EnvelopePanel(Static):
    """The limit curve with the operating point, the limit and margin here, the law, and its regime warning (once)."""

    def __init__(self, *, id: str) -> None:
        super().__init__(id=id, classes="panel")
        self.border_title = "envelope  ω_r ↑ rpm  (● measured, ○ target)"
        self.curve: Curve | None = None
        self.envelope: EnvelopeOut | None = None
        self.status: StatusOut | None = None

    def set_envelope(self, envelope: EnvelopeOut) -> None:
        """Take the service's limit curve (``/v1/envelope``)."""
        self.envelope = envelope
        self.curve = Curve.from_envelope(envelope)
        self.redraw()

    def show(self, status: StatusOut) -> None:
        """Update from a status."""
        self.status = status
        self.redraw()

    def on_resize(self) -> None:
        """Redraw the plot for the new size."""
        self.redraw()

    def redraw(self) -> None:
        """Render the plot and the summary lines."""
        s, curve = self.status, self.curve
        if curve is None:
            self.update(Text("waiting for the service’s envelope…", style="dim"), layout=False)
            return
        point, target = operating_points(s)
        width = max(self.content_size.width, 20)
        summary = self.summary(width)
        lines = len(summary.wrap(self.app.console, width))  # the summary wraps on a narrow screen: the plot gives way
        text = render_plot(curve, width, max(self.content_size.height - lines, 4), point, target)
        text.append("\n")
        text.append_text(summary)
        self.update(text, layout=False)

    def summary(self, width: int) -> Text:
        """The lines under the plot: the limit and margin here, the law, and the regime warning (said once).

        Under 60 columns (an 80 × 24 terminal) the same in fewer words, so the plot keeps its rows.
        """
        s, env = self.status, self.envelope
        narrow = width < NARROW_SUMMARY_BELOW
        w_v = s.setpoint_vibration_rpm if s else None
        limit = s.limit_rotary_rpm if s else None
        text = Text.assemble(
            ("limit " if not narrow else "", "dim"), (f"ω_r ≤ {num(limit)} rpm", "bold"),
            (f" at ω_v = {num(w_v)} rpm" if not narrow else f" at ω_v {num(w_v)}", "dim"),
            ("   margin " if not narrow else " · margin ", "dim"), num(s.margin_rpm if s else None, ".1f", " rpm"),
        )
        law = s.law if s else (env.law if env else "?")
        margin = s.margin if s else (env.margin if env else None)
        shown_margin = num(margin, ".0%")
        text.append(f"\nlaw {law} · margin {shown_margin} · " if not narrow else f"\n{law} −{shown_margin} · ",
                    style="dim")
        mono = bool(getattr(self.app, "no_color", False))  # NO_COLOR: no colour word names a part of the curve
        if not mono:
            text.append("green: every-cycle bound" if not narrow else "green: every-cycle", style="green")
        text.append((" · " if not mono else "") + ("e: all laws" if not narrow else "e"), style="dim")
        if env is not None and env.regime is not None:
            here = s is not None and not s.law_is_every_cycle  # the setpoint is in the region: say it louder
            short = f"ω_v > {env.regime.above_vibration_rpm:.1f} rpm: not every-cycle"
            words = env.regime.summary if not narrow else short
            text.append(f"\n⚠ {words}" + ("" if mono else " (yellow)"), style="bold yellow" if here else "yellow")
        return text


class PhysicsPanel(Static):
    """Physics telemetry from the node: detached or pinned, detachment angle θ_d, impact rate and energy, shear."""

    def show(self, status: StatusOut) -> None:
        """Update from a status."""
        detached = status.detached
        regime = "—" if detached is None else ("detached (flying)" if detached else "pinned to the wall")
        self.update(layout=False, content=Text.assemble(
            ("rods ", "dim"), (regime, "bold"), "\n",
            ("θ_d ", "dim"), num(status.theta_d_deg, ".1f", "°"), "\n",
            ("impacts ", "dim"), num(status.impact_rate_hz, ".1f", " Hz"), "\n",
            ("impact energy ", "dim"), num(status.impact_energy_mj, ".2f", " mJ"), "\n",
            ("shear ", "dim"), num(status.shear_kpa, ".1f", " kPa"),
        ))


def link_text(status: StatusOut) -> Text:
    """The link panel's text: per frame kind age, E2E errors and score; invalid frames; the CAN bus when unwell."""
    text = Text()
    for name, link in sorted(status.link.items()):
        age, bound = link.age_s, link.stale_after_s or 1.0
        dead = age is None or age > DEAD_FACTOR * bound
        style = "bold red" if dead else ("dim" if link.stale else "")
        errors = e2e_errors(link.e2e)
        flag = " DEAD" if dead else (" STALE" if link.stale else "")
        score = link.e2e_score
        short = name.removesuffix("Telemetry")
        line = f"{short[:10]:<10} {num(age, '.2f', ' s'):>8}  e2e err {errors} score {score}{flag}\n"
        text.append(line, style=style)
    invalid = status.invalid_frames
    text.append(f"invalid frames {invalid}", style="red" if invalid else "dim")
    if receive_errors := status.receive_errors:
        text.append(f"  receive errors {receive_errors}", style="red")
    health = status.bus_health
    if health.condition is not BusCondition.ERROR_ACTIVE or health.error_frames:
        text.append(f"\nCAN {describe_bus_health(health)}", style="bold red")
    return text


class LinkPanel(Static):
    """Node link health per frame kind: age, E2E errors and score; dim when stale, red when dead."""

    def show(self, status: StatusOut) -> None:
        """Update from a status."""
        self.update(link_text(status), layout=False)


class StatePanel(Static):
    """Controller and node state, node faults, control holder, and the running recipe (step i/N, time left)."""

    def show(self, status: StatusOut | None, control: ControlOut | None, mine: bool,
             recipe: RecipeOut | None) -> None:
        """Update from a status, the lease (``/v1/control``), whether we hold it, and ``/v1/recipe``."""
        state = status.state if status else None
        text = Text.assemble(("controller ", "dim"), (f" {state or '—'} ", state_style(state)))
        faults = " ".join(status.node_faults if status else []) or "no faults"
        node = status.node_state if status else None
        text.append_text(Text.assemble("\n", ("node ", "dim"), f"{node or '—'}  {faults}"))
        backend = status.drives_backend if status else ""
        for drive in status.drives if status else []:  # CiA 402: each drive's power state (and a furnace node's)
            where = f"{backend} node {drive.node_id}" if drive.node_id is not None else drive.detail.split(";")[0]
            text.append_text(Text.assemble("\n", (f"{drive.name} ", "dim"), f"{drive.state}  ({where})"))
        holder = control.holder if control else None
        who = "you (this terminal)" if mine else (holder or "nobody")
        expired = " (lease expired)" if control and control.expired else ""
        text.append_text(Text.assemble("\n", ("control ", "dim"), (who + expired, "bold" if mine else "")))
        progress = recipe.progress if recipe else None
        if recipe is not None and progress is not None:
            resumes = " — p resumes" if recipe.active and progress.state.resumable else ""
            text.append_text(Text.assemble(
                "\n", ("recipe ", "dim"), (progress.recipe, "bold"), f"  {progress.state}{resumes}", "\n",
                ("step ", "dim"), f"{progress.step}/{progress.steps} {progress.kind or ''}",
                ("  left ", "dim"), duration(progress.remaining_s),
            ))
            if progress.reason:
                text.append(f"\n{progress.reason}", style="dim")
        else:
            text.append_text(Text.assemble("\n", ("recipe ", "dim"), "none (n runs one)"))
        self.update(text, layout=False)


__all__ = ["DrivePanel", "EnvelopePanel", "FurnacePanel", "LinkPanel", "PhysicsPanel", "StatePanel", "TrendPanel"]
