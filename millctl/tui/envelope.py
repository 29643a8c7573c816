"""The envelope view (key ``e``): which rotary speed is safe, every law, and where the mill is and is going.

The whole screen is the limit plot: the enforced curve (green where the
configured law is the every-cycle bound, yellow where it is not), every
other law of the service's ``GET /v1/envelope`` under it in a colour of its
own, the measured point ``●`` and the target ``○``; below it a legend in an
operator's words, the regime warning in full (once, with its number: the
service's :func:`millctl.safety.regime.regime_warning`, the same as
``millctl limits``), and the numbers at the operating point.
"""

from __future__ import annotations

from typing import ClassVar

from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import Vertical
from textual.screen import Screen
from textual.widgets import Footer, Static

from millctl.api import EnvelopeOut, StatusOut
from millctl.config.models import LimitLaw
from millctl.safety.envelope import LAW_IN_WORDS
from millctl.tui.format import num
from millctl.tui.plot import Curve, operating_points, render_plot

LAW_COLOUR = {
    LimitLaw.PAPER_EQ9: "blue",
    LimitLaw.PAPER_EVERY_CYCLE: "magenta",
    LimitLaw.CORRECTED_EVERY_PHASE: "cyan",
    LimitLaw.CORRECTED_BEST_PHASE: "bright_white",
}
"""The colour of each law's curve (the enforced curve is green and yellow)."""


def other_curves(envelope: EnvelopeOut) -> tuple[tuple[Curve, str], ...]:
    """Every law the service sends, without margin, with its colour."""
    names = envelope.points[0].laws_rotary_rpm if envelope.points else {}
    return tuple((Curve.from_envelope(envelope, law=name), LAW_COLOUR[LimitLaw(name)]) for name in names)


def legend(envelope: EnvelopeOut, status: StatusOut | None, no_color: bool = False) -> Text:
    """What each mark means, the regime warning in full, and the numbers at the operating point.

    Under NO_COLOR no colour word names a part of the curve: the regime is told by its ω_v (the ⚠ line).
    """
    text = Text()
    text.append("⣿ ", style="green")
    text.append(f"enforced limit: {envelope.law} − {envelope.margin:.0%} margin; below it is allowed ", style="bold")
    if no_color:
        text.append("(the every-cycle bound except where ⚠ says)\n" if envelope.regime else "\n")
    else:
        text.append("(green: every-cycle bound", style="green")
        text.append(", yellow: not)\n" if envelope.regime else ")\n", style="yellow" if envelope.regime else "green")
    names = envelope.points[0].laws_rotary_rpm if envelope.points else {}
    for name in names:
        law = LimitLaw(name)
        configured = " — configured law, no margin" if name == envelope.law else ""
        text.append("⣿ ", style=LAW_COLOUR[law])
        text.append(f"{name}: {LAW_IN_WORDS[law]}{configured}\n")
    text.append("● ", style="bold")
    text.append("measured now (red: outside)   ")
    text.append("○ ", style="bold cyan")
    text.append("target (where the ramp is going)\n")
    if envelope.regime is not None:
        text.append(f"⚠ {envelope.regime.message}\n", style="bold yellow")
    if status is not None:
        text.append_text(Text.assemble(
            ("at ω_v = ", "bold"), num(status.setpoint_vibration_rpm), " rpm: ",
            ("limit ω_r ≤ ", "bold"), num(status.limit_rotary_rpm), " rpm, ",
            ("ω_r ", "bold"), num(status.setpoint_rotary_rpm), " rpm, ",
            ("margin ", "bold"), num(status.margin_rpm, ".1f", " rpm"),
        ))
    return text


class EnvelopeScreen(Screen[None]):
    """The envelope, full screen; ``e`` or Escape goes back."""

    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("escape,e", "app.pop_screen", "Back"),
    ]

    def __init__(self, envelope: EnvelopeOut | None, status: StatusOut | None) -> None:
        super().__init__()
        self.envelope = envelope
        self.status = status

    def compose(self) -> ComposeResult:
        """The plot and its legend."""
        with Vertical(id="envelope-view", classes="panel"):
            yield Static(id="envelope-plot")
            yield Static(id="envelope-legend")
        yield Footer(compact=True)

    def on_mount(self) -> None:
        """Title and first drawing."""
        self.query_one("#envelope-view").border_title = "which rotary speed is safe: ω_r ↑ rpm against ω_v →"
        self.redraw()

    def on_resize(self) -> None:
        """Redraw the plot for the new size."""
        self.redraw()

    def show(self, envelope: EnvelopeOut | None, status: StatusOut | None) -> None:
        """Update from the service's envelope and the latest status."""
        self.envelope, self.status = envelope, status
        self.redraw()

    def redraw(self) -> None:
        """The plot over the legend."""
        plot = self.query_one("#envelope-plot", Static)
        envelope, s = self.envelope, self.status
        if envelope is None:
            plot.update(Text("waiting for the service’s envelope…"), layout=False)
            return
        point, target = operating_points(s)
        width = max(plot.content_size.width, 20)
        height = max(plot.content_size.height, 6)
        plot.update(render_plot(Curve.from_envelope(envelope), width, height, point, target,
                                others=other_curves(envelope)), layout=False)
        self.query_one("#envelope-legend", Static).update(legend(envelope, s, bool(getattr(self.app, "no_color",
                                                                                            False))))


__all__ = ["LAW_COLOUR", "EnvelopeScreen", "legend", "other_curves"]
