"""What ``kill -9`` of a recording costs: messages and seconds lost per kill.

Ten times: start the recorder node in its own process, publish WrenchStamped at 1 kHz
from this process (force.z = sequence number, header.stamp = publish time), ``kill -9`` the
recorder at a random moment 2-8 s after publishing began, recover the bag with
``tactile-sensor bag recover``'s core, and compare the messages published between the start
and the kill with the messages recovered. The time lost is the kill time minus the publish
stamp of the last recovered message, so a late delivery counts as lost too.

Each run starts only once the killed recorder before it has left the graph. Fast DDS keeps
a killed participant matched until its lease ends (about 20 s), and a recorder started
beside one can get its messages 0.2-3.2 s late (shared memory or UDP alike), or none before
a kill 2-3 s in. That start-up lag is the middleware's, not a crash loss, so the runs wait it
out; a recorder started after the lease ended gets its first message within milliseconds.

Run (after ``. scripts/env.sh``): ``python benchmarks/bench_recording_kill.py [KILLS]``.
Uses ROS domain 98 (override with ROS_DOMAIN_ID); takes about 5 min (mostly the waits).
"""

from __future__ import annotations

import functools
import os
import random
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path

from results import Figure, write_results
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

SOURCE = Path(__file__).resolve().parents[1] / "tactile_sensor"
sys.path.insert(0, str(SOURCE))

from tactile_sensor.recording.recovery import recover  # noqa: E402

RATE_HZ = 1000
KILLS = 10
#: Longest wait for a killed recorder to leave the graph (Fast DDS's lease is 20 s).
LEAVE_TIMEOUT_S = 60.0


class Publisher:
    """1 kHz WrenchStamped with the sequence number in force.z and the publish time in
    header.stamp, in a thread."""

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
            sec, nanosec = divmod(time.time_ns(), 1_000_000_000)
            self.msg.header.stamp.sec, self.msg.header.stamp.nanosec = sec, nanosec
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


def _wait_until(condition: Callable[[], bool], timeout_s: float, failure: str) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            raise SystemExit(failure)
        time.sleep(0.02)


def one_kill(pub: Publisher, folder: Path, env: dict[str, str], run: int,
             rng: random.Random) -> tuple[int, int, float]:
    """One recording killed; returns (published, recovered, seconds lost)."""
    # The recorder killed before is still matched until its lease ends; a new one started
    # beside it gets its messages late (see the module docstring), so let it go first.
    _wait_until(lambda: pub.pub.get_subscription_count() == 0, LEAVE_TIMEOUT_S,
                f"the recorder killed before run {run + 1} stayed in the ROS graph for "
                f"{LEAVE_TIMEOUT_S:.0f} s; is another recorder on domain "
                f"{env['ROS_DOMAIN_ID']}?")
    bag = folder / f"bag{run}"
    log_path = folder / f"recorder{run}.log"
    log = log_path.open("wb")
    recorder = subprocess.Popen(
        [sys.executable, "-m", "tactile_sensor.nodes.recorder", "--ros-args",
         "-p", f"path:={bag}", "-p", "topics:=['/bench/kill']"],
        env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        _wait_until(lambda: recorder.poll() is not None or (
            "Recording /bench/kill" in log_path.read_text(errors="replace")
            and pub.pub.get_subscription_count() > 0), 30,
            f"recorder did not subscribe; see {log_path}")
        if recorder.poll() is not None:
            raise SystemExit(f"recorder exited with {recorder.returncode}; see {log_path}")
        first_seq = pub.sent
        started_ns = time.time_ns()
        pub.running.set()
        time.sleep(rng.uniform(2.0, 8.0))
        os.killpg(recorder.pid, signal.SIGKILL)
        killed_ns = time.time_ns()
        published = pub.sent - first_seq
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
        return published, 0, (killed_ns - started_ns) / 1e9
    last_stamp_ns = max(_publish_stamp_ns(cdr) for _, _, cdr in messages)
    return published, len(messages), (killed_ns - last_stamp_ns) / 1e9


@functools.cache
def _typestore() -> Typestore:
    return get_typestore(Stores.ROS2_JAZZY)


def _publish_stamp_ns(cdr: bytes) -> int:
    msg = _typestore().deserialize_cdr(cdr, "geometry_msgs/msg/WrenchStamped")
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


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
          f"max {max(lost_spans):.2f} s (flush period 0.5 s; publish stamp of the last "
          "recovered message to the kill)")
    write_results("recording_kill", [
        Figure("time lost per kill: median", statistics.median(lost_spans), "s"),
        Figure("time lost per kill: max", max(lost_spans), "s")],
        notes=f"{kills} kills of the recorder node at {RATE_HZ} Hz; flush period 0.5 s.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
