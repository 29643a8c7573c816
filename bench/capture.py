"""Bus load from a capture: a running service + node on udp_multicast, counted by a listener over a fixed window.

Run only inside the hil tier's private network namespace (multicast must not
leave the machine)::

    tests/hil/rt tests/hil/in_netns .venv/bin/python -m bench.capture --seconds 10 --json FILE

Started under a real-time policy (``tests/hil/rt``, as the hil tiers run), it
keeps that policy for the node and the service only (tests/support/realtime.py)
and counts at the normal one. It writes a config (the packaged Set A with a udp_multicast ``[bus]``), starts
``python -m firmware_sim`` and ``millctl serve`` as separate processes, arms
and runs the mill at 150/800 rpm through the service API (so every periodic
frame flows), then counts every frame a third bus node receives during the
window. Each frame is charged the same worst-case length as
:mod:`millctl.protocol.busload` uses, so measured and computed loads differ
only by the frame rates actually seen on the bus.
"""

from __future__ import annotations

import argparse
import json
import socket
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from millctl.api.enums import ControllerState
from millctl.client import Client
from millctl.config import load_config
from millctl.config.loader import packaged_file
from millctl.protocol import default_codec
from millctl.protocol.busload import worst_case_frame_bits
from millctl.protocol.factory import open_bus
from millctl.protocol.messages import MESSAGE_TYPES
from tests.support import realtime

MULTICAST_GROUP = "239.74.163.9"
RUN_RPM = (150.0, 800.0)


def _only_loopback() -> bool:
    return [name for _, name in socket.if_nameindex()] == ["lo"]


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        port: int = sock.getsockname()[1]
        return port


def write_config(directory: Path) -> Path:
    """Set A with a private udp_multicast bus and a service socket in ``directory``."""
    head = packaged_file("mill.toml").read_text(encoding="utf-8").partition("[bus]")[0]
    port = _free_udp_port()
    body = (
        f'[bus]\ninterface = "udp_multicast"\nchannel = "{MULTICAST_GROUP}"\n'
        f"options = {{ port = {port}, hop_limit = 0 }}\n\n"
        f'[service]\nsocket_path = "{directory / "mill.sock"}"\nrecords_dir = "{directory / "records"}"\n'
    )
    path = directory / "mill.toml"
    path.write_text(head + body, encoding="utf-8")
    return path


def _wait(cond: Callable[[], object], timeout_s: float, what: str, seen: Callable[[], str]) -> None:
    """Poll ``cond`` until it is true (errors while the service starts count as not yet).

    On timeout the error says what ``seen`` reports then (the controller's state and trip cause).
    """
    deadline = time.monotonic() + timeout_s
    last_error = "no answer yet"
    while time.monotonic() < deadline:
        try:
            if cond():
                return
        except Exception as exc:  # the service is still starting
            last_error = f"{type(exc).__name__}: {exc}"
        time.sleep(0.05)
    try:
        state = seen()
    except Exception as exc:
        state = f"no status ({type(exc).__name__}: {exc}; before that: {last_error})"
    raise TimeoutError(f"timed out after {timeout_s:g} s waiting for {what}; the service says: {state}")


def _near(measured_rpm: float | None, target_rpm: float) -> bool:
    """Whether a measured speed (None before the node reports one) is within 2 rpm of the target."""
    return measured_rpm is not None and abs(measured_rpm - target_rpm) < 2.0


def capture(window_s: float) -> dict[str, Any]:
    """Start node and service, run the mill, count frames for ``window_s``; return rates and loads."""
    codec = default_codec()
    names = {codec.frame_id(kind): kind.__name__ for kind in MESSAGE_TYPES}
    with tempfile.TemporaryDirectory(prefix="bench-capture-") as tmp:
        directory = Path(tmp)
        cfg_path = write_config(directory)
        config = load_config(cfg_path).config
        py = sys.executable
        logs = [(directory / "node.log").open("wb"), (directory / "service.log").open("wb")]
        procs = [
            realtime.popen([py, "-m", "firmware_sim", "--config", str(cfg_path)], realtime="node", stderr=logs[0]),
            realtime.popen(
                [py, "-m", "millctl", "--config", str(cfg_path), "serve", "--socket", str(directory / "mill.sock")],
                realtime="controller",
                stderr=logs[1],
            ),
        ]
        bus = open_bus(config.bus)
        client = Client(directory / "mill.sock", name="bench")

        def seen() -> str:
            status = client.status()
            return f"state {status.state}, trip cause {status.trip_cause!r}"

        try:
            seen_node = "the controller to see the node"
            _wait(lambda: client.status().state == ControllerState.DISABLED, 30.0, seen_node, seen)
            client.take_control()
            client.arm()
            _wait(lambda: client.status().state == ControllerState.ARMED, 10.0, "ARMED", seen)
            client.set_speeds(*RUN_RPM)
            _wait(lambda: _near(client.status().measured_rotary_rpm, RUN_RPM[0]), 60.0, "the run speed", seen)
            state = client.status().state
            counts: Counter[int] = Counter()
            bits: Counter[int] = Counter()
            while bus.recv(0.0) is not None:  # drain what queued before the window
                pass
            start = time.monotonic()
            while (now := time.monotonic()) < start + window_s:
                frame = bus.recv(start + window_s - now)
                if frame is not None:
                    counts[frame.arbitration_id] += 1
                    bits[frame.arbitration_id] += worst_case_frame_bits(len(frame.data), frame.is_extended_id)
            elapsed = time.monotonic() - start
        except TimeoutError as exc:
            for log in logs:
                log.flush()
            tails = [f"{log.name}: ...{Path(log.name).read_text(errors='replace')[-400:]}" for log in logs]
            raise TimeoutError("\n".join([str(exc), *tails])) from None
        finally:
            client.close()
            bus.shutdown()
            for proc in procs:
                proc.kill()
                proc.wait()
            for log in logs:
                log.close()
    bitrate = config.bus.bitrate_bit_s
    frames = [
        {"name": names.get(fid, hex(fid)), "id": f"0x{fid:03X}", "frames": n, "rate_hz": n / elapsed}
        for fid, n in sorted(counts.items())
    ]
    return {
        "transport": "udp_multicast",
        "window_s": elapsed,
        "controller_state": state,
        "run_rpm": list(RUN_RPM),
        "bitrate_bit_s": bitrate,
        "frames": frames,
        "measured_load": sum(bits.values()) / elapsed / bitrate,
    }


def main(argv: Sequence[str] | None = None) -> int:
    """Command line (see module docstring)."""
    parser = argparse.ArgumentParser(prog="python -m bench.capture", description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="capture window (s)")
    parser.add_argument("--json", metavar="FILE", required=True, help="write the result here")
    args = parser.parse_args(argv)
    if not _only_loopback():
        print("error: run inside tests/hil/in_netns (udp_multicast must stay on this host)", file=sys.stderr)
        return 1
    realtime.take_over()  # the real-time policy it was started with (if any) for the node and service only
    Path(args.json).write_text(json.dumps(capture(args.seconds), indent=1), encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
