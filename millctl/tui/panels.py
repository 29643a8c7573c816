"""The main screen's panels: drives, furnace, envelope, physics, link health, controller and recipe.

Each panel takes the service's status dict (``GET /v1/status``, see
:class:`millctl.controller.status.Status`) in :meth:`show`; none of them
talks to the service itself.
"""

from __future__ import annotations

from collections import deque
from typing import Any

from rich.text import Text
from textual.app import ComposeResult
from textual.containers import Vertical
from textual.widgets import Sparkline, Static

from millctl.tui.format import duration, e2e_errors, num, state_style
from millctl.tui.plot import Curve, render_plot

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

    def show(self, status: dict[str, Any]) -> None:
        """Update from a status."""
        a = self.axis
        measured = status.get(f"measured_{a}_rpm")
        text = Text.assemble(
            ("measured ", "dim"), (num(measured, ".1f", " rpm"), "bold"), "\n",
            ("setpoint ", "dim"), num(status.get(f"setpoint_{a}_rpm"), ".1f"),
            (" → target ", "dim"), num(status.get(f"target_{a}_rpm"), ".1f", " rpm"), "\n",
            ("torque ", "dim"), num(status.get(f"{a}_torque_nm"), ".2f", " N·m"),
        )
        self.set_content(text, measured)


class FurnacePanel(TrendPanel):
    """The furnace: temperature, ramped setpoint and target, heater duty, with a temperature trend."""

    def show(self, status: dict[str, Any]) -> None:
        """Update from a status."""
        temp = status.get("furnace_temp_c")
        target = status.get("furnace_target_c")
        heater = status.get("heater_pct")
        on = status.get("heater_on")
        text = Text.assemble(
            ("measured ", "dim"), (num(temp, ".1f", " °C"), "bold"), "\n",
            ("setpoint ", "dim"), num(status.get("furnace_setpoint_c"), ".1f"),
            (" → target ", "dim"), num(target, ".1f", " °C") if target is not None else ("heater off", "dim"), "\n",
            ("heater ", "dim"), num(heater, ".0f", " %"), ("" if on is None else (" on" if on else " off"), "dim"),
        )
        self.set_content(text, temp)


class EnvelopePanel(Static):
    """The limit curve with the operating point, the limit and margin here, the law, and its every-cycle warning."""

    def __init__(self, *, id: str) -> None:
        super().__init__(id=id, classes="panel")
        self.border_title = "envelope  ω_r ↑ rpm  (● measured, ○ target)"
        self.curve: Curve | None = None
        self.envelope: dict[str, Any] = {}
        self.status: dict[str, Any] = {}

    def set_envelope(self, envelope: dict[str, Any]) -> None:
        """Take the service's limit curve (``/v1/envelope``)."""
        self.envelope = envelope
        self.curve = Curve.from_envelope(envelope)
        self.redraw()

    def show(self, status: dict[str, Any]) -> None:
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
        point = None
        if s.get("measured_vibration_rpm") is not None and s.get("measured_rotary_rpm") is not None:
            point = (float(s["measured_vibration_rpm"]), float(s["measured_rotary_rpm"]))
        target = None
        if s.get("target_vibration_rpm") is not None:
            target = (float(s["target_vibration_rpm"]), float(s["target_rotary_rpm"]))
        width = max(self.content_size.width, 20)
        height = max(self.content_size.height - 3, 4)
        text = render_plot(curve, width, height, point, target)
        text.append("\n")
        w_v = s.get("setpoint_vibration_rpm")
        text.append_text(Text.assemble(
            ("limit ", "dim"), (f"ω_r ≤ {num(s.get('limit_rotary_rpm'))} rpm", "bold"),
            (f" at ω_v = {num(w_v)} rpm", "dim"), ("   margin ", "dim"), num(s.get("margin_rpm"), ".1f", " rpm"),
        ))
        law = s.get("law", self.envelope.get("law", "?"))
        margin = s.get("margin", self.envelope.get("margin"))
        if s and not s.get("law_is_every_cycle", True):
            text.append(f"\n⚠ at this ω_v {law} is not the every-cycle bound (docs/model.md)", style="bold yellow")
        start = curve.first_not_every_cycle_rpm()
        text.append(f"\nlaw {law} · margin {num(margin, '.0%')} · ", style="dim")
        text.append("green: every-cycle", style="green")
        if start is not None:
            text.append(" · ", style="dim")
            text.append(f"yellow: not (ω_v ≥ {start:.0f} rpm)", style="yellow")
        self.update(text, layout=False)


