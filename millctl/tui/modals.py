"""Modal dialogs: set speeds and furnace (checked against the service's envelope before sending), confirm.

The setpoint dialog never decides a limit itself: every keystroke asks the
service's ``POST /v1/envelope/check`` (the interlock's own
:meth:`millctl.safety.Envelope.check`), shows the limit at the typed ω_v, and
refuses to send a point it rejects, with the interlock's reason.
"""

from __future__ import annotations

import math
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import ClassVar

from rich.text import Text
from textual import work
from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import Horizontal, Vertical
from textual.content import Content
from textual.screen import ModalScreen
from textual.widgets import Checkbox, Input, Label, Static

from millctl.api import CheckOut
from millctl.errors import MillctlError
from millctl.tui.styles import SHORT_BELOW_ROWS

Checker = Callable[[float, float, float | None], Awaitable[CheckOut]]
"""``check(rotary_rpm, vibration_rpm, temp_c)`` → the service's verdict."""


@dataclass(frozen=True)
class SetRequest:
    """What the operator asked for: speeds (rpm) and, when given, a furnace target (°C) or heater off."""

    rotary_rpm: float
    vibration_rpm: float
    furnace: bool
    temp_c: float | None
    rotary_rate_rpm_s: float | None = None
    """Ramp rate of ω_r (rpm/s); None: the drive's maximum (the service's default)."""
    vibration_rate_rpm_s: float | None = None
    linear: bool = False
    """One straight ramp in both axes (refused if the line leaves the envelope) instead of the sequenced path."""


class InputError(ValueError):
    """A field that is not a usable number."""


def _number(text: str, what: str) -> float:
    try:
        value = float(text.strip())
    except ValueError:
        raise InputError(f"{what}: {text.strip() or 'empty'!r} is not a number") from None
    if not math.isfinite(value):
        raise InputError(f"{what}: {value} is not a finite number")
    return value


def _rate(text: str, what: str) -> float | None:
    """A ramp rate (rpm/s), or None when the field is empty (the drive's maximum)."""
    if not text.strip():
        return None
    value = _number(text, what)
    if value <= 0.0:
        raise InputError(f"{what}: {value:g} rpm/s must be > 0 (empty: the drive's maximum)")
    return value


def parse_request(rot: str, vib: str, temp: str, rot_rate: str = "", vib_rate: str = "",
                  linear: bool = False) -> SetRequest:
    """Parse the dialog's fields; an empty furnace field leaves the furnace alone, ``off`` turns the heater off.

    Empty rate fields leave the ramp rates at the drives' maxima; ``linear`` asks for the straight path.
    """
    temp = temp.strip().lower()
    furnace = bool(temp)
    temp_c = None if temp in ("", "off") else _number(temp, "furnace °C")
    return SetRequest(_number(rot, "ω_r"), _number(vib, "ω_v"), furnace, temp_c,
                      _rate(rot_rate, "ω_r rate"), _rate(vib_rate, "ω_v rate"), linear)


class MarkedCheckbox(Checkbox):
    """A checkbox whose X is drawn only when ticked: without colour (NO_COLOR) ticked and unticked still differ.

    Textual's own draws the X always and tells the states apart by its colour alone.
    """

    @property
    def _button(self) -> Content:
        self.BUTTON_INNER = "X" if self.value else " "
        return super()._button


