"""What ``kill -9`` of a recording costs: messages and seconds lost per kill.

Ten times: start the recorder node in its own process, publish WrenchStamped at 1 kHz
from this process (force.z = sequence number), ``kill -9`` the recorder at a random moment
2-8 s in, recover the bag with ``tactile-sensor bag recover``'s core, and compare the
messages published between the recorder's first message and the kill with the messages
recovered. The time lost is the kill
time minus the reception stamp of the last recovered message.

Run (after ``. scripts/env.sh``): ``python benchmarks/bench_recording_kill.py [KILLS]``.
Uses ROS domain 98 (override with ROS_DOMAIN_ID); takes about 1.5 min.
"""

from __future__ import annotations

import os
import random
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

SOURCE = Path(__file__).resolve().parents[1] / "tactile_sensor"
sys.path.insert(0, str(SOURCE))

from tactile_sensor.recording.recovery import recover  # noqa: E402

RATE_HZ = 1000
KILLS = 10


class Publisher:
    """1 kHz WrenchStamped with the sequence number in force.z, in a thread."""

    def __init__(self) -> None:
        import rclpy
        from geometry_msgs.msg import WrenchStamped
        from rclpy.node import Node
        from rclpy.qos import QoSProfile, ReliabilityPolicy

        rclpy.init()
        self.node = Node("bench_kill_publisher")
        self.pub = self.node.create_publisher(
            WrenchStamped, "/bench/kill", QoSProfile(depth=10_000,
                                                     reliability=ReliabilityPolicy.RELIABLE))
        self.msg = WrenchStamped()
        self.sent = 0
        self.running = threading.Event()
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        next_t = time.monotonic()
        while not self.stop.is_set():
            if not self.running.wait(0.05):
                next_t = time.monotonic()
                continue
            self.msg.wrench.force.z = float(self.sent)
            self.pub.publish(self.msg)
            self.sent += 1
            next_t += 1.0 / RATE_HZ
            delay = next_t - time.monotonic()
            if delay > 0:
                time.sleep(delay)

    def close(self) -> None:
        import rclpy

        self.stop.set()
        self.thread.join()
        self.node.destroy_node()
        rclpy.shutdown()


def one_kill(pub: Publisher, folder: Path, env: dict[str, str], run: int,
             rng: random.Random) -> tuple[int, int, float]:
    bag = folder / f"bag{run}"
    log = (folder / f"recorder{run}.log").open("wb")
    recorder = subprocess.Popen(
        [sys.executable, "-m", "tactile_sensor.nodes.recorder", "--ros-args",
         "-p", f"path:={bag}", "-p", "topics:=['/bench/kill']"],
        env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        deadline = time.monotonic() + 30
        # A killed recorder's subscription stays matched until its lease ends, so wait for
        # the new one's own word; "published" counts from its first recorded message.
        log_path = folder / f"recorder{run}.log"
        while ("Recording /bench/kill" not in log_path.read_text(errors="replace")
               or pub.pub.get_subscription_count() == 0):
            if time.monotonic() > deadline or recorder.poll() is not None:
                raise SystemExit(f"recorder did not subscribe; see {log.name}")
            time.sleep(0.02)
        pub.running.set()
        time.sleep(rng.uniform(2.0, 8.0))
        os.killpg(recorder.pid, signal.SIGKILL)
        killed_ns = time.time_ns()
        sent_total = pub.sent
        pub.running.clear()
        recorder.wait(10)
    finally:
        if recorder.poll() is None:
            os.killpg(recorder.pid, signal.SIGKILL)
            recorder.wait(10)
        log.close()
        pub.running.clear()
    result = recover(bag, folder / f"bag{run}-recovered")
    messages = [m for f in result.files for m in f.messages]
    if not messages:
        return sent_total, 0, float("nan")
    last_ns = max(stamp for _, stamp, _ in messages)
    first_seq = _sequence(messages[0][2])  # files and chunks are read in order
    # Published while the recorder was recording: from its first message to the kill.
    return sent_total - first_seq, len(messages), (killed_ns - last_ns) / 1e9


def _sequence(cdr: bytes) -> int:
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    msg = store.deserialize_cdr(cdr, "geometry_msgs/msg/WrenchStamped")
    return int(msg.wrench.force.z)


def main() -> int:
    kills = int(sys.argv[1]) if len(sys.argv) > 1 else KILLS
    env = dict(os.environ)
    env.setdefault("ROS_DOMAIN_ID", "98")
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.update({k: env[k] for k in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE")})
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(SOURCE), env.get("PYTHONPATH")]))
    rng = random.Random(int(os.environ.get("BENCH_SEED", "1")))
    pub = Publisher()
    lost_spans = []
    print(f"kill -9 of the recorder node at {RATE_HZ} Hz, {kills} times")
    print(f"{'kill':>4} {'published':>9} {'recovered':>9} {'lost':>6} {'time lost':>9}")
    try:
        with tempfile.TemporaryDirectory(prefix="bench_kill_") as tmp:
            for run in range(kills):
                sent, got, lost_s = one_kill(pub, Path(tmp), env, run, rng)
                lost_spans.append(lost_s)
                print(f"{run + 1:>4} {sent:>9,} {got:>9,} {sent - got:>6,} {lost_s:>8.2f}s",
                      flush=True)
    finally:
        pub.close()
    print(f"time lost per kill: median {statistics.median(lost_spans):.2f} s, "
          f"max {max(lost_spans):.2f} s (flush period 0.5 s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
