"""Driver with four modules against one module at 1 kHz, side by side in one run: CPU and
lost frames (issue 16's goal: no dropped frames, CPU at most 1.5x the single module's).

Two drivers run at once, each in its own process with its own mock ADC process (1 kHz,
a looping 3 mm press; the four-channel ADC sends the press on every channel): ``single``
reads one module on channel 0 with a curve calibration, ``array`` reads four modules
(``modules: 0:front,1:back,2:left,3:right``) with an array calibration fitted here on
synthetic outputs. Both publish every sample (``publish_rate`` 0) and this process
subscribes to both readings, so both pay the same DDS cost. CPU = user+system time of
each driver process over the window; lost frames = the drivers' own diagnostics counters
(sequence gaps and backlog overflows) at the end.

    python benchmarks/bench_array_driver.py [--seconds 30]

Run with ``scripts/env.sh`` sourced. ROS domain: $ROS_DOMAIN_ID (default 216).
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.executors import SingleThreadedExecutor

from tactile_sensor.nodes.background_spin import BackgroundSpin
from tactile_sensor.nodes.ros_session import ros_session
from tactile_sensor.sensing.array_calibration import ArrayCalibration
from tactile_sensor_interfaces.msg import TactileReading

ROOT = Path(__file__).resolve().parents[1]
FACES = ("front", "back", "left", "right")
LOST_KEYS = ("frames_dropped", "frames_overflowed")


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


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
    ArrayCalibration.fit(FACES, outputs, forces, 3, "bench").to_file(tmp / "array.json")


def start(tmp: Path, name: str, channels: int, modules: str, calibration: str,
          rate: float, env: dict[str, str]) -> list[subprocess.Popen]:
    py = sys.executable
    link = tmp / f"{name}_adc"
    driver = subprocess.Popen(
        [py, "-m", "tactile_sensor.nodes.driver", "--ros-args", "-r", f"__node:={name}",
         "-p", f"port:={link}", "-p", "calibration_source:=file",
         "-p", f"calibration_file:={tmp / calibration}", "-p", "autostart:=true",
         "-p", f"modules:='{modules}'", "-p", f"sample_rate:={rate}"],
        env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    mock = subprocess.Popen(
        [py, "-m", "tactile_sensor.cli", "mock", "adc", "--link", str(link), "--rate",
         str(rate), "--channels", str(channels), "--skin-table", str(tmp / "skin.json"),
         "--loop", "--profile", "ramp:depth=0.003,speed=0.003,cycles=1,rest=0.5"],
        env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return [driver, mock]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--rate", type=float, default=1000.0)
    args = parser.parse_args()
    os.environ.setdefault("ROS_DOMAIN_ID", "216")
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    source = ROOT / "tactile_sensor"
    env = dict(os.environ, PYTHONPATH=f"{source}:{os.environ.get('PYTHONPATH', '')}")
    tmp = Path(tempfile.mkdtemp(prefix="bench_array_driver_"))
    write_inputs(tmp)
    runs = {"single": start(tmp, "single", 1, "", "curve.json", args.rate, env),
            "array": start(tmp, "array", 4, ",".join(f"{i}:{f}" for i, f in enumerate(FACES)),
                           "array.json", args.rate, env)}
    counts = {name: 0 for name in runs}
    lost: dict[str, dict[str, int]] = {}
    lateral = {"array": 0}
    lock = threading.Lock()

    def counter(name: str) -> Callable[[TactileReading], None]:
        def on_reading(msg: TactileReading) -> None:
            with lock:
                counts[name] += 1
                if name == "array" and len(msg.outputs) == 4:
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
            deadline = time.monotonic() + 60
            while min(counts.values()) < 2000 and time.monotonic() < deadline:
                time.sleep(0.1)
            if min(counts.values()) < 2000:
                print(f"a driver produced no data within 60 s: {counts}", file=sys.stderr)
                return 1
            with lock:
                start_counts, start_lost = dict(counts), {k: dict(v) for k, v in lost.items()}
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
        for procs in runs.values():
            for proc in procs:
                proc.send_signal(signal.SIGINT)
        for procs in runs.values():
            for proc in procs:
                try:
                    proc.wait(5)
                except subprocess.TimeoutExpired:
                    proc.kill()
    span = t1 - t0
    cpu = {name: 100 * (cpu1[name] - cpu0[name]) / span for name in runs}
    print(f"two drivers at {args.rate:g} Hz side by side for {span:.1f} s "
          f"(load average {os.getloadavg()[0]:.1f})")
    for name in runs:
        received = (end_counts[name] - start_counts[name]) / span
        window_lost = {k: end_lost.get(name, {}).get(k, 0) - start_lost.get(name, {}).get(k, 0)
                       for k in LOST_KEYS}
        print(f"  {name:6s}: CPU {cpu[name]:5.1f} % of one core, {received:6.0f} readings/s "
              f"received, frames lost in the window: {window_lost} (since start: "
              f"{end_lost.get(name, 'no diagnostics')})")
    print(f"  CPU ratio array / single: {cpu['array'] / max(cpu['single'], 1e-9):.2f} "
          f"(goal <= 1.5); array readings with 4 outputs: {lateral['array']}")
    from results import Figure, write_results

    ratio = cpu["array"] / max(cpu["single"], 1e-9)
    write_results("array_driver", [
        *(Figure(f"{name} driver CPU", cpu[name], "% of one core") for name in runs),
        Figure("CPU ratio array / single", ratio, "", "<= 1.5", ratio <= 1.5)],
        notes=f"Two drivers at {args.rate:g} Hz side by side for {span:.1f} s.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
