"""The soak (issue 37): a long recipe on the embedded node, in real time, with a study and a CPU hog beside it.

``bash .ci/soak [--minutes N]`` (default 60) runs ``millctl serve`` (the
embedded node on a virtual bus, at the priority it is started with), one
recipe that ramps to 120/400 rpm and holds for the rest of the time, a design
study run over and over at its default priority (niceness +10,
millctl/cli/priority.py) and ``--hogs`` busy-loop CPU hogs (default 1) at
normal priority. Every ``SAMPLE_S`` it samples the service's resident memory, its
open files and the size of its records. At the end it prints the figures
(``SOAK {json}`` and a table) and checks:

* trips: none, or each one named host starvation by the service (a trip the
  host caused, warned about and named as such: SAFETY 27); any other trip
  is spurious;
* resident memory and open files flat: the last quarter's mean within
  ``RSS_SLACK`` (and ``FD_SLACK`` files) of the second quarter's;
* record sizes flat: the records grow no faster in the second half than in
  the first (×``GROWTH_SLACK``), and the bus log stays within its rotation
  (``keep_files`` + 1 files of ``rotate_bytes``).

Exit 0 when every check holds, 1 when one fails, 4 when the soak itself
could not run. A design aid, not a CI gate: a full hour is opt-in.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from millctl.client import Client
from millctl.config import load_config
from millctl.records import read_records
from tests.support.service import write_config

REPO = Path(__file__).resolve().parents[2]
STUDY = REPO / "config" / "studies" / "paper-operating-point.toml"
SAMPLE_S = 10.0
RSS_SLACK = 0.10
FD_SLACK = 4
GROWTH_SLACK = 1.5
RUN_RPM = (120.0, 400.0)


def recipe_text(minutes: float) -> str:
    hold_s = max(minutes * 60.0 - 30.0, 10.0)
    return (
        '[recipe]\nname = "soak"\nmaterial_system = "none (soak)"\n\n'
        "[defaults]\nrotary_rate_rpm_s = 40.0\nvibration_rate_rpm_s = 120.0\n\n"
        f'[[steps]]\nkind = "ramp"\nrotary_rpm = {RUN_RPM[0]}\nvibration_rpm = {RUN_RPM[1]}\n\n'
        f'[[steps]]\nkind = "hold"\nduration_s = {hold_s:.0f}\n'
    )


def dir_bytes(path: Path) -> int:
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file()) if path.exists() else 0


def spawn(argv: list[str], log: Path, *, env: dict[str, str] | None = None) -> subprocess.Popen[bytes]:
    with log.open("wb") as out:
        return subprocess.Popen(argv, cwd=REPO, stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT,
                                env={**os.environ, "PYTHONUNBUFFERED": "1", **(env or {})}, start_new_session=True)


def stop(proc: subprocess.Popen[bytes], sig: int = signal.SIGTERM, grace_s: float = 60.0) -> None:
    if proc.poll() is not None:
        return
    os.killpg(proc.pid, sig)
    try:
        proc.wait(grace_s)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()


def rss_mb(pid: int) -> float:
    """Resident memory of ``pid`` (MiB, /proc/PID/status VmRSS)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    raise RuntimeError(f"no VmRSS in /proc/{pid}/status")


def sample(pid: int, records: Path, t0: float) -> dict[str, float]:
    return {
        "t_s": time.monotonic() - t0,
        "rss_mb": rss_mb(pid),
        "open_files": float(len(os.listdir(f"/proc/{pid}/fd"))),
        "records_bytes": float(dir_bytes(records)),
        "bus_log_bytes": float(dir_bytes(records / "bus")),
        "load_1min": os.getloadavg()[0],
    }


def mean(values: list[float]) -> float:
    return sum(values) / len(values) if values else 0.0


