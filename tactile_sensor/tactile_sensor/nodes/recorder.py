"""Recorder node: chosen topics into a rosbag2 folder (MCAP by default), losing nothing.

The node is the ROS half of :mod:`tactile_sensor.recording`: it learns each requested
topic's type and offered QoS from the graph, subscribes raw (serialized CDR goes into the
bag untouched), stamps each message with its reception time from the middleware, and on
shutdown takes whatever is still waiting in the subscriptions before closing the bag.

The subscriptions are drained on a timer rather than by the executor: an executor wakes
once per message (four topics at 1 kHz are four thousand wake-ups a second, each rebuilding
the wait set of every node it spins), while a drain takes all that the middleware queued
for every topic in one callback. The queues are deep enough for seconds of traffic, and
each message keeps the reception time the middleware stamped on it.

Run: ``python -m tactile_sensor.nodes.recorder --ros-args -p path:=run1
-p topics:="['/driver/wrench', '/driver/reading']"``
"""

from __future__ import annotations

import contextlib
import importlib
import json
import shutil
import sys
import time
from pathlib import Path
from typing import Any

from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.exceptions import InvalidHandle, InvalidTopicNameException
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
)
from rclpy.subscription import Subscription
from rclpy.topic_endpoint_info import TopicEndpointInfo

from tactile_sensor.nodes.lifecycle_main import run_plain_node
from tactile_sensor.nodes.parameters import (
    ParameterError,
    ParamSpec,
    declare_parameters,
    read_parameters,
)
from tactile_sensor.recording import STORAGES, BagRecorder, RecordingError
from tactile_sensor.recording.rosbag2_writer import WriterOptions

QUEUE_DEPTH = 10_000  # messages the middleware may hold per topic between two drains
DISCOVERY_PERIOD_S = 0.2
PROGRESS_PERIOD_S = 10.0
DRAIN_PERIOD_S = 0.02  # how often every subscription's queue is taken into the bag


def _check_topics(value: list[Any]) -> str | None:
    if not value:
        return "give at least one topic, e.g. \"['/driver/wrench']\"."
    if not all(isinstance(t, str) and t.strip() for t in value):
        return "expected a list of non-empty topic names."
    return None


def parse_topic_type(entry: str) -> tuple[str, str]:
    """``'/topic=pkg/msg/Type'`` -> ``('/topic', 'pkg/msg/Type')``; ValueError when malformed."""
    topic, sep, msgtype = entry.partition("=")
    parts = msgtype.strip().split("/")
    if not sep or not topic.strip() or len(parts) not in (2, 3) or not all(parts):
        raise ValueError(entry)
    if len(parts) == 2:
        parts.insert(1, "msg")
    return topic.strip(), "/".join(parts)


def _check_topic_types(value: list[Any]) -> str | None:
    for entry in value:
        try:
            parse_topic_type(entry)
        except (ValueError, AttributeError):
            return f"entry {entry!r} should look like '/topic=pkg/msg/Type'."
    return None


PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec("path", "", "Bag folder to create (must not exist); empty = "
              "recorder_<YYYYmmdd_HHMMSS> in the working directory."),
    ParamSpec("topics", [], "Topics to record (string list).", check=_check_topics),
    ParamSpec("storage", "mcap", "rosbag2 storage plugin.", choices=tuple(STORAGES)),
    ParamSpec("max_bag_duration", 0.0, "Start a new storage file (<bag>_1.mcap, ...) once a "
              "file spans this many seconds of messages [s]; 0 = never (rosbag2's "
              "--max-bag-duration).", minimum=0.0),
    ParamSpec("max_bag_size", 0, "Start a new storage file once a file reaches this size "
              "[bytes]; 0 = never (rosbag2's --max-bag-size).", minimum=0),
    ParamSpec("topic_types", [], "Optional '/topic=pkg/msg/Type' entries: subscribe to these "
              "at once (reliable, volatile) instead of waiting for a publisher to appear.",
              check=_check_topic_types),
)


def _duration(d: Any) -> dict[str, int]:
    sec, nsec = divmod(int(d.nanoseconds), 1_000_000_000)
    return {"sec": sec, "nsec": nsec}


def offered_qos_yaml(profiles: list[QoSProfile]) -> str:
    """Publishers' QoS in rosbag2's offered_qos_profiles form (JSON is valid YAML)."""
    return json.dumps([
        {
            "history": p.history.name.lower(),
            "depth": p.depth,
            "reliability": p.reliability.name.lower(),
            "durability": p.durability.name.lower(),
            "deadline": _duration(p.deadline),
            "lifespan": _duration(p.lifespan),
            "liveliness": p.liveliness.name.lower(),
            "liveliness_lease_duration": _duration(p.liveliness_lease_duration),
            "avoid_ros_namespace_conventions": p.avoid_ros_namespace_conventions,
        }
        for p in profiles
    ])


