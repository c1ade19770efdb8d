"""``tactile-sensor grasp | release | tare | self-check``: drive a running gripper by hand.

The wheels path has no ``ros2 action``, and a newcomer's first grasp should not need its
YAML: these talk to the nodes a ``tactile-sensor bringup gripper --protocol idle`` (or a
``ros2 launch``) runs, in this shell's ROS domain, through the same actions and service a
manipulation stack uses. Each prints the goal's feedback a few times a second, then its
result and the reason it ended; a refused goal prints the gripper's reason. Ctrl-C during a
goal cancels it (the fingers stop where they are). Exit status: 0 done, 1 not done (aborted,
canceled, refused, nothing answering), 2 a bad argument.
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

#: How long a command waits for the gripper or the driver to answer before saying so [s].
FIND_TIMEOUT_S = 3.0
#: Feedback lines per second at most.
FEEDBACK_RATE_HZ = 4.0


class HandCommandError(Exception):
    """A bad argument or nothing answering; the message says which and what to do."""


def _positive(what: str, unit: str, allow_zero: bool = False) -> Callable[[str], float]:
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{what} must be a number of {unit}, got "
                                             f"{text!r}") from None
        if not math.isfinite(value) or value < 0 or (value == 0 and not allow_zero):
            bound = ">= 0" if allow_zero else "> 0"
            raise argparse.ArgumentTypeError(f"{what} must be a finite number {bound} "
                                             f"{unit}, got {text!r}")
        return value
    return parse


def parse_args(command: str, argv: Sequence[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog=f"tactile-sensor {command}",
                                     description=_DESCRIPTIONS[command])
    if command == "grasp":
        parser.add_argument("force", type=_positive("the target force", "N"),
                            help="tactile force to grasp with [N], e.g. 1.5")
        parser.add_argument("--speed", type=_positive("--speed", "m/s", allow_zero=True),
                            default=0.0, help="closing speed [m/s] (default: the gripper's)")
        parser.add_argument("--timeout", type=_positive("--timeout", "s", allow_zero=True),
                            default=0.0, help="give up after this long [s] (default: the "
                            "gripper's)")
        parser.add_argument("--hold", choices=("fixed", "adaptive"), default="",
                            help="hold mode (default: the gripper's hold_mode)")
    elif command == "release":
        parser.add_argument("--opening", type=_positive("--opening", "m", allow_zero=True),
                            default=0.0, help="opening to reach [m] (default: fully open)")
    elif command == "self-check":
        parser.add_argument("--apply", action="store_true",
                            help="latch the fitted correction for the driver")
    parser.add_argument("--namespace", default="", help="ROS namespace of the nodes")
    return parser.parse_args(list(argv))


_DESCRIPTIONS = {
    "grasp": "Close the running gripper until its fingertip feels FORCE, then hold it.",
    "release": "Open the running gripper.",
    "tare": "Tare the running driver (the skin must be at rest).",
    "self-check": "Close slowly on the rod and fit the module's optical gain and the "
                  "skin's stiffness against the model.",
}


def _name(namespace: str, node: str, entity: str) -> str:
    ns = namespace.strip("/")
    return f"/{ns}/{node}/{entity}" if ns else f"/{node}/{entity}"


def _say(text: str) -> None:
    print(text, flush=True)


def _nobody(what: str, name: str) -> HandCommandError:
    import os

    domain = os.environ.get("ROS_DOMAIN_ID", "0")
    return HandCommandError(
        f"no {what} answers on {name} in ROS domain {domain} within {FIND_TIMEOUT_S:g} s: "
        "start one (tactile-sensor bringup gripper --protocol idle) in a shell with the "
        "same ROS_DOMAIN_ID, or give its --namespace.")


def _feedback_printer(describe: Callable[[Any], str]) -> Callable[[Any], None]:
    last = [-math.inf]

    def on_feedback(message: Any) -> None:
        now = time.monotonic()
        if now - last[0] >= 1.0 / FEEDBACK_RATE_HZ:
            last[0] = now
            _say("  " + describe(message.feedback))
    return on_feedback


def run_goal(node: Any, action_type: Any, name: str, goal: Any,
             describe_feedback: Callable[[Any], str],
             describe_result: Callable[[Any], tuple[bool, str]]) -> int:
    """Send ``goal``, print its feedback and result; Ctrl-C cancels it."""
    from tactile_sensor.nodes.action_client import RaceFreeActionClient

    client = RaceFreeActionClient(node, action_type, name)
    if not client.wait_for_server(timeout_sec=FIND_TIMEOUT_S):
        raise _nobody("gripper", name)
    sent = client.send_goal_async(goal, feedback_callback=_feedback_printer(describe_feedback))
    handle = _wait(sent, "the goal's answer")
    if not handle.accepted:
        _say(f"refused: the gripper rejected the goal (its log says why: {name})")
        return 1
    result_future = handle.get_result_async()
    try:
        answer = _wait(result_future, "the result")
    except KeyboardInterrupt:
        _say("canceling (Ctrl-C) ...")
        _wait(handle.cancel_goal_async(), "the cancel")
        answer = _wait(result_future, "the result")
    from action_msgs.msg import GoalStatus

    if answer.status == GoalStatus.STATUS_ABORTED and _refused(answer.result):
        _say(f"refused: {answer.result.message}")
        return 1
    done, text = describe_result(answer.result)
    status = {GoalStatus.STATUS_SUCCEEDED: "succeeded", GoalStatus.STATUS_ABORTED: "aborted",
              GoalStatus.STATUS_CANCELED: "canceled"}.get(answer.status, str(answer.status))
    _say(f"{status}: {text}")
    return 0 if done and answer.status == GoalStatus.STATUS_SUCCEEDED else 1


def _refused(result: Any) -> bool:
    """The gripper accepts every goal and aborts one it cannot run at once, with the reason
    in the result's message and NaN for what it never measured (nodes/gripper.py)."""
    measured = getattr(result, "opening", getattr(result, "optical_gain", 0.0))
    return hasattr(result, "message") and math.isnan(measured)


