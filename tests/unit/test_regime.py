"""The regime warning is one function: ``millctl limits``, ``GET /v1/envelope`` and the TUI say the same number.

They disagreed (315 against 307.8 rpm): the TUI showed the first point of the service's 7.5 rpm grid where
the law stops being the every-cycle bound, ``limits`` the switch speed √(k/m).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from millctl.cli import main
from millctl.config import LimitLaw, load_config
from millctl.config.loader import packaged_file
from millctl.errors import ExitCode
from millctl.physics.limits import is_every_cycle_bound, switch_omega_v_rad_s
from millctl.safety import Envelope
from millctl.safety.regime import regime_warning
from millctl.tui import MillApp
from millctl.tui.panels import EnvelopePanel
from millctl.units import rad_s_to_rpm, rpm_to_rad_s
from tests.unit.tui import frozen

CONFIG = load_config(packaged_file("mill.toml")).config
SWITCH_RPM = float(rad_s_to_rpm(switch_omega_v_rad_s(Envelope.from_config(CONFIG).params)))


def test_the_warning_is_at_the_switch_speed_where_is_every_cycle_bound_flips() -> None:
    envelope = Envelope.from_config(CONFIG)
    warning = regime_warning(envelope)
    assert warning is not None and warning.above_vibration_rpm == SWITCH_RPM
    assert f"{SWITCH_RPM:.1f}" == "307.8"
    below, above = np.nextafter(SWITCH_RPM, 0.0), np.nextafter(SWITCH_RPM, np.inf)
    flags = is_every_cycle_bound(envelope.law, envelope.params, rpm_to_rad_s(np.array([below, above])))
    assert flags.tolist() == [True, False]
    assert not warning.applies_at(below) and warning.applies_at(above)


@pytest.mark.parametrize("law", list(LimitLaw))
def test_each_law_warns_where_it_is_not_the_every_cycle_bound(law: LimitLaw) -> None:
    envelope = Envelope.from_config(CONFIG, law=law)
    warning = regime_warning(envelope)
    grid = np.linspace(0.0, envelope.vibration_max_rpm, 241)
    every = envelope.every_cycle(grid)
    if warning is None:
        assert every.all()
    else:
        assert [not warning.applies_at(w) for w in grid] == every.tolist()
        assert str(law.value) in warning.message and "docs/model.md#eq-9" in warning.message


def test_limits_service_and_tui_say_the_same_number(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--config", str(packaged_file("mill.toml")), "limits", "--json"]) == ExitCode.OK
    cli = json.loads(capsys.readouterr().out)["result"]["regime"]
    service = frozen.ENVELOPE.regime  # GET /v1/envelope of the service's own app, 161 points (a 7.5 rpm grid)
    assert service is not None
    assert cli["above_vibration_rpm"] == service.above_vibration_rpm == SWITCH_RPM
    assert cli["summary"] == service.summary and cli["message"] == service.message


async def test_the_tui_panel_says_the_services_number_once() -> None:
    app = MillApp(frozen.SOCKET, live=False)
    async with app.run_test(size=(120, 40)) as pilot:
        app.apply_envelope(frozen.ENVELOPE)
        app.apply_status(frozen.status_at(39))
        await pilot.pause()
        panel = app.query_one("#envelope", EnvelopePanel)
        text = panel.summary(80).plain
        assert text.count("307.8") == 1 and "315" not in text, text
        assert text.count("⚠") == 1
        assert panel.summary(40).plain.count("307.8") == 1  # the narrow wording keeps the number
