"""The simulated CiA 402 mill with its furnace: the drives on one bus, the furnace-only millbus node on a second.

What ``millctl serve`` embeds for ``[drives] backend = "cia402"`` with
``furnace = "millbus"`` (``config/mill-cia402-furnace.toml``): the two
simulated CiA 402 drives (:class:`~firmware_sim.cia402.mill.Cia402Mill`) on the
drives' bus, and the millbus node in its furnace-only mode
(:class:`~firmware_sim.furnace_node.FurnaceNode`) on ``[drives.furnace_bus]``,
as a lab wires a separate furnace controller (docs/deployment.md, "A furnace
beside the drives: a second CAN channel"). Both are stepped by the one clock.
"""

from __future__ import annotations

from dataclasses import dataclass

import can

from firmware_sim.cia402.drive import SimDrive
from firmware_sim.cia402.mill import Cia402Mill
from firmware_sim.faults import FaultInjector
from firmware_sim.furnace_node import FurnaceNode
from millctl.clock import Clock
from millctl.config.models import MillConfig
from millctl.errors import InvalidInputError
from millctl.protocol import SimFaultCode, open_bus


@dataclass(frozen=True)
class InjectorPair:
    """The two simulated devices' fault injectors as the service's drill routes read them.

    A SimFault frame reaches the injector of the bus it is sent on: the furnace's HEATER_FAIL goes to the
    furnace node's channel, the drives' faults to the drives' bus, CLEAR to both (millctl/service/faults.py).
    """

    drives: FaultInjector
    furnace: FaultInjector

    @property
    def enabled(self) -> bool:
        """Injection is on (both were built with the same ``fault_injection``)."""
        return self.drives.enabled and self.furnace.enabled

    @property
    def active(self) -> dict[SimFaultCode, float]:
        """Every fault active now on either device, with its parameter."""
        return {**self.drives.active, **self.furnace.active}


class Cia402FurnaceMill:
    """The drives (``mill``, its ``drives`` by motor) and the furnace node (``furnace_node``), ticked together."""

    def __init__(
        self,
        config: MillConfig,
        bus: can.BusABC,
        clock: Clock,
        *,
        fault_injection: bool = False,
        seed: int = 0,
        furnace_bus: can.BusABC | None = None,
    ) -> None:
        """``furnace_bus``: the furnace node's bus (None: opened from ``[drives.furnace_bus]``, and shut at close)."""
        bus_config = config.drives.furnace_bus
        if bus_config is None:
            raise InvalidInputError(
                'the simulated furnace beside CiA 402 drives needs furnace = "millbus" and [drives.furnace_bus] '
                "(config/mill-cia402-furnace.toml)"
            )
        self.mill = Cia402Mill(config, bus, clock, fault_injection=fault_injection, seed=seed)
        self._owns_furnace_bus = furnace_bus is None
        self.furnace_bus = furnace_bus if furnace_bus is not None else open_bus(bus_config)
        self.furnace_node = FurnaceNode(config, self.furnace_bus, clock, fault_injection=fault_injection, seed=seed)

    @property
    def drives(self) -> dict[str, SimDrive]:
        """The simulated CiA 402 drives by motor (``rotary``, ``vibration``), as :class:`Cia402Mill` has them."""
        return self.mill.drives

    @property
    def faults(self) -> InjectorPair:
        """The drives' and the furnace node's fault injectors, each fed by SimFault frames on its own bus."""
        return InjectorPair(self.mill.faults, self.furnace_node.faults)

    @property
    def true_speeds_rpm(self) -> tuple[float, float]:
        """The rotors' true (ω_r, ω_v) (rpm)."""
        return self.mill.true_speeds_rpm

    @property
    def measured_speeds_rpm(self) -> tuple[float, float]:
        """The drives' last sensor readings (ω_r, ω_v) (rpm)."""
        return self.mill.measured_speeds_rpm

    @property
    def at_standstill(self) -> bool:
        """Both drives at rest with no demand."""
        return self.mill.at_standstill

    @property
    def heater_on(self) -> bool:
        """The furnace node's heater loop is on."""
        return self.furnace_node.heater_on

    @property
    def furnace_temp_c(self) -> float:
        """The furnace's temperature (°C)."""
        return self.furnace_node.furnace_temp_c

    def tick(self) -> None:
        """One step of the drives and one of the furnace node."""
        self.mill.tick()
        self.furnace_node.tick()

    def shutdown_stop(self) -> None:
        """The process is ending: quick stop on the drives, the furnace node's controlled stop (heater off)."""
        self.mill.shutdown_stop()
        self.furnace_node.shutdown_stop()

    def close(self) -> None:
        """Release the furnace node (and its bus when opened here); the drives' bus is the caller's."""
        self.mill.close()
        self.furnace_node.close()
        if self._owns_furnace_bus:
            self.furnace_bus.shutdown()


__all__ = ["Cia402FurnaceMill", "InjectorPair"]
