"""Where the socket and records go without systemd: per user (root too) and per configuration (issue 39, item 6)."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from millctl.config import load_config
from millctl.config.loader import packaged_file
from millctl.config.paths import ensure_private_dir, service_paths


def _clone(tmp_path: Path, name: str) -> Path:
    folder = tmp_path / name / "config"
    folder.mkdir(parents=True)
    path = folder / "mill.toml"
    path.write_text(packaged_file("mill.toml").read_text())
    return path


@pytest.fixture
def root_without_systemd(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    for name in ("RUNTIME_DIRECTORY", "STATE_DIRECTORY", "XDG_RUNTIME_DIR", "XDG_STATE_HOME"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.setattr(os, "geteuid", lambda: 0)
    monkeypatch.setattr(os, "getuid", lambda: 0)


def test_root_without_systemd_writes_no_system_folder(tmp_path: Path, root_without_systemd: None) -> None:
    paths = service_paths(load_config(_clone(tmp_path, "clone-a")))
    for path in (paths.socket, paths.records_dir):
        assert not str(path).startswith(("/run/millctl", "/var/lib/millctl")), path
    assert paths.records_dir.is_relative_to(tmp_path / "home" / ".local" / "state" / "millctl")


def test_two_clones_share_neither_socket_nor_records(tmp_path: Path, root_without_systemd: None) -> None:
    a = service_paths(load_config(_clone(tmp_path, "clone-a")))
    b = service_paths(load_config(_clone(tmp_path, "clone-b")))
    assert a.socket != b.socket and a.records_dir != b.records_dir
    again = service_paths(load_config(tmp_path / "clone-a" / "config" / "mill.toml"))
    assert (again.socket, again.records_dir) == (a.socket, a.records_dir)  # a client finds its clone's service


def test_under_systemd_the_units_folders_stay(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("RUNTIME_DIRECTORY", "/run/millctl")
    monkeypatch.setenv("STATE_DIRECTORY", "/var/lib/millctl")
    paths = service_paths(load_config(_clone(tmp_path, "etc")))
    assert (paths.socket, paths.records_dir) == (Path("/run/millctl/millctl.sock"), Path("/var/lib/millctl/records"))


def test_folders_made_for_the_socket_are_0750_whatever_the_umask(tmp_path: Path) -> None:
    old = os.umask(0o022)
    try:
        ensure_private_dir(tmp_path / "run" / "millctl" / "mill-x")
    finally:
        os.umask(old)
    for folder in (tmp_path / "run", tmp_path / "run" / "millctl", tmp_path / "run" / "millctl" / "mill-x"):
        assert stat.S_IMODE(folder.stat().st_mode) == 0o750, folder
