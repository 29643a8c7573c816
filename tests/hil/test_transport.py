"""Back-to-back smoke tests of every transport: frames cross intact and in order.

Two buses in one process, and a bus here with one in a second process. The
second process is this module run as a program (``python -m
tests.hil.test_transport``, see :func:`peer_main`), so the test and its peer
share one frame generator. Plain python-can only: the transport, not millctl,
is under test.
"""

from __future__ import annotations

import json
import signal
import sys
import time
from typing import TYPE_CHECKING

import can
import pytest

from tests.support.pace import Deadline

if TYPE_CHECKING:
    from tests.hil.conftest import Spawner, Transport

pytestmark = pytest.mark.hil

HELLO_ID = 0x7F0  # peer -> test, repeated: "my bus is open"
GO_ID = 0x7F1  # test -> peer: "start now"
CONTROL_IDS = frozenset({HELLO_ID, GO_ID})
HELLO_PERIOD_S = 0.1
PEER_TIMEOUT_S = 20.0  # before scaling; a generous safety net, not a bound under test

FrameKey = tuple[int, bool, int, str]


def key(msg: can.Message) -> FrameKey:
    """What must survive the trip: ID, ID kind, DLC and payload."""
    return (msg.arbitration_id, msg.is_extended_id, msg.dlc, bytes(msg.data).hex())


def burst(n: int) -> list[can.Message]:
    """``n`` frames alternating standard and extended IDs, each with a distinct 8-byte payload."""
    frames = []
    for i in range(n):
        extended = i % 2 == 1
        arbitration_id = (0x1ABC_0000 | i) if extended else 0x100 + (i % 0x400)
        data = bytes([i & 0xFF, (i >> 8) & 0xFF, 0x00, 0xFF, 0xA5, 0x5A, 0x80, 0x01])
        frames.append(can.Message(arbitration_id=arbitration_id, is_extended_id=extended, data=data))
    return frames


def receive(bus: can.BusABC, n: int, timeout_s: float) -> list[can.Message]:
    """Up to ``n`` data frames from ``bus`` (control frames skipped), giving up after ``timeout_s``."""
    frames: list[can.Message] = []
    deadline = time.monotonic() + timeout_s
    while len(frames) < n and (left := deadline - time.monotonic()) > 0:
        msg = bus.recv(left)
        if msg is not None and msg.arbitration_id not in CONTROL_IDS:
            frames.append(msg)
    return frames


# --- two buses in one process -----------------------------------------------


@pytest.mark.parametrize(
    "sent",
    [
        can.Message(arbitration_id=0x123, is_extended_id=False, data=bytes(range(1, 9))),
        can.Message(arbitration_id=0x1ABCDEF0, is_extended_id=True, data=b"\x00\xff\x55\xaa\x00\xff\x55\xaa"),
        can.Message(arbitration_id=0x7FF, is_extended_id=False, data=b""),
    ],
    ids=["standard", "extended", "empty"],
)
def test_frame_crosses_intact(transport: Transport, sent: can.Message) -> None:
    sender, receiver = transport.open_bus(), transport.open_bus()
    sender.send(sent)
    got = receiver.recv(transport.timeout(2.0))
    assert got is not None, f"no frame arrived over {transport.name}"
    assert key(got) == key(sent)
    assert not got.is_remote_frame and not got.is_error_frame


def test_burst_arrives_in_order(transport: Transport) -> None:
    sender, receiver = transport.open_bus(), transport.open_bus()
    sent = burst(200)
    for msg in sent:
        sender.send(msg)
    got = receive(receiver, len(sent), transport.timeout(5.0))
    assert [key(m) for m in got] == [key(m) for m in sent]


def test_own_frames_echo_only_where_documented(transport: Transport) -> None:
    """Scenario code relies on ``echoes_own_frames`` to know whether it must drop its own frames."""
    sender, receiver = transport.open_bus(), transport.open_bus()
    sent = can.Message(arbitration_id=0x321, is_extended_id=False, data=b"echo?")
    sender.send(sent)
    assert receiver.recv(transport.timeout(2.0)) is not None  # delivery is done by now
    echo = sender.recv(transport.timeout(0.3))
    if transport.echoes_own_frames:
        assert echo is not None and key(echo) == key(sent)
    else:
        assert echo is None