def _wait(future: Any, what: str, timeout_s: float = math.inf) -> Any:
    """The future's result, spun by the background executor; Ctrl-C reaches the caller."""
    done = threading.Event()
    future.add_done_callback(lambda _: done.set())
    deadline = time.monotonic() + timeout_s
    while not done.wait(0.1):
        if time.monotonic() > deadline:
            raise HandCommandError(f"no answer with {what} within {timeout_s:g} s.")
    return future.result()


def _grasp(node: Any, options: argparse.Namespace) -> int:
    from tactile_sensor_interfaces.action import Grasp

    goal = Grasp.Goal(target_force=options.force, closing_speed=options.speed,
                      timeout=options.timeout, hold_mode=options.hold)
    _say(f"grasp: {options.force:g} N")
    return run_goal(
        node, Grasp, _name(options.namespace, "gripper", "grasp"), goal,
        lambda f: f"force {f.force:6.3f} N, opening {f.opening * 1e3:6.2f} mm",
        lambda r: (r.contact_detected, f"{'contact' if r.contact_detected else 'no contact'}"
                   f", force {r.force:.3f} N, opening {r.opening * 1e3:.2f} mm ({r.message})"))


def _release(node: Any, options: argparse.Namespace) -> int:
    from tactile_sensor_interfaces.action import Release

    _say("release")
    return run_goal(
        node, Release, _name(options.namespace, "gripper", "release"),
        Release.Goal(opening=options.opening),
        lambda f: f"opening {f.opening * 1e3:6.2f} mm",
        lambda r: (r.success, f"opening {r.opening * 1e3:.2f} mm ({r.message})"))


def _self_check(node: Any, options: argparse.Namespace) -> int:
    from tactile_sensor_interfaces.action import SelfCheck

    _say("self-check: closing slowly on the rod")
    return run_goal(
        node, SelfCheck, _name(options.namespace, "gripper", "self_check"),
        SelfCheck.Goal(apply=options.apply),
        lambda f: f"opening {f.opening * 1e3:6.2f} mm",
        lambda r: (r.outcome == "fitted",
                   f"{r.outcome}: optical gain {r.optical_gain:.3f} ± {r.optical_gain_sigma:.3f}"
                   f", stiffness {r.stiffness:.3f} ± {r.stiffness_sigma:.3f}, "
                   f"{'applied' if r.applied else 'not applied'} ({r.message})"))


def _tare(node: Any, options: argparse.Namespace) -> int:
    from std_srvs.srv import Trigger

    name = _name(options.namespace, "driver", "tare")
    client = node.create_client(Trigger, name)
    if not client.wait_for_service(timeout_sec=FIND_TIMEOUT_S):
        raise _nobody("driver", name)
    response = _wait(client.call_async(Trigger.Request()), "the tare", 30.0)
    _say(("tared: " if response.success else "refused: ") + response.message)
    return 0 if response.success else 1


_COMMANDS: dict[str, Callable[[Any, argparse.Namespace], int]] = {
    "grasp": _grasp, "release": _release, "tare": _tare, "self-check": _self_check}


def run(command: str, argv: Sequence[str]) -> int:
    options = parse_args(command, argv)
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    from tactile_sensor.nodes.background_spin import BackgroundSpin
    from tactile_sensor.nodes.ros_session import ros_session

    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with ros_session(signal_handler_options=SignalHandlerOptions.NO):
            node = rclpy.create_node(f"tactile_sensor_{command.replace('-', '_')}_command")
            executor = SingleThreadedExecutor()
            executor.add_node(node)
            spin = BackgroundSpin(executor)
            try:
                return _COMMANDS[command](node, options)
            except HandCommandError as exc:
                print(f"tactile-sensor {command}: {exc}", file=sys.stderr)
                return 1
            finally:
                spin.stop()
                node.destroy_node()
    except KeyboardInterrupt:
        print(f"tactile-sensor {command}: interrupted", file=sys.stderr)
        return 1
    finally:
        signal.signal(signal.SIGINT, previous)


def grasp(argv: Sequence[str]) -> int:
    return run("grasp", argv)


def release(argv: Sequence[str]) -> int:
    return run("release", argv)


def tare(argv: Sequence[str]) -> int:
    return run("tare", argv)


def self_check(argv: Sequence[str]) -> int:
    return run("self-check", argv)
