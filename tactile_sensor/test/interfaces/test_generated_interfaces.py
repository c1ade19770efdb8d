"""The generated interfaces work across processes (action with feedback, service)."""

from __future__ import annotations

from pathlib import Path

import pytest
import rclpy
from rclpy.action import ActionClient

from tactile_sensor.nodes.ros_session import ros_session
from tactile_sensor_interfaces.action import Grasp, Release
from tactile_sensor_interfaces.msg import CalibrationCurve, TactileReading
from tactile_sensor_interfaces.srv import PredictOutput

SERVERS = Path(__file__).with_name("interface_servers.py")


@pytest.fixture
def servers(spawn, ros_domain):
    child = spawn("python", str(SERVERS))
    assert child.wait_for_output("servers ready", 30), child.output()
    return child


def test_message_fields_exist():
    reading = TactileReading(voltage=1.2, output=0.3, force=4.0, contact=True)
    assert (reading.voltage, reading.output, reading.force, reading.contact) == (
        1.2, 0.3, 4.0, True)
    curve = CalibrationCurve(output=[0.0, 0.5], force=[0.0, 7.0], source="fem:abc")
    assert list(curve.force) == [0.0, 7.0]
    assert Release.Goal(opening=0.0).opening == 0.0


def test_grasp_action_across_processes(servers):
    with ros_session():
        node = rclpy.create_node("grasp_client")
        client = ActionClient(node, Grasp, "grasp")
        assert client.wait_for_server(timeout_sec=20.0)
        feedback: list[float] = []
        goal_future = client.send_goal_async(
            Grasp.Goal(target_force=3.0, closing_speed=0.01, timeout=5.0),
            feedback_callback=lambda msg: feedback.append(msg.feedback.force))
        rclpy.spin_until_future_complete(node, goal_future, timeout_sec=10.0)
        handle = goal_future.result()
        assert handle is not None and handle.accepted
        result_future = handle.get_result_async()
        rclpy.spin_until_future_complete(node, result_future, timeout_sec=10.0)
        result = result_future.result().result
        client.destroy()  # destroy_node() leaves action clients to the garbage collector
        node.destroy_node()
    assert result.contact_detected and result.force == pytest.approx(3.0)
    assert result.message == "contact"
    assert feedback and feedback[-1] == pytest.approx(3.0)


def test_predict_service_across_processes(servers):
    with ros_session():
        node = rclpy.create_node("predict_client")
        client = node.create_client(PredictOutput, "predict")
        assert client.wait_for_service(timeout_sec=20.0)
        future = client.call_async(PredictOutput.Request(indentation=[0.001, 0.002]))
        rclpy.spin_until_future_complete(node, future, timeout_sec=10.0)
        response = future.result()
        node.destroy_node()
    assert response.success
    assert list(response.force) == pytest.approx([0.002, 0.004])
    assert list(response.distance) == pytest.approx([0.001, 0.0])
