"""The mill devices' one connection to ``millctl serve``: the typed async client, the status poller, the lease keeper.

Everything the devices do goes through the service's API (:class:`millctl.client.AsyncClient`): the interlock,
the control lease and the records apply to a bluesky plan exactly as to the CLI. Nothing here talks to the bus.

The poller asks for the status and the control lease every ``poll_s`` and publishes them (the devices' soft
signals follow). While the device is staged the keeper renews the lease (a lease lapses after 30 s without a
command), gives control back to the operator when the mill trips (a tripped mill is the operator's to reset), and
takes it back once the operator has reset and armed and released control again.
"""

from __future__ import annotations

import asyncio
import contextlib
import enum
import logging
import os
import time
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass

from millctl.api import ControllerState, ControlOut, StatusOut
from millctl.client import AsyncClient, ControlHeld
from millctl.errors import BusError, InterlockError

log = logging.getLogger(__name__)

S = ControllerState
MOVING = frozenset({S.ARMED, S.RUNNING})
"""The states in which the mill takes setpoints."""
STANDSTILL_RPM = 1.0
"""Both drives below this count as at rest (rpm), as the recipe runner counts them."""


class Readiness(enum.StrEnum):
    """Whether a plan may go on driving the mill (the suspender's signal, :mod:`millctl.bluesky.suspenders`)."""

    READY = "READY"
    """ARMED or RUNNING, and (when staged) the control lease held by this device."""
    NOT_ARMED = "NOT_ARMED"
    """DISABLED (reset, not armed yet), STOPPING or not connected to the node: wait, neither suspend nor resume."""
    TRIPPED = "TRIPPED"
    """A trip latched: suspend until the operator has reset and armed."""
    LEASE_LOST = "LEASE_LOST"
    """Staged, but the lease is gone (expired, taken over, or given back on a trip): suspend."""


def readiness(state: ControllerState, *, staged: bool, holding: bool) -> Readiness:
    """What the mill's state and this device's hold on control mean for a running plan."""
    if state is S.TRIPPED:
        return Readiness.TRIPPED
    if staged and not holding:
        return Readiness.LEASE_LOST
    if state in MOVING:
        return Readiness.READY
    return Readiness.NOT_ARMED


class MillTripped(InterlockError):
    """The mill tripped during a move (or was found TRIPPED): the move failed with the trip's cause."""


class MoveInterrupted(InterlockError):
    """A move ended before its target: the mill was stopped, or its setpoints were changed by someone else."""


@dataclass(frozen=True)
class Settle:
    """When a move counts as done: measured within ``tolerance_rpm`` of the target for ``steady_s`` seconds."""

    tolerance_rpm: float = 5.0
    steady_s: float = 1.0
    timeout_s: float = 30.0
    """Allowed past the service's planned ramp duration before the move fails (s)."""


def off_target_rpm(status: StatusOut, rotary_rpm: float, vibration_rpm: float) -> float | None:
    """The larger distance of a measured speed from its target (rpm); None while a speed is not measured."""
    if status.measured_rotary_rpm is None or status.measured_vibration_rpm is None:
        return None
    return max(abs(status.measured_rotary_rpm - rotary_rpm), abs(status.measured_vibration_rpm - vibration_rpm))


def move_failure(status: StatusOut, rotary_rpm: float, vibration_rpm: float) -> InterlockError | None:
    """Why a move to (``rotary_rpm``, ``vibration_rpm``) can no longer finish, from one status; None if it can."""
    if status.state is S.TRIPPED:
        return MillTripped(f"the mill tripped during the move to {rotary_rpm:g}/{vibration_rpm:g} rpm: "
                           f"{status.trip_cause or 'no cause given'} (reset at standstill, then arm: "
                           "docs/operations.md#state-machine)")
    if status.state not in MOVING:
        return MoveInterrupted(f"the move to {rotary_rpm:g}/{vibration_rpm:g} rpm ended: the controller is "
                               f"{status.state}")
    if (status.target_rotary_rpm, status.target_vibration_rpm) != (rotary_rpm, vibration_rpm):
        return MoveInterrupted(f"the move to {rotary_rpm:g}/{vibration_rpm:g} rpm ended: the setpoints are now "
                               f"{status.target_rotary_rpm}/{status.target_vibration_rpm} rpm (changed by another "
                               "command)")
    return None


