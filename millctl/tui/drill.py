"""Fault drills (key ``f``, only on a service started with ``--fault-injection``): inject the node's faults.

For an instructor training operators on the simulated mill: pick a fault
from the list (what it does, what its parameter means), give the parameter
and press Enter; ``x`` clears every injected fault. The service sends a real
``SimFault`` frame and records a ``drill`` event; the operator handles the
trip as on the real mill (docs/operations.md#fault-drills).
"""

from __future__ import annotations

import math
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import ClassVar

from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import Horizontal, Vertical
from textual.screen import ModalScreen
from textual.widgets import Input, Label, OptionList, Static
from textual.widgets.option_list import Option

from millctl.api import FaultsOut, SimFaultName
from millctl.tui.link import LINK_ERRORS

F = SimFaultName
FAULT_DRILLS: dict[SimFaultName, tuple[str, str]] = {
    F.VIB_STALL: ("—", "the vibration rotor blocks; the controller trips (STALL), reset refused until cleared"),
    F.ROTARY_RUNAWAY: ("runaway speed, rpm (0: 1.25 × the drive's max)",
                       "the rotary drive ignores its command and runs away past the limit"),
    F.SENSOR_STUCK: ("—", "both speed sensors freeze at their readings (SENSOR once turning)"),
    F.SENSOR_NOISY: ("noise σ, rpm (0: 10 × the measurement tolerance)", "both speed sensors turn noisy (SENSOR)"),
    F.HEATER_FAIL: ("0: open element; other: welded relay", "the furnace heater fails (HEATER_VERIFY or OVERTEMP)"),
    F.NODE_SILENT: ("—", "the node sends nothing: stale telemetry trips the controller, the node's watchdog latches"),
    F.NODE_BABBLE: ("rate, Hz", "junk frames just below the E-stop load the bus"),
    F.TX_LOSS: ("probability 0–1", "frames from the node are lost"),
    F.TX_CORRUPT: ("probability 0–1", "one bit of the node's frames is flipped (E2E errors; at 1: the link faults)"),
}
"""Each injectable fault: what its parameter means, and what the operator will see (firmware_sim/faults.py)."""


@dataclass(frozen=True)
class DrillRequest:
    """What the instructor asked for: a fault, on or off, and its parameter."""

    fault: SimFaultName
    active: bool = True
    param: float = 0.0


def fault_line(fault: SimFaultName, active: dict[SimFaultName, float]) -> Text:
    """One line of the list: the fault, whether it is injected now, and what it does."""
    on = fault in active
    mark = ("● ", "bold red") if on else ("○ ", "bold")
    now = f" (injected, param {active[fault]:g})" if on else ""
    return Text.assemble(mark, (fault.value, "bold"), (now, "bold red"), f"  {FAULT_DRILLS[fault][1]}")


class FaultDrillModal(ModalScreen[DrillRequest | None]):
    """The faults with what they do; Enter injects the highlighted one, x clears them all."""

    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("escape", "cancel", "Close"),
        Binding("x", "clear_all", "Clear all faults"),
    ]

    def __init__(self, read: Callable[[], Awaitable[FaultsOut]]) -> None:
        super().__init__()
        self.read = read
        self.active: dict[SimFaultName, float] = {}

    def compose(self) -> ComposeResult:
        """The list, the parameter field, the highlighted fault's parameter meaning and the hint."""
        with Vertical(id="dialog", classes="dialog"):
            yield Label("Fault drill — inject a fault into the SIMULATED node (instructor)", classes="dialog-title")
            yield OptionList(*(Option(fault_line(f, {}), id=f.value) for f in FAULT_DRILLS), id="faults")
            with Horizontal(classes="field"):
                yield Label("parameter", classes="field-label")
                yield Input("0", id="param", type="number")
            yield Static(id="meaning")
            yield Static("Enter: inject the highlighted fault    x: clear every fault    Esc: close",
                         classes="hint")

    async def on_mount(self) -> None:
        """Show which faults are injected now."""
        self.query_one("#faults", OptionList).focus()
        try:
            self.active = dict((await self.read()).active)
        except LINK_ERRORS as exc:  # shown; the dialog stays usable
            self.query_one("#meaning", Static).update(Text(f"cannot read the injected faults: {exc}", style="red"))
            return
        options = self.query_one("#faults", OptionList)
        for fault in FAULT_DRILLS:
            options.replace_option_prompt(fault.value, fault_line(fault, self.active))

    def on_option_list_option_highlighted(self, event: OptionList.OptionHighlighted) -> None:
        """Say what the highlighted fault's parameter means."""
        if event.option.id is not None:
            meaning = FAULT_DRILLS[SimFaultName(event.option.id)][0]
            self.query_one("#meaning", Static).update(Text(f"parameter: {meaning}"))

    def on_option_list_option_selected(self, event: OptionList.OptionSelected) -> None:
        """Inject the selected fault with the parameter typed."""
        if event.option.id is not None:
            self._inject(SimFaultName(event.option.id))

    def on_input_submitted(self, event: Input.Submitted) -> None:
        """Enter in the parameter field injects the highlighted fault."""
        options = self.query_one("#faults", OptionList)
        if options.highlighted is not None:
            option_id = options.get_option_at_index(options.highlighted).id
            if option_id is not None:
                self._inject(SimFaultName(option_id))

    def _inject(self, fault: SimFaultName) -> None:
        text = self.query_one("#param", Input).value.strip() or "0"
        try:
            param = float(text)
        except ValueError:
            param = math.nan
        if not math.isfinite(param):
            self.query_one("#meaning", Static).update(Text(f"parameter: {text!r} is not a number", style="red"))
            return
        self.dismiss(DrillRequest(fault, True, param))

    def action_clear_all(self) -> None:
        """Clear every injected fault."""
        self.dismiss(DrillRequest(SimFaultName.CLEAR, False))

    def action_cancel(self) -> None:
        """Close without injecting."""
        self.dismiss(None)


__all__ = ["FAULT_DRILLS", "DrillRequest", "FaultDrillModal", "fault_line"]
