"""Helpers of the hil scenario suite (tests/hil/test_scenarios.py): the mill under test, the bus probe, the bounds.

``Mill`` starts the controller service (``millctl serve``) and the simulated
node (``python -m firmware_sim --fault-injection``) as separate processes on
the transport under test; on ``virtual`` the service runs its embedded node
and there is no probe. ``Probe`` is the third bus of a scenario, in the test
process: it injects faults, plays the rogue sender and the E-stop button, and
captures every frame with its receive timestamp (the kernel's, on
udp_multicast and socketcan), from which each scenario measures its
reaction time. ``Bounds`` derives every safety bound from the config and the
DBC's cycle times. ``report_timing`` prints ``HIL-TIMING {json}`` and appends
it to the file named by ``MILLCTL_HIL_TIMINGS``.
"""

from __future__ import annotations

import contextlib
import json
import os
import secrets
import signal
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import can
import pytest

from millctl.client import DEFAULT_TIMEOUT_S, Client
from millctl.config import load_config
from millctl.config.models import MillConfig
from millctl.controller.tracking import SAFETY_RELEVANT
from millctl.errors import MillctlError
from millctl.protocol import (
    Codec,
    DriveTelemetry,
    MillMessage,
    NodeStatus,
    default_codec,
)
from millctl.safety import Envelope
from tests.hil.conftest import IN_VM
from tests.hil.probe import (  # re-exported: the scenarios import them from here
    POLL_S,
    Probe,
    Seen,
    bound_scale,
    deepen_receive_queue,
    is_command,
    is_kind,
    is_status,
    sequence_limit_reached_at,
)
from tests.hil.scenario_config import (  # re-exported
    BACKEND_CONFIGS,
    upper_bound,
    vm_scaled,
    write_config,
)
from tests.support.pace import slowdown_now

if TYPE_CHECKING:
    import subprocess

    from tests.hil.conftest import Spawner, Transport

T = TypeVar("T")

STANDSTILL_RPM = 1.0
"""Measured speeds below this count as standstill (rpm), as in the controller."""
SCHEDULING_ALLOWANCE_S = 0.05
"""Added to every reaction bound on the host (s): late wake-ups of the Python processes in the chain."""


# --- bounds ---------------------------------------------------------------------------------------------------


def load_scale() -> float:
    """The factor a generated load (flood, babble) is divided by: the VM's slowdown measured now; 1 on the host."""
    return slowdown_now() if IN_VM else 1.0


@dataclass(frozen=True)
class Bounds:
    """Reaction-time bounds (s), each derived from the config and the DBC (docs/safety.md, "What trips").

    Every bound is the sum of what the chain of reactions may take by design:
    a receiver sees a frame at its next tick, a state change reaches the bus
    with the next periodic frame. ``scheduling_s`` allows for the processes'
    sleeping loops waking late: the simulated node and the controller are
    Python processes (under ``.ci/test`` at a real-time policy, which keeps
    other work from delaying them, not their own interpreter's pauses), and a
    wake-up can come tens of ms late (``SCHEDULING_ALLOWANCE_S``, env
    ``MILLCTL_HIL_SCHEDULING_S``). Load on the machine stretches none of them.
    """

    config: MillConfig
    codec: Codec

    def _period(self, kind: type[MillMessage]) -> float:
        period = self.codec.cycle_time_s(kind)
        assert period is not None, f"{kind.__name__} has no cycle time in the DBC"
        return period

    @property
    def scheduling_s(self) -> float:
        """The allowance for late wake-ups of the processes in the chain (s)."""
        return float(os.environ.get("MILLCTL_HIL_SCHEDULING_S", SCHEDULING_ALLOWANCE_S))

    def scaled(self, seconds: float) -> float:
        """``seconds`` of processes reacting (ticks, frame periods) plus the scheduling allowance, times the VM factor.

        Only what processes take scales here; a timeout of the config (``VM_SCALED_KEYS``) is added
        as it stands in the config in force, which inside the VM is already scaled.
        """
        return (seconds + self.scheduling_s) * bound_scale()

    @property
    def node_reports_s(self) -> float:
        """From a frame on the bus to the node's NodeStatus reporting its effect: one tick, one status period."""
        return self.scaled(self.config.timing.node_tick_s + self._period(NodeStatus))

    @property
    def controller_reacts_s(self) -> float:
        """A frame on the bus that trips the controller → its STOP on the bus: one controller tick."""
        return self.scaled(self.config.timing.controller_tick_s)

    @property
    def watchdog_s(self) -> float:
        """Last heartbeat on the bus → NodeStatus FAULT/WATCHDOG: the timeout, one node tick, one status period."""
        timing = self.config.timing
        return timing.watchdog_timeout_s + self.scaled(timing.node_tick_s + self._period(NodeStatus))

    @property
    def measured_trip_s(self) -> float:
        """First out-of-envelope DriveTelemetry → STOP: the rest of the debounce samples, one controller tick."""
        samples = self.config.interlock.debounce_samples - 1
        return self.scaled(samples * self._period(DriveTelemetry) + self.config.timing.controller_tick_s)

    @property
    def e2e_trip_s(self) -> float:
        """First corrupted DriveTelemetry → STOP: ``e2e_error_limit`` bad frames in a row, one controller tick."""
        frames = self.config.interlock.e2e_error_limit - 1
        return self.scaled(frames * self._period(DriveTelemetry) + self.config.timing.controller_tick_s)

    @property
    def stale_trip_s(self) -> float:
        """Last frame of the first kind to go stale → STOP: the longest stale bound of them, one controller tick."""
        interlock = self.config.interlock
        periods = [self._period(kind) for kind in SAFETY_RELEVANT]
        stale = max(max(interlock.stale_periods * p, interlock.min_stale_s) for p in periods)
        return stale + self.scaled(self.config.timing.controller_tick_s)

    @property
    def heartbeat_gap_s(self) -> float:
        """The longest gap between controller heartbeats the node tolerates: its watchdog timeout (not padded)."""
        return self.config.timing.watchdog_timeout_s


