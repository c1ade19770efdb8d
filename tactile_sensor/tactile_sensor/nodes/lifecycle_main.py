"""``main()`` of a lifecycle node executable, with optional autostart.

Under ``ros2 launch`` the launch file drives the transitions; for ``ros2 run`` and tests,
``--ros-args -p autostart:=true`` configures and activates the node at start-up, and a
failed transition leaves it running (unconfigured) so it can be fixed with ``ros2 param``
and ``ros2 lifecycle set`` without a restart.
"""

from __future__ import annotations

from collections.abc import Callable

import rclpy
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.lifecycle import Node, TransitionCallbackReturn


def declare_autostart(node: Node) -> bool:
    return bool(node.declare_parameter(
        "autostart", False,
        ParameterDescriptor(description="configure and activate at start-up (for ros2 run)"),
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


def run_lifecycle_node(factory: Callable[[], Node], args: list[str] | None = None) -> None:
    try:
        with rclpy.init(args=args):
            node = factory()
            if declare_autostart(node):
                autostart(node)
            executor = MultiThreadedExecutor(num_threads=4)
            executor.add_node(node)
            try:
                executor.spin()
            finally:
                node.destroy_node()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