def subscription_qos(publishers: list[TopicEndpointInfo]) -> QoSProfile:
    """Deep reliable queue, downgraded only where a publisher would not match otherwise.

    Reliable unless some publisher is best-effort; transient-local (to receive latched
    samples such as a calibration curve) when every publisher offers it.
    """
    offered = [p.qos_profile for p in publishers]
    reliable = all(q.reliability == ReliabilityPolicy.RELIABLE for q in offered)
    latched = bool(offered) and all(
        q.durability == DurabilityPolicy.TRANSIENT_LOCAL for q in offered)
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=QUEUE_DEPTH,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
    )


def message_class(msgtype: str) -> type:
    """The generated Python class for ``pkg/msg/Type``; ImportError/AttributeError if absent."""
    package, kind, name = msgtype.split("/")
    return getattr(importlib.import_module(f"{package}.{kind}"), name)


class DrainedGroup(ReentrantCallbackGroup):
    """Keeps its subscriptions out of every executor's wait set, so that no message wakes
    an executor; the recorder's drain timer takes them."""

    def can_execute(self, entity: Any) -> bool:
        return False


def reception_stamp_ns(received_ns: int, system_now_ns: int, node_now_ns: int,
                       sim_time: bool) -> int:
    """A message's bag time: its reception time from the middleware (system clock); under
    sim time, the node clock at the drain less the time the message waited in the queue;
    the node clock when the middleware gave no reception time."""
    if not received_ns:
        return node_now_ns
    if not sim_time:
        return received_ns
    return node_now_ns - max(0, system_now_ns - received_ns)


def _never_called(*_args: Any) -> None:
    """A drained subscription's callback: the executor never waits on it (DrainedGroup)."""


