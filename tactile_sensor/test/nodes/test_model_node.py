"""Model node in its own process: ~/predict answers from the FEM curve, the latched
calibration reaches a subscriber that starts late, bad input is refused with a message; with
several modules the array calibration is latched too."""

from __future__ import annotations

import time

import numpy as np
import pytest
import rclpy
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from tactile_sensor.configurations import config_dir
from tactile_sensor.nodes import array_calibration_msg
from tactile_sensor.nodes.ros_session import ros_session
from tactile_sensor.physics.array_grid import load_or_compute_grid
from tactile_sensor.physics.array_report import fit_grid, fit_wrench
from tactile_sensor.physics.params import PhysicsParams
from tactile_sensor.physics.prediction import load_or_compute_curve
from tactile_sensor.physics.wrench import cached_wrench_set
from tactile_sensor_interfaces.msg import ArrayCalibration as ArrayCalibrationMsg
from tactile_sensor_interfaces.msg import CalibrationCurve
from tactile_sensor_interfaces.srv import PredictOutput

LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                     reliability=ReliabilityPolicy.RELIABLE)
# Upper bound of every wait on a condition: generous, because a wait ends as soon as its
# condition holds and a busy machine may be slow to get there (never a fixed sleep).
PATIENCE_S = 60.0


@pytest.fixture(scope="module")
def curve():
    return load_or_compute_curve(PhysicsParams())


def start_model(spawn, *extra: str):
    return spawn("--ros-args", "-r", "__node:=model",
                 "--params-file", str(config_dir() / "physics.yaml"),
                 "-p", "autostart:=true", *extra, module="tactile_sensor.nodes.model")


def spin_until(node, predicate, timeout_s: float = PATIENCE_S) -> bool:
    deadline = time.monotonic() + timeout_s
    while not predicate() and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
    return bool(predicate())


ATTEMPT_S = 10.0  # one request's wait for its answer before it is sent again


def call(node, client, request, timeout_s: float = PATIENCE_S):
    """The service's answer, asked again when none came (the queries are read-only).

    ``wait_for_service`` can return before the middleware has matched the reply's path
    back to this client; a request sent then is served and its reply lost. Beside a busy
    core a first call once waited its full 60 s (the rerun passed)."""
    deadline = time.monotonic() + timeout_s
    while True:
        future = client.call_async(request)
        rclpy.spin_until_future_complete(
            node, future, timeout_sec=min(ATTEMPT_S, max(0.0, deadline - time.monotonic())))
        if future.done() or time.monotonic() >= deadline:
            break
        client.remove_pending_request(future)
    assert future.done(), f"no answer from {client.service_name} in {timeout_s:g} s"
    return future.result()


def test_predict_and_latched_calibration(spawn, ros_domain, curve):
    model = start_model(spawn)
    assert model.wait_for_output("prediction ready", 120), model.output()
    with ros_session():
        # Once a first subscriber has the curve, the model has published it: a subscriber
        # created after that is late for certain (not merely 1 s after the log line).
        early = rclpy.create_node("model_early_client")
        first: list[CalibrationCurve] = []
        early.create_subscription(CalibrationCurve, "/calibration_curve", first.append,
                                  LATCHED)
        assert spin_until(early, lambda: first), "no calibration published"
        early.destroy_node()
        node = rclpy.create_node("model_client")
        received: list[CalibrationCurve] = []
        node.create_subscription(CalibrationCurve, "/calibration_curve", received.append,
                                 LATCHED)
        client = node.create_client(PredictOutput, "/model/predict")
        assert client.wait_for_service(timeout_sec=PATIENCE_S)
        d = np.linspace(0.0, float(curve.indentation_m[-1]), 7)
        response = call(node, client, PredictOutput.Request(indentation=d.tolist()))
        assert response.success, response.message
        expected = curve.at(d)
        np.testing.assert_allclose(response.force, expected.force_n, rtol=1e-9)
        np.testing.assert_allclose(response.output, expected.output_v, rtol=1e-9)
        np.testing.assert_allclose(response.distance, expected.distance_m, rtol=1e-9)
        assert np.all(np.diff(response.force) > 0)

        outside = call(node, client, PredictOutput.Request(indentation=[0.001, 0.02]))
        assert not outside.success
        assert "0.02" in outside.message

        spin_until(node, lambda: received)
        node.destroy_node()
    assert received, "the late subscriber got no latched calibration"
    output, force = curve.calibration()
    np.testing.assert_allclose(received[0].output, output)
    np.testing.assert_allclose(received[0].force, force)
    assert received[0].source.startswith("fem:")


def _done_percent(message: str) -> int:
    """N of the node's "not ready, N% done"."""
    return int(message.split("not ready, ", 1)[1].split("%", 1)[0])


