"""Fault drills: ``millctl serve --fault-injection`` lets an instructor inject the simulated node's faults.

For operator training: the instructor injects a vibration stall, a runaway, a
silent node… from the TUI (or ``POST /v1/sim/faults``) and the operator
handles the trip as on the real mill. Only a simulated mill may be drilled:
the service refuses the switch (:class:`FaultInjectionRefused`, exit 2)
unless it runs the embedded simulated node, and without the switch the
routes do not exist (404). Each injection is a real ``SimFault`` frame on the
service's bus (so the bus log holds it) and a ``drill`` event naming who
injected what (docs/operations.md#fault-drills). Beside CiA 402 drives with the
furnace node on its own channel, the furnace's fault (HEATER_FAIL) is sent on
that channel and CLEAR on both, so each simulated device gets its own faults.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from fastapi import FastAPI

from millctl.api import EventKind, FaultRequest, FaultsOut, SimFaultName
from millctl.config.models import MillConfig
from millctl.errors import InterlockError
from millctl.protocol import SimFault, SimFaultCode, default_codec
from millctl.service.headers import ClientName, client_source

if TYPE_CHECKING:
    from millctl.controller import Controller
    from millctl.service.runtime import ServiceRuntime
    from millctl.service.tap import TappedBus

DOC_REF = "docs/operations.md#fault-drills"


class FaultInjectionRefused(InterlockError):
    """``--fault-injection`` on a service that does not run the simulated node: refused, nothing started."""


def embeds_node(config: MillConfig, embed_node: bool | None = None) -> bool:
    """True when the service runs the simulated node itself (the ``virtual`` bus, unless told otherwise)."""
    return config.bus.interface == "virtual" if embed_node is None else embed_node


def require_simulated(config: MillConfig, embed_node: bool | None = None) -> None:
    """Refuse fault injection unless the service's node is the embedded simulation."""
    if not embeds_node(config, embed_node):
        bus = f"{config.bus.interface}:{config.bus.channel}"
        raise FaultInjectionRefused(
            f"--fault-injection refused: this service talks to a node on {bus}, not to its embedded simulated "
            "node, and faults are injected into a simulated mill only. Use `millctl serve --sim --fault-injection`, "
            f'or a config with bus.interface = "virtual" (see {DOC_REF})'
        )


def inject(rt: ServiceRuntime, request: FaultRequest, who: str) -> FaultsOut:
    """Send the SimFault frame from the control loop and record a drill event; the faults active before it."""
    code = SimFaultCode[request.fault.value]
    frame = default_codec().encode(SimFault(code, request.active, request.param))

    def send(c: Controller) -> FaultsOut:
        for bus in _buses_for(rt, code):
            bus.send(frame)
        return active_faults(rt)

    before = rt.call(send, needs_node=False)
    if request.fault is SimFaultName.CLEAR:
        what = "cleared every injected fault"
    else:
        what = f"{'injected' if request.active else 'cleared'} {request.fault.value} (param {request.param:g})"
    rt.journal.add(EventKind.DRILL, who, f"fault drill: {what}", fault=request.fault.value, active=request.active,
                   param=request.param)
    return before


FURNACE_FAULTS = frozenset({SimFaultCode.HEATER_FAIL})
"""Faults of the furnace: beside CiA 402 drives they go to the furnace node on its own channel."""


def _buses_for(rt: ServiceRuntime, code: SimFaultCode) -> list[TappedBus]:
    """Where a SimFault frame goes: the node's bus, or two buses beside CiA 402 drives.

    There the furnace's faults go to the furnace node's channel ([drives.furnace_bus]) and CLEAR to both,
    so that each simulated device gets its own.
    """
    if rt.furnace_bus is None:
        return [rt.bus]
    if code is SimFaultCode.CLEAR:
        return [rt.bus, rt.furnace_bus]
    return [rt.furnace_bus] if code in FURNACE_FAULTS else [rt.bus]


def active_faults(rt: ServiceRuntime) -> FaultsOut:
    """The faults the embedded node has injected now (read in the control loop)."""
    return FaultsOut(active={SimFaultName(code.name): param for code, param in rt.node.faults.active.items()})


def add_fault_routes(app: FastAPI, rt: ServiceRuntime) -> None:
    """``GET``/``POST /v1/sim/faults``, on a service started with ``--fault-injection`` only."""
    from millctl.service.errors import READ_RESPONSES  # errors imports the runtime, which imports this module

    @app.get("/v1/sim/faults", response_model=FaultsOut, responses=READ_RESPONSES, tags=["drill"])
    def faults() -> FaultsOut:
        """The faults injected into the simulated node now (serve --fault-injection only)."""
        return rt.call(lambda c: active_faults(rt), needs_node=False)

    @app.post("/v1/sim/faults", response_model=FaultsOut, responses=READ_RESPONSES, tags=["drill"])
    def inject_fault(body: FaultRequest, x_millctl_client: ClientName = None) -> FaultsOut:
        """Inject or clear a simulated node fault for an operator drill; answers the faults active before it.

        Needs no control lease: the instructor is not the operator who holds it. The node applies the
        frame on its next tick; read ``GET /v1/sim/faults`` for the faults active then.
        """
        return inject(rt, body, client_source(x_millctl_client))


__all__ = ["DOC_REF", "FaultInjectionRefused", "add_fault_routes", "embeds_node", "inject", "require_simulated"]
