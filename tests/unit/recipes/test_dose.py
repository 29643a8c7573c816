"""Dose-targeted steps: "mill until D kJ/g" plans with its expected time and runs until the dose is reached."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from millctl.cli import main
from millctl.config import MillConfig
from millctl.errors import RecipeError
from millctl.physics.dose import dose_rate_j_g_s
from millctl.physics.model import MillModel
from millctl.physics.telemetry import revolution_summary
from millctl.recipes import load_recipe, plan_recipe
from millctl.recipes.runner import RecipeRunner, RunState
from millctl.records import read_records
from millctl.units import rpm_to_rad_s
from tests.conftest import CONFIG_FILE
from tests.unit.scenarios.rig import Rig

DOSE_RECIPE = """
[recipe]
name = "dose test"
powder_charge_g = 0.5

[defaults]
rotary_rate_rpm_s = 40.0
vibration_rate_rpm_s = 120.0

[[steps]]
kind = "ramp"
rotary_rpm = 150.0
vibration_rpm = 800.0

[[steps]]
kind = "hold"
dose_kj_g = 0.002

[[steps]]
kind = "ramp"
rotary_rpm = 0.0
vibration_rpm = 0.0
"""


@pytest.fixture
def dose_file(tmp_path: Path) -> Path:
    path = tmp_path / "dose.toml"
    path.write_text(DOSE_RECIPE)
    return path


def test_plan_gives_the_expected_dose_and_time_of_each_step(dose_file: Path, config: MillConfig) -> None:
    plan = plan_recipe(load_recipe(dose_file).recipe, config)
    assert plan.ok and plan.powder_charge_g == 0.5
    hold = plan.steps[1]
    model = MillModel.from_config(config)
    rate = dose_rate_j_g_s(model, revolution_summary(model, rpm_to_rad_s(150.0), rpm_to_rad_s(800.0)), 0.5)
    assert rate > 0.0
    assert hold.dose_target_kj_g == 0.002
    assert hold.duration_s == pytest.approx(2.0 / rate)
    assert hold.dose_kj_g == pytest.approx(0.002)
    assert plan.steps[0].dose_kj_g > 0.0 and plan.total_dose_kj_g > 0.002


def test_recipe_plan_json_shows_the_dose_per_step(dose_file: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--config", str(CONFIG_FILE), "recipe", "plan", str(dose_file), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)["result"]
    assert [s["dose_target_kj_g"] for s in data["steps"]] == [None, 0.002, None]
    assert data["steps"][1]["dose_kj_g"] == pytest.approx(0.002)
    assert data["powder_charge_g"] == 0.5 and data["total_dose_kj_g"] > 0.002


def test_a_dose_at_a_point_without_impacts_is_refused_in_pre_flight(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "r.toml"
    path.write_text('[recipe]\nname = "x"\n[[steps]]\nkind = "hold"\ndose_kj_g = 1.0\n')
    assert main(["--config", str(CONFIG_FILE), "recipe", "check", str(path)]) == 2  # a pre-flight refusal
    err = capsys.readouterr().err
    assert "step 1" in err and "would never end" in err
    with pytest.raises(RecipeError, match="exactly one of duration_s, duration_min, duration_h, dose_kj_g"):
        path.write_text('[recipe]\nname = "x"\n[[steps]]\nkind = "hold"\ndose_kj_g = 1.0\nduration_s = 3\n')
        load_recipe(path)


def test_runner_ends_the_step_when_the_dose_is_reached(dose_file: Path, config: MillConfig, tmp_path: Path) -> None:
    rig = Rig(config)
    try:
        loaded = load_recipe(dose_file)
        plan = plan_recipe(loaded.recipe, config)
        runner = RecipeRunner(rig.controller, loaded, plan, rig.clock, records_dir=tmp_path, config_sha256="0" * 64)
        for _ in range(round(120.0 / rig.dt_s)):
            if runner.finished:
                break
            rig.step()
            runner.tick()
        assert runner.state is RunState.DONE, runner.reason
    finally:
        rig.close()
    records = list(read_records(runner.record.path))
    starts = {r["step"]: r["clock_s"] for r in records if r["event"] == "step_start"}
    ends = {r["step"]: r for r in records if r["event"] == "step_end"}
    assert ends[2]["dose_kj_g"] >= 0.002
    # it ended at the dose (one tick's worth past it at most), not at a clock
    rate_j_g_s = plan.steps[1].dose_kj_g * 1e3 / plan.steps[1].duration_s
    assert ends[2]["dose_kj_g"] <= 0.002 + 2.0 * rate_j_g_s * rig.dt_s * 1e-3
    took_s = ends[2]["clock_s"] - starts[2]
    assert 0.9 * plan.steps[1].duration_s <= took_s <= 2.0 * plan.steps[1].duration_s
