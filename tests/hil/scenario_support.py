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
import math
import os
import re
import secrets
import signal
import socket
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import can
import pytest
from pydantic import BaseModel

from millctl.client import DEFAULT_TIMEOUT_S, Client
from millctl.config import load_config
from millctl.config.loader import packaged_file
from millctl.config.models import Bus, Furnace, Interlock, MillConfig, Timing
from millctl.controller.tracking import SAFETY_RELEVANT
from millctl.errors import MillctlError
from millctl.protocol import (
    Codec,
    Command,
    CommandCode,
    Decoded,
    DriveTelemetry,
    FaultCode,
    MillMessage,
    NodeState,
    NodeStatus,
    ProtocolError,
    SimFault,
    SimFaultCode,
    default_codec,
    open_bus,
)
from millctl.protocol.e2e import E2EReceiver
from millctl.safety import Envelope
from tests.hil.conftest import IN_VM, REPO
from tests.support.pace import slowdown_now, time_scale

if TYPE_CHECKING:
    import subprocess

    from tests.hil.conftest import Spawner, Transport

SO_RCVBUFFORCE = getattr(socket, "SO_RCVBUFFORCE", 33)
"""Linux's ``SO_RCVBUFFORCE`` (33; Python names it only where the platform headers do)."""

M = TypeVar("M", bound=MillMessage)
T = TypeVar("T")

STANDSTILL_RPM = 1.0
"""Measured speeds below this count as standstill (rpm), as in the controller."""
SCHEDULING_ALLOWANCE_S = 0.05
"""Added to every reaction bound on the host (s): late wake-ups of the Python processes in the chain."""
POLL_S = 0.02
"""How often the wait helpers look again (s), times ``bound_scale()``: in the VM each status request costs the
service (whose control loop shares its process) the measured factor times the host's CPU, so polling at the
host's rate would load the process under test that much more."""


# --- bounds ---------------------------------------------------------------------------------------------------


def bound_scale() -> float:
    """The factor on every safety bound: ``time_scale()`` inside the VM, 1 on the host (the tight bounds)."""
    return time_scale() if IN_VM else 1.0


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


# --- config ---------------------------------------------------------------------------------------------------


def _toml_value(value: Any) -> str:
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {_toml_value(v)}" for k, v in value.items()) + " }"
    return json.dumps(value)


VM_SCALED_KEYS: dict[str, type[BaseModel]] = {
    "watchdog_timeout_s": Timing,
    "challenge_lifetime_s": Timing,
    "setpoint_period_s": Timing,
    "min_setpoint_expiry_s": Timing,
    "min_stale_s": Interlock,
    "startup_grace_s": Interlock,
    "command_confirm_s": Interlock,
    "command_repeat_s": Interlock,
    "setpoint_refresh_s": Furnace,
}
"""Periods and timeouts of the config multiplied by the VM's measured slowdown there (and their config section).

Python under emulation runs many times slower (``tests/vm/run`` measures how much), so it cannot
meet the host's periods: frames arrive in bursts, and a setpoint step that the node allows per
``setpoint_period_s`` is refused when two frames arrive together; the stale, refresh, start-up
grace and challenge bounds would expire between two slow ticks. Scaling them all by one factor
keeps their ratios. A scaled value is held at its field's upper bound in the config model (e.g.
``setpoint_refresh_s`` ≤ 60 s), so that the config stays valid at any factor.
"""


def upper_bound(section: type[BaseModel], key: str) -> float:
    """The largest value the config model accepts for ``key`` (its ``le``/``lt`` constraint; inf when none)."""
    bound = math.inf
    for constraint in section.model_fields[key].metadata:
        for name in ("le", "lt"):
            if (value := getattr(constraint, name, None)) is not None:
                bound = min(bound, float(value))
    return bound


