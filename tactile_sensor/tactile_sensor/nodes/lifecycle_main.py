"""``main()`` of a lifecycle node executable, with optional autostart and a clean exit.

Under ``ros2 launch`` the launch file drives the transitions; for ``ros2 run`` and tests,
``--ros-args -p autostart:=true`` configures and activates the node at start-up, and a
failed transition leaves it running (unconfigured) so it can be fixed with ``ros2 param``
and ``ros2 lifecycle set`` without a restart. On SIGINT/SIGTERM the node goes through its
shutdown transition (threads stopped, queued data published) before the context ends.
The nodes without a lifecycle (the mock rig, the recorder) exit the same way
(``run_plain_node``): their own stop runs before the context ends. Both return the exit
status for ``sys.exit``: 0 after SIGINT/SIGTERM, non-zero when the executor died
(``nodes/clean_exit.py``), so ``respawn`` and supervisors see a crash.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable
from typing import TypeVar

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.lifecycle import Node, TransitionCallbackReturn
from rclpy.node import Node as RclpyNode

from tactile_sensor.nodes.clean_exit import NO_RCLPY_SIGNAL_HANDLERS, spin_until_signal
from tactile_sensor.nodes.guarded_lifecycle import guard_parameter_services
from tactile_sensor.nodes.parameters import ParamSpec
from tactile_sensor.nodes.ros_session import ros_session

#: A node without a lifecycle (``run_plain_node``).
PlainNode = TypeVar("PlainNode", bound=RclpyNode)
#: Declared by every lifecycle node's executable (not by the node class, which a launch file
#: or the in-process bringup drives through its transitions).
AUTOSTART = ParamSpec("autostart", False, "configure and activate at start-up (for ros2 run)")


def declare_autostart(node: Node) -> bool:
    return bool(node.declare_parameter(
        AUTOSTART.name, AUTOSTART.default,
        ParameterDescriptor(description=AUTOSTART.description),
    ).value)


def autostart(node: Node) -> bool:
    """Configure then activate; False (with the reason already logged) when one fails."""
    if node.trigger_configure() != TransitionCallbackReturn.SUCCESS:
        node.get_logger().error("configure transition failed; node stays unconfigured")
        return False
    if node.trigger_activate() != TransitionCallbackReturn.SUCCESS:
        node.get_logger().error("activate transition failed; node stays inactive")
        return False
    node.get_logger().info("active")
    return True


def finalize(node: Node) -> None:
    """The shutdown transition from wherever the node is (finalized already: nothing)."""
    # RCLError: finalized already (e.g. by 'ros2 lifecycle set ... shutdown')
    with contextlib.suppress(_rclpy.RCLError):
        node.trigger_shutdown()


def run_lifecycle_node(factory: Callable[[], Node], args: list[str] | None = None) -> int:
    """``main()`` of a lifecycle node: its exit status."""
    code = 0
    try:
        with ros_session(args=args, signal_handler_options=NO_RCLPY_SIGNAL_HANDLERS):
            node = factory()
            if declare_autostart(node):
                autostart(node)
            executor = MultiThreadedExecutor(num_threads=4)
            executor.add_node(node)
            try:
                code = spin_until_signal(executor, lambda: finalize(node))
            finally:
                node.destroy_node()
    except KeyboardInterrupt:  # Ctrl-C before spinning (e.g. while a node loads)
        pass
    return code


def run_plain_node(name: str, factory: Callable[[], PlainNode],
                   refused: tuple[type[Exception], ...], finish: Callable[[PlainNode], None],
                   args: list[str] | None = None,
                   refused_code: int = 1) -> int:
    """``main()`` of a node without a lifecycle (the mock rig, the recorder): a node the
    user's parameters refuse (``refused``) prints one sentence and exits ``refused_code``;
    its set_parameters services refuse what rclpy cannot read (``guard_parameter_services``);
    otherwise it spins until a signal and runs ``finish`` while the context is valid;
    its exit status."""
    code = 0
    try:
        with ros_session(args=args, signal_handler_options=NO_RCLPY_SIGNAL_HANDLERS):
            try:
                node = factory()
            except refused as exc:
                print(f"{name}: {exc}", file=sys.stderr)
                return refused_code
            guard_parameter_services(node)
            executor = SingleThreadedExecutor()
            executor.add_node(node)
            try:
                code = spin_until_signal(executor, lambda: finish(node))
            finally:
                node.destroy_node()
    except KeyboardInterrupt:  # Ctrl-C while the node is being made (a skin model loading)
        pass
    return code
