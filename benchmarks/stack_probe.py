"""The stack benchmark's client in this process, through the stack's public interface only:
/diagnostics, the driver's ``~/wrench`` (its age as this process receives it), the mock's
ground truth and the gripper's Grasp and Release actions.

The wrench subscription has its own node and single-threaded executor, so the action
client and the 200 Hz ground truth do not queue in front of it; each callback takes every
message already waiting (one executor round per message would measure rclpy's executor at
250-1000 Hz, not the driver). It exists only while ages are wanted, so that an idle window
measures the stack without an extra subscriber.
"""

from __future__ import annotations

import math
import struct
import threading
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
from grasp_hold import HOLD_AFTER_S, TOUCH_N, Grasp
from rclpy.executors import SingleThreadedExecutor

from tactile_sensor.nodes.action_client import RaceFreeActionClient
from tactile_sensor.nodes.background_spin import BackgroundSpin
from tactile_sensor_interfaces.action import Grasp as GraspAction
from tactile_sensor_interfaces.action import Release

DRIVER_DIAG = "/driver: tactile ADC"
GRIPPER_DIAG = "/gripper: XM430"
#: The most one goal may take here (the node's own timeout is 10 s) [s].
GOAL_WAIT_S = 40.0
#: The most the ground truth may lag behind a goal's answer [s].
TRUTH_WAIT_S = 30.0


@dataclass
class Report:
    t: float  # time.time() of receipt [s]
    level: int
    message: str
    values: dict[str, str]


def _stamp_ns(cdr: bytes) -> int:
    """header.stamp of a serialized stamped message (after the 4-byte CDR header)."""
    sec, nanosec = struct.unpack_from("<iI", cdr, 4)
    return sec * 1_000_000_000 + nanosec


