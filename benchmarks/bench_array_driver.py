"""Driver with four modules against one module at 1 kHz, side by side in one run: CPU and
lost frames (the array's goal: no dropped frames, CPU at most 1.5x the single module's).

Two drivers run at once, each in its own process with its own mock ADC process (1 kHz,
a looping 3 mm press; the four-channel ADC sends the press on every channel): ``single``
reads one module on channel 0 with a curve calibration, ``array`` reads four modules
(``modules: 0:front,1:back,2:left,3:right``) with an array calibration fitted here on
synthetic outputs. Both publish every sample (``publish_rate`` 0) and this process
subscribes to both readings, so both pay the same DDS cost. CPU = user+system time of
each driver process over the window; lost frames = the drivers' own diagnostics counters
(sequence gaps and backlog overflows) at the end.

``--layout wrench`` runs the eight-module wrench layout (``modules:
0:front@-0.0055,...,7:right@0.0055``, an eight-channel ADC) with a six-column calibration
(torque with its own 10 Hz low-pass and the force's slow part) in place of the four-module
array: the six-axis wrench's goal is at most 1.3 x the single module's CPU. Its figures go to
``build/benchmarks/results/bench_wrench_driver.json``.

``--compare REV`` runs the same pair with the driver of commit REV (its sources unpacked by
``git archive``; this checkout's interfaces and mock ADCs) and with this checkout's, one
pair after the other for ``--rounds`` rounds whose order alternates, and prints the CPU
of each before and after (the hot-path goal: the array driver at most 0.4 x REV's). The
figures go to ``build/benchmarks/results/bench_array_driver.json``.

    python benchmarks/bench_array_driver.py [--seconds 30] [--compare REV] [--rounds 2]
        [--layout array|wrench]

Run with ``scripts/env.sh`` sourced. ROS domain: $ROS_DOMAIN_ID (default 216).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from node_processes import interrupt, isolate_ros
from rclpy.executors import SingleThreadedExecutor
from results import Figure, write_results
from side_by_side import (
    MOCK,
    WARM_UP_S,
    CompareError,
    Variant,
    cpu_seconds,
    interleaved,
    load_average,
    variants,
)

from tactile_sensor.nodes.background_spin import BackgroundSpin
from tactile_sensor.nodes.ros_session import ros_session
from tactile_sensor.sensing.array_calibration import ArrayCalibration
from tactile_sensor_interfaces.msg import TactileReading

ROOT = Path(__file__).resolve().parents[1]
FACES = ("front", "back", "left", "right")
EIGHT = tuple(f"{face}@{c}" for face in FACES for c in ("-0.0055", "0.0055"))
LOST_KEYS = ("frames_dropped", "frames_overflowed")
ARRAY_RATIO_GOAL = 0.4  # the array driver at most 0.4 x REV's CPU (b36bc06)
SINGLE_RATIO_GOAL = 1.5  # the array at most 1.5 x the single module's CPU
WRENCH_RATIO_GOAL = 1.3  # the wrench layout at most 1.3 x the single module's CPU


def write_inputs(tmp: Path) -> None:
    """A linear skin for the mock ADCs, and the two calibrations the drivers load."""
    d = np.linspace(0, 0.003, 31)
    (tmp / "skin.json").write_text(json.dumps({
        "indentation_m": d.tolist(), "force_n": (7 * d / 0.003).tolist(),
        "voltage_v": (3.0 - 0.5 * d / 0.003).tolist()}))
    (tmp / "curve.json").write_text(json.dumps({
        "format": "tactile_sensor/calibration", "version": 1, "source": "bench",
        "output_v": (0.5 * d / 0.003).tolist(), "force_n": (7 * d / 0.003).tolist()}))
    rng = np.random.default_rng(1)
    outputs = rng.uniform(0.0, 0.5, (400, 4))
    forces = np.stack([outputs[:, 3] - outputs[:, 2], outputs[:, 0] - outputs[:, 1],
                       outputs.sum(axis=1) * 3.5], axis=1)
    # Written as file version 1 (without the range of outputs seen, which version 2 adds):
    # every version compared reads it, b36bc06 reads only that one.
    array = ArrayCalibration.fit(FACES, outputs, forces, 3, "bench").to_dict()
    array.pop("observed")
    (tmp / "array.json").write_text(json.dumps({**array, "version": 1}))
    eight = rng.uniform(0.0, 0.5, (600, 8))
    wrench = np.column_stack([eight[:, 6:].sum(axis=1) - eight[:, 4:6].sum(axis=1),
                              eight[:, :2].sum(axis=1) - eight[:, 2:4].sum(axis=1),
                              eight.sum(axis=1) * 1.75, eight @ rng.normal(0, 0.01, (8, 3))])
    ArrayCalibration.fit(EIGHT, eight, wrench, 3, "bench", noise_v=0.005,
                         slow_forces=wrench[:, :3] + eight[:, :3] * 0.01
                         ).to_file(tmp / "wrench.json")


def start(tmp: Path, name: str, channels: int, modules: str, calibration: str,
          rate: float, variant: Variant) -> list[subprocess.Popen]:
    py = sys.executable
    link = tmp / f"{name}_adc"
    driver = subprocess.Popen(
        [py, "-m", "tactile_sensor.nodes.driver", "--ros-args", "-r", f"__node:={name}",
         "-p", f"port:={link}", "-p", "calibration_source:=file",
         "-p", f"calibration_file:={tmp / calibration}", "-p", "autostart:=true",
         "-p", f"modules:='{modules}'", "-p", f"sample_rate:={rate}"],
        env=variant.env(), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    mock = subprocess.Popen(
        [py, "-m", "tactile_sensor.cli", "mock", "adc", "--link", str(link), "--rate",
         str(rate), "--channels", str(channels), "--skin-table", str(tmp / "skin.json"),
         "--loop", "--profile", "ramp:depth=0.003,speed=0.003,cycles=1,rest=0.5"],
        env=MOCK.env(), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return [driver, mock]


@dataclass
class PairRun:
    """One run of a single-module and an array driver side by side."""

    span_s: float
    cpu_s: dict[str, float]
    received: dict[str, int]
    lost: dict[str, dict[str, int]]  # in the window
    lost_since_start: dict[str, object]
    lateral: int  # array readings with four outputs
    load: tuple[float, float]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--rate", type=float, default=1000.0)
    parser.add_argument("--compare", metavar="REV",
                        help="also run the drivers of commit REV, alternating with these")
    parser.add_argument("--layout", choices=("array", "wrench"), default="array",
                        help="array: four centred modules; wrench: eight modules with a "
                             "six-column calibration")
    parser.add_argument("--rounds", type=int, default=None,
                        help="runs of each version (default 2 with --compare, else 1)")
    args = parser.parse_args()
    rounds = args.rounds if args.rounds is not None else (2 if args.compare else 1)
    if rounds < 1:
        parser.error(f"--rounds must be at least 1, got {rounds}")
    if args.compare and args.layout == "wrench":
        parser.error("--compare needs --layout array: older drivers have no six-column "
                     "calibration")
    isolate_ros(216)
    tmp = Path(tempfile.mkdtemp(prefix="bench_array_driver_"))
    write_inputs(tmp)
    runs: dict[str, list[PairRun]] = {}
    try:
        with variants(args.compare) as versions:
            for r, version in interleaved(versions, rounds):
                run = measure(args, tmp, version)
                if run is None:
                    return 1
                runs.setdefault(version.label, []).append(run)
                print(f"  round {r + 1}, {version.label}: CPU array "
                      f"{100 * run.cpu_s['array'] / run.span_s:.1f} %, single "
                      f"{100 * run.cpu_s['single'] / run.span_s:.1f} % (load average "
                      f"{run.load[0]:.1f} -> {run.load[1]:.1f})", flush=True)
    except CompareError as exc:
        print(f"bench_array_driver: {exc}", file=sys.stderr)
        return 2
    figures = report(args, [v.label for v in versions], rounds, runs)
    name = "bench_array_driver" if args.layout == "array" else "bench_wrench_driver"
    path = write_results(name, figures, notes=(
        f"{rounds} round(s) of {args.seconds:g} s per version, order alternating; the "
        f"single-module and the {args.layout} driver of one version run side by side; CPU "
        "in % of one core"))
    print(f"figures written to {path.relative_to(ROOT)}")
    return 0


def report(args: argparse.Namespace, labels: list[str], rounds: int,
           runs: dict[str, list[PairRun]]) -> list[Figure]:
    loads = [x for rs in runs.values() for r in rs for x in r.load]
    print(f"\nsingle-module and {args.layout} driver side by side at {args.rate:g} Hz, {rounds} "
          f"round(s) x {args.seconds:g} s per version (load average {min(loads):.1f} .. "
          f"{max(loads):.1f} on {os.cpu_count()} cores)")
    figures: list[Figure] = []
    cpu: dict[tuple[str, str], float] = {}
    for label in labels:
        rs = runs[label]
        span = sum(r.span_s for r in rs)
        for name in ("single", "array"):
            percent = 100 * sum(r.cpu_s[name] for r in rs) / span
            cpu[(label, name)] = percent
            each = ", ".join(f"{100 * r.cpu_s[name] / r.span_s:.1f}" for r in rs)
            received = sum(r.received[name] for r in rs) / span
            lost = {k: sum(r.lost[name].get(k, 0) for r in rs) for k in LOST_KEYS}
            print(f"  {label:22s} {name:6s}: CPU {percent:5.1f} % of one core ({each}), "
                  f"{received:6.0f} readings/s received, frames lost in the windows: {lost} "
                  f"(since start, last round: {rs[-1].lost_since_start.get(name)})")
            figures += [Figure(f"driver CPU, {label}, {name}", round(percent, 2),
                               "% of one core"),
                        Figure(f"readings received, {label}, {name}", round(received, 1),
                               "1/s"),
                        Figure(f"frames lost, {label}, {name}", sum(lost.values()), "",
                               "0")]
        ratio = cpu[(label, "array")] / max(cpu[(label, "single")], 1e-9)
        goal = SINGLE_RATIO_GOAL if args.layout == "array" else WRENCH_RATIO_GOAL
        print(f"  {label}: CPU ratio {args.layout} / single: {ratio:.2f} (goal <= "
              f"{goal:g}); {args.layout} readings with {modules_of(args)} outputs: "
              f"{sum(r.lateral for r in runs[label])}")
        figures.append(Figure(f"CPU ratio {args.layout} / single, {label}", round(ratio, 3),
                              "", f"<= {goal:g}", ratio <= goal))
    if len(labels) == 2:
        before, after = labels
        for name in ("array", "single"):
            ratio = cpu[(after, name)] / max(cpu[(before, name)], 1e-9)
            goal = f"<= {ARRAY_RATIO_GOAL:g}" if name == "array" else ""
            print(f"  CPU {after} / {before}, {name}: {ratio:.2f}"
                  + (f" (goal {goal})" if goal else ""))
            figures.append(Figure(f"CPU ratio {after} / {before}, {name}", round(ratio, 3),
                                  "", goal))
    figures.append(Figure("load average during the run", f"{min(loads):.1f} .. "
                          f"{max(loads):.1f}", f"on {os.cpu_count()} cores"))
    return figures


def modules_of(args: argparse.Namespace) -> int:
    return len(FACES) if args.layout == "array" else len(EIGHT)


def measure(args: argparse.Namespace, tmp: Path, version: Variant) -> PairRun | None:
    """One run of ``version``'s single-module and array (or wrench) drivers side by side."""
    faces = FACES if args.layout == "array" else EIGHT
    runs = {"single": start(tmp, "single", 1, "", "curve.json", args.rate, version),
            "array": start(tmp, "array", len(faces),
                           ",".join(f"{i}:{f}" for i, f in enumerate(faces)),
                           f"{args.layout}.json", args.rate, version)}
    counts = {name: 0 for name in runs}
    lost: dict[str, dict[str, int]] = {}
    lateral = {"array": 0}
    lock = threading.Lock()

    def counter(name: str) -> Callable[[TactileReading], None]:
        def on_reading(msg: TactileReading) -> None:
            with lock:
                counts[name] += 1
                if name == "array" and len(msg.outputs) == len(faces):
                    lateral["array"] += 1
        return on_reading

    def on_diagnostics(msg: DiagnosticArray) -> None:
        for status in msg.status:
            for name in runs:
                if status.name.startswith(f"/{name}:"):
                    values = {kv.key: kv.value for kv in status.values}
                    with lock:
                        lost[name] = {k: int(values.get(k, "0")) for k in LOST_KEYS}

    try:
        with ros_session():
            node = rclpy.create_node("bench_array_driver_listener")
            for name in runs:
                node.create_subscription(TactileReading, f"/{name}/reading", counter(name),
                                         1000)
            node.create_subscription(DiagnosticArray, "/diagnostics", on_diagnostics, 50)
            executor = SingleThreadedExecutor()
            executor.add_node(node)
            spin = BackgroundSpin(executor)
            deadline = time.monotonic() + WARM_UP_S
            while min(counts.values()) < 2000 and time.monotonic() < deadline:
                time.sleep(0.1)
            if min(counts.values()) < 2000:
                print(f"{version.label}: a driver produced no data within {WARM_UP_S:g} s: "
                      f"{counts}", file=sys.stderr)
                return None
            with lock:
                start_counts, start_lost = dict(counts), {k: dict(v) for k, v in lost.items()}
                lateral["array"] = 0
            load0 = load_average()
            cpu0 = {name: cpu_seconds(procs[0].pid) for name, procs in runs.items()}
            t0 = time.monotonic()
            time.sleep(args.seconds)
            cpu1 = {name: cpu_seconds(procs[0].pid) for name, procs in runs.items()}
            t1 = time.monotonic()
            with lock:
                end_counts = dict(counts)
            time.sleep(1.5)  # one more diagnostics period
            with lock:
                end_lost = {k: dict(v) for k, v in lost.items()}
            spin.stop()
            node.destroy_node()
    finally:
        interrupt(*(proc for procs in runs.values() for proc in procs), timeout_s=5)
    return PairRun(
        t1 - t0, {name: cpu1[name] - cpu0[name] for name in runs},
        {name: end_counts[name] - start_counts[name] for name in runs},
        {name: {k: end_lost.get(name, {}).get(k, 0) - start_lost.get(name, {}).get(k, 0)
                for k in LOST_KEYS} for name in runs},
        {name: end_lost.get(name, "no diagnostics") for name in runs},
        lateral["array"], (load0, load_average()))


if __name__ == "__main__":
    sys.exit(main())
