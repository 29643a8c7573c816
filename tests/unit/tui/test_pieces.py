"""The TUI's pure pieces: the envelope plot, the setpoint parser, and the operator's error messages."""

from __future__ import annotations

import re

import httpx
import pytest

from millctl.client import ControlHeld, InterlockRefusal, ServiceUnavailable, raise_for_error
from millctl.errors import MillctlError
from millctl.tui.format import duration, e2e_errors
from millctl.tui.link import describe
from millctl.tui.modals import InputError, parse_request
from millctl.tui.plot import Curve, render_plot
from tests.unit.tui.frozen import ENVELOPE

CURVE = Curve.from_envelope(ENVELOPE)


def test_the_plot_marks_the_operating_point_and_colours_the_law() -> None:
    inside = render_plot(CURVE, 60, 12, point=(800.0, 150.0))
    assert "●" in inside.plain
    marker = inside.plain.index("●")
    styles = {str(span.style) for span in inside.spans if span.start <= marker < span.end}
    assert "bold red" not in styles
    assert any(str(span.style) == "green" for span in inside.spans)
    assert any(str(span.style) == "yellow" for span in inside.spans)  # eq. 9 above ω_v = 307.8 rpm

    outside = render_plot(CURVE, 60, 12, point=(800.0, 240.0))
    marker = outside.plain.index("●")
    assert any(str(span.style) == "bold red" for span in outside.spans if span.start <= marker < span.end)
    assert len(outside.plain.splitlines()) == 12


def test_the_curve_is_the_services() -> None:
    grid = ENVELOPE.points[40]
    assert CURVE.limit_at(grid.vibration_rpm) == pytest.approx(grid.limit_rotary_rpm)
    assert CURVE.limit_at(800.0) == pytest.approx(190.0, abs=0.2)  # docs/safety.md: 0.95 × 200.0 rpm
    assert CURVE.every_cycle_at(100.0) and not CURVE.every_cycle_at(800.0)


def test_setpoint_fields() -> None:
    request = parse_request(" 180 ", "800", "")
    assert (request.rotary_rpm, request.vibration_rpm, request.furnace) == (180.0, 800.0, False)
    assert parse_request("0", "0", "off").furnace and parse_request("0", "0", "off").temp_c is None
    assert parse_request("0", "0", "600").temp_c == 600.0
    ramped = parse_request("180", "800", "", "12.5", "", linear=True)
    assert (ramped.rotary_rate_rpm_s, ramped.vibration_rate_rpm_s, ramped.linear) == (12.5, None, True)
    with pytest.raises(InputError, match="must be > 0"):
        parse_request("180", "800", "", "0")
    for bad in (("x", "800", ""), ("180", "nan", ""), ("180", "800", "hot")):
        with pytest.raises(InputError):
            parse_request(*bad)


def _error(status: int, body: dict[str, object]) -> MillctlError:
    """The error the client raises for this answer (one of millctl's own: a crash would fail here)."""
    with pytest.raises(MillctlError) as raised:
        raise_for_error(httpx.Response(status, json=body), "service socket /x")
    return raised.value


def test_operator_messages_carry_the_services_reason() -> None:
    refusal = _error(409, {"code": "interlock_refused", "message": "refused", "refusals": [
        {"quantity": "omega_r", "value": 250.0, "limit": 190.0, "unit": "rpm",
         "reason": "ω_r = 250.0 rpm exceeds the limit 190.0 rpm at ω_v = 800.0 rpm"}]})
    assert isinstance(refusal, InterlockRefusal)
    message, severity = describe(refusal)
    assert "exceeds the limit 190.0 rpm" in message and severity == "error"
    held = _error(423, {"code": "control_held", "message": "held", "holder": "api:cli@bench"})
    assert isinstance(held, ControlHeld)
    assert "api:cli@bench holds control" in describe(held)[0]
    assert "service unavailable" in describe(ServiceUnavailable("no service"))[0]


def test_formatting() -> None:
    assert duration(95.0) == "1:35" and duration(3725.0) == "1:02:05" and duration(None) == "—"
    assert e2e_errors({"ok": 10, "ok-some-lost": 2, "wrong-sequence": 1, "repeated": 2}) == 3


def test_the_can_bus_condition_is_shown_by_status_and_the_tui() -> None:
    from rich.console import Console

    from millctl.cli.client_cmd import render_status
    from millctl.tui.panels import link_text
    from tests.unit.tui.frozen import status_at

    healthy = status_at(3)
    console = Console(width=200, record=True)
    console.print(render_status(healthy))
    assert re.search(r"CAN bus +error-active   error frames 0", console.export_text())
    assert "CAN " not in link_text(healthy).plain, "a healthy bus adds no line to the link panel"
    off = healthy.model_copy(update={"bus_health": healthy.bus_health.model_copy(
        update={"condition": "bus-off", "error_frames": 3, "bus_off_count": 1, "tx_error_counter": 255,
                "rx_error_counter": 0})})
    console = Console(width=200, record=True)
    console.print(render_status(off))
    shown = console.export_text()
    assert "bus-off   error frames 3" in shown and "TEC 255 REC 0" in shown
    assert "CAN bus-off   error frames 3" in link_text(off).plain