class Ages:
    """``/driver/wrench`` received here: (receipt [ns], stamp [ns], middleware receipt [ns])
    for every message while it exists."""

    def __init__(self) -> None:
        self.node = rclpy.create_node("bench_stack_ages")
        self.rows: list[tuple[int, int, int]] = []
        self.lock = threading.Lock()
        self.sub = self.node.create_subscription(WrenchStamped, "/driver/wrench",
                                                 self._on_wrench, 1000, raw=True)
        executor = SingleThreadedExecutor()
        executor.add_node(self.node)
        self.spin = BackgroundSpin(executor)

    def _record(self, cdr: bytes, info: dict) -> None:  # type: ignore[type-arg]
        now = time.time_ns()
        with self.lock:
            self.rows.append((now, _stamp_ns(cdr), int(info["received_timestamp"])))

    def _on_wrench(self, cdr: bytes, info: dict) -> None:  # type: ignore[type-arg]
        self._record(cdr, info)
        with self.sub.handle:
            for _ in range(256):
                item = self.sub.handle.take_message(WrenchStamped, True)
                if item is None:
                    break
                self._record(*item)

    def between(self, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(receipt [s], age [s], middleware age [s]) of the messages received in [t0, t1)."""
        with self.lock:
            rows = np.array(self.rows, dtype=np.int64).reshape(-1, 3)
        t = rows[:, 0] * 1e-9
        keep = (t >= t0) & (t < t1)
        rows = rows[keep]
        return t[keep], (rows[:, 0] - rows[:, 1]) * 1e-9, (rows[:, 2] - rows[:, 1]) * 1e-9

    def close(self) -> None:
        self.spin.stop()
        self.node.destroy_node()


class Probe:
    """Diagnostics, the ground truth and the gripper's actions."""

    def __init__(self) -> None:
        self.node = rclpy.create_node("bench_stack_probe")
        self.lock = threading.Lock()
        self.reports: dict[str, list[Report]] = {}
        self.truth: list[tuple[float, float]] = []  # (stamp [s], finger A force [N])
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self._on_diag, 100)
        self._truth_sub: Any = None
        self.grasp = RaceFreeActionClient(self.node, GraspAction, "/gripper/grasp")
        self.release = RaceFreeActionClient(self.node, Release, "/gripper/release")
        executor = SingleThreadedExecutor()
        executor.add_node(self.node)
        self.spin = BackgroundSpin(executor)

    def _on_diag(self, msg: DiagnosticArray) -> None:
        now = time.time()
        with self.lock:
            for s in msg.status:
                level = s.level if isinstance(s.level, int) else int.from_bytes(s.level,
                                                                                 "little")
                self.reports.setdefault(s.name, []).append(
                    Report(now, level, s.message, {kv.key: kv.value for kv in s.values}))

    def _on_truth(self, msg: WrenchStamped) -> None:
        with self.lock:
            self.truth.append((msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9,
                               msg.wrench.force.z))

    def watch_truth(self) -> None:
        if self._truth_sub is None:
            self._truth_sub = self.node.create_subscription(
                WrenchStamped, "/gripper_world/ground_truth", self._on_truth, 1000)

    def last(self, name: str) -> Report | None:
        with self.lock:
            history = self.reports.get(name)
            return history[-1] if history else None

    def ready(self) -> bool:
        """The driver streams (tared, calibrated) and the servo answers. Streaming is judged
        on the frames it takes: its readings go out only while someone listens."""
        driver, gripper = self.last(DRIVER_DIAG), self.last(GRIPPER_DIAG)
        return (driver is not None and driver.level == 0
                and int(driver.values.get("frames", "0")) > 0
                and gripper is not None and gripper.level == 0
                and self.grasp.server_is_ready() and self.release.server_is_ready())

    def driver_value(self, key: str) -> int | None:
        report = self.last(DRIVER_DIAG)
        if report is None:
            return None
        try:
            return int(report.values.get(key, ""))
        except ValueError:
            return None

    def call(self, client: Any, goal: Any) -> Any:
        """A goal's result, or None when it was refused or took longer than GOAL_WAIT_S."""
        sent = client.send_goal_async(goal)
        deadline = time.monotonic() + GOAL_WAIT_S
        while not sent.done() and time.monotonic() < deadline:
            time.sleep(0.01)
        if not sent.done() or not sent.result().accepted:
            return None
        result = sent.result().get_result_async()
        while not result.done() and time.monotonic() < deadline:
            time.sleep(0.01)
        return result.result().result if result.done() else None

    def open(self) -> bool:
        done = self.call(self.release, Release.Goal(opening=0.0))
        return done is not None and bool(done.success)

    def grasp_once(self, target_n: float) -> Grasp:
        """Open, then grasp; judged on the mock's ground truth as grasp_hold judges it: the
        true force HOLD_AFTER_S after the first touch (NaN without one)."""
        if not self.open():
            return Grasp(math.nan, math.nan, False, "release failed")
        time.sleep(0.3)
        sent = time.time()
        result = self.call(self.grasp, GraspAction.Goal(target_force=target_n))
        answered = time.time()
        message = "no result" if result is None else result.message
        # The ground truth arrives late on a busy machine (seconds beside the busy loops):
        # judge once it has caught up with the answer, and with the instant judged.
        truth: list[tuple[float, float]] = []
        touch = None
        deadline = time.monotonic() + TRUTH_WAIT_S
        while time.monotonic() < deadline:
            with self.lock:
                truth = [(t, f) for t, f in self.truth if t >= sent]
            if touch is None:
                touch = next((t for t, f in truth if f > TOUCH_N), None)
            newest = truth[-1][0] if truth else -math.inf
            if newest >= (answered if touch is None else max(answered, touch + HOLD_AFTER_S)):
                break
            time.sleep(0.05)
        peak = max((f for _, f in truth), default=math.nan)
        if touch is None or not truth or truth[-1][0] < touch + HOLD_AFTER_S:
            return Grasp(peak, math.nan, False, message)
        times, forces = np.array(truth).T
        held = float(np.interp(touch + HOLD_AFTER_S, times, forces))
        at_answer = float(np.interp(answered, times, forces)) if times[-1] >= answered else (
            math.nan)
        return Grasp(peak, held, "settled at" in message, message, at_answer)

    def close(self) -> None:
        self.spin.stop()
        self.grasp.destroy()
        self.release.destroy()
        self.node.destroy_node()