def vm_scaled(key: str, value: float, factor: float) -> float:
    """``value`` of the config key ``key`` times ``factor``, held at the key's upper bound."""
    return min(value * factor, upper_bound(VM_SCALED_KEYS[key], key))


def _scale_keys(text: str, factor: float) -> str:
    """``text`` with each of ``VM_SCALED_KEYS`` multiplied by ``factor`` (held at its upper bound)."""
    for key in VM_SCALED_KEYS:

        def scaled(match: re.Match[str], key: str = key) -> str:
            return f"{match[1]}{vm_scaled(key, float(match[2]), factor):g}"

        text, found = re.subn(rf"^({key}\s*=\s*)([0-9.]+)", scaled, text, flags=re.MULTILINE)
        assert found == 1, f"{key} is not in the packaged mill.toml"
    return text


def _dilate_drives(text: str, factor: float) -> str:
    """``text`` with both drives' ``max_accel_rpm_s`` divided by ``factor``."""
    text, found = re.subn(
        r"^(max_accel_rpm_s\s*=\s*)([0-9.]+)", lambda m: f"{m[1]}{float(m[2]) / factor:g}", text, flags=re.MULTILINE
    )
    assert found == 2, "the packaged mill.toml should set max_accel_rpm_s for the rotary and the vibration drive"
    return text


BACKEND_CONFIGS = {"millbus": "mill.toml", "cia402": "mill-cia402.toml"}
"""The shipped configuration of each drive backend (``config/``): the same mill, its drives behind the millbus
node or standard CiA 402 drives (issue 36)."""


def write_config(
    directory: Path, transport: Transport, *, dilate_drives: bool = False, backend: str = "millbus"
) -> Path:
    """The packaged config (parameter Set A) with this transport's ``[bus]`` and a ``[service]`` in ``directory``.

    Inside the VM the timeouts in ``VM_SCALED_KEYS`` are multiplied by ``bound_scale()`` (the measured
    slowdown): the VM checks behaviour and frame flow, the host the tight timing. ``dilate_drives``
    also divides the drives' accelerations by it there, so that time is dilated throughout: a rate
    rule (the node's step bound: its rate × its window, the watchdog timeout) then allows in rpm what
    it allows on the host, at the cost of ramps that many times longer. For the scenarios whose
    subject is that rule; the others keep the host's drives.
    """
    base = packaged_file("mill.toml") if backend == "millbus" else REPO / "config" / BACKEND_CONFIGS[backend]
    text = base.read_text(encoding="utf-8")
    head = text.partition("[bus]")[0]
    if bound_scale() > 1.0:
        head = _scale_keys(head, bound_scale())
        if dilate_drives:
            head = _dilate_drives(head, bound_scale())
    sections = {
        "bus": transport.bus_config_fields(),
        "service": {"socket_path": str(directory / "mill.sock"), "records_dir": str(directory / "records")},
    }
    body = "".join(
        f"[{name}]\n" + "".join(f"{key} = {_toml_value(value)}\n" for key, value in fields.items()) + "\n"
        for name, fields in sections.items()
    )
    path = directory / "mill.toml"
    path.write_text(head + body, encoding="utf-8")
    return path


# --- the probe ------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Seen:
    """One frame the probe captured: its receive time (s, wall clock), the raw frame and its decoding."""

    t: float
    frame: can.Message
    decoded: Decoded | None
    """None for frames the codec does not know (babble) or cannot read."""

    @property
    def message(self) -> MillMessage | None:
        """The decoded message; None when unknown or its CRC failed."""
        return self.decoded.message if self.decoded is not None else None

    def of(self, kind: type[M]) -> M:
        """The decoded message, which the caller has selected as a ``kind`` (fails the test if it is not one)."""
        message = self.message
        assert isinstance(message, kind), f"expected a {kind.__name__} frame, the probe saw {message!r}"
        return message

    @property
    def crc_failed(self) -> bool:
        """True for an E2E-protected frame whose CRC did not check."""
        return self.decoded is not None and not self.decoded.crc_ok