def quarter(samples: list[dict[str, float]], k: int, key: str) -> float:
    n = len(samples)
    return mean([s[key] for s in samples[k * n // 4 : max((k + 1) * n // 4, k * n // 4 + 1)]])


def judge(samples: list[dict[str, float]], events: list[dict[str, Any]], rotate_bytes: int, keep_files: int
          ) -> tuple[dict[str, Any], list[str]]:
    trips = [e for e in events if e.get("kind") == "trip"]
    host = [e for e in events if e.get("kind") == "host"]
    named = [e for e in host if e.get("data", {}).get("host_starvation")]
    warned = [e for e in host if "late_ticks" in e.get("data", {}) and not e["data"].get("session")]
    session: dict[str, Any] = next((e["data"] for e in host if e.get("data", {}).get("session")), {})
    lateness = [float(e["data"]["max_ms"]) for e in warned]
    half = len(samples) // 2
    first, second = samples[: half + 1], samples[half:]

    def rate(part: list[dict[str, float]]) -> float:
        span = part[-1]["t_s"] - part[0]["t_s"]
        return (part[-1]["records_bytes"] - part[0]["records_bytes"]) / span * 60.0 if span > 0 else 0.0

    figures: dict[str, Any] = {
        "minutes": round(samples[-1]["t_s"] / 60.0, 1),
        "samples": len(samples),
        "trips": len(trips),
        "trips_named_host_starvation": len(named),
        "spurious_trips": max(len(trips) - len(named), 0),
        "late_loop_warnings": len(warned),
        "late_ticks": session.get("late_ticks", int(sum(e["data"]["late_ticks"] for e in warned))),
        "loop_lateness_mean_ms": session.get("mean_ms"),
        "loop_lateness_max_ms": session.get("max_ms", max(lateness, default=0.0)),
        "loop_ticks": session.get("ticks"),
        "rss_mb_q2": round(quarter(samples, 1, "rss_mb"), 1),
        "rss_mb_q4": round(quarter(samples, 3, "rss_mb"), 1),
        "open_files_q2": round(quarter(samples, 1, "open_files"), 1),
        "open_files_q4": round(quarter(samples, 3, "open_files"), 1),
        "records_kb_per_min_first_half": round(rate(first) / 1024.0, 1),
        "records_kb_per_min_second_half": round(rate(second) / 1024.0, 1),
        "bus_log_mb_max": round(max(s["bus_log_bytes"] for s in samples) / 2**20, 2),
        "load_1min_mean": round(mean([s["load_1min"] for s in samples]), 2),
        "trip_causes": [e["message"] for e in trips],
    }
    failed = []
    if figures["spurious_trips"]:
        failed.append(f"{figures['spurious_trips']} trip(s) not named host starvation: {figures['trip_causes']}")
    if figures["rss_mb_q4"] > figures["rss_mb_q2"] * (1 + RSS_SLACK):
        failed.append(f"memory grew: {figures['rss_mb_q2']} → {figures['rss_mb_q4']} MB (slack {RSS_SLACK:.0%})")
    if figures["open_files_q4"] > figures["open_files_q2"] + FD_SLACK:
        failed.append(f"open files grew: {figures['open_files_q2']} → {figures['open_files_q4']} (slack {FD_SLACK})")
    growth = figures["records_kb_per_min_first_half"] * GROWTH_SLACK + 1.0
    if figures["records_kb_per_min_second_half"] > growth:
        failed.append(f"records grow faster: {figures['records_kb_per_min_first_half']} → "
                      f"{figures['records_kb_per_min_second_half']} kB/min (slack ×{GROWTH_SLACK})")
    bus_bound_mb = (keep_files + 1) * rotate_bytes / 2**20
    if figures["bus_log_mb_max"] > bus_bound_mb:
        failed.append(f"bus log {figures['bus_log_mb_max']} MB past its rotation bound {bus_bound_mb:.1f} MB")
    return figures, failed


def soak(minutes: float, directory: Path, hogs: int) -> int:
    config_path = write_config(directory)
    config = load_config(config_path).config
    (directory / "soak.toml").write_text(recipe_text(minutes), encoding="utf-8")
    service = spawn([sys.executable, "-m", "millctl", "--config", str(config_path), "serve"], directory / "serve.log")
    socket_path = directory / "mill.sock"
    helpers: list[subprocess.Popen[bytes]] = []
    samples: list[dict[str, float]] = []
    try:
        deadline = time.monotonic() + 60.0
        while not socket_path.exists():
            if service.poll() is not None or time.monotonic() > deadline:
                print((directory / "serve.log").read_text(errors="replace"), file=sys.stderr)
                return 4
            time.sleep(0.2)
        with Client(socket_path, name="soak") as client:
            while client.status().state != "DISABLED":
                time.sleep(0.2)
            client.take_control()
            client.recipe_run(directory / "soak.toml")
            for k in range(hogs):
                helpers.append(spawn([sys.executable, "-c", "while True: pass"], directory / f"hog{k}.log"))
            study_cmd = (f"while true; do {sys.executable} -m millctl study {STUDY} --fresh --workers 1 "
                         f"--out {directory / 'study.parquet'} >/dev/null 2>&1; done")
            helpers.append(spawn(["bash", "-c", study_cmd], directory / "study.log"))
            t0 = time.monotonic()
            end_s = minutes * 60.0 + 30.0
            while time.monotonic() - t0 < end_s:
                samples.append(sample(service.pid, directory / "records", t0))
                if not client.recipe().active and time.monotonic() - t0 > 60.0:
                    break
                time.sleep(SAMPLE_S)
            samples.append(sample(service.pid, directory / "records", t0))
    finally:
        for helper in helpers:
            stop(helper, signal.SIGKILL)
        stop(service)
    events = list(read_records(directory / "records" / "events.jsonl"))
    figures, failed = judge(samples, events, config.service.rotate_bytes, config.service.keep_files)
    print("SOAK " + json.dumps(figures))
    for key, value in figures.items():
        print(f"  {key:<34} {value}")
    for problem in failed:
        print(f"FAILED: {problem}")
    print("soak: " + ("every check holds" if not failed else f"{len(failed)} check(s) failed") + f" ({directory})")
    return 1 if failed else 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog=".ci/soak", description=__doc__.split("\n\n")[0])
    parser.add_argument("--minutes", type=float, default=60.0, help="how long the recipe holds (default 60)")
    parser.add_argument("--hogs", type=int, default=1, help="busy-loop CPU hogs at normal priority (default 1)")
    parser.add_argument("--keep", action="store_true", help="keep the soak's directory (records, logs)")
    args = parser.parse_args(argv)
    if not 1.0 <= args.minutes <= 24 * 60.0:
        parser.error(f"--minutes {args.minutes} must be within 1 … 1440")
    directory = Path(tempfile.mkdtemp(prefix="millctl-soak-"))
    code = soak(args.minutes, directory, max(args.hogs, 0))
    if not args.keep and code == 0:
        import shutil

        shutil.rmtree(directory, ignore_errors=True)
    return code


if __name__ == "__main__":
    sys.exit(main())