def at_rest(status: StatusOut) -> bool:
    """Nothing to stop: both targets 0, both drives measured at rest, the heater off."""
    measured = (status.measured_rotary_rpm, status.measured_vibration_rpm)
    return (not status.target_rotary_rpm and not status.target_vibration_rpm and status.furnace_target_c is None
            and all(m is not None and m < STANDSTILL_RPM for m in measured))


def _older(status: StatusOut, than: StatusOut | None) -> bool:
    """Whether ``status`` was taken before ``than`` (by the controller's clock): a stale answer, never published."""
    return (than is not None and status.time_s is not None and than.time_s is not None
            and status.time_s < than.time_s)


class ServiceLink:
    """One :class:`AsyncClient`, polled; the latest status and lease state; the lease kept while staged.

    Made in the RunEngine's event loop (by the device's ``connect``): the client, the poll task and every wait
    belong to that loop.
    """

    def __init__(self, client: AsyncClient, *, poll_s: float = 0.25, on_update: Callable[[], None] | None = None
                 ) -> None:
        self.client = client
        self.poll_s = poll_s
        self.on_update = on_update
        self.status: StatusOut | None = None
        self.control: ControlOut | None = None
        self.error: BusError | None = None
        """The last failed poll's error (None once a poll succeeds again)."""
        self.staged = False
        self.holding = False
        self.lost_reason = ""
        self._renewed_s = 0.0
        self._renew_s = 10.0
        self._updated = asyncio.Event()
        self._lease_lock = asyncio.Lock()
        """One keeper at a time: the poller and a trigger or a move may refresh together."""
        self._task: asyncio.Task[None] | None = None

    @property
    def holder(self) -> str:
        """How the service names this client as the lease holder."""
        return f"api:{self.client.name}"

    @property
    def readiness(self) -> Readiness:
        """The plan's view of the mill now (NOT_ARMED before the first status)."""
        if self.status is None:
            return Readiness.NOT_ARMED
        return readiness(self.status.state, staged=self.staged, holding=self.holding)

    async def open(self) -> None:
        """Read the status once (a missing service fails here, naming the socket), then poll in the background."""
        await self.refresh()
        if self._task is None:
            self._task = asyncio.get_running_loop().create_task(self._poll(), name="millctl-bluesky-poll")

    async def close(self) -> None:
        """Stop polling, give back a held lease, close the connection."""
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
            self._task = None
        await self.release()
        await self.client.aclose()

    async def refresh(self) -> StatusOut:
        """A fresh status and lease state, published; the lease kept."""
        status = await self.client.status()
        control = await self.client.control_state()
        if _older(status, self.status):  # asked before a newer answer arrived (a poll overtaken by a command's read)
            assert self.status is not None
            return self.status
        self.status, self.control = status, control
        self.error = None
        async with self._lease_lock:
            try:
                await self._keep_lease(status, control)
            except InterlockError as exc:  # e.g. control taken by another client in between: judged next poll
                log.warning("lease keeper: %s", exc)
        self._publish()
        return status

    async def next_status(self) -> StatusOut:
        """The status of the next poll (raises the poll's error when the service stops answering)."""
        self._updated.clear()
        await self._updated.wait()
        if self.error is not None:
            raise self.error
        assert self.status is not None
        return self.status

    def _publish(self) -> None:
        self._updated.set()
        if self.on_update is not None:
            self.on_update()

    async def _poll(self) -> None:
        while True:
            await asyncio.sleep(self.poll_s)
            try:
                await self.refresh()
            except BusError as exc:  # the service is gone or busy: say so, keep asking
                if self.error is None:
                    log.warning("mill service not answering: %s", exc)
                self.error = exc
                self._publish()

    # ------------------------------------------------------------------ the lease
    async def take(self) -> None:
        """Take control (stage); ControlHeld names the holder when another client has it."""
        await self.client.take_control()
        self.staged = self.holding = True
        self.lost_reason = ""
        self._renewed_s = time.monotonic()
        self._publish()

    async def release(self) -> None:
        """Give control back (unstage); nothing to do when not held."""
        self.staged = False
        if self.holding:
            self.holding = False
            with contextlib.suppress(BusError, InterlockError):
                await self.client.release_control()
        self.client.lease_id = None
        self._publish()

    async def _keep_lease(self, status: StatusOut, control: ControlOut) -> None:
        if not self.staged:
            return
        if self.holding:
            if not control.held or control.holder != self.holder or control.expired:
                self._lose(f"control is {'held by ' + str(control.holder) if control.held else 'free'}"
                           f"{' (lease expired)' if control.expired else ''}")
            elif status.state is S.TRIPPED:
                with contextlib.suppress(InterlockError):
                    await self.client.release_control()
                self._lose(f"given back to the operator: the mill tripped ({status.trip_cause})")
            elif time.monotonic() - self._renewed_s >= self._renew_s:
                try:
                    await self.client.take_control()
                except ControlHeld as exc:
                    self._lose(str(exc))
                else:
                    self._renewed_s = time.monotonic()
        elif not control.held and status.state in MOVING:  # the operator reset, armed and let go: ours again
            await self.client.take_control()
            self.holding, self.lost_reason, self._renewed_s = True, "", time.monotonic()
            log.info("control taken back: the mill is %s", status.state)

    def _lose(self, reason: str) -> None:
        log.warning("control lease lost: %s", reason)
        self.holding, self.lost_reason = False, reason
        self.client.lease_id = None

    @contextlib.asynccontextmanager
    async def commanding(self) -> AsyncIterator[AsyncClient]:
        """The client for a command: with the staged lease, or (unstaged) control taken for it and given back.

        As the CLI's one-shot commands do: ``RE(bps.mv(mill, (150, 800)))`` on an unstaged mill takes control for
        its commands only. Staged without the lease (lost), the service refuses the command (423).
        """
        if self.staged:
            yield self.client
            return
        await self.client.take_control()
        try:
            yield self.client
        finally:
            with contextlib.suppress(BusError, InterlockError):
                await self.client.release_control()
            self.client.lease_id = None

    # ------------------------------------------------------------------ commands
    async def stop(self) -> None:
        """The controlled stop, with the lease when held, else without; nothing to stop unless armed or running.

        A service that wants a lease for STOP (423) gets it taken for the stop when control is free.
        """
        status = await self.refresh()
        if status.state not in MOVING or at_rest(status):
            return
        try:
            await self.client.stop()
        except ControlHeld:
            if self.holding:
                raise
            control = await self.client.control_state()
            if control.held:
                raise
            await self.client.take_control()
            try:
                await self.client.stop()
            finally:
                with contextlib.suppress(BusError, InterlockError):
                    await self.client.release_control()
                self.client.lease_id = None


def client_for(socket_path: str | os.PathLike[str] | None, *, base_url: str | None, token: str | None, name: str,
               config: str | os.PathLike[str] | None) -> AsyncClient:
    """The async client the devices use (socket from the config, as every millctl client finds it)."""
    return AsyncClient(socket_path, base_url=base_url, token=token, name=name, config=config)


__all__ = [
    "MOVING",
    "STANDSTILL_RPM",
    "MillTripped",
    "MoveInterrupted",
    "Readiness",
    "ServiceLink",
    "Settle",
    "at_rest",
    "client_for",
    "move_failure",
    "off_target_rpm",
    "readiness",
]
