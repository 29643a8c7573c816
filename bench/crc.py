"""The E2E CRC's speed: millctl's table-driven CRC-8/SAE-J1850 against crccheck's, measured in one run.

``python -m bench.crc`` prints frames per second of each and the ratio. The
table stays in millctl.protocol.e2e because it is faster (the controller and
the node compute a CRC for every frame sent and received); crccheck stays the
independent oracle of the E2E tests (tests/unit/protocol/test_e2e.py).
"""

from __future__ import annotations

import os
import timeit

from crccheck.crc import Crc8SaeJ1850

from millctl.protocol.e2e import crc8_sae_j1850

PAYLOAD = bytes(range(7))
"""A classic CAN frame's data without its CRC byte."""


def frames_per_s(crc: object, repeat: int = 5, number: int = 20_000) -> float:
    """The best of ``repeat`` runs of ``number`` CRCs of :data:`PAYLOAD`, in CRCs per second."""
    best_s = min(timeit.repeat(lambda: crc(PAYLOAD), repeat=repeat, number=number))  # type: ignore[operator]
    return number / best_s


def main() -> None:
    """Measure both in this process, one after the other, and print the ratio."""
    assert crc8_sae_j1850(PAYLOAD) == Crc8SaeJ1850.calc(PAYLOAD)
    ours = frames_per_s(crc8_sae_j1850)
    theirs = frames_per_s(Crc8SaeJ1850.calc)
    print(f"CRC-8/SAE-J1850 of {len(PAYLOAD)} bytes (load average {os.getloadavg()[0]:.1f}):")
    print(f"  millctl table   {ours:12,.0f} /s")
    print(f"  crccheck        {theirs:12,.0f} /s")
    print(f"  ratio           {ours / theirs:12.1f} ×")


if __name__ == "__main__":
    main()
