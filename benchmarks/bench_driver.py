"""Driver node over ROS at 1 kHz: end-to-end latency and CPU use.

Starts the mock ADC (1 kHz, its own process) and the driver node (its own process), and
subscribes here. Latency = reception time - the reading's stamp, which is the sample's
device time mapped to the host clock (so it includes serial transfer, framing, the signal
chain, publishing and DDS delivery, less the smallest transfer delay, which the clock
mapping absorbs). Two reception times are reported: the middleware's (DDS hands the
message to this subscriber; MessageInfo.received_timestamp) and this Python callback's
(adds rclpy's executor, which for any Python subscriber at 1 kHz is the slowest link).
CPU = the driver process's user+system time over the window.

The driver runs with a static calibration file, then with the same curve and two rate
terms (calibration across speeds: the Prony estimator on every sample), then (``all``)
with those terms and play (two branches and the direction tracker, file version 3).

    python benchmarks/bench_driver.py [--seconds 30] [--model static|rate|play|both|all]
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import struct
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import rclpy
from rclpy.executors import SingleThreadedExecutor

from tactile_sensor.nodes.background_spin import BackgroundSpin
from tactile_sensor.nodes.ros_session import ros_session
from tactile_sensor_interfaces.msg import TactileReading

ROOT = Path(__file__).resolve().parents[1]


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--rate", type=float, default=1000.0)
    parser.add_argument("--model", choices=("static", "rate", "play", "both", "all"),
                        default="both", help="both: static and rate; all: and play")
    args = parser.parse_args()
    os.environ.setdefault("ROS_DOMAIN_ID", str(150 + os.getpid() % 50))
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    models = {"both": ("static", "rate"), "all": ("static", "rate", "play")}.get(
        args.model, (args.model,))
    cpu = {}
    for model in models:
        result = measure(args, model)
        if result is None:
            return 1
        cpu[model] = result
    for model, name in (("rate", "rate-aware"), ("play", "rate-aware with play")):
        if "static" in cpu and model in cpu:
            print(f"driver CPU, {name} against static: {cpu[model]:.1f} % vs "
                  f"{cpu['static']:.1f} % of one core "
                  f"({100 * (cpu[model] / cpu['static'] - 1):+.1f} %; goal: at most +10 %)")
    from results import Figure, write_results

    write_results("driver", [Figure(f"driver CPU, {m} calibration", c, "% of one core")
                             for m, c in cpu.items()],
                  notes=f"{args.rate:g} Hz for {args.seconds:g} s per calibration.")
    return 0


def measure(args: argparse.Namespace, model: str) -> float | None:
    """One driver run with a static or a rate-aware file; its CPU [% of one core]."""
    source = ROOT / "tactile_sensor"
    env = dict(os.environ, PYTHONPATH=f"{source}:{os.environ.get('PYTHONPATH', '')}")
    tmp = Path(tempfile.mkdtemp(prefix="bench_driver_"))
    d = np.linspace(0, 0.003, 31)
    (tmp / "skin.json").write_text(json.dumps({"indentation_m": d.tolist(),
                                               "force_n": (7 * d / 0.003).tolist(),
                                               "voltage_v": (3.0 - 0.5 * d / 0.003).tolist()}))
    calibration = {"format": "tactile_sensor/calibration", "version": 1, "source": "bench",
                   "output_v": (0.5 * d / 0.003).tolist(), "force_n": (7 * d / 0.003).tolist()}
    if model in ("rate", "play"):  # the simulation's own terms (config/physics.yaml)
        calibration.update(version=2, rate_terms=[{"g": 0.05, "tau_s": 0.1},
                                                  {"g": 0.04, "tau_s": 1.5}])
    if model == "play":  # a half-gap like the mock's play makes, a band like the fit's
        calibration.update(version=3, play={"half_gap_n": (0.1 * d / 0.003).tolist(),
                                            "band_v": 0.05, "smoothing_hz": 10.0})
    (tmp / "cal.json").write_text(json.dumps(calibration))
    py = sys.executable
    driver = subprocess.Popen(
        [py, "-m", "tactile_sensor.nodes.driver", "--ros-args", "-r", "__node:=driver",
         "-p", f"port:={tmp / 'adc'}", "-p", "calibration_source:=file",
         "-p", f"calibration_file:={tmp / 'cal.json'}", "-p", "autostart:=true",
         "-p", f"sample_rate:={args.rate}"], env=env, stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL)
    mock = subprocess.Popen(
        [py, "-m", "tactile_sensor.cli", "mock", "adc", "--link", str(tmp / "adc"),
         "--rate", str(args.rate), "--skin-table", str(tmp / "skin.json"), "--loop",
         "--profile", "ramp:depth=0.003,speed=0.003,cycles=1,rest=0.5"],
        env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    latencies: list[tuple[float, float]] = []  # (middleware, callback) [s]
    lock = threading.Lock()

    def record(cdr: bytes, info: dict) -> None:
        now = time.time_ns()
        sec, nanosec = struct.unpack_from("<iI", cdr, 4)  # CDR header, then header.stamp
        stamp = sec * 1_000_000_000 + nanosec
        with lock:
            latencies.append(((info["received_timestamp"] - stamp) * 1e-9,
                              (now - stamp) * 1e-9))

    def on_reading(cdr: bytes, info: dict) -> None:
        record(cdr, info)
        with subscription.handle:  # drain what else waits: one executor round per message
            for _ in range(256):   # would measure rclpy, not the driver
                item = subscription.handle.take_message(TactileReading, True)
                if item is None:
                    break
                record(*item)

    try:
        with ros_session():
            node = rclpy.create_node("bench_driver_listener")
            subscription = node.create_subscription(TactileReading, "/driver/reading",
                                                    on_reading, 1000, raw=True)
            executor = SingleThreadedExecutor()
            executor.add_node(node)
            spin = BackgroundSpin(executor)
            deadline = time.monotonic() + 30
            while len(latencies) < 2000 and time.monotonic() < deadline:
                time.sleep(0.1)
            if len(latencies) < 2000:
                print("driver produced no data within 30 s", file=sys.stderr)
                return None
            with lock:
                latencies.clear()
            cpu0, t0 = cpu_seconds(driver.pid), time.monotonic()
            time.sleep(args.seconds)
            cpu1, t1 = cpu_seconds(driver.pid), time.monotonic()
            with lock:
                both = np.array(latencies)
            spin.stop()
            node.destroy_node()
    finally:
        for proc in (mock, driver):
            proc.send_signal(signal.SIGINT)
        for proc in (mock, driver):
            try:
                proc.wait(5)
            except subprocess.TimeoutExpired:
                proc.kill()
    received = len(both) / (t1 - t0)
    print(f"driver ({model} calibration) at {args.rate:g} Hz for {t1 - t0:.1f} s: "
          f"{received:.0f} readings/s received")
    for column, what in ((0, "sample -> subscriber (DDS)"), (1, "sample -> Python callback")):
        lat = both[:, column] * 1e3
        print(f"  latency {what}: median {np.median(lat):.2f} ms, p99 "
              f"{np.percentile(lat, 99):.2f} ms, max {lat.max():.2f} ms (goal: p99 <= 2 ms)")
    percent = 100 * (cpu1 - cpu0) / (t1 - t0)
    print(f"  driver CPU: {percent:.1f} % of one core")
    return percent


if __name__ == "__main__":
    sys.exit(main())
