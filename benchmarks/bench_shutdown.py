"""How long ``ros2 launch`` takes to exit after SIGINT, for each launch file.

Starts ``ros2 launch tactile_sensor <file>`` on mock hardware (device links in a temporary
folder), waits until every lifecycle node was configured and the driver has its
calibration, lets it run ``--settle`` seconds, sends SIGINT (to ``ros2 launch`` only, as a
supervisor does; ``--group`` sends it to the process group, as Ctrl-C in a terminal does)
and times the exit. Each run also counts the faults a user must never see (Traceback,
"never retrieved", "context is invalid") and ERROR/WARN lines logged before the SIGINT.

    python benchmarks/bench_shutdown.py [--runs 10] [--settle 2] [--group] [array bench gripper]

Run with ``scripts/env.sh`` sourced (``ros2`` on PATH, built by ``make setup``). ROS domain:
$ROS_DOMAIN_ID (default 215, outside the test suite's block of ids); discovery stays
on localhost.
"""

from __future__ import annotations

import argparse
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from results import Figure, without_ros2, write_results

FAULTS = ("Traceback", "never retrieved", "context is invalid")
LIFECYCLE_NODES = {"array": 2, "bench": 2, "gripper": 3}
READY_TIMEOUT_S = 180.0
EXIT_TIMEOUT_S = 30.0


def one_run(name: str, folder: Path, settle_s: float, group: bool) -> tuple[float, int, int, int]:
    """(seconds to exit, exit status, faults, ERROR/WARN lines before SIGINT)."""
    log_path = folder / f"{name}.log"
    ports = [f"adc_port:={folder / 'adc'}"] + (
        [f"servo_port:={folder / 'xm430'}"] if name == "gripper" else [])
    with log_path.open("wb") as log:
        proc = subprocess.Popen(["ros2", "launch", "tactile_sensor", f"{name}.launch.py",
                                 *ports], stdout=log, stderr=subprocess.STDOUT,
                                start_new_session=True)
    try:
        deadline = time.monotonic() + READY_TIMEOUT_S
        while True:
            text = log_path.read_text(errors="replace")
            if (text.count("configured, activating") >= LIFECYCLE_NODES[name]
                    and ("[driver]: calibration from" in text
                         or "[driver]: array calibration from" in text)):
                break
            if time.monotonic() > deadline or proc.poll() is not None:
                raise RuntimeError(f"{name} did not come up; see {log_path}")
            time.sleep(0.1)
        time.sleep(settle_s)
        before = log_path.read_text(errors="replace")
        start = time.monotonic()
        if group:
            os.killpg(proc.pid, signal.SIGINT)
        else:
            proc.send_signal(signal.SIGINT)
        code = proc.wait(EXIT_TIMEOUT_S)
        seconds = time.monotonic() - start
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    text = log_path.read_text(errors="replace")
    faults = sum(text.count(f) for f in FAULTS)
    noisy = sum(1 for line in before.splitlines() if "[ERROR]" in line or "[WARN" in line)
    return seconds, code, faults, noisy


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("launch_files", nargs="*", choices=[[], *sorted(LIFECYCLE_NODES)],
                        help="bench and/or gripper (default: both)")
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--settle", type=float, default=2.0,
                        help="seconds between ready and SIGINT")
    parser.add_argument("--group", action="store_true",
                        help="SIGINT to the whole process group (Ctrl-C in a terminal)")
    args = parser.parse_args()
    cannot = without_ros2("bench_shutdown")
    if cannot is not None:
        return cannot
    os.environ.setdefault("ROS_DOMAIN_ID", "215")
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    target = "process group" if args.group else "ros2 launch"
    print(f"SIGINT to the {target}; {args.runs} runs per launch file", flush=True)
    failed = False
    figures: list[Figure] = []
    for name in args.launch_files or sorted(LIFECYCLE_NODES):
        times, bad = [], []
        for run in range(args.runs):
            with tempfile.TemporaryDirectory(prefix=f"bench_shutdown_{name}_") as tmp:
                try:
                    seconds, code, faults, noisy = one_run(name, Path(tmp), args.settle,
                                                           args.group)
                except RuntimeError as exc:  # did not come up: a failed run, not a crash
                    print(f"  {name} run {run + 1}/{args.runs}: {exc}; log:\n"
                          + (Path(tmp) / f"{name}.log").read_text(errors="replace")[-1500:])
                    bad.append(run + 1)
                    continue
            times.append(seconds)
            print(f"  {name} run {run + 1}/{args.runs}: exit {code} after {seconds:.2f} s, "
                  f"{faults} fault(s), {noisy} ERROR/WARN line(s) at start", flush=True)
            if code != 0 or faults or noisy or seconds >= 5.0:
                bad.append(run + 1)
        if not times:
            print(f"{name}.launch.py: no run came up")
            failed = True
            continue
        print(f"{name}.launch.py: time to exit after SIGINT min {min(times):.2f} s, median "
              f"{statistics.median(times):.2f} s, max {max(times):.2f} s over {len(times)} "
              f"runs; runs with a non-zero status, a fault, a noisy start or >= 5 s: "
              f"{bad or 'none'}", flush=True)
        failed = failed or bool(bad)
        figures += [Figure(f"{name}.launch.py: exit after SIGINT, median",
                           statistics.median(times), "s"),
                    Figure(f"{name}.launch.py: exit after SIGINT, max", max(times), "s",
                           "< 5 s", max(times) < 5.0),
                    Figure(f"{name}.launch.py: bad runs", len(bad), f"of {args.runs}",
                           "none", not bad)]
    write_results("shutdown", figures, notes=f"SIGINT to the {target}, {args.runs} runs per "
                  "launch file; a bad run has a non-zero status, a fault, a noisy start or "
                  "takes >= 5 s.")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
