"""Gripper over ROS in separate processes: mock rig (emulated XM430 + mock photoreflector
sharing one gripper world) -> driver -> gripper node -> this test's action client.
"""

from __future__ import annotations

import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import rclpy
import yaml
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import WrenchStamped
from rclpy.action import ActionClient, get_action_names_and_types
from sensor_msgs.msg import JointState

from tactile_sensor.configurations import config_dir
from tactile_sensor.nodes.ros_session import ros_session
from tactile_sensor.physics.params import PhysicsParams
from tactile_sensor.physics.prediction import load_or_compute_curve
from tactile_sensor.sensing.calibration import Calibration
from tactile_sensor_interfaces.action import Grasp, Release

CONFIG = config_dir()


@pytest.fixture(scope="module")
def calibration_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The FEM calibration the model node would publish, as a file for the driver."""
    path = tmp_path_factory.mktemp("cal") / "calibration.json"
    Calibration.from_prediction_curve(load_or_compute_curve(PhysicsParams())).to_file(path)
    return path


def overrides(tmp_path: Path, node: str, **values: object) -> str:
    """A parameter file applied after the configuration's own: a node-specific section of
    a file takes precedence over a global '-p', so test settings go in a file too."""
    path = tmp_path / f"{node}_overrides.yaml"
    path.write_text(yaml.safe_dump({f"/**/{node}": {"ros__parameters": values}}))
    return str(path)


class Rig:
    def __init__(self, spawn, tmp_path: Path, calibration: Path) -> None:
        self.adc = tmp_path / "adc"
        self.servo = tmp_path / "xm430"
        self.control = tmp_path / "xm430.ctl"
        self.mock = spawn(
            "--ros-args", "-r", "__node:=gripper_world",
            "--params-file", str(CONFIG / "physics.yaml"),
            "--params-file", str(CONFIG / "gripper.yaml"),
            "--params-file", overrides(tmp_path, "gripper_world", adc_link=str(self.adc),
                                       servo_link=str(self.servo),
                                       servo_control=str(self.control), seed=3),
            module="tactile_sensor.nodes.mock_hardware")
        assert self.mock.wait_for_output("mock gripper ready", 120), self.mock.output()
        self.driver = spawn(
            "--ros-args", "-r", "__node:=driver", "--params-file", str(CONFIG / "sensor.yaml"),
            "--params-file", str(CONFIG / "gripper.yaml"),
            "--params-file", overrides(tmp_path, "driver", port=str(self.adc),
                                       calibration_source="file",
                                       calibration_file=str(calibration), autostart=True),
            module="tactile_sensor.nodes.driver")
        self.gripper = spawn(
            "--ros-args", "-r", "__node:=gripper", "-r", "tactile_wrench:=/driver/wrench",
            "--params-file", str(CONFIG / "gripper.yaml"),
            # tactile_timeout: on a loaded 2-core machine the driver's 250 Hz stream stalls
            # for more than the configured 0.2 s now and then, and the grasp aborts
            # "tactile_stale" (tested in test/control); these tests are about other things
            "--params-file", overrides(tmp_path, "gripper", port=str(self.servo),
                                       autostart=True, tactile_timeout=1.0),
            module="tactile_sensor.nodes.gripper")
        assert self.driver.wait_for_output("active", 30), self.driver.output()
        assert self.gripper.wait_for_output("active", 30), self.gripper.output()

    def inject(self, command: str) -> None:
        with self.control.open("w") as fifo:
            fifo.write(command + "\n")


class Client:
    def __init__(self) -> None:
        self.node = rclpy.create_node("gripper_test_client")
        self.grasp = ActionClient(self.node, Grasp, "/gripper/grasp")
        self.release = ActionClient(self.node, Release, "/gripper/release")
        self.force: list[tuple[float, float]] = []
        self.truth: list[tuple[float, float]] = []
        self.opening: list[tuple[float, float]] = []
        self.diagnostics: list[DiagnosticStatus] = []
        self.node.create_subscription(WrenchStamped, "/driver/wrench",
                                      lambda m: self.force.append((time.time(),
                                                                   m.wrench.force.z)), 1000)
        self.node.create_subscription(WrenchStamped, "/gripper_world/ground_truth",
                                      lambda m: self.truth.append((time.time(),
                                                                   m.wrench.force.z)), 1000)
        self.node.create_subscription(JointState, "/gripper/joint_states",
                                      lambda m: self.opening.append(
                                          (_stamp(m), m.position[0])), 1000)
        self.node.create_subscription(
            DiagnosticArray, "/diagnostics",
            lambda m: self.diagnostics.extend(s for s in m.status if "XM430" in s.name), 100)
        self.executor = rclpy.executors.MultiThreadedExecutor(num_threads=2)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()
        assert self.grasp.wait_for_server(timeout_sec=20)
        assert self.release.wait_for_server(timeout_sec=20)

    def send(self, client: ActionClient, goal, feedback=None):
        future = client.send_goal_async(goal, feedback_callback=feedback)
        handle = _wait(future, 10)
        assert handle.accepted
        return handle

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=1)
        self.thread.join(2)
        self.node.destroy_node()


def _stamp(msg) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def _wait(future, timeout_s: float):
    deadline = time.monotonic() + timeout_s
    while not future.done():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.005)
    return future.result()


@pytest.fixture
def rig(spawn, ros_domain, tmp_path, calibration_file):
    rig = Rig(spawn, tmp_path, calibration_file)
    with ros_session():
        client = Client()
        # the driver tares while the fingers are open and still
        deadline = time.monotonic() + 20
        while not client.force and time.monotonic() < deadline:
            time.sleep(0.05)
        assert client.force, rig.driver.output()
        # ... and the gripper must hear the force too before a grasp starts: the first
        # grasp used to abort "tactile_stale" (force nan) while discovery was still going
        while (client.node.count_subscribers("/driver/wrench") < 2
               and time.monotonic() < deadline):
            time.sleep(0.05)
        time.sleep(0.3)
        yield rig, client
        client.close()


def test_grasp_reaches_the_target_then_release_reopens(rig):
    _, client = rig
    feedback_times: list[float] = []
    handle = client.send(client.grasp, Grasp.Goal(target_force=2.0, closing_speed=0.01,
                                                  timeout=10.0),
                         lambda _: feedback_times.append(time.monotonic()))
    result = _wait(handle.get_result_async(), 20).result
    assert result.contact_detected, result.message
    time.sleep(0.5)  # hold: let the filter settle on the held force
    held = [f for t, f in client.force if t > time.time() - 0.3]
    assert np.mean(held) == pytest.approx(2.0, rel=0.10), (np.mean(held), result.message)
    gaps = np.diff(feedback_times)
    assert len(feedback_times) > 5 and np.median(gaps) <= 1 / 20, gaps

    handle = client.send(client.release, Release.Goal(opening=0.0))
    released = _wait(handle.get_result_async(), 20).result
    assert released.success, released.message
    assert released.opening == pytest.approx(0.060, abs=0.001)


def test_cancel_stops_the_fingers_promptly(rig):
    """Issue #4: cancel mid-grasp stops the fingers within 50 ms. Measured from the moment
    the cancel request is sent to the first ~/joint_states sample that shows the fingers
    where they came to rest (its stamp is when the servo was read), over several cancels:
    the median must meet the 50 ms; on a loaded 2-core machine single cancels wait for a
    CPU now and then (the scheduler, not the code), so one cancel only has to stay below
    250 ms. Moving again after the stop (a second stop elsewhere, a closing command after
    the stop) counts as not stopped."""
    devices, client = rig
    devices.inject("rod none")  # nothing to touch: the fingers keep closing until canceled
    latencies = []
    for trial in range(6):  # each grasp closes ~6 mm more; no release in between
        handle = client.send(client.grasp, Grasp.Goal(target_force=1.5, closing_speed=0.01,
                                                      timeout=10.0))
        time.sleep(0.2 + 0.015 * trial)  # cancel at different phases of the 100 Hz loop
        moving_before = client.opening[-1][1]
        canceled_at = time.time()
        cancel = _wait(handle.cancel_goal_async(), 5)
        result = _wait(handle.get_result_async(), 5).result
        assert cancel.goals_canceling and "cancel" in result.message, result.message
        # 0.3 s of joint states after the cancel (waited for, not slept: on a loaded
        # machine the stream itself can pause for longer than that)
        deadline = time.monotonic() + 5
        while (time.monotonic() < deadline
               and not any(t >= canceled_at + 0.3 for t, _ in client.opening[-100:])):
            time.sleep(0.01)
        after = [(t, o) for t, o in client.opening if t >= canceled_at]
        assert after, "no ~/joint_states for 5 s after the cancel"
        final = after[-1][1]
        assert final < moving_before  # it was closing
        # stopped = the first sample from which on the opening stays within 0.05 mm of
        # where it came to rest (a finger passing that point and coming back, or closing
        # again after the stop, counts as still moving)
        last_off = max((i for i, (_, o) in enumerate(after) if abs(o - final) >= 5e-5),
                       default=-1)
        latencies.append(after[last_off + 1][0] - canceled_at)
    ms = np.array(latencies) * 1e3
    print(f"cancel -> fingers stopped (joint_states stamps), {len(ms)} cancels: median "
          f"{np.median(ms):.0f} ms, max {ms.max():.0f} ms ({np.round(ms).astype(int)})")
    assert np.median(ms) <= 50.0, ms
    assert ms.max() < 250.0, ms


def test_overload_aborts_with_the_decoded_reason_and_torque_off(rig):
    devices, client = rig
    devices.inject("rod none")
    handle = client.send(client.grasp, Grasp.Goal(target_force=1.5, closing_speed=0.005,
                                                  timeout=10.0))
    time.sleep(0.5)
    devices.inject("fault overload")
    result = _wait(handle.get_result_async(), 5).result
    assert not result.contact_detected
    assert "overload" in result.message, result.message
    deadline = time.monotonic() + 3
    while time.monotonic() < deadline and not any(
            s.level == DiagnosticStatus.ERROR and "overload" in s.message
            for s in client.diagnostics):
        time.sleep(0.05)
    assert any(s.level == DiagnosticStatus.ERROR and "overload" in s.message
               for s in client.diagnostics)
    assert devices.gripper.wait_for_output("torque off", 3), devices.gripper.output()
    # recovery by the ~/reboot service: a new grasp works again
    from std_srvs.srv import Trigger
    reboot = client.node.create_client(Trigger, "/gripper/reboot")
    assert reboot.wait_for_service(timeout_sec=5)
    answer = _wait(reboot.call_async(Trigger.Request()), 10)
    assert answer.success, answer.message


def test_a_second_goal_preempts_the_first(rig):
    devices, client = rig
    devices.inject("rod none")
    first = client.send(client.grasp, Grasp.Goal(target_force=1.5, closing_speed=0.005,
                                                 timeout=10.0))
    time.sleep(0.5)
    second = client.send(client.release, Release.Goal(opening=0.0))
    first_result = _wait(first.get_result_async(), 5).result
    assert "preempted" in first_result.message
    assert _wait(second.get_result_async(), 20).result.success


def test_an_unreachable_servo_fails_configure_with_one_sentence(spawn, ros_domain, tmp_path):
    gripper = spawn("--ros-args", "-r", "__node:=gripper", "-p",
                    f"port:={tmp_path / 'no_such_port'}", "-p", "autostart:=true",
                    module="tactile_sensor.nodes.gripper")
    assert gripper.wait_for_output("configure transition failed", 30), gripper.output()
    line = next(line for line in gripper.output().splitlines() if "configure failed" in line)
    assert "no_such_port" in line and "Traceback" not in gripper.output()


def test_without_control_msgs_the_gripper_starts_and_says_which_actions_are_missing(
        spawn, ros_domain, tmp_path):
    """A ROS 2 with no control_msgs (hidden here by a package that refuses to import): the
    node comes up active with ~/grasp and ~/release and one warning naming the fix."""
    hidden = tmp_path / "hide" / "control_msgs"
    hidden.mkdir(parents=True)
    (hidden / "__init__.py").write_text("raise ImportError('control_msgs hidden by the test')\n")
    servo = tmp_path / "xm430"
    emulator = spawn("mock", "xm430", "--link", str(servo), "--baud", "1000000", "--no-world",
                     module="tactile_sensor.cli")
    assert _wait_path(servo, 30), emulator.output()
    shim = (f"import sys; sys.path.insert(0, {str(hidden.parent)!r}); "
            "from tactile_sensor.nodes.gripper import main; sys.exit(main())")
    gripper = spawn(sys.executable, "-c", shim, "--ros-args", "-r", "__node:=gripper",
                    "-p", f"port:={servo}", "-p", "autostart:=true")
    assert gripper.wait_for_output("active", 60), gripper.output()
    output = gripper.output()
    warnings = [line for line in output.splitlines() if "[WARN]" in line]
    assert len(warnings) == 1 and "control_msgs is not installed" in warnings[0], output
    assert "ros-<distro>-control-msgs" in warnings[0] and "Traceback" not in output
    with ros_session():
        node = rclpy.create_node("probe")
        try:
            grasp = ActionClient(node, Grasp, "/gripper/grasp")
            assert grasp.wait_for_server(timeout_sec=30)
            names = {name for name, _ in get_action_names_and_types(node)}
            assert "/gripper/grasp" in names and "/gripper/gripper_cmd" not in names
        finally:
            node.destroy_node()


def _wait_path(path: Path, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while not path.exists():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.05)
    return True
