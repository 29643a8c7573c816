"""``millctl serve --fault-injection``: refused unless the node is the embedded simulation; routes only then."""

from __future__ import annotations

import asyncio
from pathlib import Path

import httpx
import pytest

from millctl.api import SimFaultName
from millctl.cli import main
from millctl.config import load_config
from millctl.errors import ExitCode
from millctl.protocol import SimFaultCode
from millctl.service import ServiceRuntime, create_app
from millctl.service.faults import FaultInjectionRefused
from tests.support.service import write_config


def real_bus_config(tmp_path: Path) -> Path:
    """The packaged config on a socketcan bus: a real mill as far as the service can tell."""
    path = write_config(tmp_path)
    text = path.read_text()
    path.write_text(text.replace('interface = "virtual"', 'interface = "socketcan"', 1))
    assert 'interface = "socketcan"' in path.read_text()
    return path


def test_the_api_fault_names_are_the_nodes() -> None:
    assert [f.value for f in SimFaultName] == [c.name for c in SimFaultCode]


def test_runtime_refuses_fault_injection_without_the_simulated_node(tmp_path: Path) -> None:
    with pytest.raises(FaultInjectionRefused, match=r"--fault-injection refused: .* socketcan:.*--sim"):
        ServiceRuntime(load_config(real_bus_config(tmp_path)), fault_injection=True)
    with pytest.raises(FaultInjectionRefused):
        ServiceRuntime(load_config(write_config(tmp_path)), embed_node=False, fault_injection=True)


def test_serve_refuses_with_the_refusal_exit_code_before_serving(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = real_bus_config(tmp_path)
    assert main(["--config", str(config), "serve", "--fault-injection"]) == ExitCode.INTERLOCK
    err = capsys.readouterr().err
    assert "--fault-injection refused" in err and "serve --sim --fault-injection" in err
    assert not (tmp_path / "mill.sock").exists()


def ask(runtime: ServiceRuntime, method: str, path: str, **kwargs: object) -> httpx.Response:
    async def go() -> httpx.Response:
        transport = httpx.ASGITransport(app=create_app(runtime))
        async with httpx.AsyncClient(transport=transport, base_url="http://millctl") as http:
            return await http.request(method, path, **kwargs)  # type: ignore[arg-type]

    return asyncio.run(go())


def test_without_the_switch_the_drill_routes_do_not_exist(tmp_path: Path) -> None:
    runtime = ServiceRuntime(load_config(write_config(tmp_path)))
    try:
        assert ask(runtime, "GET", "/v1/sim/faults").status_code == 404
        answer = ask(runtime, "POST", "/v1/sim/faults", json={"fault": "VIB_STALL"})
        assert answer.status_code == 404 and answer.json()["code"] == "http_error"
        assert "/v1/sim/faults" not in create_app(runtime).openapi()["paths"]
        assert runtime.describe().fault_injection is False
        assert runtime.node is not None and runtime.node.faults.enabled is False
    finally:
        runtime.close()


def test_with_the_switch_the_routes_are_documented_and_the_node_accepts_faults(tmp_path: Path) -> None:
    runtime = ServiceRuntime(load_config(write_config(tmp_path)), fault_injection=True)
    try:
        spec = create_app(runtime).openapi()
        assert set(spec["paths"]["/v1/sim/faults"]) == {"get", "post"}
        assert spec["components"]["schemas"]["SimFaultName"]["enum"] == [f.value for f in SimFaultName]
        assert runtime.describe().fault_injection is True and runtime.node.faults.enabled is True
        bad = ask(runtime, "POST", "/v1/sim/faults", json={"fault": "MELTDOWN"})
        assert bad.status_code == 422 and bad.json()["field"] == "body.fault"
    finally:
        runtime.close()