class PhysicsPanel(Static):
    """Physics telemetry from the node: detached or pinned, detachment angle θ_d, impact rate and energy, shear."""

    def show(self, status: dict[str, Any]) -> None:
        """Update from a status."""
        detached = status.get("detached")
        regime = "—" if detached is None else ("detached (flying)" if detached else "pinned to the wall")
        self.update(layout=False, content=Text.assemble(
            ("rods ", "dim"), (regime, "bold"), "\n",
            ("θ_d ", "dim"), num(status.get("theta_d_deg"), ".1f", "°"), "\n",
            ("impacts ", "dim"), num(status.get("impact_rate_hz"), ".1f", " Hz"), "\n",
            ("impact energy ", "dim"), num(status.get("impact_energy_mj"), ".2f", " mJ"), "\n",
            ("shear ", "dim"), num(status.get("shear_kpa"), ".1f", " kPa"),
        ))


class LinkPanel(Static):
    """Node link health per frame kind: age, E2E errors and score; dim when stale, red when dead."""

    def show(self, status: dict[str, Any]) -> None:
        """Update from a status."""
        text = Text()
        for name, link in sorted(status.get("link", {}).items()):
            age, bound = link.get("age_s"), float(link.get("stale_after_s") or 1.0)
            dead = age is None or age > DEAD_FACTOR * bound
            style = "bold red" if dead else ("dim" if link.get("stale") else "")
            errors = e2e_errors(link.get("e2e", {}))
            flag = " DEAD" if dead else (" STALE" if link.get("stale") else "")
            score = link.get("e2e_score", 0)
            short = name.removesuffix("Telemetry")
            line = f"{short[:10]:<10} {num(age, '.2f', ' s'):>8}  e2e err {errors} score {score}{flag}\n"
            text.append(line, style=style)
        invalid = status.get("invalid_frames", 0)
        text.append(f"invalid frames {invalid}", style="red" if invalid else "dim")
        if receive_errors := status.get("receive_errors", 0):
            text.append(f"  receive errors {receive_errors}", style="red")
        self.update(text, layout=False)


class StatePanel(Static):
    """Controller and node state, node faults, control holder, and the running recipe (step i/N, time left)."""

    def show(self, status: dict[str, Any], control: dict[str, Any], mine: bool, recipe: dict[str, Any]) -> None:
        """Update from a status, the lease (``/v1/control``), whether we hold it, and ``/v1/recipe``."""
        state = str(status.get("state", "—"))
        text = Text.assemble(("controller ", "dim"), (f" {state} ", state_style(state)))
        faults = " ".join(status.get("node_faults") or []) or "no faults"
        text.append_text(Text.assemble("\n", ("node ", "dim"), f"{status.get('node_state') or '—'}  {faults}"))
        holder = control.get("holder")
        who = "you (this terminal)" if mine else (holder or "nobody")
        expired = " (lease expired)" if control.get("expired") else ""
        text.append_text(Text.assemble("\n", ("control ", "dim"), (who + expired, "bold" if mine else "")))
        progress = recipe.get("progress") or {}
        if progress:
            active = recipe.get("active")
            text.append_text(Text.assemble(
                "\n", ("recipe ", "dim"), (str(progress.get("recipe", "?")), "bold"),
                f"  {progress.get('state', '?')}"
                + (" — p resumes" if active and progress.get("state") in ("PAUSED", "HELD") else ""), "\n",
                ("step ", "dim"), f"{progress.get('step', 0)}/{progress.get('steps', 0)} {progress.get('kind') or ''}",
                ("  left ", "dim"), duration(progress.get("remaining_s")),
            ))
            if progress.get("reason"):
                text.append(f"\n{progress['reason']}", style="dim")
        else:
            text.append_text(Text.assemble("\n", ("recipe ", "dim"), "none (n runs one)"))
        self.update(text, layout=False)


__all__ = ["DrivePanel", "EnvelopePanel", "FurnacePanel", "LinkPanel", "PhysicsPanel", "StatePanel", "TrendPanel"]