# --- timing report --------------------------------------------------------------------------------------------


def report_timing(
    capsys: pytest.CaptureFixture[str], name: str, transport: str, measured_s: float, bound_s: float
) -> None:
    """Print ``HIL-TIMING {json}`` (past pytest's capture) and append it to ``$MILLCTL_HIL_TIMINGS`` if set."""
    record = {
        "name": name,
        "transport": transport,
        "measured_s": round(measured_s, 4),
        "bound_s": round(bound_s, 4),
        "in_vm": IN_VM,
        "time_scale": bound_scale(),
    }
    line = "HIL-TIMING " + json.dumps(record)
    with capsys.disabled():
        print(f"\n{line}")
    if path := os.environ.get("MILLCTL_HIL_TIMINGS"):
        with open(path, "a", encoding="utf-8") as out:
            out.write(json.dumps(record) + "\n")


# --- the mill under test --------------------------------------------------------------------------------------


def wait_for(condition: Callable[[], T | None], timeout_s: float, what: str | Callable[[], str]) -> T:
    """Poll ``condition()`` until it returns something true, and return it (a safety net, not a timing check).

    ``timeout_s`` comes stretched for load and the VM (``Transport.timeout``); ``what`` may be a
    callable, evaluated only for the failure message (to show the latest state).
    """
    deadline = time.monotonic() + timeout_s
    error: Exception | None = None
    while True:
        try:
            if result := condition():
                return result
        except (can.CanError, OSError, LookupError, MillctlError) as exc:  # e.g. the socket not listening yet
            error = exc
        if time.monotonic() > deadline:
            detail = f" (last error: {error})" if error else ""
            described = what() if callable(what) else what
            pytest.fail(f"timed out after {timeout_s:.1f} s waiting for {described}{detail}")
        time.sleep(POLL_S * bound_scale())


NODE_SEED_ENV = "MILLCTL_NODE_SEED"
"""Environment variable that fixes the node's seed (to replay a run: its seed is printed as each node starts)."""


def mean_measured_rpm(statuses: list[dict[str, Any]]) -> tuple[float, float]:
    """The mean measured ω_r, ω_v (rpm) over a window of statuses, each sensor reading counted once.

    One reading carries the sensor's Gaussian noise (``drives.*.speed_noise_rpm``: σ = 1 rpm on the
    vibration drive), so the 3 rpm measurement tolerance is 3σ and one reading in about 370 falls outside
    it while the drive holds its speed exactly. "The mill holds the pair" is a claim about the mean:
    σ/√n. Consecutive statuses often repeat one telemetry frame; repeats are counted once.
    """
    if not statuses:
        raise ValueError("no statuses in the window: nothing to average")
    pairs = [(float(s["measured_rotary_rpm"]), float(s["measured_vibration_rpm"])) for s in statuses]
    readings = [pair for i, pair in enumerate(pairs) if i == 0 or pair != pairs[i - 1]]
    n = len(readings)
    return sum(r for r, _ in readings) / n, sum(v for _, v in readings) / n