# --- a bus here, a bus in another process -------------------------------------


@pytest.mark.parametrize("peer_mode", ["send", "receive"], ids=["from_peer", "to_peer"])
def test_burst_crosses_processes(transport: Transport, spawn: Spawner, peer_mode: str) -> None:
    if not transport.crosses_processes:
        pytest.skip(f"{transport.name} frames stay inside one process")
    bus = transport.open_bus()
    n = 100
    timeout_s = transport.timeout(PEER_TIMEOUT_S)
    argv = ["python", "-m", "tests.hil.test_transport", peer_mode, str(n), transport.bus_kwargs_json(), str(timeout_s)]
    peer = spawn(argv)

    hello = None
    deadline = time.monotonic() + timeout_s
    while hello is None and peer.poll() is None and (left := deadline - time.monotonic()) > 0:
        msg = bus.recv(min(left, 0.5))
        hello = msg if msg is not None and msg.arbitration_id == HELLO_ID else None
    assert hello is not None, f"peer never said hello; its output:\n{spawn.output(peer)}"
    bus.send(can.Message(arbitration_id=GO_ID, is_extended_id=False, data=b""))

    expected = [key(m) for m in burst(n)]
    if peer_mode == "send":
        got = [key(m) for m in receive(bus, n, timeout_s)]
        assert got == expected
        assert peer.wait(timeout_s) == 0, spawn.output(peer)
    else:
        for msg in burst(n):
            bus.send(msg)
        assert peer.wait(timeout_s) == 0, spawn.output(peer)
        got = [tuple(k) for k in json.loads(spawn.output(peer).splitlines()[-1])]
        assert got == expected


def test_spawn_reaps_children_and_reports_leaks(spawn: Spawner) -> None:
    """The process fixture itself: a child left running (with a grandchild) is reported and killed."""
    script = "import subprocess, time; subprocess.Popen(['sleep', '600']); print('up', flush=True); time.sleep(600)"
    proc = spawn(["python", "-c", script])
    deadline = Deadline(10.0)
    while "up" not in spawn.output(proc) and not deadline.expired():
        time.sleep(0.05)
    leaked = spawn.cleanup()
    assert len(leaked) == 1 and "sleep(600)" in leaked[0]
    assert proc.returncode == -signal.SIGKILL
    assert spawn.cleanup() == []  # nothing left, the grandchild included


# --- the peer program -----------------------------------------------------------


def _wait_for_go(bus: can.BusABC, deadline: float) -> None:
    """Say hello every HELLO_PERIOD_S until the test says go."""
    while time.monotonic() < deadline:
        bus.send(can.Message(arbitration_id=HELLO_ID, is_extended_id=False, data=b""))
        until = time.monotonic() + HELLO_PERIOD_S
        while (left := until - time.monotonic()) > 0:
            msg = bus.recv(left)
            if msg is not None and msg.arbitration_id == GO_ID:
                return
    raise TimeoutError("the test never said go")


def peer_main(argv: list[str]) -> int:
    """``send|receive N BUS_KWARGS_JSON TIMEOUT_S``: send the burst, or receive it and print it as JSON."""
    mode, n, bus_kwargs, timeout_s = argv[0], int(argv[1]), json.loads(argv[2]), float(argv[3])
    deadline = time.monotonic() + timeout_s
    with can.Bus(**bus_kwargs) as bus:
        _wait_for_go(bus, deadline)
        if mode == "send":
            for msg in burst(n):
                bus.send(msg)
            return 0
        got = receive(bus, n, deadline - time.monotonic())
        print(json.dumps([key(m) for m in got]), flush=True)
        return 0 if len(got) == n else 1


if __name__ == "__main__":
    sys.exit(peer_main(sys.argv[1:]))
