"""The mill as ophyd-async devices over the service's API: :class:`Mill` with its rotary, vibration and furnace axes.

Shaped like ophyd-async's ``SimMotor``: soft signals that the poller (:class:`~millctl.bluesky.link.ServiceLink`)
keeps up to date, and ``set()`` returning a watchable status that completes when the measured value has reached
the target and stayed there, and fails with the reason (the interlock's :class:`~millctl.client.InterlockRefusal`,
:class:`~millctl.bluesky.link.MillTripped`, :class:`~millctl.bluesky.link.MoveInterrupted`).

Every command is a request to ``millctl serve`` with this device's control lease: ``stage`` takes it and
``unstage`` gives it back; ``stop()`` is the controlled stop. Nothing here reaches the bus or the interlock by
another way.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import AsyncIterator, Callable
from typing import Any, NamedTuple

from ophyd_async.core import (
    AsyncStatus,
    Device,
    DeviceConnector,
    StandardReadable,
    WatchableAsyncStatus,
    WatcherUpdate,
    soft_signal_r_and_setter,
)
from ophyd_async.core import StandardReadableFormat as Format

from millctl.api import ErrorBody, ErrorCode, ServiceOut, StatusOut
from millctl.bluesky.link import (
    MOVING,
    MillTripped,
    S,
    ServiceLink,
    Settle,
    at_rest,
    client_for,
    move_failure,
    off_target_rpm,
)
from millctl.client import InterlockRefusal


class MillPoint(NamedTuple):
    """An operating point: rotary and vibration speeds (rpm), and a furnace target (°C) or None to leave it."""

    rotary_rpm: float
    vibration_rpm: float
    temp_c: float | None = None


def _num(value: float | None) -> float:
    """A reading's value: NaN where the service reports none (null: not measured yet, or not finite)."""
    return math.nan if value is None else float(value)


class Axis(StandardReadable):
    """One movable quantity of the mill: its measured value (hinted, named as the axis) and its target."""

    def __init__(self, units: str, mover: Callable[[float], AsyncIterator[WatcherUpdate[float]]],
                 stopper: Callable[[], Any], name: str = "") -> None:
        with self.add_children_as_readables(Format.HINTED_SIGNAL):
            self.readback, self._set_readback = soft_signal_r_and_setter(float, math.nan, units=units, precision=1)
        with self.add_children_as_readables(Format.UNCACHED_SIGNAL):
            self.setpoint, self._set_setpoint = soft_signal_r_and_setter(float, math.nan, units=units, precision=1)
        self._mover = mover
        self._stopper = stopper
        super().__init__(name=name)

    def set_name(self, name: str, *, child_name_separator: str | None = None) -> None:
        """Name the measured value as the axis itself (``mill-rotary``), as ophyd-async's movables do."""
        super().set_name(name, child_name_separator=child_name_separator)
        self.readback.set_name(name)

    @WatchableAsyncStatus.wrap
    async def set(self, value: float) -> AsyncIterator[WatcherUpdate[float]]:
        """Move this axis alone (the others keep their targets); done when measured there and steady."""
        async for update in self._mover(float(value)):
            yield update

    async def stop(self, success: bool = True) -> None:
        """The mill's controlled stop (both drives stop: they are one machine)."""
        await self._stopper()


class _ServiceConnector(DeviceConnector):
    """Connects the soft signals, then the service link (a missing service fails ``connect``, naming the socket)."""

    async def connect_real(self, device: Device, timeout: float, force_reconnect: bool) -> None:
        await super().connect_real(device, timeout, force_reconnect)
        assert isinstance(device, Mill)
        await device.open_link()


