"""A Grasp action server and a PredictOutput service with trivial, checkable behaviour.

Run as a separate process by test_generated_interfaces.py: the point is to exercise the
generated interfaces across processes, not project logic.
"""

from __future__ import annotations

import time

from rclpy.action import ActionServer
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.node import Node

from tactile_sensor.nodes.ros_session import ros_session
from tactile_sensor_interfaces.action import Grasp
from tactile_sensor_interfaces.srv import PredictOutput


class InterfaceServers(Node):
    def __init__(self) -> None:
        super().__init__("interface_servers")
        self._grasp = ActionServer(self, Grasp, "grasp", self._execute)
        self._predict = self.create_service(PredictOutput, "predict", self._on_predict)
        self.get_logger().info("servers ready")

    def _execute(self, handle):
        target = handle.request.target_force
        for i in range(1, 6):
            feedback = Grasp.Feedback(force=target * i / 5, opening=0.05 - 0.01 * i)
            handle.publish_feedback(feedback)
            time.sleep(0.02)
        handle.succeed()
        return Grasp.Result(contact_detected=True, force=target, opening=0.0,
                            message="contact")

    def _on_predict(self, request, response):
        response.force = [2.0 * d for d in request.indentation]
        response.distance = [0.002 - d for d in request.indentation]
        response.voltage = [1.0] * len(request.indentation)
        response.output = [0.5 * d for d in request.indentation]
        response.success = True
        response.message = "ok"
        return response


def main() -> None:
    try:
        with ros_session():
            executor = MultiThreadedExecutor()
            node = InterfaceServers()
            executor.add_node(node)
            executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass


if __name__ == "__main__":
    main()
