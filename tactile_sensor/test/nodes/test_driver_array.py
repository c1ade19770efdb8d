"""Four-module array: a mock ADC streaming four channels (own process) -> the driver node
with ``modules`` (own process) -> this test, over ROS.

The mock's channel i carries module i's voltage: at rest, then a press with shear toward +x
that it holds; the driver calibrates with an array calibration fitted here on synthetic
data (Fx = 10 (right - left), Fy = 10 (front - back), Fz = 5 x the sum of the outputs), so
the true wrench of the hold is known.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from driver_listener import DriverListener, start_driver
from geometry_msgs.msg import WrenchStamped
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from tactile_sensor.nodes import array_calibration_msg
from tactile_sensor.sensing.array_calibration import ArrayCalibration
from tactile_sensor_interfaces.msg import ArrayCalibration as ArrayCalibrationMsg
from tactile_sensor_interfaces.msg import TactileReading

FACES = ("front", "back", "left", "right")
MODULES = "0:front,1:back,2:left,3:right"
REST_V = (3.0, 2.9, 3.1, 3.0)
HOLD_OUTPUT_V = (0.2, 0.2, 0.1, 0.3)  # +x shear: right out, left in
HOLD_FORCE_N = (10.0 * (0.3 - 0.1), 10.0 * (0.2 - 0.2), 5.0 * 0.8)  # (2, 0, 4)
# Upper bound of every wait on a condition: generous, because a wait ends as soon as its
# condition holds and a busy machine may be slow to get there (never a fixed sleep).
PATIENCE_S = 60.0

# The device: rest for 1.5 s, ramp over 0.5 s to the hold, hold for ever.
MOCK = """
import signal, sys, threading
import numpy as np
from tactile_sensor.sim.adc_device import AdcNoise, MockAdcDevice
link, channels = sys.argv[1], int(sys.argv[2])
rest, hold = (np.array(sys.argv[k].split(","), float)[:channels] for k in (3, 4))
def source(t):
    t = np.asarray(t, dtype=float)
    ramp = np.clip((t - 1.5) / 0.5, 0.0, 1.0)[:, None]
    return rest[None, :] - ramp * hold[None, :]
device = MockAdcDevice(link, source, channels=channels, seed=1,
                       noise=AdcNoise(white_v=0.002, drift_v=0.0))
device.start()
stop = threading.Event()
for sig in (signal.SIGINT, signal.SIGTERM):
    signal.signal(sig, lambda *_: stop.set())
