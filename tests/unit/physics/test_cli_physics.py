"""``millctl physics``: what an operator or a script reads."""

from __future__ import annotations

import json

import pytest

from millctl.cli import main
from tests.conftest import CONFIG_FILE


def _run(capsys, *args):
    code = main(["--config", str(CONFIG_FILE), "physics", *args])
    return code, capsys.readouterr()


def test_json_report_corrected(capsys):
    code, out = _run(capsys, "--rot-rpm", "200", "--vib-rpm", "800", "--variant", "corrected", "--json")
    assert code == 0
    report = json.loads(out.out)["result"]
    assert report["variant"] == "corrected" and not report["pinned"]
    assert report["first_detachment"]["time_s"] >= 0.0
    imp = report["first_impact"]
    assert imp["flight_time_s"] > 0.0 and imp["energy_j"] > 0.0
    assert report["summary"]["detached"] is True and report["summary"]["impact_rate_hz"] > 0.0


def test_text_report_paper_pinned(capsys):
    code, out = _run(capsys, "--rot-rpm", "200", "--vib-rpm", "800", "--variant", "paper")
    assert code == 0
    assert "stay pinned" in out.out and "per revolution: pinned" in out.out


def test_legacy_method_and_phases(capsys):
    args = ("--rot-rpm", "100", "--vib-rpm", "800", "--method", "legacy", "--dt", "1e-4")
    code, out = _run(capsys, *args, "--theta0-deg", "-120", "--alpha0-deg", "45", "--json")
    assert code == 0
    report = json.loads(out.out)["result"]
    assert report["method"] == "legacy" and report["first_impact"] is not None


def test_negative_speed_is_invalid_input(capsys):
    with pytest.raises(SystemExit) as exc:
        _run(capsys, "--rot-rpm=-5", "--vib-rpm", "800")
    assert exc.value.code == 1
    assert "≥ 0" in capsys.readouterr().err


def test_no_slip_flag_in_json_and_text(capsys):
    """Issue 20: the report says where the carried rod needs |F_t|/N > μ (−52.4° at 200/800, α0 = 0)."""
    code, out = _run(capsys, "--rot-rpm", "200", "--vib-rpm", "800", "--variant", "corrected", "--json")
    assert code == 0
    ns = json.loads(out.out)["result"]["no_slip"]
    assert ns["violated"] is True and ns["friction"] == pytest.approx(0.3)
    assert ns["onset_theta_deg"] == pytest.approx(-52.37, abs=0.01) and ns["onset_time_s"] < ns["arc_end_s"]
    code, out = _run(capsys, "--rot-rpm", "200", "--vib-rpm", "800", "--variant", "corrected")
    assert code == 0 and "no-slip violated" in out.out and "θ = -52.37°" in out.out


@pytest.mark.parametrize(("spin", "detached"), [("locked", True), ("free", False)])
def test_slip_ride_option(capsys, spin, detached):
    """--slip: rod 0 with Coulomb slip; at α0 = 213.75° the locked rod still leaves, the rolling one does not."""
    args = ("--rot-rpm", "200", "--vib-rpm", "800", "--variant", "corrected", "--alpha0-deg", "213.75")
    code, out = _run(capsys, *args, "--slip", spin, "--json")
    assert code == 0
    sr = json.loads(out.out)["result"]["slip_ride"]
    assert sr["spin"] == spin and sr["detached"] is detached and sr["sliding_s"] > 0.0
    if detached:
        assert 0.0 < sr["theta_d_deg"] < 10.0 and sr["flight_time_s"] > 0.0 and sr["energy_j"] > 0.0
    code, out = _run(capsys, *args, "--slip", spin)
    assert code == 0 and f"slip ride (spin {spin}" in out.out
