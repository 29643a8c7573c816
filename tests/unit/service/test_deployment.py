"""Where the service lives, which mill a client may start, bad headers and bodies, and event numbering."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from millctl.cli import main
from millctl.config import load_config
from millctl.config.loader import LoadedConfig, packaged_file
from millctl.config.paths import SOCKET_NAME, instance_name, service_paths
from millctl.errors import ConfigError, ExitCode
from millctl.service import ServiceRuntime, create_app
from millctl.service.journal import Journal
from tests.support.service import DEMO_RECIPE as DEMO
from tests.support.service import write_config


def _loaded(tmp_path: Path, service: str = "", bus: str = "") -> LoadedConfig:
    text = packaged_file("mill.toml").read_text(encoding="utf-8")
    if bus:
        text = re.sub(r"(?ms)^\[bus\]\n.*?(?=^\[)", bus + "\n\n", text)
    path = tmp_path / "conf" / "mill.toml"
    path.parent.mkdir(exist_ok=True)
    path.write_text(text.replace("[service]\n", "[service]\n" + service + "\n"), encoding="utf-8")
    return load_config(path)


def test_paths_follow_the_conventions_unless_the_config_says(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    for name in ("RUNTIME_DIRECTORY", "STATE_DIRECTORY"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path / "run"))
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    paths = service_paths(_loaded(tmp_path))
    instance = instance_name(_loaded(tmp_path))  # this config's own folders (issue 39, item 6)
    assert instance is not None
    assert paths.socket == tmp_path / "run" / "millctl" / instance / SOCKET_NAME
    assert paths.records_dir == tmp_path / "state" / "millctl" / instance / "records"
    monkeypatch.setenv("RUNTIME_DIRECTORY", "/run/millctl")  # as systemd sets them
    monkeypatch.setenv("STATE_DIRECTORY", "/var/lib/millctl")
    paths = service_paths(_loaded(tmp_path))
    assert (paths.socket, paths.records_dir) == (Path("/run/millctl/millctl.sock"), Path("/var/lib/millctl/records"))
    relative = service_paths(_loaded(tmp_path, 'socket_path = "s/m.sock"\nrecords_dir = "rec"'))
    assert relative.socket == (tmp_path / "conf" / "s" / "m.sock").resolve()  # from the config's folder
    assert relative.records_dir == (tmp_path / "conf" / "rec").resolve()
    assert service_paths(_loaded(tmp_path), tmp_path / "x.sock").socket == tmp_path / "x.sock"


@pytest.mark.parametrize("mode", ["0o604", "0o606", "0o666", "0o700", "0o601"])
def test_socket_mode_gives_others_nothing(tmp_path: Path, mode: str) -> None:
    with pytest.raises(ConfigError, match="socket_mode"):
        _loaded(tmp_path, f"socket_mode = {mode}")
    assert _loaded(tmp_path, "socket_mode = 0o660").config.service.socket_mode == 0o660


def test_recipe_run_never_starts_a_simulated_mill_against_a_real_bus_config(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    loaded = _loaded(tmp_path, f'socket_path = "{tmp_path / "real.sock"}"',
                     bus='[bus]\ninterface = "socketcan"\nchannel = "can0"')
    code = main(["--config", loaded.source, "recipe", "run", str(DEMO)])
    err = capsys.readouterr().err
    assert code == ExitCode.BUS, err
    assert "real bus (socketcan:can0)" in err and "--sim" in err
    assert not (tmp_path / "real.sock").exists()
    assert not list(tmp_path.glob("*.log"))


@pytest.fixture
def api(tmp_path: Path) -> Iterator[httpx.AsyncClient]:
    runtime = ServiceRuntime(load_config(write_config(tmp_path)), embed_node=False)
    try:
        transport = httpx.ASGITransport(app=create_app(runtime))
        yield httpx.AsyncClient(transport=transport, base_url="http://millctl")
    finally:
        runtime.close()


async def test_a_non_ascii_lease_header_and_nul_bytes_are_4xx(api: httpx.AsyncClient) -> None:
    for lease in ("lé-ase".encode("latin-1"), b"\xff\xfe", b"a\x00b"):
        response = await api.post("/v1/arm", headers={b"X-Millctl-Lease": lease})
        assert response.status_code == 422, (lease, response.text)
        assert response.json()["field"] == "header.x-millctl-lease"
    taken = (await api.post("/v1/control/take")).json()["lease_id"]
    headers = {"X-Millctl-Lease": taken}
    nul_name = await api.post("/v1/recipe/run", headers=headers, json={"name": "a\x00b.toml", "text": "x"})
    assert nul_name.status_code == 422 and nul_name.json()["field"] == "body.name"
    nul_text = await api.post("/v1/recipe/run", headers=headers, json={"name": "r.toml", "text": "a = \x00"})
    assert nul_text.status_code == 422 and "r.toml" in nul_text.json()["message"]
    old = await api.post("/v1/recipe/run", headers=headers, json={"path": "/etc/passwd"})
    assert old.status_code == 422 and old.json()["code"] == "invalid_request"


async def test_a_body_over_the_bound_is_413_unread(api: httpx.AsyncClient) -> None:
    big = b"{" + b" " * (2 << 20) + b"}"
    response = await api.post("/v1/envelope/check", content=big, headers={"content-type": "application/json"})
    assert response.status_code == 413 and response.json()["code"] == "body_too_large"

    async def chunks() -> object:
        for _ in range(3):
            yield b" " * (1 << 20)

    streamed = await api.post("/v1/envelope/check", content=chunks())  # type: ignore[arg-type]
    assert streamed.status_code == 413


def test_event_numbers_continue_across_restarts(tmp_path: Path) -> None:
    first = Journal(tmp_path, rotate_bytes=1 << 20, keep_files=2)
    for i in range(5):
        first.add("service", "test", f"event {i}")
    first.close()
    second = Journal(tmp_path, rotate_bytes=1 << 20, keep_files=2)
    assert second.add("service", "test", "after the restart")["seq"] == 6
    second.close()