def is_status(state: NodeState | None = None, first_fault: FaultCode | None = None) -> Callable[[Seen], bool]:
    """A predicate: a NodeStatus (in ``state``, with ``first_fault``)."""

    def check(seen: Seen) -> bool:
        m = seen.message
        return (
            isinstance(m, NodeStatus)
            and (state is None or m.state is state)
            and (first_fault is None or FaultCode(m.first_fault) is first_fault)
        )

    return check


def is_command(code: CommandCode) -> Callable[[Seen], bool]:
    """A predicate: a Command frame with ``code``."""
    return lambda seen: isinstance(seen.message, Command) and seen.message.command is code


def is_kind(kind: type[MillMessage]) -> Callable[[Seen], bool]:
    """A predicate: a frame of this kind, decoded or not (a corrupted frame still has its identifier)."""
    return lambda seen: seen.decoded is not None and seen.decoded.kind is kind


def sequence_limit_reached_at(
    seen: list[Seen], limit: int, decay_frames: int, min_decay_s: float = 0.0
) -> float | None:
    """When the frames ``seen`` on one identifier first give a sequence score of ``limit`` (s), as sent or as received.

    The score is the receiver's own (SAFETY 17, :class:`~millctl.protocol.e2e.E2EReceiver`, with the
    controller's ``min_decay_s`` for the identifier), fed the frames with a good CRC and a counter at their
    capture times. Two orders are judged, and the earlier moment is the evidence (None while neither
    reaches the limit): the order the probe received them in, and the order of their kernel
    timestamps, which is the order they were sent in. On a CAN wire the two are one. On vcan, frames from
    senders on different CPUs reach each socket in the order those CPUs' soft interrupts deliver them, so
    every receiver, the controller's included, may see its own order (seen in the VM: a forged counter 2
    received before the genuine 1 stamped 1.8 ms earlier, and the probe's score resynchronised on it).
    """
    moments = [
        _limit_reached_at(order, E2EReceiver(limit, sequence_decay_frames=decay_frames, min_decay_s=min_decay_s))
        for order in (seen, sorted(seen, key=lambda s: s.t))
    ]
    return min((t for t in moments if t is not None), default=None)


def _limit_reached_at(seen: list[Seen], receiver: E2EReceiver) -> float | None:
    """When the frames ``seen``, in this order, first bring ``receiver``'s sequence score to its limit (s)."""
    limit = receiver.error_limit
    for s in seen:
        if s.decoded is not None and s.decoded.crc_ok and s.decoded.counter is not None:
            receiver.classify(s.decoded.counter, crc_ok=True, now_s=s.t)
            if receiver.sequence_score >= limit:
                return s.t
    return None


PROBE_RECEIVE_QUEUE_BYTES = 4 * 2**20
"""The probe's socket receive queue on SocketCAN (bytes; udp_multicast's bus sizes its own, millctl.protocol.udp).

The kernel's default (``net.core.rmem_default``, ~208 KiB: a few hundred frames) is what the test process
may fall behind by when it stalls under emulation, and a frame the probe misses is evidence it lacks."""


def deepen_receive_queue(bus: can.BusABC, size_bytes: int = PROBE_RECEIVE_QUEUE_BYTES) -> int | None:
    """Ask the kernel for a receive queue of ``size_bytes`` on a SocketCAN bus; return what it granted (None: not one).

    ``SO_RCVBUFFORCE`` passes ``net.core.rmem_max`` where the process may (root in the VM; the namespace's owner);
    elsewhere ``SO_RCVBUF`` gets what the cap allows.
    """
    sock = getattr(bus, "socket", None)
    if not isinstance(sock, socket.socket):
        return None
    try:
        sock.setsockopt(socket.SOL_SOCKET, SO_RCVBUFFORCE, size_bytes)
    except OSError:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, size_bytes)
    granted: int = sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
    return granted


