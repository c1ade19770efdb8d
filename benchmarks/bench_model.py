"""Model node over ROS: ~/predict for 1000 indentations (latency median / p99), and the
time to load a cached prediction curve.

    python benchmarks/bench_model.py [--calls 200]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import rclpy
from node_processes import interrupt, isolate_ros
from results import Figure, write_results

from tactile_sensor.nodes.ros_session import ros_session
from tactile_sensor_interfaces.srv import PredictOutput

ROOT = Path(__file__).resolve().parents[1]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=200)
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT / "tactile_sensor"))
    from tactile_sensor.physics.params import PhysicsParams
    from tactile_sensor.physics.prediction import load_or_compute_curve

    curve = load_or_compute_curve(PhysicsParams())  # warm the cache (cold: a full sweep)
    start = time.perf_counter()
    load_or_compute_curve(PhysicsParams())
    load_ms = (time.perf_counter() - start) * 1e3
    print(f"cached curve load: {load_ms:.1f} ms (goal < 100 ms)")
    isolate_ros(200 + os.getpid() % 30)
    source = ROOT / "tactile_sensor"
    env = dict(os.environ, PYTHONPATH=f"{source}:{os.environ.get('PYTHONPATH', '')}")
    model = subprocess.Popen(
        [sys.executable, "-m", "tactile_sensor.nodes.model", "--ros-args", "-r",
         "__node:=model", "--params-file", str(ROOT / "tactile_sensor/config/physics.yaml"),
         "-p", "autostart:=true"], env=env, stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL)
    indentations = np.linspace(0.0, curve.max_indentation_m, 1000).tolist()
    times: list[float] = []
    try:
        with ros_session():
            node = rclpy.create_node("bench_model_client")
            client = node.create_client(PredictOutput, "/model/predict")
            if not client.wait_for_service(timeout_sec=30):
                print("the model node did not come up", file=sys.stderr)
                return 1
            request = PredictOutput.Request(indentation=indentations)
            while True:  # until the curve is loaded
                future = client.call_async(request)
                rclpy.spin_until_future_complete(node, future, timeout_sec=10)
                if future.result().success:
                    break
                time.sleep(0.1)
            for _ in range(args.calls):
                start = time.perf_counter()
                future = client.call_async(request)
                rclpy.spin_until_future_complete(node, future, timeout_sec=10)
                times.append(time.perf_counter() - start)
            node.destroy_node()
    finally:
        interrupt(model, timeout_s=5)
    t = np.array(times) * 1e3
    print(f"~/predict, 1000 indentations, {len(t)} calls: median {np.median(t):.2f} ms, "
          f"p99 {np.percentile(t, 99):.2f} ms (goal p99 < 20 ms)")
    p99 = float(np.percentile(t, 99))
    write_results("model", [
        Figure("cached curve load", load_ms, "ms", "< 100 ms", load_ms < 100),
        Figure("~/predict of 1000 indentations: median", float(np.median(t)), "ms"),
        Figure("~/predict of 1000 indentations: p99", p99, "ms", "< 20 ms", p99 < 20)],
        notes=f"{len(t)} calls to the model node in its own process.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
