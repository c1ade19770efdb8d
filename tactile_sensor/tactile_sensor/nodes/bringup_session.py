"""What a protocol needs of the running in-process bringup (``bringup_runner``): the
runner's view, the one way a protocol speaks, and an action call that gives up when the
bringup stops. The bench, grasp and lift protocols share them."""

from __future__ import annotations

import sys
import threading
from typing import Any, Protocol

from rclpy.action import ActionClient


class RunningBringup(Protocol):
    """What a protocol needs of the running bringup (``bringup_runner.BringupRunner``)."""

    nodes: dict[str, Any]
    protocol: dict[str, Any]
    configuration: Any
    use_mock: bool

    def wait(self, seconds: float) -> bool: ...

    @property
    def stopped(self) -> bool: ...

    def now(self) -> float: ...


def say(message: str) -> None:
    print(f"[bringup] {message}", file=sys.stderr, flush=True)


def call_action(runner: RunningBringup, client: ActionClient, goal: Any, timeout_s: float) -> Any:
    done = threading.Event()
    box: dict[str, Any] = {}

    def on_result(future: Any) -> None:
        box["result"] = future.result().result
        done.set()

    def on_goal(future: Any) -> None:
        handle = future.result()
        if not handle.accepted:
            box["rejected"] = True
            done.set()
            return
        handle.get_result_async().add_done_callback(on_result)

    client.send_goal_async(goal).add_done_callback(on_goal)
    deadline = runner.now() + timeout_s
    while not done.is_set():
        if runner.stopped or runner.now() > deadline:
            say("no action result in time" if not runner.stopped else "stopped")
            return None
        done.wait(0.05)
    if box.get("rejected"):
        say("the goal was rejected")
        return None
    return box["result"]
