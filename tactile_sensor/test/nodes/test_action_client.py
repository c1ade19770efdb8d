"""A goal's answer that arrives before its future is filed still completes the future.

The race (ros2/rclpy#1123, Jazzy's rclpy 7.1.6) is made certain here: the client's handle
holds every request for a while after sending it, long enough for the server's answer to
arrive and for the executor thread to be woken by it.
"""

from __future__ import annotations

import threading
import time
from typing import Any

import pytest

rclpy = pytest.importorskip("rclpy")
pytest.importorskip("tactile_sensor_interfaces.action")

from rclpy.action import ActionServer  # noqa: E402
from rclpy.executors import MultiThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402

from tactile_sensor.nodes.action_client import RaceFreeActionClient  # noqa: E402
from tactile_sensor.nodes.background_spin import BackgroundSpin  # noqa: E402
from tactile_sensor_interfaces.action import Grasp  # noqa: E402

pytestmark = [pytest.mark.ros]

PATIENCE_S = 60.0
HELD_S = 0.3  # a request's sender pauses this long between sending and filing its future


class SlowFiling:
    """The client's rcl handle, pausing after each request it sends (and once it saw the
    answer ready, so the pause surely covers the answer's arrival)."""

    def __init__(self, handle: Any) -> None:
        self._handle = handle
        self.answered = threading.Event()

    def __getattr__(self, name: str) -> Any:
        attr = getattr(self._handle, name)
        if not name.startswith("send_"):
            return attr

        def send_then_pause(*args: Any) -> Any:
            sequence = attr(*args)
            time.sleep(HELD_S)
            return sequence

        return send_then_pause

    def __enter__(self) -> Any:
        return self._handle.__enter__()

    def __exit__(self, *exc: Any) -> Any:
        return self._handle.__exit__(*exc)


def answer_at_once(goal_handle: Any) -> Grasp.Result:
    goal_handle.succeed()
    return Grasp.Result(contact_detected=True, force=1.0, message="done")


def test_an_answer_before_the_future_is_filed_is_not_lost(ros_domain):
    context = rclpy.Context()
    rclpy.init(context=context)
    spin = None
    try:
        node = Node("race_probe", context=context)
        server = ActionServer(node, Grasp, "grasp", answer_at_once)
        client = RaceFreeActionClient(node, Grasp, "grasp")
        executor = MultiThreadedExecutor(num_threads=2, context=context)
        executor.add_node(node)
        spin = BackgroundSpin(executor)
        assert client.wait_for_server(timeout_sec=PATIENCE_S)
        client._client_handle = SlowFiling(client._client_handle)
        goal = client.send_goal_async(Grasp.Goal(target_force=1.0, closing_speed=0.01,
                                                 timeout=5.0))
        deadline = time.monotonic() + PATIENCE_S
        while not goal.done() and time.monotonic() < deadline:
            time.sleep(0.01)
        assert goal.done() and goal.result().accepted, "the goal's answer was lost"
        result = goal.result().get_result_async()
        while not result.done() and time.monotonic() < deadline:
            time.sleep(0.01)
        assert result.done() and result.result().result.message == "done"
        server.destroy()
        client.destroy()
    finally:
        if spin is not None:
            spin.stop()
        rclpy.try_shutdown(context=context)


def test_a_client_added_to_a_node_being_spun_is_ready_for_its_executor(ros_domain):
    """An executor spinning the node may take a new client up as soon as it is added to the
    node, before its constructor returns (Kilted's rclpy then lacked the lock its
    get_num_entities holds, and the spinning thread stopped). Made certain here: the node
    asks the client for its entities the moment it is added, as that executor would."""
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = Node("spun_probe", context=context)
        asked: list[object] = []
        add_waitable = node.add_waitable

        def add_then_ask(waitable: Any) -> None:
            add_waitable(waitable)
            asked.append(waitable.get_num_entities())

        node.add_waitable = add_then_ask  # type: ignore[method-assign]
        client = RaceFreeActionClient(node, Grasp, "grasp")
        assert len(asked) == 1
        client.destroy()
    finally:
        rclpy.try_shutdown(context=context)
