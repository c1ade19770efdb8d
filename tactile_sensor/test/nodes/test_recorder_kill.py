"""``kill -9`` of the recorder node in its own process: ``bag recover`` and the analysis'
reader get back all but the last second of what it recorded."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

rclpy = pytest.importorskip("rclpy")

from geometry_msgs.msg import WrenchStamped  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402

from tactile_sensor.analysis.bag_reader import TopicSpec, read_recording  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.slow]
RATE_HZ = 500
SOURCE = Path(__file__).resolve().parents[2]


def test_a_killed_recorder_leaves_all_but_the_last_second(ros_domain, spawn, tmp_path):
    context = rclpy.Context()
    rclpy.init(context=context)
    node = Node("kill_test", context=context)
    try:
        pub = node.create_publisher(WrenchStamped, "/test/kill",
                                    QoSProfile(depth=5000,
                                               reliability=ReliabilityPolicy.RELIABLE))
        bag = tmp_path / "bag"
        recorder = spawn("--ros-args", "-p", f"path:={bag}", "-p", "topics:=['/test/kill']",
                         module="tactile_sensor.nodes.recorder")
        deadline = time.monotonic() + 30
        while pub.get_subscription_count() == 0:
            assert time.monotonic() < deadline, recorder.output()
            time.sleep(0.02)
        msg = WrenchStamped()
        start = time.monotonic()
        sent = 0
        while sent < 3 * RATE_HZ:  # 3 s at 500 Hz, paced by the clock
            msg.wrench.force.z = float(sent)
            pub.publish(msg)
            sent += 1
            delay = start + sent / RATE_HZ - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        recorder.send_signal(signal.SIGKILL)
        recorder.proc.wait(10)
    finally:
        node.destroy_node()
        context.try_shutdown()
    assert not (bag / "metadata.yaml").exists()
    env = {**os.environ, "PYTHONPATH": str(SOURCE)}
    result = subprocess.run([sys.executable, "-m", "tactile_sensor.cli", "bag", "recover",
                             str(bag)], capture_output=True, text=True, timeout=60, env=env)
    assert result.returncode == 0, result.stderr
    assert "recovered" in result.stdout and "bag_0.mcap" in result.stdout
    notes: list[str] = []
    spec = TopicSpec("wrench", "/test/kill", {"force_n": "wrench.force.z"}, "--topic",
                     "WrenchStamped")
    recording = read_recording(bag, [spec], notify=notes.append)
    force = recording.series["wrench"].values["force_n"]
    assert len(notes) == 1 and "recovered" in notes[0]
    # a prefix of what was sent, short by at most about one second (0.5 s flush period
    # plus the writer thread's latency on a busy machine)
    assert list(force) == [float(i) for i in range(len(force))]
    assert len(force) >= sent - 1.0 * RATE_HZ, (len(force), sent)
    recovered = bag.with_name("bag-recovered")
    assert (recovered / "metadata.yaml").is_file()
