"""``millctl physics``: what an operator or a script reads."""

from __future__ import annotations

import json
import math

import pytest

from millctl.cli import main
from millctl.config import MillConfig
from tests.conftest import CONFIG_FILE


def _run(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str]:
    """``millctl physics ARGS``: its exit code and what it printed on stdout."""
    code = main(["--config", str(CONFIG_FILE), "physics", *args])
    return code, capsys.readouterr().out


def test_json_report_corrected(capsys: pytest.CaptureFixture[str], config: MillConfig) -> None:
    code, out = _run(capsys, "--rot-rpm", "200", "--vib-rpm", "800", "--variant", "corrected", "--json")
    assert code == 0
    report = json.loads(out)["result"]
    assert report["variant"] == "corrected" and not report["pinned"]
    detach, imp, summary = report["first_detachment"], report["first_impact"], report["summary"]
    # Relations derived by hand, not by the code under test:
    # the flight lasts from detachment to impact;
    assert imp["flight_time_s"] == pytest.approx(imp["time_s"] - detach["time_s"], abs=1e-12)
    assert imp["flight_time_s"] > 0.0
    # a plastic impact (e = 0, eq. 19) dissipates the normal kinetic energy ½·m·v_n², m = π·r_r²·L·ρ (Set A: 0.0886 kg);
    rods = config.mill.rods
    density_kg_m3 = config.materials[rods.material].density_kg_m3
    mass_kg = math.pi * (rods.radius_mm / 1000) ** 2 * (rods.length_mm / 1000) * density_kg_m3
    assert imp["energy_j"] == pytest.approx(0.5 * mass_kg * imp["normal_velocity_m_s"] ** 2, rel=1e-9)
    # n rods, each turning at ω_r / 2π rev/s, collide collisions_per_rod_rev times a revolution;
    assert summary["detached"] is True and summary["collisions_per_rod_rev"] > 0
    revs_per_s = 200.0 / 60.0
    rate_hz = rods.count * revs_per_s * summary["collisions_per_rod_rev"]
    assert summary["impact_rate_hz"] == pytest.approx(rate_hz, rel=1e-9)
    # and the power is the mean energy per impact at that rate.
    assert summary["impact_power_w"] == pytest.approx(summary["mean_impact_energy_j"] * summary["impact_rate_hz"])


def test_text_report_paper_pinned(capsys: pytest.CaptureFixture[str]) -> None:
    code, out = _run(capsys, "--rot-rpm", "200", "--vib-rpm", "800", "--variant", "paper")
    assert code == 0
    assert "stay pinned" in out and "per revolution: pinned" in out


def test_legacy_method_and_phases(capsys: pytest.CaptureFixture[str]) -> None:
    args = ("--rot-rpm", "100", "--vib-rpm", "800", "--method", "legacy", "--dt", "1e-4")
    code, out = _run(capsys, *args, "--theta0-deg", "-120", "--alpha0-deg", "45", "--json")
    assert code == 0
    report = json.loads(out)["result"]
    assert report["method"] == "legacy" and report["first_impact"] is not None


def test_negative_speed_is_invalid_input(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        _run(capsys, "--rot-rpm=-5", "--vib-rpm", "800")
    assert exc.value.code == 1
    assert "≥ 0" in capsys.readouterr().err


def test_no_slip_flag_in_json_and_text(capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 20: the report says where the carried rod needs |F_t|/N > μ (−52.4° at 200/800, α0 = 0)."""
    code, out = _run(capsys, "--rot-rpm", "200", "--vib-rpm", "800", "--variant", "corrected", "--json")
    assert code == 0
    ns = json.loads(out)["result"]["no_slip"]
    assert ns["violated"] is True and ns["friction"] == pytest.approx(0.3)
    assert ns["onset_theta_deg"] == pytest.approx(-52.37, abs=0.01) and ns["onset_time_s"] < ns["arc_end_s"]
    code, out = _run(capsys, "--rot-rpm", "200", "--vib-rpm", "800", "--variant", "corrected")
    assert code == 0 and "no-slip violated" in out and "θ = -52.37°" in out


@pytest.mark.parametrize(("spin", "detached"), [("locked", True), ("free", False)])
def test_slip_ride_option(capsys: pytest.CaptureFixture[str], spin: str, detached: bool) -> None:
    """--slip: rod 0 with Coulomb slip; at α0 = 213.75° the locked rod still leaves, the rolling one does not."""
    args = ("--rot-rpm", "200", "--vib-rpm", "800", "--variant", "corrected", "--alpha0-deg", "213.75")
    code, out = _run(capsys, *args, "--slip", spin, "--json")
    assert code == 0
    sr = json.loads(out)["result"]["slip_ride"]
    assert sr["spin"] == spin and sr["detached"] is detached and sr["sliding_s"] > 0.0
    if detached:
        assert 0.0 < sr["theta_d_deg"] < 10.0 and sr["flight_time_s"] > 0.0 and sr["energy_j"] > 0.0
    code, out = _run(capsys, *args, "--slip", spin)
    assert code == 0 and f"slip ride (spin {spin}" in out
