"""`config show`: TOML that reads back as the same configuration, each value saying where it came from."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import pytest

from millctl.cli import main
from millctl.config import load_config
from millctl.config.loader import packaged_file
from millctl.config.models import MillConfig
from millctl.config.paths import service_paths
from millctl.errors import ExitCode


def _shown(capsys: pytest.CaptureFixture[str], *argv: str) -> str:
    assert main([*argv, "config", "show"]) == ExitCode.OK
    return capsys.readouterr().out


def _config(tmp_path: Path) -> Path:
    path = tmp_path / "mill.toml"
    path.write_text(packaged_file("mill.toml").read_text().replace("[service]", "[service]\ntcp_port = 8765\n"))
    return path


def test_it_is_toml_that_reads_back_as_the_same_configuration(tmp_path: Path,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    config = _config(tmp_path)
    text = _shown(capsys, "--config", str(config))
    assert MillConfig.model_validate(tomllib.loads(text)) == load_config(config).config
    assert "False" not in text and "None" not in text and "socket_mode = 0o600" in text


def test_each_value_says_where_it_came_from(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    config = _config(tmp_path)
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path / "run"))
    monkeypatch.delenv("RUNTIME_DIRECTORY", raising=False)
    text = _shown(capsys, "--config", str(config))
    assert text.startswith(f"# config {config}, chosen by the --config flag")
    lines = text.splitlines()
    assert "tcp_port = 8765  # file" in lines
    assert "keep_files = 10  # default" in lines
    socket = next(line for line in lines if line.startswith("socket_path = "))
    assert socket.endswith(f"by convention: {service_paths(load_config(config)).socket} (convention)")
    assert socket.split("by convention: ")[1].startswith(str(tmp_path / "run" / "millctl"))
    monkeypatch.setenv("MILLCTL_CONFIG", str(config))
    assert "chosen by $MILLCTL_CONFIG (environment)" in _shown(capsys).splitlines()[0]
    assert main(["config", "show", "--json"]) == ExitCode.OK
    result = json.loads(capsys.readouterr().out)["result"]
    assert result["origin"]["service.tcp_port"] == "file" and result["origin"]["service.keep_files"] == "default"
    assert result["chosen_by"] == "$MILLCTL_CONFIG (environment)"
