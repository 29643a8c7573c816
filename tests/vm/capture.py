"""Read a ``candump -L`` capture and summarise it: frame count, and frames and rate per CAN ID.

    python tests/vm/capture.py runs/vcan/candump.log [--head N]

Exit status 0 if the capture holds at least one frame, 1 if it holds none.
Scenario tests can import :func:`read_candump` and :func:`rates_hz` to check a
node's frame rates from a capture.
"""

from __future__ import annotations

import argparse
import re
import sys
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

TOP_IDS = 15  # how many CAN IDs the summary lists
# "(1732212345.123456) vcan0 123#0102" or "... 1ABCDEF0#..." (extended) or "123#R" (remote)
_LINE = re.compile(r"^\((?P<t>\d+\.\d+)\)\s+(?P<channel>\S+)\s+(?P<id>[0-9A-Fa-f]+)#(?P<data>\S*)$")


@dataclass(frozen=True)
class Frame:
    """One captured frame: time in s (host clock of the capturing machine), channel, ID and payload."""

    time_s: float
    channel: str
    arbitration_id: int
    is_extended_id: bool
    data: bytes


def read_candump(path: Path) -> list[Frame]:
    """Every frame in a ``candump -L`` file, in order; lines that are not frames are ignored."""
    frames = []
    for line in path.read_text(errors="replace").splitlines():
        m = _LINE.match(line.strip())
        if m is None:
            continue
        payload = m["data"]
        data = b"" if payload.startswith(("R", "#")) else bytes.fromhex(payload)
        frames.append(Frame(float(m["t"]), m["channel"], int(m["id"], 16), len(m["id"]) == 8, data))
    return frames


def rates_hz(frames: list[Frame]) -> dict[int, float]:
    """Mean rate of each CAN ID in Hz, over the span between its first and last frame (IDs seen twice or more)."""
    times: dict[int, list[float]] = {}
    for frame in frames:
        times.setdefault(frame.arbitration_id, []).append(frame.time_s)
    return {i: (len(t) - 1) / (t[-1] - t[0]) for i, t in times.items() if len(t) > 1 and t[-1] > t[0]}


def main(argv: list[str]) -> int:
    """Print the summary of one capture."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("capture", type=Path)
    parser.add_argument("--head", type=int, default=5, help="print the first N lines of the capture")
    args = parser.parse_args(argv)
    frames = read_candump(args.capture)
    for line in args.capture.read_text(errors="replace").splitlines()[: args.head]:
        print(f"  {line}")
    print(f"{len(frames)} frames in {args.capture}")
    if frames:
        span_s = frames[-1].time_s - frames[0].time_s
        counts = Counter(f.arbitration_id for f in frames)
        rates = rates_hz(frames)
        print(f"over {span_s:.2f} s, {len(counts)} CAN IDs; the busiest (frames, mean rate):")
        for can_id, count in counts.most_common(TOP_IDS):
            rate = f"{rates[can_id]:.1f} Hz" if can_id in rates else "-"
            print(f"  0x{can_id:03X}  {count:6d}  {rate}")
    return 0 if frames else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
