"""Recipes: every bad-recipe class gives its message and exit code; good ones plan."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from millctl.cli import main
from millctl.config import MillConfig, load_config
from millctl.errors import ExitCode, RecipeError
from millctl.recipes import load_recipe, plan_recipe
from tests.conftest import CONFIG_FILE, REPO

RECIPES = sorted((REPO / "config" / "recipes").glob("*.toml"))

HEAD = """
[recipe]
name = "test"
"""


def write(tmp_path: Path, body: str) -> Path:
    path = tmp_path / "r.toml"
    path.write_text(HEAD + body)
    return path


def check(path: Path, capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    code = main(["--config", str(CONFIG_FILE), "recipe", "check", str(path)])
    return code, capsys.readouterr().err


@pytest.mark.parametrize("recipe", RECIPES, ids=[p.stem for p in RECIPES])
def test_shipped_recipes_pass(recipe: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, err = check(recipe, capsys)
    assert code == ExitCode.OK, err


def test_demo_is_under_a_minute(config: MillConfig) -> None:
    plan = plan_recipe(load_recipe(REPO / "config/recipes/demo.toml").recipe, config)
    assert 0 < plan.total_s < 60


@pytest.mark.parametrize(
    ("body", "pattern"),
    [
        ("[[steps]\nkind = 'hold'", r"TOML syntax error"),
        ("[[steps]]\nkind = 'hold'\nduration_s = 5\ncolour = 'red'", r"step 1 colour: unknown key"),
        ("[[steps]]\nkind = 'hold'\nduration_sec = 5", r"duration_sec: unknown key"),
        ("[[steps]]\nkind = 'hold'\nduration_s = 5\nduration_min = 1", r"exactly one of duration_s"),
        ("[[steps]]\nkind = 'ramp'\nrotary_rpm = -5\nvibration_rpm = 100", r"rotary_rpm = -5: .*bound: ≥ 0"),
        ("[[steps]]\nkind = 'spin'\n", r"step 1 = .*'spin'.*does not match any of the expected tags"),
        ("", r"steps = \(missing\): Field required"),
        (
            "[[steps]]\nkind = 'ramp'\nrotary_rpm = 60\nvibration_rpm = 300\nheating_rate_c_per_min = 5",
            r"step 1: .*heating_rate_c_per_min = 5\.0 given without furnace_c: there is nothing to heat to",
        ),
    ],
    ids=[
        "syntax", "unknown-key", "unit", "two-durations", "out-of-range", "unknown-kind", "no-steps", "rate-no-target"
    ],
)
def test_invalid_recipe_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str], body: str, pattern: str) -> None:
    path = write(tmp_path, body)
    code, err = check(path, capsys)
    assert code == ExitCode.INVALID_INPUT
    assert re.search(pattern, err), err
    assert str(path) in err


def test_step_the_envelope_forbids(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write(tmp_path, "[[steps]]\nkind = 'ramp'\nrotary_rpm = 250\nvibration_rpm = 800\n")
    code, err = check(path, capsys)
    assert code == ExitCode.INTERLOCK  # a refusal exits 2 from every command, as `set` does
    assert re.search(r"step 1 at t = 0\.0 s: ω_r = 250\.0 rpm exceeds the limit 190\.0 rpm .*law paper-eq9", err)


def test_linear_ramp_crossing_the_limit_midway(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    body = (
        "[[steps]]\nkind = 'ramp'\nrotary_rpm = 140\nvibration_rpm = 0\n"
        "[[steps]]\nkind = 'ramp'\nrotary_rpm = 230\nvibration_rpm = 1200\npath = 'linear'\n"
    )
    code, err = check(write(tmp_path, body), capsys)
    assert code == ExitCode.INTERLOCK
    assert re.search(r"step 2 at t = 3\.5 s: linear ramp at t = [\d.]+ s of [\d.]+ s .*exceeds the limit", err), err
    # the same ends with the default (sequenced) path are fine
    code, err = check(write(tmp_path, body.replace("path = 'linear'\n", "")), capsys)
    assert code == ExitCode.OK, err


def test_every_problem_is_listed(tmp_path: Path) -> None:
    body = (
        "[[steps]]\nkind = 'ramp'\nrotary_rpm = 250\nvibration_rpm = 800\nfurnace_c = 1500\n"
        "heating_rate_c_per_min = 100\n"
        "[[steps]]\nkind = 'ramp'\nrotary_rpm = 300\nvibration_rpm = 100\n"
    )
    plan = plan_recipe(load_recipe(write(tmp_path, body)).recipe, load_config(CONFIG_FILE).config)
    assert [(v.step, v.quantity) for v in plan.violations] == [
        (1, "omega_r"),
        (1, "furnace_temp"),
        (1, "heating_rate"),
        (2, "omega_r"),
    ]


def test_wait_furnace_needs_a_setpoint(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, err = check(write(tmp_path, "[[steps]]\nkind = 'wait_furnace'\n"), capsys)
    assert code == ExitCode.INTERLOCK and "no furnace setpoint" in err  # refused by the pre-flight, as by the service


def test_missing_file_is_a_recipe_error(tmp_path: Path) -> None:
    with pytest.raises(RecipeError, match="no such file"):
        load_recipe(tmp_path / "nope.toml")


def test_plan_json_has_timeline_and_total(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--config", str(CONFIG_FILE), "recipe", "plan", "--json", str(REPO / "config/recipes/demo.toml")]) == 0
    data = json.loads(capsys.readouterr().out)["result"]
    assert [s["kind"] for s in data["steps"]] == ["ramp", "hold", "ramp", "hold"]
    assert data["steps"][2]["start_s"] == pytest.approx(data["steps"][1]["start_s"] + 5.0)
    assert data["total_s"] == pytest.approx(data["steps"][-1]["start_s"] + 10.0 + data["stop_s"])