class Mill(StandardReadable):
    """The mill behind ``millctl serve``: movable speeds and furnace, readings with units, the lease on stage.

    ``set(MillPoint(150, 800))`` (or ``bps.mv(mill, (150, 800))``) ramps both drives as the service plans and
    completes when both measured speeds are within ``settle.tolerance_rpm`` of the target for ``settle.steady_s``;
    a disarmed mill is armed first. ``rotary``, ``vibration`` and ``furnace`` are movables of their own.
    """

    def __init__(self, socket_path: str | os.PathLike[str] | None = None, *, base_url: str | None = None,
                 token: str | None = None, client_name: str = "bluesky", config: str | os.PathLike[str] | None = None,
                 settle: Settle | None = None, poll_s: float = 0.25, furnace_band_c: float = 10.0,
                 name: str = "") -> None:
        self._where = (socket_path, base_url, token, client_name, config)
        self.settle = settle or Settle()
        self.poll_s = poll_s
        self.furnace_band_c = furnace_band_c
        self.link: ServiceLink | None = None
        self.service: ServiceOut | None = None
        """The service as it was at ``connect``: mill, configuration sha256, law, margin (the start documents')."""
        self._noted_run = ""
        self.suspenders = 0
        """Suspenders watching this mill (:class:`~millctl.bluesky.suspenders.SuspendWhenMillNotReady` counts
        itself): with one, a move that meets a trip waits for the suspension's ``stop()`` instead of failing."""
        self._stop_requested = False
        self.rotary = Axis("rpm", lambda v: self._move_axis(rotary_rpm=v), self.stop)
        self.vibration = Axis("rpm", lambda v: self._move_axis(vibration_rpm=v), self.stop)
        self.furnace = Axis("degC", self._heat, self.stop)
        self.add_readables([self.rotary, self.vibration, self.furnace])
        with self.add_children_as_readables(Format.UNCACHED_SIGNAL):
            self.state, self._set_state = soft_signal_r_and_setter(str, "")
            self.readiness, self._set_readiness = soft_signal_r_and_setter(str, "")
            self.limit_rotary_rpm, self._set_limit = soft_signal_r_and_setter(float, math.nan, units="rpm")
            self.margin_rpm, self._set_margin = soft_signal_r_and_setter(float, math.nan, units="rpm")
            self.impact_rate_hz, self._set_impact_rate = soft_signal_r_and_setter(float, math.nan, units="Hz")
            self.impact_energy_mj, self._set_impact_energy = soft_signal_r_and_setter(float, math.nan, units="mJ")
            self.event_seq, self._set_event_seq = soft_signal_r_and_setter(int, 0)
            self.run_id, self._set_run_id = soft_signal_r_and_setter(str, "")
        with self.add_children_as_readables(Format.CONFIG_SIGNAL):
            self.law, self._set_law = soft_signal_r_and_setter(str, "")
            self.margin, self._set_margin_fraction = soft_signal_r_and_setter(float, math.nan, units="fraction")
            self.config_sha256, self._set_config_sha256 = soft_signal_r_and_setter(str, "")
            self.mill_name, self._set_mill_name = soft_signal_r_and_setter(str, "")
            self.simulated, self._set_simulated = soft_signal_r_and_setter(bool, False)
        self._heating_rate_c_per_min = 10.0
        super().__init__(name=name, connector=_ServiceConnector())

    # ------------------------------------------------------------------ connection
    def require_link(self) -> ServiceLink:
        """The connected link (``connect()`` first: ``init_devices()`` does it)."""
        if self.link is None:
            raise RuntimeError(f"{self.name or 'mill'} is not connected: connect it first (ophyd_async init_devices)")
        return self.link

    async def open_link(self) -> None:
        """Connect to the service: its identity and envelope into the configuration signals, then poll."""
        if self.link is None:
            socket_path, base_url, token, client_name, config = self._where
            client = client_for(socket_path, base_url=base_url, token=token, name=client_name, config=config)
            self.link = ServiceLink(client, poll_s=self.poll_s, on_update=self._publish)
        link = self.link
        service = self.service = await link.client.service()
        envelope = await link.client.envelope(points=2)
        self._set_law(service.law)
        self._set_margin_fraction(service.margin)
        self._set_config_sha256(service.config_sha256)
        self._set_mill_name(service.mill_name)
        self._set_simulated(service.simulated)
        self._heating_rate_c_per_min = envelope.max_heating_rate_c_per_min
        await link.open()

    async def close(self) -> None:
        """Stop polling and give back the lease (the mill keeps what it was doing)."""
        if self.link is not None:
            await self.link.close()

    def _publish(self) -> None:
        link = self.link
        if link is None or link.status is None:
            return
        s = link.status
        self.rotary._set_readback(_num(s.measured_rotary_rpm))
        self.rotary._set_setpoint(_num(s.target_rotary_rpm))
        self.vibration._set_readback(_num(s.measured_vibration_rpm))
        self.vibration._set_setpoint(_num(s.target_vibration_rpm))
        self.furnace._set_readback(_num(s.furnace_temp_c))
        self.furnace._set_setpoint(_num(s.furnace_target_c))
        self._set_state(str(s.state))
        self._set_readiness(str(link.readiness))
        self._set_limit(_num(s.limit_rotary_rpm))
        self._set_margin(_num(s.margin_rpm))
        self._set_impact_rate(_num(s.impact_rate_hz))
        self._set_impact_energy(_num(s.impact_energy_mj))

    # ------------------------------------------------------------------ bluesky verbs
    @AsyncStatus.wrap
    async def stage(self) -> None:
        """Take the control lease (ControlHeld names the holder when another client has it)."""
        await super().stage()
        await self.require_link().take()

    @AsyncStatus.wrap
    async def unstage(self) -> None:
        """Give the control lease back."""
        await self.require_link().release()
        await super().unstage()

    @AsyncStatus.wrap
    async def trigger(self) -> None:
        """Fresh readings: the status now, the service's last event number and the recipe run (if any)."""
        link = self.require_link()
        await link.refresh()
        events = await link.client.events(after=2**62, limit=1)
        self._set_event_seq(events.last_seq)
        recipe = await link.client.recipe()
        active = recipe.progress.run_id if recipe.active and recipe.progress is not None else ""
        self._set_run_id(active or self._noted_run)

    def note_run(self, run_id: str) -> None:
        """The recipe run a plan follows ("" for none): its id stays in ``run_id`` after the run has ended."""
        self._noted_run = run_id
        self._set_run_id(run_id)

    async def check_value(self, value: MillPoint | tuple[float, ...]) -> None:
        """The envelope's verdict on a point, nothing commanded: raises InterlockRefusal when it is outside."""
        point = MillPoint(*value)
        verdict = await self.require_link().client.check(point.rotary_rpm, point.vibration_rpm, point.temp_c)
        if not verdict.ok:
            raise InterlockRefusal(f"{point.rotary_rpm:g}/{point.vibration_rpm:g} rpm is outside the envelope: "
                                   f"{verdict.reason}")

    @WatchableAsyncStatus.wrap
    async def set(self, value: MillPoint | tuple[float, ...]) -> AsyncIterator[WatcherUpdate[float]]:
        """Ramp to the point (all or nothing: a refusal applies no part of it); done when measured there and steady."""
        point = MillPoint(*value)
        async for update in self._move(point.rotary_rpm, point.vibration_rpm, point.temp_c):
            yield update

    async def stop(self, success: bool = True) -> None:
        """The controlled stop: both drives ramp down inside the envelope, heater off (nothing if at rest).

        A move in progress ends at the next status (successfully: the RunEngine stops what it moved when it
        suspends, and replays the move after the resume).
        """
        self._stop_requested = True
        await self.require_link().stop()

    async def _until_stopped(self, failure: Exception) -> None:
        """A trip under a suspender: wait for the suspension's stop(), then end the move; without one, fail."""
        if not self.suspenders:
            raise failure
        while not self._stop_requested:
            await self.require_link().next_status()

    def at_point(self, rotary_rpm: float, vibration_rpm: float) -> bool:
        """Whether the latest status shows the mill running at the point, within the settle tolerance."""
        link = self.require_link()
        s = link.status
        if s is None or move_failure(s, rotary_rpm, vibration_rpm) is not None:
            return False
        off = off_target_rpm(s, rotary_rpm, vibration_rpm)
        return off is not None and off <= self.settle.tolerance_rpm

    # ------------------------------------------------------------------ motion
    def _move_axis(self, *, rotary_rpm: float | None = None, vibration_rpm: float | None = None
                   ) -> AsyncIterator[WatcherUpdate[float]]:
        s = self.require_link().status
        rot = rotary_rpm if rotary_rpm is not None else _target(s, "target_rotary_rpm")
        vib = vibration_rpm if vibration_rpm is not None else _target(s, "target_vibration_rpm")
        return self._move(rot, vib, None, watch="vibration" if rotary_rpm is None else "rotary")

    async def _move(self, rotary_rpm: float, vibration_rpm: float, temp_c: float | None, *, watch: str = "rotary"
                    ) -> AsyncIterator[WatcherUpdate[float]]:
        link = self.require_link()
        self._stop_requested = False
        status = await link.refresh()
        to_rest = rotary_rpm == vibration_rpm == 0.0 and temp_c is None
        if status.state is S.TRIPPED:
            raise MillTripped(f"the mill is TRIPPED ({status.trip_cause}): reset at standstill, then arm, before "
                              f"moving it to {rotary_rpm:g}/{vibration_rpm:g} rpm")
        if to_rest and (status.state not in MOVING or at_rest(status)):
            return  # nothing runs: already at rest
        if status.state is S.DISABLED:  # checked before arming: a refused point changes nothing at all
            verdict = await link.client.check(rotary_rpm, vibration_rpm, temp_c)
            if not verdict.ok:
                raise InterlockRefusal(f"setpoints {rotary_rpm:g}/{vibration_rpm:g} rpm refused: {verdict.reason}",
                                       ErrorBody(code=ErrorCode.INTERLOCK_REFUSED, message=verdict.reason,
                                                 refusals=verdict.refusals))
        async with link.commanding() as client:
            if status.state is S.DISABLED:
                await client.arm()
            answer = await client.set_speeds(rotary_rpm, vibration_rpm, temp_c=temp_c)
        deadline = time.monotonic() + (answer.duration_s or 0.0) + self.settle.timeout_s
        initial = _num(getattr(status, f"measured_{watch}_rpm"))
        target = rotary_rpm if watch == "rotary" else vibration_rpm
        steady_since: float | None = None
        status = await link.refresh()  # read after the command: an older answer still on its way is dropped
        while True:
            if self._stop_requested:
                return
            failure = move_failure(status, rotary_rpm, vibration_rpm)
            if isinstance(failure, MillTripped):
                await self._until_stopped(failure)
                return
            if failure is not None:
                raise failure
            yield WatcherUpdate(current=_num(getattr(status, f"measured_{watch}_rpm")), initial=initial,
                                target=target, name=f"{self.name}-{watch}", unit="rpm", precision=1)
            off = off_target_rpm(status, rotary_rpm, vibration_rpm)
            ramping = (status.ramp_remaining_s or 0.0) > 0.0
            if off is None or ramping or off > self.settle.tolerance_rpm:
                steady_since = None
            elif steady_since is None:
                steady_since = time.monotonic()
            elif time.monotonic() - steady_since >= self.settle.steady_s:
                return
            if time.monotonic() > deadline:
                raise TimeoutError(f"the drives did not settle within ±{self.settle.tolerance_rpm:g} rpm of "
                                   f"{rotary_rpm:g}/{vibration_rpm:g} rpm within {self.settle.timeout_s:g} s of the "
                                   f"planned ramp ({answer.duration_s or 0.0:.1f} s): off by {off} rpm")
            status = await link.next_status()

    async def _heat(self, temp_c: float) -> AsyncIterator[WatcherUpdate[float]]:
        link = self.require_link()
        self._stop_requested = False
        status = await link.refresh()
        start = _num(status.furnace_temp_c)
        async with link.commanding() as client:
            await client.set_furnace(temp_c)
        heating_s = abs(temp_c - (0.0 if math.isnan(start) else start)) / self._heating_rate_c_per_min * 60.0
        deadline = time.monotonic() + heating_s + 10.0 * self.settle.timeout_s
        steady_since: float | None = None
        while True:
            status = await link.next_status()
            if self._stop_requested:
                return
            if status.state is S.TRIPPED:
                await self._until_stopped(MillTripped(f"the mill tripped while heating to {temp_c:g} °C: "
                                                      f"{status.trip_cause}"))
                return
            now_c = _num(status.furnace_temp_c)
            yield WatcherUpdate(current=now_c, initial=start, target=temp_c, name=f"{self.name}-furnace",
                                unit="degC", precision=1)
            if not abs(now_c - temp_c) <= self.furnace_band_c:
                steady_since = None
            elif steady_since is None:
                steady_since = time.monotonic()
            elif time.monotonic() - steady_since >= self.settle.steady_s:
                return
            if time.monotonic() > deadline:
                raise TimeoutError(f"the furnace did not reach {temp_c:g} ± {self.furnace_band_c:g} °C within "
                                   f"{heating_s + 10.0 * self.settle.timeout_s:.0f} s: it reads {now_c:.1f} °C")


def _target(status: StatusOut | None, field: str) -> float:
    value = None if status is None else getattr(status, field)
    return 0.0 if value is None else float(value)


__all__ = ["Axis", "Mill", "MillPoint"]
