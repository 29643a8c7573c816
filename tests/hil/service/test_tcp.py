"""Starting the service: TCP only with a bearer token, stale sockets replaced, anything else left alone."""

from __future__ import annotations

import socket
from pathlib import Path

import httpx
import pytest

from millctl.cli import main
from millctl.client import AccessDenied, Client
from millctl.config import load_config
from millctl.errors import BusError, ExitCode
from millctl.service import serve
from tests.support.service import private_dir, start_service, write_config

TOKEN = "s3cret-token-for-the-test-0123456789"


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port: int = sock.getsockname()[1]
        return port


def test_tcp_needs_the_token_and_a_stale_socket_is_replaced() -> None:
    with private_dir() as directory:
        token_file = directory / "token"
        token_file.write_text(TOKEN + "\n")
        token_file.chmod(0o600)
        port = _free_port()
        write_config(directory, tcp_port=port, token_file=str(token_file))
        stale = socket.socket(socket.AF_UNIX)
        stale.bind(str(directory / "mill.sock"))  # a socket file nobody listens on, as a killed service leaves
        stale.close()
        service = start_service(directory)
        try:
            url = f"http://127.0.0.1:{port}"
            missing = httpx.get(f"{url}/v1/status")
            assert missing.status_code == 401
            assert missing.json()["code"] == "unauthorized"
            wrong = httpx.get(f"{url}/v1/status", headers={"Authorization": "Bearer wrong-token-0000000000"})
            assert wrong.status_code == 401
            with Client(base_url=url, token="wrong-token-0000000000") as intruder, pytest.raises(AccessDenied):
                intruder.status()
            with Client(base_url=url, token=TOKEN) as client:
                assert client.status().state == "DISABLED"
            with service.client() as local:  # the Unix socket needs no token
                assert local.status().state == "DISABLED"
        finally:
            assert service.stop() == 0


def test_tcp_without_a_token_file_refuses_to_start(capsys: pytest.CaptureFixture[str]) -> None:
    with private_dir() as directory:
        config = write_config(directory, tcp_port=_free_port())
        assert main(["--config", str(config), "serve"]) == ExitCode.INVALID_INPUT
        assert "token_file" in capsys.readouterr().err
        assert not (directory / "mill.sock").exists()


def test_a_file_in_the_way_of_the_socket_is_never_replaced(tmp_path: Path) -> None:
    config = write_config(tmp_path)
    in_the_way = tmp_path / "mill.sock"
    in_the_way.write_text("keep me")
    with pytest.raises(BusError, match="not a socket"):
        serve(load_config(config))
    assert in_the_way.read_text() == "keep me"