class RecorderNode(Node):
    """Records ``topics`` into the bag at ``path``; the bag is complete after destroy_node()."""

    def __init__(self, node_name: str = "recorder", **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self._bag: BagRecorder | None = None
        self._subscriptions_by_topic: dict[str, Subscription[Any]] = {}
        self._drained = DrainedGroup()
        declare_parameters(self, PARAMETERS)
        params = read_parameters(self, PARAMETERS)
        self._pending = {self._resolve("topics", t) for t in params["topics"]}
        topic_types = [parse_topic_type(entry) for entry in params["topic_types"]]
        topic_types = [(self._resolve("topic_types", t), m) for t, m in topic_types]
        path = params["path"] or time.strftime("recorder_%Y%m%d_%H%M%S")
        self._bag = BagRecorder(
            Path(path), params["storage"], custom_data={"recorder": "tactile_sensor.recorder"},
            options=WriterOptions(max_bag_duration_s=params["max_bag_duration"],
                                  max_bag_size_bytes=params["max_bag_size"]))
        #: One line saying what a failed recording kept, None while recording works.
        self.failure: str | None = None
        self._bag.open()
        self.path = self._bag.path
        self._last_total = 0
        try:
            for topic, msgtype in topic_types:
                self._pending.add(topic)
                self._subscribe(topic, msgtype, [])
        except RecordingError:
            # The folder is ours (BagRecorder refuses existing paths) and holds nothing yet;
            # remove it so the same command works once the cause is fixed.
            bag, self._bag = self._bag, None
            bag.close()
            shutil.rmtree(bag.path, ignore_errors=True)
            raise
        self.get_logger().info(
            f"Recording to {self.path} ({params['storage']}); waiting for "
            f"{', '.join(sorted(self._pending - set(self._subscriptions_by_topic))) or 'nothing'}")
        self._discovery = self.create_timer(DISCOVERY_PERIOD_S, self._discover)
        self._progress = self.create_timer(PROGRESS_PERIOD_S, self._report_progress)
        self._drain_timer = self.create_timer(DRAIN_PERIOD_S, self._drain)
        self._discover()

    def _resolve(self, parameter: str, topic: str) -> str:
        try:
            return self.resolve_topic_name(topic.strip())
        except (InvalidTopicNameException, RuntimeError):
            raise ParameterError(
                f"Parameter '{parameter}' holds {topic!r}, which is not a valid topic name; "
                "use names like '/driver/wrench'.") from None

    @property
    def counts(self) -> dict[str, int]:
        """Messages written to the bag so far, per topic."""
        return self._bag.counts if self._bag is not None else {}

    @property
    def pending(self) -> int:
        """Messages taken from the middleware but not yet written to storage."""
        return self._bag.pending if self._bag is not None else 0

    def _discover(self) -> None:
        """Subscribe to every requested topic that now has a publisher (and so a type)."""
        waiting = self._pending - set(self._subscriptions_by_topic)
        if not waiting:
            self._discovery.cancel()
            return
        types = dict(self.get_topic_names_and_types())
        for topic in sorted(waiting):
            publishers = self.get_publishers_info_by_topic(topic)
            if topic not in types or not publishers:
                continue
            msgtypes = sorted({p.topic_type for p in publishers})
            if len(msgtypes) > 1:
                self.get_logger().warning(
                    f"{topic} is published with several types {msgtypes}; recording "
                    f"{msgtypes[0]} only.")
            try:
                self._subscribe(topic, msgtypes[0], publishers)
            except RecordingError as exc:
                self.get_logger().error(str(exc))
                self._pending.discard(topic)

    def _subscribe(self, topic: str, msgtype: str, publishers: list[TopicEndpointInfo]) -> None:
        """Add the topic to the bag and subscribe raw; RecordingError when it cannot be."""
        assert self._bag is not None
        try:
            cls = message_class(msgtype)
        except (ImportError, AttributeError, ValueError):
            raise RecordingError(
                f"Cannot record {topic}: message type {msgtype} is not installed here; "
                "source the workspace that defines it and restart the recorder.") from None
        self._bag.add_topic(topic, msgtype, offered_qos_yaml([p.qos_profile for p in publishers]))
        qos = subscription_qos(publishers) if publishers else QoSProfile(
            depth=QUEUE_DEPTH, reliability=ReliabilityPolicy.RELIABLE)
        self._subscriptions_by_topic[topic] = self.create_subscription(
            cls, topic, _never_called, qos, raw=True, callback_group=self._drained,
            # No QoS event handlers: attached to a wait set, they wake it on every message
            # (Fast DDS), which is what the drain avoids. The QoS is the publishers' own.
            event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False))
        self.get_logger().info(
            f"Recording {topic} [{msgtype}] ({qos.reliability.name.lower()}, "
            f"{qos.durability.name.lower()})")

    def _drain(self) -> None:
        bag = self._bag
        if bag is None:
            return
        try:
            for topic, sub in list(self._subscriptions_by_topic.items()):
                self._take(bag, topic, sub, QUEUE_DEPTH)
        except RecordingError as exc:
            # A storage failure (disk full, folder removed) ends this recording but not the
            # node: say so once, drop further messages.
            self._bag = None
            self.get_logger().error(str(exc))
            with contextlib.suppress(RecordingError):
                bag.close()  # keep whatever part of the bag the storage still accepts
            self._record_failure(bag)

    def _record_failure(self, bag: BagRecorder) -> None:
        after = bag.failed_after_s
        when = f" at {after:.1f} s" if after is not None else ""
        self.failure = (f"recording failed{when}: {bag.kept:,} messages kept in {bag.path} "
                        "(read them with 'tactile-sensor bag recover')")

    def _take(self, bag: BagRecorder, topic: str, sub: Subscription[Any], limit: int) -> int:
        """Write up to ``limit`` messages the middleware holds for ``sub``; returns how many."""
        taken = 0
        system_now = time.time_ns()
        node_now = self.get_clock().now().nanoseconds
        sim_time = self.get_clock().ros_time_is_active
        with sub.handle:
            while taken < limit:
                item = sub.handle.take_message(sub.msg_type, True)
                if item is None:
                    break
                cdr, info = item
                stamp = reception_stamp_ns(int(info.get("received_timestamp", 0)),
                                           system_now, node_now, sim_time)
                bag.write(topic, stamp, cdr)
                taken += 1
        return taken

    def _report_progress(self) -> None:
        if self._bag is None:
            return  # stopped, or failed (said once, with what was kept)
        counts = self.counts
        total = sum(counts.values())
        if total != self._last_total:
            self._last_total = total
            detail = ", ".join(f"{t}: {n}" for t, n in sorted(counts.items()))
            self.get_logger().info(f"Recorded {total} messages ({detail})")

    def _take_waiting(self, bag: BagRecorder) -> int:
        """Take what the middleware still holds for us, so a shutdown loses no message."""
        return sum(self._take(bag, topic, sub, sys.maxsize)
                   for topic, sub in self._subscriptions_by_topic.items())

    def close_bag(self) -> None:
        """Finish the bag (metadata included); later messages are not recorded."""
        bag = self._bag
        if bag is None:
            return
        try:
            taken = self._take_waiting(bag)
        except (InvalidHandle, _rclpy.RCLError) as exc:
            taken = 0
            self.get_logger().warning(f"Could not take the last queued messages: {exc}")
        self._bag = None
        try:
            bag.close()
        except RecordingError as exc:
            self.get_logger().error(str(exc))
            self._record_failure(bag)
            return
        counts = bag.counts
        detail = ", ".join(f"{t}: {n}" for t, n in sorted(counts.items()))
        self.get_logger().info(
            f"Closed {bag.path} with {sum(counts.values())} messages ({detail}; "
            f"{taken} taken at shutdown)")

    def destroy_node(self) -> None:
        self.close_bag()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Record until Ctrl-C; a bad parameter or path prints one sentence and exits 1. The bag
    closes (last messages taken, index and metadata written, the count logged) while the
    context is valid; a second Ctrl-C cannot stop it."""
    return run_plain_node("recorder", RecorderNode, (ParameterError, RecordingError),
                          RecorderNode.close_bag, args)


if __name__ == "__main__":
    sys.exit(main())