class Probe:
    """The third bus: a capture thread that timestamps every frame, and a sender (faults, rogue frames, E-stop).

    It is opened by the project's bus factory, so on udp_multicast it does not
    hear its own frames (like a real CAN controller).
    """

    def __init__(self, bus_config: Bus, codec: Codec) -> None:
        self.bus = open_bus(bus_config)
        deepen_receive_queue(self.bus)
        self.codec = codec
        self._seen: list[Seen] = []
        self._lock = threading.Lock()
        self._halt = threading.Event()
        self._thread = threading.Thread(target=self._capture, name="hil-probe", daemon=True)
        self._thread.start()

    def _capture(self) -> None:
        while not self._halt.is_set():
            try:
                frame = self.bus.recv(0.05)
            except (can.CanError, OSError):  # a datagram that is no frame (the adversary's): not ours to judge
                continue
            if frame is None:
                continue
            try:
                decoded: Decoded | None = self.codec.decode(frame)
            except ProtocolError:
                decoded = None
            t = frame.timestamp or time.time()
            with self._lock:
                self._seen.append(Seen(t, frame, decoded))

    def send(self, message: MillMessage, counter: int = 0) -> float:
        """Send one message; return the wall-clock time just before it went out (s)."""
        frame = self.codec.encode(message, counter)
        t = time.time()
        self.bus.send(frame)
        return t

    def inject(self, fault: SimFaultCode, param: float = 0.0, active: bool = True) -> float:
        """Send a SimFault frame to the node (fault injection); return when it was sent."""
        return self.send(SimFault(fault, active, param))

    def frames(self, after: float = -math.inf, where: Callable[[Seen], bool] | None = None) -> list[Seen]:
        """Captured frames received after ``after`` (s) matching ``where``, in order."""
        with self._lock:
            seen = list(self._seen)
        return [s for s in seen if s.t > after and (where is None or where(s))]

    def forget(self) -> None:
        """Drop what was captured so far: a scenario handed a shared mill (tests/hil/mill_pool.py) sees its own."""
        with self._lock:
            self._seen.clear()

    def now(self) -> float:
        """The capture's clock (s, wall clock)."""
        return time.time()

    def wait_first(self, where: Callable[[Seen], bool], after: float, timeout_s: float, what: str) -> Seen:
        """The first frame after ``after`` matching ``where``, waiting up to ``timeout_s`` for it to arrive."""
        deadline = time.monotonic() + timeout_s
        while True:
            found = self.frames(after, where)
            if found:
                return found[0]
            if time.monotonic() > deadline:
                pytest.fail(f"the probe saw no {what} within {timeout_s:.1f} s; {self.describe_since(after)}")
            time.sleep(POLL_S * bound_scale())

    def describe_since(self, after: float) -> str:
        """What the probe captured after ``after``: how many frames, and the node's state in its newest NodeStatus."""
        seen = self.frames(after)
        count = f"{len(seen)} frame{'' if len(seen) == 1 else 's'}"
        statuses = [s for s in seen if isinstance(s.message, NodeStatus)]
        if not statuses:
            return f"it captured {count} since, no NodeStatus among them"
        newest = statuses[-1]
        status = newest.of(NodeStatus)
        return (
            f"it captured {count} since, {len(statuses)} NodeStatus; the newest, at "
            f"+{newest.t - after:.2f} s: {status.state.name}, first fault {FaultCode(status.first_fault).name}, "
            f"fault bits {status.fault_bits!r}"
        )

    def latest(self, kind: type[MillMessage]) -> Any:
        """The newest decoded message of ``kind`` (None before the first)."""
        found = self.frames(where=lambda s: isinstance(s.message, kind))
        return found[-1].message if found else None

    def close(self) -> None:
        """Stop capturing and shut the bus down."""
        self._halt.set()
        self._thread.join(timeout=5.0)
        self.bus.shutdown()


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