def test_not_ready_while_computing_and_bad_physics_parameter(spawn, ros_domain, tmp_path):
    # A fresh cache and a long sweep: 60 load steps on the default meshes take tens of seconds
    # on an idle machine (and longer on a busy one, where discovery slows too), against well
    # under a second to discover the service. (A small mesh solves in about 1 s now: a first
    # call raced the sweep and sometimes found it done.) The node answers "not ready, N%
    # done", and N grows while the sweep goes on; the test waits for that, not for the end.
    start_model(spawn, "-p", f"cache_dir:={tmp_path}", "-p", "steps:=60")
    request = PredictOutput.Request(indentation=[0.001])
    with ros_session():
        node = rclpy.create_node("model_client")
        client = node.create_client(PredictOutput, "/model/predict")
        assert client.wait_for_service(timeout_sec=PATIENCE_S)
        first = call(node, client, request)
        assert not first.success, first.message
        assert "not ready" in first.message and "% done" in first.message, first.message
        later = first
        deadline = time.monotonic() + 10 * PATIENCE_S  # a load step on a saturated machine
        while (_done_percent(later.message) <= _done_percent(first.message)
               and time.monotonic() < deadline):
            rclpy.spin_once(node, timeout_sec=0.5)
            later = call(node, client, request)
            assert not later.success, "60 load steps solved before any progress was seen"
        node.destroy_node()
    assert _done_percent(later.message) > _done_percent(first.message), later.message
    bad = start_model(spawn, "-r", "__node:=model_bad", "-p", "height:=-0.01")
    assert bad.wait_for_output("configure transition failed", 30), bad.output()
    assert "'height'" in bad.output() and "Traceback" not in bad.output()


def test_an_array_latches_the_calibration_fitted_on_its_grid(spawn, ros_domain):
    # The grid comes from the cache ($XDG_CACHE_HOME/tactile_sensor, as the curve above);
    # computed cold it takes minutes on a loaded machine.
    faces = ("front", "back", "left", "right")
    params = PhysicsParams().replace(modules=",".join(faces))
    grid, wrench_set = load_or_compute_grid(params), cached_wrench_set(params)
    # with the layout's wrench set cached ('model array-calibration --wrench') the node fits
    # torque columns too
    expected, _ = fit_grid(grid, degree=3) if wrench_set is None else fit_wrench(
        grid, wrench_set, degree=3)
    model = start_model(spawn, "-p", f"modules:={','.join(faces)}")
    assert model.wait_for_output("array calibration ready", 600), model.output()
    with ros_session():
        node = rclpy.create_node("array_client")
        received: list[ArrayCalibrationMsg] = []
        node.create_subscription(ArrayCalibrationMsg, "/array_calibration", received.append,
                                 LATCHED)
        spin_until(node, lambda: received)
        node.destroy_node()
    assert received, model.output()
    msg = received[0]
    assert list(msg.faces) == list(faces)
    assert msg.source.startswith(f"fem-array:{params.grid_digest()}")
    assert msg.source == expected.source and list(msg.observed) == list(expected.observed)
    calibration = array_calibration_msg.from_msg(msg)
    np.testing.assert_array_equal(calibration.terms, expected.terms)
    np.testing.assert_allclose(calibration.coefficients, expected.coefficients, rtol=1e-12)
    outputs = [0.2, 0.15, 0.05, 0.3]
    assert calibration.force(outputs) == pytest.approx(expected.force(outputs), rel=1e-12)


def test_a_single_module_model_latches_no_array_calibration(spawn, ros_domain):
    model = start_model(spawn)
    assert model.wait_for_output("prediction ready", 120), model.output()
    with ros_session():
        node = rclpy.create_node("array_client")
        # The model creates its publishers (the curve's, an array's if any) before its
        # ~/predict service, and the middleware announces a participant's endpoints in
        # order: once the service and the curve are seen, an array publisher would be too.
        client = node.create_client(PredictOutput, "/model/predict")
        assert client.wait_for_service(timeout_sec=PATIENCE_S)
        assert spin_until(node, lambda: "/calibration_curve" in dict(
            node.get_topic_names_and_types()))
        names = dict(node.get_topic_names_and_types())
        node.destroy_node()
    assert "/calibration_curve" in names and "/array_calibration" not in names
    assert "array" not in model.output()


def test_rate_terms_from_a_physics_with_more_than_the_driver_takes_fail_configure(
        spawn, ros_domain):
    model = start_model(spawn, "-p", "calibration_rate_terms:=true",
                        "-p", "prony_g:=[0.01, 0.01, 0.01, 0.01]",
                        "-p", "prony_tau:=[0.1, 0.3, 1.0, 3.0]")
    assert model.wait_for_output("configure transition failed", 30), model.output()
    assert ("Parameter 'calibration_rate_terms' is true but the physics has 4 Prony terms "
            "(prony_g); a rate-aware calibration takes 1 to 3") in model.output()
    assert "Traceback" not in model.output()


def test_an_output_that_never_grows_is_no_curve_in_one_sentence(spawn, ros_domain):
    # 20 mm from the skin the photoreflector sits at its rail: the output stays 0.
    model = start_model(spawn, "-p", "gap:=0.02", "-p", "steps:=10", "-p", "mesh_nx:=6",
                        "-p", "mesh_ny:=6", "-p", "mesh_nz:=22")
    assert model.wait_for_output("no calibration curve", 120), model.output()
    assert ("no calibration curve: The predicted output does not grow with indentation"
            in model.output())
    assert "prediction ready" in model.output() and "Traceback" not in model.output()
