"""Recorder throughput: how many messages per second reach the bag without loss.

Two figures:
1. core: BagRecorder.write + close for pre-serialized WrenchStamped (no ROS), messages/s;
2. node: the recorder node in its own process, fed by a publisher in this process at
   rising rates (reliable, deep queues, as the driver publishes); for each rate the
   messages sent, found in the bag, and the rate actually achieved by the publisher.

Run from /work/main with the venv active and scripts/env.sh sourced
(``make bench`` does both). Uses ROS domain 97 (override with ROS_DOMAIN_ID).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SOURCE = Path(__file__).resolve().parents[1] / "tactile_sensor"
sys.path.insert(0, str(SOURCE))

from results import Figure, write_results  # noqa: E402

from tactile_sensor.recording import BagRecorder, default_typestore  # noqa: E402

RATES_HZ = (1000, 2000, 5000, 10000, 0)  # 0 = as fast as the publisher can
PHASE_S = 2.0
MAX_BURST = 20_000  # messages in the as-fast-as-possible phase


def bench_core(folder: Path, n: int = 200_000) -> list[Figure]:
    ts = default_typestore()
    t = ts.types
    msg = t["geometry_msgs/msg/WrenchStamped"](
        header=t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](sec=1, nanosec=2),
                                         frame_id="skin"),
        wrench=t["geometry_msgs/msg/Wrench"](force=t["geometry_msgs/msg/Vector3"](x=1, y=2, z=3),
                                             torque=t["geometry_msgs/msg/Vector3"](x=0, y=0, z=0)))
    cdr = bytes(ts.serialize_cdr(msg, "geometry_msgs/msg/WrenchStamped"))
    start = time.perf_counter()
    with BagRecorder(folder / "core") as bag:
        bag.add_topic("/w", "geometry_msgs/msg/WrenchStamped")
        for i in range(n):
            bag.write("/w", i, cdr)
        queued_s = time.perf_counter() - start
    total_s = time.perf_counter() - start
    assert bag.counts["/w"] == n
    print(f"core: {n} messages queued at {n / queued_s:,.0f}/s (caller side), "
          f"written and closed at {n / total_s:,.0f}/s")
    return [Figure("core: queued (caller side)", n / queued_s, "messages/s"),
            Figure("core: written and closed", n / total_s, "messages/s")]


def bench_node(folder: Path) -> list[Figure]:
    import rclpy
    from geometry_msgs.msg import WrenchStamped
    from rclpy.duration import Duration
    from rclpy.node import Node
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    env = dict(os.environ)
    env.setdefault("ROS_DOMAIN_ID", "97")
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.update({k: env[k] for k in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE")})
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(SOURCE), env.get("PYTHONPATH")]))
    bag_path = folder / "node"
    log = (folder / "recorder.log").open("wb")
    recorder = subprocess.Popen(
        [sys.executable, "-m", "tactile_sensor.nodes.recorder", "--ros-args",
         "-p", f"path:={bag_path}", "-p", "topics:=['/bench/wrench']"],
        env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        rclpy.init()
        node = Node("bench_recorder_publisher")
        depth = 10_000  # as the recorder's own queue
        pub = node.create_publisher(
            WrenchStamped, "/bench/wrench", QoSProfile(depth=depth,
                                                       reliability=ReliabilityPolicy.RELIABLE))
        deadline = time.monotonic() + 30
        while pub.get_subscription_count() == 0:
            if time.monotonic() > deadline or recorder.poll() is not None:
                raise SystemExit("recorder did not subscribe; see " + str(folder / "recorder.log"))
            time.sleep(0.05)
        msg = WrenchStamped()
        sent: dict[int, tuple[int, float]] = {}
        seq = 0
        for phase, rate in enumerate(RATES_HZ):
            msg.wrench.torque.x = float(phase)
            n = int(rate * PHASE_S) if rate else MAX_BURST
            start = time.monotonic()
            for i in range(n):
                msg.wrench.force.z = float(seq)
                seq += 1
                pub.publish(msg)
                if rate:
                    delay = start + (i + 1) / rate - time.monotonic()
                    if delay > 0:
                        time.sleep(delay)
            sent[phase] = (n, n / (time.monotonic() - start))
            pub.wait_for_all_acked(Duration(seconds=30))
            time.sleep(0.5)
        node.destroy_node()
        rclpy.shutdown()
        os.killpg(recorder.pid, signal.SIGINT)
        recorder.wait(60)
    finally:
        if recorder.poll() is None:  # only on failure above: never leave it running
            os.killpg(recorder.pid, signal.SIGKILL)
            recorder.wait(10)
        log.close()
    return node_figures(bag_path, sent)


def node_figures(bag_path: Path, sent: dict[int, tuple[int, float]]) -> list[Figure]:
    """What the bag holds of each phase (messages sent, rate achieved) against what was
    sent: the loss per rate and the highest rate recorded without loss."""
    from rosbags.highlevel import AnyReader

    got: dict[int, int] = dict.fromkeys(sent, 0)
    received: dict[int, list[int]] = {phase: [] for phase in sent}
    with AnyReader([bag_path]) as reader:
        for conn, stamp_ns, raw in reader.messages():
            phase = int(reader.deserialize(raw, conn.msgtype).wrench.torque.x)
            got[phase] += 1
            received[phase].append(stamp_ns)
    best = 0.0
    figures = []
    for phase, rate in enumerate(RATES_HZ):
        n, achieved = sent[phase]
        lost = n - got[phase]
        label = f"{rate} Hz" if rate else "max"
        stamps = received[phase]
        span_s = (max(stamps) - min(stamps)) / 1e9 if len(stamps) > 1 else 0.0
        rate_in = (len(stamps) - 1) / span_s if span_s else 0.0
        taken = f"{rate_in:8,.0f}/s" if span_s else "n/a"
        print(f"node: target {label:>8}: sent {n:6d} at {achieved:8,.0f}/s, "
              f"in bag {got[phase]:6d} received at {taken}, lost {lost}")
        if lost == 0:
            best = max(best, min(achieved, rate_in))
        figures.append(Figure(f"node: lost at {label}", lost, f"of {n}"))
    print(f"node: highest sustained rate recorded without loss: {best:,.0f} messages/s "
          f"(a burst faster than that loses once it exceeds the {10_000}-message queue)")
    return [Figure("node: highest sustained rate recorded without loss", best, "messages/s"),
            *figures]


def main() -> int:
    with tempfile.TemporaryDirectory(prefix="bench_recorder_") as tmp:
        folder = Path(tmp)
        figures = bench_core(folder)
        try:
            import rclpy  # noqa: F401
        except ImportError:
            print("node: skipped (. scripts/env.sh for rclpy)")
            write_results("recorder", figures, notes="Node figures not measured (no rclpy).")
            return 0
        figures += bench_node(folder)
    write_results("recorder", figures, notes="Core: pre-serialized WrenchStamped, no ROS. "
                  "Node: the recorder node in its own process, fed by a reliable publisher.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
