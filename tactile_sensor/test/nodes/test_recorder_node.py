"""The recorder node in its own process loses nothing a 1 kHz publisher sends it."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path

import pytest

rclpy = pytest.importorskip("rclpy")
pytest.importorskip("tactile_sensor_interfaces.msg")

from geometry_msgs.msg import WrenchStamped  # noqa: E402
from rclpy.duration import Duration  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from rosbags.highlevel import AnyReader  # noqa: E402
from rosbags.interfaces import QosDurability  # noqa: E402
from waiting import wait_until  # noqa: E402

from tactile_sensor_interfaces.msg import CalibrationCurve, TactileReading  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.slow]

N_WRENCH = 3000
READING_EVERY = 100
RECORDER = "tactile_sensor.nodes.recorder"


@pytest.fixture
def node(ros_domain: int) -> Iterator[Node]:
    """A test-side node in its own context (so the test's domain id applies)."""
    context = rclpy.Context()
    rclpy.init(context=context)
    test_node = Node("recorder_test", context=context)
    yield test_node
    test_node.destroy_node()
    context.try_shutdown()


# Upper bound of every wait on a condition (a wait ends as soon as its condition holds; a
# busy machine may take long to get there).
PATIENCE_S = 60.0


def test_records_every_message_published_at_1khz(node, spawn, tmp_path: Path):
    reliable = QoSProfile(depth=N_WRENCH, reliability=ReliabilityPolicy.RELIABLE)
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
    curve_pub = node.create_publisher(CalibrationCurve, "/test/curve", latched)
    curve = CalibrationCurve(output=[0.0, 0.1, 0.2], force=[0.0, 1.0, 3.0], source="test")
    curve_pub.publish(curve)  # before the recorder exists: only a latched match records it
    wrench_pub = node.create_publisher(WrenchStamped, "/test/wrench", reliable)
    bag_path = tmp_path / "bag"
    recorder = spawn(
        "--ros-args", "-p", f"path:={bag_path}",
        "-p", "topics:=['/test/wrench', '/test/reading', '/test/curve']",
        # No publisher of /test/reading exists yet: the recorder subscribes from the type given.
        "-p", "topic_types:=['/test/reading=tactile_sensor_interfaces/msg/TactileReading']",
        module=RECORDER)
    assert wait_until(lambda: wrench_pub.get_subscription_count() > 0
                      and curve_pub.get_subscription_count() > 0
                      and node.count_subscribers("/test/reading") > 0), recorder.output()
    reading_pub = node.create_publisher(TactileReading, "/test/reading", reliable)
    assert wait_until(lambda: reading_pub.get_subscription_count() > 0), recorder.output()

    wrench = WrenchStamped()
    wrench.header.frame_id = "skin"
    reading = TactileReading()
    period_s = 1e-3
    start = time.monotonic()
    for i in range(N_WRENCH):
        stamp = node.get_clock().now().to_msg()
        wrench.header.stamp = stamp
        wrench.wrench.force.z = float(i)
        wrench_pub.publish(wrench)
        if i % READING_EVERY == 0:
            reading.header.stamp = stamp
            reading.force = float(i)
            reading_pub.publish(reading)
        delay = start + (i + 1) * period_s - time.monotonic()
        if delay > 0:
            time.sleep(delay)
    elapsed_s = time.monotonic() - start
    # The loop keeps a 1 ms schedule and catches up after a stall (3.0 s when idle and
    # beside a busy loop): only a broken loop is this slow. Its pace is not what is tested.
    assert elapsed_s < 10 * N_WRENCH * period_s, f"publisher too slow: {elapsed_s:.2f} s"
    assert wrench_pub.wait_for_all_acked(Duration(seconds=PATIENCE_S))
    assert reading_pub.wait_for_all_acked(Duration(seconds=PATIENCE_S))
    wrench_hash = str(node.get_publishers_info_by_topic("/test/wrench")[0].topic_type_hash)

    stopped_ns = time.time_ns()
    returncode = recorder.stop()  # SIGINT, as Ctrl-C
    log = recorder.log.read_text(errors="replace")  # output() needs the open log file
    assert returncode == 0 and "Traceback" not in log, log
    assert f"Closed {bag_path} with {N_WRENCH + N_WRENCH // READING_EVERY + 1} messages" in log

    with AnyReader([bag_path]) as reader:
        conns = {c.topic: c for c in reader.connections}
        assert set(conns) == {"/test/wrench", "/test/reading", "/test/curve"}
        assert conns["/test/wrench"].digest == wrench_hash
        assert (conns["/test/curve"].ext.offered_qos_profiles[0].durability
                == QosDurability.TRANSIENT_LOCAL)
        rows = [(t, reader.deserialize(raw, c.msgtype))
                for c, t, raw in reader.messages(connections=[conns["/test/wrench"]])]
        readings = [reader.deserialize(raw, c.msgtype)
                    for c, _, raw in reader.messages(connections=[conns["/test/reading"]])]
        curves = [reader.deserialize(raw, c.msgtype)
                  for c, _, raw in reader.messages(connections=[conns["/test/curve"]])]

    # Every message, once. The bag's time is the middleware's reception time and the bag is
    # in that order, which need not be the order sent: beside a busy core one message of
    # 3000 was received 12 ms after the 552 sent after it (all of them after a 0.54 s stall).
    assert sorted(m.wrench.force.z for _, m in rows) == [float(i) for i in range(N_WRENCH)]
    bag_stamps = [t for t, _ in rows]
    header_ns = [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for _, m in rows]
    assert bag_stamps == sorted(bag_stamps)
    # Reception stamps, on the senders' host clock: after each send, before the recorder
    # was stopped (how long after is the scheduler's business: 0.05-0.18 s beside a busy
    # loop)
    lags_s = [(b - h) / 1e9 for b, h in zip(bag_stamps, header_ns, strict=True)]
    assert min(lags_s) >= 0.0 and max(bag_stamps) <= stopped_ns, (min(lags_s), max(lags_s))
    assert sorted(r.force for r in readings) == [float(i)
                                                 for i in range(0, N_WRENCH, READING_EVERY)]
    assert len(curves) == 1 and list(curves[0].force) == [0.0, 1.0, 3.0]


def test_bad_storage_exits_with_one_sentence(ros_domain, spawn, tmp_path: Path):
    recorder = spawn("--ros-args", "-p", f"path:={tmp_path / 'bag'}", "-p", "topics:=['/a']",
                     "-p", "storage:=hdf5", module=RECORDER)
    assert recorder.proc.wait(PATIENCE_S) == 1
    out = recorder.output()
    assert "Parameter 'storage' = 'hdf5' is invalid" in out and "Traceback" not in out
    assert not (tmp_path / "bag").exists()


def test_existing_bag_folder_exits_with_one_sentence(ros_domain, spawn, tmp_path: Path):
    (tmp_path / "bag").mkdir()
    recorder = spawn("--ros-args", "-p", f"path:={tmp_path / 'bag'}", "-p", "topics:=['/a']",
                     module=RECORDER)
    assert recorder.proc.wait(PATIENCE_S) == 1
    out = recorder.output()
    assert "exists already; choose a new path" in out and "Traceback" not in out


def test_missing_topics_exits_with_one_sentence(ros_domain, spawn, tmp_path: Path):
    recorder = spawn("--ros-args", "-p", f"path:={tmp_path / 'bag'}", module=RECORDER)
    assert recorder.proc.wait(PATIENCE_S) == 1
    out = recorder.output()
    assert "Parameter 'topics'" in out and "give at least one topic" in out
    assert "Traceback" not in out


# -- in process, as the bringup composes it ----------------------------------------------------

def make_recorder(node: Node, **params):
    from rclpy.parameter import Parameter

    from tactile_sensor.nodes.recorder import RecorderNode

    return RecorderNode("inproc_recorder", context=node.context, parameter_overrides=[
        Parameter(name, value=value) for name, value in params.items()])


def test_composed_recorder_records_and_finishes_on_destroy(node, tmp_path: Path):
    from rclpy.executors import SingleThreadedExecutor

    recorder = make_recorder(node, path=str(tmp_path / "bag"), topics=["/inproc/wrench"])
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(recorder)
    pub = node.create_publisher(WrenchStamped, "/inproc/wrench", 100)

    def spin_until(predicate) -> bool:
        deadline = time.monotonic() + PATIENCE_S
        while time.monotonic() < deadline and not predicate():
            executor.spin_once(timeout_sec=0.05)
        return predicate()

    assert spin_until(lambda: pub.get_subscription_count() > 0)
    for i in range(20):
        msg = WrenchStamped()
        msg.wrench.force.z = float(i)
        pub.publish(msg)
    assert spin_until(lambda: recorder.counts.get("/inproc/wrench", 0) >= 20)
    recorder.destroy_node()
    executor.shutdown()
    with AnyReader([tmp_path / "bag"]) as reader:
        forces = [reader.deserialize(raw, c.msgtype).wrench.force.z
                  for c, _, raw in reader.messages()]
    assert forces == [float(i) for i in range(20)]


def test_messages_at_1khz_do_not_wake_the_executor_once_each(node, tmp_path: Path):
    """The subscriptions are drained on a timer: while a publisher sends at 1 kHz, the
    executor spinning the recorder wakes about once per drain, not once per message."""
    import threading

    from rclpy.executors import SingleThreadedExecutor

    from tactile_sensor.nodes.recorder import DRAIN_PERIOD_S

    recorder = make_recorder(node, path=str(tmp_path / "bag"), topics=["/inproc/wrench"])
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(recorder)
    pub = node.create_publisher(WrenchStamped, "/inproc/wrench", 1000)
    deadline = time.monotonic() + PATIENCE_S
    while time.monotonic() < deadline and pub.get_subscription_count() == 0:
        executor.spin_once(timeout_sec=0.05)
    n = 1000

    def publish() -> None:
        start = time.monotonic()
        for i in range(n):
            msg = WrenchStamped()
            msg.wrench.force.z = float(i)
            pub.publish(msg)
            delay = start + (i + 1) * 1e-3 - time.monotonic()
            if delay > 0:
                time.sleep(delay)

    sender = threading.Thread(target=publish)
    wakes, start = 0, time.monotonic()
    sender.start()
    while sender.is_alive():
        executor.spin_once(timeout_sec=0.05)
        wakes += 1
    elapsed_s = time.monotonic() - start
    deadline = time.monotonic() + PATIENCE_S
    while time.monotonic() < deadline and recorder.counts.get("/inproc/wrench", 0) < n:
        executor.spin_once(timeout_sec=0.05)
    assert recorder.counts.get("/inproc/wrench", 0) == n
    # the drain timer, the 50 ms spin timeouts and the other timers; once per message
    # would be n
    assert wakes <= elapsed_s / DRAIN_PERIOD_S * 1.5 + 20 < n / 2, (wakes, elapsed_s)
    recorder.destroy_node()
    executor.shutdown()


def test_bag_time_is_the_reception_time_or_the_sim_clock_less_the_wait() -> None:
    from tactile_sensor.nodes.recorder import reception_stamp_ns

    # system clock: the middleware's reception time, however late the drain
    assert reception_stamp_ns(1_000, 9_000, 50, sim_time=False) == 1_000
    # sim time: the node clock at the drain, less the 8 us the message waited
    assert reception_stamp_ns(1_000, 9_000, 50_000, sim_time=True) == 42_000
    # a reception time from the future (clocks adjusted) waited 0 s
    assert reception_stamp_ns(10_000, 9_000, 50_000, sim_time=True) == 50_000
    # no reception time: the node clock
    assert reception_stamp_ns(0, 9_000, 50_000, sim_time=False) == 50_000


@pytest.mark.parametrize(("params", "match"), [
    ({"topics": ["/ok", "not a topic"]}, "Parameter 'topics' holds 'not a topic'"),
    ({"topics": ["/a"], "topic_types": ["/a:std_msgs/msg/String"]},
     "Parameter 'topic_types' = .* should look like '/topic=pkg/msg/Type'"),
    ({"topics": ["/a"], "topic_types": ["bad name=std_msgs/msg/String"]},
     "Parameter 'topic_types' holds 'bad name'"),
    ({"topics": ["/a"], "storage": "parquet"}, "Parameter 'storage' = 'parquet' is invalid"),
])
def test_bad_parameters_fail_construction_with_the_parameter_named(node, tmp_path, params, match):
    from tactile_sensor.nodes.parameters import ParameterError

    with pytest.raises(ParameterError, match=match):
        make_recorder(node, path=str(tmp_path / "bag"), **params)
    assert not (tmp_path / "bag").exists()


def test_uninstalled_type_fails_construction_and_leaves_no_folder(node, tmp_path):
    from tactile_sensor.recording import RecordingError

    with pytest.raises(RecordingError, match="no_such_pkg/msg/Thing is not installed here"):
        make_recorder(node, path=str(tmp_path / "bag"), topics=["/a"],
                      topic_types=["/a=no_such_pkg/msg/Thing"])
    assert not (tmp_path / "bag").exists()
