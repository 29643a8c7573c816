"""How often independent frame loss trips the E2E sequence score, and the default fault seed's loss stretch.

The hil frame-loss scenario (tests/hil/test_scenarios.py) expects a 20 % ``TX_LOSS`` phase to be counted
and tolerated. Its realized loss can still trip the link: three or more lost in a row is a counter jump past
``max_delta`` (+1 on the sequence score, docs/safety.md item 17), and a cluster of them inside the decay
window reaches ``e2e_error_limit``. This prints that probability, simulated through the controller's own
:class:`~millctl.protocol.e2e.E2EReceiver` with the config's E2E parameters, and the share of draws under the
loss probability in a stretch of the node's fault stream for a given seed (the node's FaultInjector draws
from ``default_rng(seed + 1)``), which is what the scenario replayed while every node ran seed 0
(docs/operations.md, "Fault seeds").

    .venv/bin/python -m bench.loss_trip                        # 200000 phases of 120 frames at 20 %
    .venv/bin/python -m bench.loss_trip --trials 20000 --loss 0.3
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence

import numpy as np

from bench.common import bench_config
from millctl.protocol import DriveTelemetry, default_codec
from millctl.protocol.e2e import COUNTER_MODULO, E2EReceiver, sequence_decay_s


def trip_probability(loss: float, frames: int, trials: int, seed: int = 17) -> float:
    """Share of ``trials`` phases of ``frames`` frames, each lost independently with ``loss``, that fault the link."""
    interlock = bench_config().interlock
    period_s = default_codec().cycle_time_s(DriveTelemetry) or 1.0  # the node's fastest stream, sent on time
    min_decay_s = sequence_decay_s(interlock.e2e_sequence_decay_frames, period_s)
    rng = np.random.default_rng(seed)
    trips = 0
    for _ in range(trials):
        receiver = E2EReceiver(
            interlock.e2e_error_limit,
            sequence_decay_frames=interlock.e2e_sequence_decay_frames,
            min_decay_s=min_decay_s,
        )
        receiver.classify(0, True, 0.0)
        lost = rng.random(frames) < loss
        for k in range(1, frames + 1):
            if lost[k - 1]:
                continue
            receiver.classify(k % COUNTER_MODULO, True, k * period_s)
            if receiver.faulted:
                trips += 1
                break
    return trips / trials


def stretch_loss(seed: int, loss: float, start: int, stop: int) -> float:
    """Share of the node's fault draws ``start`` … ``stop`` - 1 under ``loss`` (its ``default_rng(seed + 1)``)."""
    draws = np.random.default_rng(seed + 1).random(stop)
    return float(np.mean(draws[start:stop] < loss))


def main(argv: Sequence[str] | None = None) -> int:
    """Print the trip probability and the seed's stretches; 0, or 2 for a bad argument (argparse)."""
    parser = argparse.ArgumentParser(prog="python -m bench.loss_trip", description=__doc__.splitlines()[0])
    parser.add_argument("--loss", type=float, default=0.2, help="probability that a frame is lost (default 0.2)")
    parser.add_argument("--frames", type=int, default=120, help="frames sent in a phase (default 120)")
    parser.add_argument("--trials", type=int, default=200_000, help="phases simulated (default 200000)")
    parser.add_argument("--seed", type=int, default=0, help="node seed whose fault stream to inspect (default 0)")
    args = parser.parse_args(argv)
    if not 0.0 <= args.loss <= 1.0 or args.frames < 1 or args.trials < 1:
        parser.error(f"need 0 ≤ --loss ≤ 1, --frames ≥ 1, --trials ≥ 1 (got {args.loss}, {args.frames}, {args.trials})")
    p = trip_probability(args.loss, args.frames, args.trials)
    print(f"independent loss {args.loss:g} over {args.frames} frames: {p:.2e} of {args.trials} phases trip the link")
    for start in range(0, 400, 100):
        share = stretch_loss(args.seed, args.loss, start, start + 100)
        print(f"node seed {args.seed}: draws {start}-{start + 99}: {share:.0%} under {args.loss:g}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