def node_seed() -> int:
    """The seed of a scenario's node (``--seed``): ``MILLCTL_NODE_SEED`` if set, else a fresh one for each node.

    The seed drives the node's injected faults (which frames ``TX_LOSS`` drops, which bit ``TX_CORRUPT`` flips)
    and its sensor noise. With one fixed seed every run replays the same stretch of draws: the 20 % loss phase
    of the frame-loss scenario starts after the 1 % phase, ~170-230 draws in, and with the node's default seed
    draws 200-300 are 32 % under 0.2. That stretch, not the VM, gave the bursty "extra" loss of the
    vcan runs, and one E2E sequence trip (docs/operations.md, "Fault seeds").
    """
    text = os.environ.get(NODE_SEED_ENV, "").strip()
    if not text:
        return secrets.randbelow(2**31)
    try:
        seed = int(text)
    except ValueError:
        raise ValueError(f"{NODE_SEED_ENV}={text!r} is not an integer seed (unset it for fresh seeds)") from None
    if seed < 0:
        raise ValueError(f"{NODE_SEED_ENV}={seed} is negative; numpy seeds are integers ≥ 0")
    return seed


class Mill:
    """The controller service and the node as separate processes (or the service alone on ``virtual``).

    ``client`` commands the service through its API, ``probe`` watches and
    drives the bus (None on ``virtual``), ``bounds`` are the config's
    reaction-time bounds.
    """

    def __init__(
        self,
        transport: Transport,
        spawn: Spawner,
        directory: Path,
        *,
        dilate_drives: bool = False,
        backend: str = "millbus",
        node_args: tuple[str, ...] = (),
    ) -> None:
        self.transport = transport
        self.spawn = spawn
        self.backend = backend
        self.node_args = node_args
        """Extra arguments of ``python -m firmware_sim`` (e.g. a CiA 402 drive's ``--lie-readback``)."""
        self.config_path = write_config(directory, transport, dilate_drives=dilate_drives, backend=backend)
        self.config = load_config(self.config_path).config
        self.codec = default_codec()
        self.bounds = Bounds(self.config, self.codec)
        self.envelope = Envelope.from_config(self.config)
        self.socket_path = directory / "mill.sock"
        self.separate = transport.crosses_processes
        self.probe = Probe(self.config.bus, self.codec) if self.separate else None
        self.node: subprocess.Popen[bytes] | None = None
        self.service: subprocess.Popen[bytes] | None = None
        self.client = Client(self.socket_path, name="hil", timeout_s=transport.timeout(DEFAULT_TIMEOUT_S))

    # -- processes
    def start_node(self) -> subprocess.Popen[bytes]:
        """Start ``python -m firmware_sim --fault-injection --seed N`` on the transport (N: :func:`node_seed`).

        The seed is printed, so that a failing run's output says how to replay its faults.
        """
        assert self.separate, "on virtual the node runs inside the service"
        seed = node_seed()
        print(f"node seed {seed} (replay: {NODE_SEED_ENV}={seed})")
        argv = ["python", "-m", "firmware_sim", "--config", str(self.config_path), "--fault-injection"]
        self.node = self.spawn([*argv, "--seed", str(seed), *self.node_args], realtime="node")
        return self.node

    def start_service(self) -> subprocess.Popen[bytes]:
        """Start ``millctl serve`` and wait for its socket."""
        self.service = self.spawn(
            ["python", "-m", "millctl", "--config", str(self.config_path), "serve", "--socket", str(self.socket_path)],
            realtime="controller",
        )
        service = self.service
        wait_for(
            lambda: self.socket_path.exists() or service.poll() is not None,
            self.timeout(30.0),
            "the service socket",
        )
        assert service.poll() is None, f"the service exited:\n{self.spawn.output(service)}"
        return service

    def start(self) -> None:
        """Node (when separate) and service, then wait until the controller has seen the node DISABLED."""
        if self.separate:
            self.start_node()
        self.start_service()
        self.wait_state("DISABLED", 30.0)

    def kill(self, proc: subprocess.Popen[bytes] | None) -> None:
        """SIGKILL a process (and its helpers) and reap it."""
        if proc is not None and proc.poll() is None:
            self.spawn.stop(proc, signal.SIGKILL)

    def close(self) -> None:
        """Tear down: the client, the probe, then SIGKILL both processes (their clean shutdown is not under test)."""
        self.client.close()
        if self.probe is not None:
            self.probe.close()
        self.kill(self.service)
        self.kill(self.node)

    # -- commanding and watching
    def timeout(self, seconds: float) -> float:
        """A safety-net timeout, scaled for the VM."""
        return self.transport.timeout(seconds)

    def status(self) -> dict[str, Any]:
        """The controller's status through the API, as plain data."""
        return self.client.status().model_dump(mode="json")

    def wait_state(self, state: str, timeout_s: float = 10.0) -> dict[str, Any]:
        """Wait until the controller reports ``state``; return that status (a failure names the last one seen)."""
        last: dict[str, Any] = {}

        def reached() -> dict[str, Any] | None:
            last.update(self.status())
            return dict(last) if last["state"] == state else None

        def what() -> str:
            seen = f"last seen {last.get('state')}, trip cause {last.get('trip_cause')!r}" if last else "no status yet"
            return f"the controller to be {state} ({seen})\n{self._tail()}"

        return wait_for(reached, self.timeout(timeout_s), what)

    def _tail(self) -> str:
        """The last lines of the service's and the node's output, for failure messages."""
        parts = [
            f"{name} output:\n{self.spawn.output(proc)[-2000:]}"
            for name, proc in (("service", self.service), ("node", self.node))
            if proc is not None
        ]
        return "\n".join(parts)

    def run_at(self, rotary_rpm: float, vibration_rpm: float) -> dict[str, Any]:
        """Take control, arm, ramp to the speed pair and wait until the measured speeds are there."""
        self.client.take_control()
        self.client.arm()
        self.wait_state("ARMED")
        self.client.set_speeds(rotary_rpm, vibration_rpm)
        return self.wait_speeds(rotary_rpm, vibration_rpm, 30.0)

    def wait_speeds(self, rotary_rpm: float, vibration_rpm: float, timeout_s: float) -> dict[str, Any]:
        """Wait until both measured speeds are within the measurement tolerance of the pair; return the status."""
        tolerance = self.config.interlock.measurement_tolerance_rpm

        def there() -> dict[str, Any] | None:
            s = self.status()
            if s["state"] == "TRIPPED":
                pytest.fail(f"tripped on the way to {rotary_rpm}/{vibration_rpm} rpm: {s['trip_cause']}")
            measured = (s["measured_rotary_rpm"], s["measured_vibration_rpm"])
            close = all(abs(m - w) <= tolerance for m, w in zip(measured, (rotary_rpm, vibration_rpm), strict=True))
            return s if close else None

        return wait_for(there, self.timeout(timeout_s), f"measured speeds {rotary_rpm}/{vibration_rpm} rpm")

    def watch(self, window_s: float, period_s: float = 0.05) -> list[dict[str, Any]]:
        """The controller's status every ``period_s`` through a window of ``window_s`` (both scaled), in order."""
        deadline = time.monotonic() + self.timeout(window_s)
        seen = [self.status()]
        while time.monotonic() < deadline:
            time.sleep(self.timeout(period_s))
            seen.append(self.status())
        return seen

    def at_standstill(self) -> bool:
        """Both measured speeds (as the controller sees them) below the standstill threshold."""
        s = self.status()
        return max(abs(float(s["measured_rotary_rpm"])), abs(float(s["measured_vibration_rpm"]))) < STANDSTILL_RPM

    def outside_envelope(self, frames: list[Seen]) -> list[tuple[float, float]]:
        """Measured pairs in ``frames`` that the envelope (with the measurement tolerance) does not contain."""
        drives = [s.message for s in frames if isinstance(s.message, DriveTelemetry)]
        pairs = [(d.rotary_rpm, d.vibration_rpm) for d in drives]
        return [(r, v) for r, v in pairs if not self.envelope.check_measured(max(r, 0.0), max(v, 0.0)).ok]


@contextlib.contextmanager
def mill_on(
    transport: Transport,
    spawn: Spawner,
    directory: Path,
    *,
    dilate_drives: bool = False,
    backend: str = "millbus",
    node_args: tuple[str, ...] = (),
) -> Iterator[Mill]:
    """A started mill on ``transport``, torn down afterwards (``dilate_drives``: see :func:`write_config`)."""
    mill = Mill(transport, spawn, directory, dilate_drives=dilate_drives, backend=backend, node_args=node_args)
    try:
        mill.start()
        yield mill
    finally:
        mill.close()


__all__ = [
    "BACKEND_CONFIGS",
    "NODE_SEED_ENV",
    "SCHEDULING_ALLOWANCE_S",
    "STANDSTILL_RPM",
    "Bounds",
    "Mill",
    "Probe",
    "Seen",
    "bound_scale",
    "deepen_receive_queue",
    "is_command",
    "is_kind",
    "is_status",
    "load_scale",
    "mill_on",
    "node_seed",
    "report_timing",
    "sequence_limit_reached_at",
    "upper_bound",
    "vm_scaled",
    "wait_for",
    "write_config",
]
