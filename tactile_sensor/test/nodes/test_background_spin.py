"""Stopping an executor's spin waits for the callback still running and takes its outcome.

rclpy's ``Executor.shutdown`` does not wait for the pool's callbacks, so one still running
when a node's entities were destroyed failed, and its task printed "The following
exception was never retrieved" when collected (seen at the end of a bringup).
"""

from __future__ import annotations

import gc
import threading
import time

import pytest

rclpy = pytest.importorskip("rclpy")

from rclpy.executors import MultiThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402

from tactile_sensor.nodes.background_spin import BackgroundSpin  # noqa: E402

pytestmark = [pytest.mark.ros]

PATIENCE_S = 30.0
BUSY_S = 0.3  # how long the callback still runs after stop() was asked


def test_stop_waits_for_the_running_callback_and_takes_its_failure(ros_domain, capfd):
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = Node("settle_probe", context=context)
        executor = MultiThreadedExecutor(num_threads=2, context=context)
        executor.add_node(node)
        started = threading.Event()

        def late_failure() -> None:
            started.set()
            time.sleep(BUSY_S)
            raise RuntimeError("failed while the spin was being stopped")

        timer = node.create_timer(0.01, late_failure)
        spin = BackgroundSpin(executor)
        assert started.wait(PATIENCE_S)
        # the spin thread files the task it dispatched just after the pool started it
        deadline = time.monotonic() + PATIENCE_S
        while not executor._futures and time.monotonic() < deadline:
            time.sleep(0.001)
        tasks = list(executor._futures)  # the dispatched callbacks (both distributions)
        assert tasks and not tasks[0].done(), "the callback should still be running"
        spin.stop()
        assert all(task.done() for task in tasks), "stop() returned while a callback ran"
        node.destroy_timer(timer)
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
    del tasks, spin, executor
    gc.collect()
    assert "never retrieved" not in capfd.readouterr().err