print("mock array adc: streaming", flush=True)
stop.wait()
device.stop()
"""


def fit_calibration(path: Path, faces=FACES) -> None:
    rng = np.random.default_rng(0)
    o = rng.uniform(-0.05, 0.5, size=(400, len(faces)))
    col = {f: o[:, i] for i, f in enumerate(faces)}
    none = np.zeros(len(o))
    forces = np.stack([10.0 * (col.get("right", none) - col.get("left", none)),
                       10.0 * (col.get("front", none) - col.get("back", none)),
                       5.0 * o.sum(axis=1)], axis=1)
    ArrayCalibration.fit(faces, o, forces, 3, "synthetic").to_file(path)


def _seconds(stamp: Time) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


class Listener(DriverListener):
    def __init__(self) -> None:
        self.readings: list[TactileReading] = []
        self.wrenches: list[tuple[float, float, float]] = []
        self.torques: list[tuple[float, float, float]] = []
        self.wrench_stamps: list[float] = []  # [s], the samples' host-clock stamps
        self.diagnostics: list[DiagnosticStatus] = []
        super().__init__("array_listener")

    def subscribe(self) -> None:
        self.node.create_subscription(TactileReading, "/driver/reading",
                                      self.readings.append, 1000)
        self.node.create_subscription(WrenchStamped, "/driver/wrench", self._on_wrench, 1000)
        self.node.create_subscription(
            DiagnosticArray, "/diagnostics",
            lambda m: self.diagnostics.extend(s for s in m.status if "tactile ADC" in s.name),
            100)

    def _on_wrench(self, m: WrenchStamped) -> None:
        self.wrenches.append((m.wrench.force.x, m.wrench.force.y, m.wrench.force.z))
        self.torques.append((m.wrench.torque.x, m.wrench.torque.y, m.wrench.torque.z))
        self.wrench_stamps.append(_seconds(m.header.stamp))


@pytest.fixture
def ros(ros_domain):
    with Listener.listening() as listener:
        yield listener


def start_array_driver(spawn, link: Path, calibration: Path, *extra: str):
    return start_driver(spawn, link, calibration, "-p", f"modules:={MODULES}", *extra)


def start_mock(spawn, link: Path, channels: int = 4):
    child = spawn(sys.executable, "-c", MOCK, str(link), str(channels),
                  ",".join(map(str, REST_V)), ",".join(map(str, HOLD_OUTPUT_V)))
    assert child.wait_for_output("mock array adc: streaming", PATIENCE_S), child.output()
    return child


def _value(status: DiagnosticStatus, key: str) -> str | None:
    return next((kv.value for kv in status.values if kv.key == key), None)


def test_four_modules_give_the_wrench_and_every_module_in_the_reading(spawn, ros, tmp_path):
    calibration = tmp_path / "array.json"
    fit_calibration(calibration)
    driver = start_array_driver(spawn, tmp_path / "adc", calibration)
    assert driver.wait_for_output("active", PATIENCE_S), driver.output()
    assert "modules 0:front,1:back,2:left,3:right" in driver.output()
    start_mock(spawn, tmp_path / "adc")
    # auto-tare at rest, then the press; the hold is steady 2.5 s after the device starts
    assert ros.wait_for(lambda: len(ros.wrenches) > 2500, PATIENCE_S), driver.output()
    hold = np.array(ros.wrenches[-300:])
    print(f"hold wrench: mean {hold.mean(axis=0)}, std {hold.std(axis=0)}")
    np.testing.assert_allclose(hold.mean(axis=0), HOLD_FORCE_N, atol=0.1)

    last = ros.readings[-1]
    assert list(last.faces) == list(FACES)
    assert len(last.voltages) == len(last.outputs) == 4
    np.testing.assert_allclose(last.outputs, HOLD_OUTPUT_V, atol=0.01)
    np.testing.assert_allclose(last.voltages, np.subtract(REST_V, HOLD_OUTPUT_V), atol=0.015)
    assert (last.voltage, last.output) == (last.voltages[0], last.outputs[0])
    assert last.force == pytest.approx(HOLD_FORCE_N[2], abs=0.15)
    assert last.contact  # |F| = 4.5 N

    assert np.isnan(ros.torques[-300:]).all()  # a force-only calibration: torque NaN
    status = ros.diagnostics[-1]
    assert _value(status, "unobserved") == ("tx, ty, tz: the calibration has no torque "
                                            "columns (force only; centred windows cannot "
                                            "observe a torque at all)")
    for face, rest in zip(FACES, REST_V, strict=True):
        assert float(_value(status, f"baseline_v.{face}")) == pytest.approx(rest, abs=0.01)

    # ~/tare zeroes every module at the hold (at rest there): all outputs and forces ~0
    answer = ros.call_tare()
    assert answer.success, answer.message
    assert answer.message.startswith("baselines front ")
    # Samples taken 0.3 s after the answer: this listener may still be reading older ones
    # (stamps are the device's time mapped to this clock).
    tared_at = time.time()
    assert ros.wait_for(lambda: bool(ros.readings and ros.wrench_stamps)
                        and _seconds(ros.readings[-1].header.stamp) > tared_at + 0.3
                        and ros.wrench_stamps[-1] > tared_at + 0.3, PATIENCE_S)
    after = ros.readings[-1]
    np.testing.assert_allclose(after.outputs, 0.0, atol=0.01)
    np.testing.assert_allclose(ros.wrenches[-1], 0.0, atol=0.15)

    # modules describes the wiring: read on configure, refused while configured
    client = ros.node.create_client(SetParameters, "/driver/set_parameters")
    assert client.wait_for_service(timeout_sec=PATIENCE_S)
    future = client.call_async(SetParameters.Request(parameters=[
        Parameter("modules", value="0:front,1:back").to_parameter_msg()]))
    assert ros.wait_for(future.done, PATIENCE_S)
    refused = future.result().results[0]
    assert not refused.successful
    assert refused.reason.startswith("Parameter 'modules' is read on configure")


def test_a_six_column_calibration_gives_low_passed_torque_and_nan_for_the_rest(spawn, ros,
                                                                                tmp_path):
    fit_calibration(tmp_path / "forces.json")
    forces = ArrayCalibration.from_file(tmp_path / "forces.json")
    torque = np.zeros((3, forces.terms.shape[0]))
    torque[0, 1:5] = 0.05                    # Tx: linear in the features [N m]
    six = ArrayCalibration(forces.faces, forces.feature_matrix, forces.terms,
                           forces.coefficients, forces.output_scale_v, forces.output_max_v,
                           "synthetic", torque, ["fx", "fy", "fz", "tx"])
    calibration = tmp_path / "six.json"
    six.to_file(calibration)
    driver = start_array_driver(spawn, tmp_path / "adc", calibration, "-p", "torque_cutoff_hz:=5.0")
    assert driver.wait_for_output("active", PATIENCE_S), driver.output()
    start_mock(spawn, tmp_path / "adc")
    assert ros.wait_for(lambda: len(ros.torques) > 2500, PATIENCE_S), driver.output()
    hold = np.array(ros.torques[-300:])
    assert hold[:, 0].mean() == pytest.approx(six.wrench(HOLD_OUTPUT_V)[3], abs=2e-3)
    assert np.isnan(hold[:, 1:]).all()
    assert ros.wait_for(lambda: _value(ros.diagnostics[-1], "unobserved") is not None,
                        PATIENCE_S)
    status = ros.diagnostics[-1]
    assert _value(status, "unobserved") == "ty, tz: the layout's modules cannot observe torque"
    assert _value(status, "torque_cutoff_hz") == "5"


def test_a_calibration_for_other_faces_is_refused(spawn, ros_domain, tmp_path):
    calibration = tmp_path / "two.json"
    fit_calibration(calibration, ("front", "back"))
    driver = start_array_driver(spawn, tmp_path / "adc", calibration)
    assert driver.wait_for_output("configure transition failed", PATIENCE_S), driver.output()
    assert f"configure failed: The array calibration file:{calibration}" in driver.output()
    assert ("is for modules front, back but the driver's modules are front, back, left, "
            "right; fit one for these modules or set modules to match.") in driver.output()
    assert "Traceback" not in driver.output()


def test_a_device_with_too_few_channels_is_an_error_naming_both(spawn, ros, tmp_path):
    calibration = tmp_path / "array.json"
    fit_calibration(calibration)
    driver = start_array_driver(spawn, tmp_path / "adc", calibration)
    assert driver.wait_for_output("active", PATIENCE_S), driver.output()
    start_mock(spawn, tmp_path / "adc", channels=2)
    expected = "The driver reads channel 3 but the device sends 2 channel(s)"
    # (before the mock's link exists, "does not exist" is an ERROR too)
    assert ros.wait_for(lambda: any(s.message.startswith(expected)
                                    for s in ros.diagnostics), PATIENCE_S), driver.output()
    error = next(s for s in ros.diagnostics if s.message.startswith(expected))
    assert error.level == DiagnosticStatus.ERROR
    assert ros.wrenches == [] and ros.readings == []


@pytest.mark.parametrize(("modules", "sentence"), [
    ("0:front,1:top", "has face 'top'"),
    ("0:front,0:back", "Channel 0 appears twice in modules"),
    ("0:front,9:back", "has channel 9; ADC channels are 0..7"),
])
def test_a_bad_modules_parameter_fails_configure_with_its_sentence(spawn, ros_domain,
                                                                   tmp_path, modules,
                                                                   sentence):
    driver = start_array_driver(spawn, tmp_path / "adc", tmp_path / "none.json",
                          "-p", f"modules:={modules}")
    assert driver.wait_for_output("configure transition failed", PATIENCE_S), driver.output()
    assert "'modules'" in driver.output() and sentence in driver.output()
    assert "Traceback" not in driver.output()


def test_the_latched_array_calibration_is_used_and_one_for_other_faces_ignored(spawn, ros,
                                                                                tmp_path):
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                         reliability=ReliabilityPolicy.RELIABLE)
    publisher = ros.node.create_publisher(ArrayCalibrationMsg, "/array_calibration", latched)
    wrong, right = tmp_path / "two.json", tmp_path / "four.json"
    fit_calibration(wrong, ("front", "back"))
    fit_calibration(right)
    publisher.publish(array_calibration_msg.to_msg(ArrayCalibration.from_file(wrong)))
    driver = spawn("--ros-args", "-r", "__node:=driver", "-p", f"port:={tmp_path / 'adc'}",
                   "-p", f"modules:={MODULES}", "-p", "autostart:=true",
                   module="tactile_sensor.nodes.driver")
    assert driver.wait_for_output("ignoring array calibration: The array calibration "
                                  f"file:{wrong}", PATIENCE_S), driver.output()
    start_mock(spawn, tmp_path / "adc")
    assert ros.wait_for(lambda: len(ros.readings) > 2500, PATIENCE_S), driver.output()
    assert ros.wrenches == []  # no calibration: no wrench, readings with outputs only
    publisher.publish(array_calibration_msg.to_msg(ArrayCalibration.from_file(right)))
    assert ros.wait_for(lambda: len(ros.wrenches) > 300, PATIENCE_S), driver.output()
    np.testing.assert_allclose(np.mean(ros.wrenches[-300:], axis=0), HOLD_FORCE_N, atol=0.1)
    assert f"array calibration from file:{right}" in driver.output()
