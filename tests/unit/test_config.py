"""Configuration: every bad-input class gives its message and exit code."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from millctl.cli import main
from millctl.config import ENV_VAR, MillConfig, load_config, resolve_config_path
from millctl.errors import ConfigError, ExitCode
from tests.conftest import CONFIG_FILE


def write_variant(tmp_path: Path, old: str, new: str) -> Path:
    text = CONFIG_FILE.read_text()
    assert old in text, old
    path = tmp_path / "mill.toml"
    path.write_text(text.replace(old, new, 1))
    return path


def test_default_config_is_set_a(config: MillConfig) -> None:
    assert config.mill.rods.radius_mm == 6.0
    assert config.mill.vial.radius_mm == 24.0
    assert config.rod_mass_kg == pytest.approx(0.0886, abs=5e-4)
    assert config.interlock.law.value == "paper-eq9"


@pytest.mark.parametrize(
    ("old", "new", "pattern"),
    [
        ("radius_mm = 6.0 ", 'radius_mm = "six" ', r"mill\.rods\.radius_mm = 'six': .*valid number"),
        ("radius_mm = 6.0 ", "radius_mm = -1.0 ", r"mill\.rods\.radius_mm = -1\.0: .*\(bound: > 0\.0\)"),
        ("margin = 0.05", "margin = 0.9", r"interlock\.margin = 0\.9: .*\(bound: ≤ 0\.5\)"),
        ("count = 6", "count = 6\ncolour = 3", r"mill\.rods\.colour: unknown key"),
        ('law = "paper-eq9"', 'law = "eq9"', r"interlock\.law = 'eq9': .*'paper-eq9'"),
        ("radius_mm = 6.0 ", "radius_mm = 30.0 ", r"must be < vial\.radius_mm"),
        ("count = 6", "count = 10", r"overlap .*packing limit"),
        ('material = "steel"', 'material = "unobtainium"', r"'unobtainium' is not a defined material"),
        ("watchdog_timeout_s = 0.25", "watchdog_timeout_s = 0.06", r"watchdog_timeout_s = 0\.06 must be ≥ 2"),
    ],
    ids=["type", "range", "range-margin", "unknown-key", "enum", "rod-too-big", "packing", "material", "timing"],
)
def test_invalid_field_is_named_with_value_and_bound(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], old: str, new: str, pattern: str
) -> None:
    path = write_variant(tmp_path, old, new)
    with pytest.raises(ConfigError) as info:
        load_config(path)
    assert any(re.search(pattern, p) for p in info.value.problems), info.value.problems
    assert all(p.startswith(str(path)) for p in info.value.problems)
    assert main(["config", "check", str(path)]) == ExitCode.INVALID_INPUT
    assert re.search(pattern, capsys.readouterr().err)


def test_every_problem_is_reported_at_once(tmp_path: Path) -> None:
    path = write_variant(tmp_path, "margin = 0.05", "margin = -1\nspeed = 2")
    with pytest.raises(ConfigError) as info:
        load_config(path)
    assert len(info.value.problems) == 2


def test_missing_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    missing = tmp_path / "nope.toml"
    assert main(["--config", str(missing), "config", "show"]) == ExitCode.INVALID_INPUT
    assert f"{missing}: no such file" in capsys.readouterr().err


def test_bad_toml_syntax(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "bad.toml"
    path.write_text("[mill\nrods = 1\n")
    assert main(["config", "check", str(path)]) == ExitCode.INVALID_INPUT
    assert "TOML syntax error" in capsys.readouterr().err


def test_precedence(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert resolve_config_path(None).name == "mill.toml"  # packaged default
    assert "millctl" in str(resolve_config_path(None))
    local = tmp_path / "config" / "mill.toml"
    local.parent.mkdir()
    local.write_text(CONFIG_FILE.read_text())
    assert resolve_config_path(None) == Path("config/mill.toml")
    monkeypatch.setenv(ENV_VAR, "/env/mill.toml")
    assert resolve_config_path(None) == Path("/env/mill.toml")
    assert resolve_config_path("/cli/mill.toml") == Path("/cli/mill.toml")


def test_packaged_default_loads(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv(ENV_VAR, raising=False)
    loaded = load_config()
    assert loaded.config.mill.rods.count == 6
    assert len(loaded.sha256) == 64


def test_config_show_json(capsys: pytest.CaptureFixture[str]) -> None:
    import json

    assert main(["--config", str(CONFIG_FILE), "config", "show", "--json"]) == ExitCode.OK
    data = json.loads(capsys.readouterr().out)["result"]
    assert data["config"]["interlock"]["margin"] == 0.05