class SetpointsModal(ModalScreen[SetRequest | None]):
    """Ask for ω_r, ω_v (rpm) and a furnace target; show the live limit; refuse out-of-envelope values."""

    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("escape", "cancel", "Cancel"),
        Binding("enter", "send", "Send", priority=True),
    ]

    def __init__(self, check: Checker, rotary_rpm: float, vibration_rpm: float, temp_c: float | None) -> None:
        super().__init__()
        self.check = check
        self.initial = (rotary_rpm, vibration_rpm, temp_c)

    def compose(self) -> ComposeResult:
        """Three fields, the live limit, the verdict and the keys; compact (one row a field) on a short terminal."""
        rot, vib, temp = self.initial
        compact = self.app.size.height < SHORT_BELOW_ROWS  # 80 × 24: everything, the verdict too, on screen
        with Vertical(id="dialog", classes="dialog -compact" if compact else "dialog"):
            yield Label("Set speeds and furnace — checked against the interlock before anything is sent",
                        classes="dialog-title")
            with Horizontal(classes="field"):
                yield Label("ω_v vibration (rpm)", classes="field-label")
                yield Input(f"{vib:g}", id="vib", type="number", compact=compact)
            with Horizontal(classes="field"):
                yield Label("ω_r rotary (rpm)", classes="field-label")
                yield Input(f"{rot:g}", id="rot", type="number", compact=compact)
            with Horizontal(classes="field"):
                yield Label("furnace (°C, off, or empty)", classes="field-label")
                yield Input("" if temp is None else f"{temp:g}", id="temp", placeholder="unchanged", compact=compact)
            with Horizontal(classes="field"):
                yield Label("ramp rates ω_r, ω_v (rpm/s)", classes="field-label")
                yield Input("", id="rot_rate", type="number", placeholder="ω_r: drive max", compact=compact)
                yield Input("", id="vib_rate", type="number", placeholder="ω_v: drive max", compact=compact)
            yield MarkedCheckbox("linear path: one straight ramp in both axes (refused if it leaves the envelope)",
                                 id="linear", compact=compact)
            yield Static(id="limit")
            yield Static(id="verdict")
            yield Static("Enter: check and send    Esc: cancel    Tab: next field", classes="hint")

    def on_mount(self) -> None:
        """Focus ω_v first (the limit depends on it) and show the limit for the prefilled values."""
        self.query_one("#vib", Input).focus()
        self.refresh_check()

    def fields(self) -> SetRequest:
        """The parsed fields (raises :class:`InputError`)."""
        rot, vib, temp, rot_rate, vib_rate = (self.query_one(f"#{name}", Input).value
                                              for name in ("rot", "vib", "temp", "rot_rate", "vib_rate"))
        return parse_request(rot, vib, temp, rot_rate, vib_rate, self.query_one("#linear", Checkbox).value)

    def on_input_changed(self, event: Input.Changed) -> None:
        """Re-check on every keystroke."""
        self.refresh_check()

    @work(exclusive=True, group="check")
    async def refresh_check(self) -> CheckOut | None:
        """Ask the service for the limit at the typed ω_v and its verdict on the typed point; show both."""
        return await self._check(show_ok=True)

    async def _check(self, show_ok: bool) -> CheckOut | None:
        limit, verdict = self.query_one("#limit", Static), self.query_one("#verdict", Static)
        try:
            request = self.fields()
        except InputError as exc:
            verdict.update(Text(str(exc), style="yellow"))
            return None
        try:
            result = await self.check(request.rotary_rpm, request.vibration_rpm, request.temp_c)
        except MillctlError as exc:
            verdict.update(Text(f"cannot check with the service, nothing will be sent: {exc}", style="bold red"))
            return None
        limit_rpm = result.limit_rotary_rpm
        limit_text = "none" if limit_rpm is None else f"{limit_rpm:.1f} rpm"
        limit.update(Text.assemble(("limit at ω_v = ", "dim"), f"{request.vibration_rpm:g} rpm: ",
                                   (f"ω_r ≤ {limit_text}", "bold cyan")))
        if result.ok:
            margin = result.margin_rpm
            verdict.update(Text(f"inside the envelope{'' if margin is None else f', margin {margin:.1f} rpm'}",
                                style="green") if show_ok else "")
        else:
            verdict.update(Text(f"refused: {result.reason}", style="bold red"))
        return result

    async def action_send(self) -> None:
        """Check once more; send only a point the interlock accepts."""
        try:
            request = self.fields()
        except InputError as exc:
            self.query_one("#verdict", Static).update(Text(str(exc), style="bold red"))
            return
        result = await self._check(show_ok=True)
        if result is not None and result.ok:
            self.dismiss(request)

    def action_cancel(self) -> None:
        """Close without sending."""
        self.dismiss(None)


class ConfirmModal(ModalScreen[bool]):
    """A yes/no question."""

    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("y", "answer(True)", "Yes"),
        Binding("n,escape", "answer(False)", "No"),
    ]

    def __init__(self, question: str) -> None:
        super().__init__()
        self.question = question

    def compose(self) -> ComposeResult:
        """The question and two buttons."""
        with Vertical(id="dialog", classes="dialog"):
            yield Static(self.question)
            yield Static("y: yes    n or Esc: no", classes="hint")

    def action_answer(self, answer: bool) -> None:
        """Close with the answer."""
        self.dismiss(answer)


__all__ = ["Checker", "ConfirmModal", "InputError", "MarkedCheckbox", "SetRequest", "SetpointsModal", "parse_request"]
