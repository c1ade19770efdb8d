"""The soak's eyes and hands in this process: diagnostics and calibrations as the nodes
report them, and the gripper's grasp and release actions in a loop."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from soak_processes import WAIT_S, wait_until

BENCH_NS, GRIPPER_NS = "/soak_bench", "/soak_gripper"
TEARDOWN_S = 20.0  # this process's own ROS teardown, after the figures are written
GRASP_FORCE_N = 2.0


@dataclass
class Report:
    t_s: float
    level: int
    message: str
    values: dict[str, str]


class Monitor:
    def __init__(self, t0: float) -> None:
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.executors import MultiThreadedExecutor
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

        from tactile_sensor.nodes.action_client import RaceFreeActionClient as ActionClient
        from tactile_sensor_interfaces.action import Grasp, Release
        from tactile_sensor_interfaces.msg import CalibrationCurve

        self.t0 = t0
        rclpy.init()
        self.node = rclpy.create_node("soak_monitor")
        self.lock = threading.Lock()
        self.reports: dict[str, list[Report]] = {}
        self.calibrations: list[float] = []
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                             reliability=ReliabilityPolicy.RELIABLE)
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self._on_diag, 100)
        self.node.create_subscription(CalibrationCurve, f"{BENCH_NS}/calibration_curve",
                                      self._on_calibration, latched)
        self.grasp = ActionClient(self.node, Grasp, f"{GRIPPER_NS}/gripper/grasp")
        self.release = ActionClient(self.node, Release, f"{GRIPPER_NS}/gripper/release")
        self.Grasp, self.Release = Grasp, Release
        self.executor = MultiThreadedExecutor(num_threads=2)
        self.executor.add_node(self.node)
        self.spinning = threading.Event()
        self.spinning.set()
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _spin(self) -> None:
        # spin_once in a loop, so close() can stop it before the node and context go (a
        # thread left in spin() when they do aborts the interpreter at exit)
        while self.spinning.is_set():
            self.executor.spin_once(timeout_sec=0.05)

    def now(self) -> float:
        return time.monotonic() - self.t0

    def _on_diag(self, msg: Any) -> None:
        t = self.now()
        with self.lock:
            for status in msg.status:
                self.reports.setdefault(status.name, []).append(Report(
                    t, int.from_bytes(status.level, "little") if isinstance(status.level, bytes)
                    else int(status.level), status.message,
                    {kv.key: kv.value for kv in status.values}))

    def _on_calibration(self, msg: Any) -> None:
        with self.lock:
            self.calibrations.append(self.now())

    def history(self, name: str) -> list[Report]:
        with self.lock:
            return list(self.reports.get(name, []))

    def first(self, name: str, after_s: float, test: Callable[[Report], bool],
              timeout_s: float = WAIT_S) -> Report | None:
        return wait_until(lambda: next((r for r in self.history(name)
                                        if r.t_s > after_s and test(r)), None), timeout_s)

    def call(self, client: Any, goal: Any, timeout_s: float) -> Any:
        """Send a goal and wait for its result; None when it was rejected or took too long."""
        if not client.wait_for_server(timeout_sec=timeout_s):
            return None
        sent = client.send_goal_async(goal)
        if not wait_until(sent.done, timeout_s) or not sent.result().accepted:
            return None
        result = sent.result().get_result_async()
        return result.result().result if wait_until(result.done, timeout_s) else None

    def close(self, timeout_s: float = TEARDOWN_S) -> bool:
        """Stop spinning and tear the node down; False when the teardown did not end in
        ``timeout_s``. On Kilted, Fast DDS 3.2 can deadlock destroying a publisher (its
        event thread and a receive thread each waiting on the other), which would hang the
        benchmark after its run; the caller then exits without waiting for it."""
        import rclpy

        def teardown() -> None:
            self.spinning.clear()
            self.thread.join(5.0)
            self.executor.shutdown(timeout_sec=2.0)
            self.grasp.destroy()  # destroy_node() leaves action clients to the collector
            self.release.destroy()
            self.node.destroy_node()
            rclpy.try_shutdown()

        worker = threading.Thread(target=teardown, daemon=True)
        worker.start()
        worker.join(timeout_s)
        return not worker.is_alive()


DRIVER_DIAG = f"{BENCH_NS}/driver: tactile ADC"
GRIPPER_DIAG = f"{GRIPPER_NS}/gripper: XM430"
GRIPPER_DRIVER_DIAG = f"{GRIPPER_NS}/driver: tactile ADC"


class GraspLoop:
    """Release, grasp the rod, again and again, through the gripper's actions."""

    def __init__(self, monitor: Monitor) -> None:
        self.monitor = monitor
        self.attempted = self.succeeded = 0
        self.outcomes: dict[str, int] = {}
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        m = self.monitor
        while not self.stop.is_set():
            m.call(m.release, m.Release.Goal(opening=0.0), 30.0)
            if self.stop.is_set():
                break
            result = m.call(m.grasp, m.Grasp.Goal(target_force=GRASP_FORCE_N), 30.0)
            self.attempted += 1
            # the outcome without its figures: "contact", "tactile_stale", ...
            outcome = ("no result" if result is None
                       else (result.message or "?").split(":")[0])
            self.outcomes[outcome] = self.outcomes.get(outcome, 0) + 1
            if result is not None and result.contact_detected:
                self.succeeded += 1
            else:
                self.stop.wait(0.5)  # e.g. a servo being rebooted: do not spin
