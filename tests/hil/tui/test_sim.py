"""``millctl tui --sim``: a private service with the simulated node, up for the TUI and gone after it."""

from __future__ import annotations

from pathlib import Path

from millctl.client import Client
from millctl.tui import SimService


def test_sim_service_starts_on_a_private_socket_and_stops_cleanly() -> None:
    with SimService() as sim:
        directory = sim.directory
        with Client(sim.socket_path, name="test") as client:
            assert client.status().state == "DISABLED"
            service = client.service()
        assert service.embedded_node is True
        assert Path(service.records_dir).is_relative_to(directory)
        assert sim.proc is not None and service.pid == sim.proc.pid
    assert sim.proc is not None and sim.proc.returncode == 0  # SIGTERM: controlled stop, exit 0
    assert not directory.exists()
