"""Model node: serves FEM predictions of the module and publishes the calibration curve.

Wiring only: physics parameters become ROS parameters, a background thread loads or
computes the prediction curve (so a cold FEM sweep never blocks the executor), ``~/predict``
answers from it, and the output -> force curve goes out latched on ``calibration_curve``.
With ``calibration_rate_terms`` the curve carries the physics' Prony terms as its rate terms
(a simulation's assumption: the mock gauge's force is that very series), so a driver runs the
rate-aware model on a calibration from simulation alone.
When the physics parameter ``modules`` names several faces, a second thread loads or
computes the array grid and latches its fitted outputs -> (Fx, Fy, Fz) calibration on
``array_calibration`` (docs/array.md), with torque columns when the layout has windows off
their faces' centres (the wrench set is computed and cached like the grid).
"""

from __future__ import annotations

import sys
import threading
from pathlib import Path
from typing import Any

from rclpy.lifecycle import State, TransitionCallbackReturn
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from tactile_sensor.nodes import array_calibration_msg, calibration_curve_msg
from tactile_sensor.nodes.guarded_lifecycle import GuardedLifecycleNode
from tactile_sensor.nodes.lifecycle_main import run_lifecycle_node
from tactile_sensor.nodes.parameters import (
    ParameterError,
    ParamSpec,
    declare_parameters,
    read_parameters,
)
from tactile_sensor.nodes.physics_parameters import physics_from_values, physics_specs
from tactile_sensor.physics.array_grid import load_or_compute_grid
from tactile_sensor.physics.array_report import fit_grid, fit_wrench
from tactile_sensor.physics.errors import OutOfRangeError, PhysicsError
from tactile_sensor.physics.params import PhysicsParams
from tactile_sensor.physics.prediction import PredictionCurve, load_or_compute_curve
from tactile_sensor.physics.wrench import load_or_compute_wrench_set, off_centre
from tactile_sensor.sensing.array_calibration import ArrayCalibration
from tactile_sensor.sensing.calibration import Calibration
from tactile_sensor.sensing.errors import SensingError
from tactile_sensor.sensing.rate_calibration import MAX_RATE_TERMS, RateCalibration, RateTerm
from tactile_sensor_interfaces.msg import ArrayCalibration as ArrayCalibrationMsg
from tactile_sensor_interfaces.msg import CalibrationCurve as CalibrationCurveMsg
from tactile_sensor_interfaces.srv import PredictOutput

LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                     reliability=ReliabilityPolicy.RELIABLE)


ARRAY_DEGREE = 3  # the polynomial degree of docs/array.md (held-out error 0.13 % of range)

NODE_SPECS = [
    ParamSpec("cache_dir", "", "folder of the prediction cache; empty = "
              "$XDG_CACHE_HOME/tactile_sensor"),
    ParamSpec("calibration_rate_terms", False, "publish the physics' Prony terms (prony_g, "
              "prony_tau) as the calibration curve's rate terms, so a driver runs the "
              "rate-aware model (source 'fem:<digest>+prony'): a simulation's assumption; a "
              "real skin's terms come from 'tactile-sensor analyze --fit-calibration'. "
              "false = the static (relaxed) curve alone"),
]


def rate_terms(values: dict[str, Any], params: PhysicsParams) -> tuple[RateTerm, ...]:
    """The curve's rate terms: none, or the physics' Prony series when asked for."""
    if not values["calibration_rate_terms"]:
        return ()
    count = len(params.prony_g)
    if not 1 <= count <= MAX_RATE_TERMS:
        raise ParameterError(
            f"Parameter 'calibration_rate_terms' is true but the physics has {count} Prony "
            f"terms (prony_g); a rate-aware calibration takes 1 to {MAX_RATE_TERMS}, so give "
            "prony_g and prony_tau that many or set calibration_rate_terms false.")
    return tuple(RateTerm(g, tau) for g, tau in zip(params.prony_g, params.prony_tau,
                                                    strict=True))


class ModelNode(GuardedLifecycleNode):
    def __init__(self, node_name: str = "model", **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self._specs = physics_specs() + NODE_SPECS
        declare_parameters(self, self._specs)
        self._curve: PredictionCurve | None = None
        self._calibration: Calibration | RateCalibration | None = None
        self._progress = 0.0
        self._failure: str | None = None
        self._worker: threading.Thread | None = None
        self._array_worker: threading.Thread | None = None
        self._publisher = None
        self._service = None
        self._array: ArrayCalibration | None = None
        self._array_publisher = None

    # -- lifecycle -------------------------------------------------------------------------
    def on_configure(self, state: State) -> TransitionCallbackReturn:
        try:
            values = read_parameters(self, self._specs)
            cache_dir = values["cache_dir"] or None
            params = physics_from_values(values)
            terms = rate_terms(values, params)
        except (ParameterError, PhysicsError) as exc:
            self.get_logger().error(f"configure failed: {exc}")
            return TransitionCallbackReturn.FAILURE
        self._curve, self._failure, self._progress = None, None, 0.0
        self._calibration = None
        self._array = None
        self._publisher = self.create_lifecycle_publisher(
            CalibrationCurveMsg, "calibration_curve", LATCHED)
        if len(params.module_faces) > 1:
            self._array_publisher = self.create_lifecycle_publisher(
                ArrayCalibrationMsg, "array_calibration", LATCHED)
        self._service = self.create_service(PredictOutput, "~/predict", self._on_predict)
        self._worker = threading.Thread(
            target=self._compute, args=(params, cache_dir, terms), name="fem-sweep",
            daemon=True)
        self._worker.start()
        if self._array_publisher is not None:  # independent of the curve: its own thread
            self._array_worker = threading.Thread(
                target=self._compute_array, args=(params, cache_dir), name="array-grid",
                daemon=True)
            self._array_worker.start()
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: State) -> TransitionCallbackReturn:
        result = super().on_activate(state)
        if self._calibration is not None:
            self._publish_curve()
        if self._array is not None:
            self._publish_array()
        return result

    def on_cleanup(self, state: State) -> TransitionCallbackReturn:
        for worker in (self._worker, self._array_worker):
            if worker is not None:
                worker.join()
        self._destroy_interfaces()
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: State) -> TransitionCallbackReturn:
        self._destroy_interfaces()
        return TransitionCallbackReturn.SUCCESS

    def _destroy_interfaces(self) -> None:
        if self._service is not None:
            self.destroy_service(self._service)
        for publisher in (self._publisher, self._array_publisher):
            if publisher is not None:
                self.destroy_lifecycle_publisher(publisher)
        self._service = self._publisher = self._array_publisher = None
        self._curve = self._calibration = self._array = None

    # -- work --------------------------------------------------------------------------------
    def _compute(self, params: PhysicsParams, cache_dir: str | None,
                 terms: tuple[RateTerm, ...]) -> None:
        def progress(fraction: float, message: str) -> None:
            self._progress = fraction
            self.get_logger().info(f"FEM sweep {fraction:4.0%}: {message}",
                                   throttle_duration_sec=2.0)

        try:
            curve = load_or_compute_curve(
                params, Path(cache_dir) if cache_dir else None, progress)
        except PhysicsError as exc:
            self._failure = str(exc)
            self.get_logger().error(f"prediction failed: {exc}")
            return
        self._curve = curve
        self._progress = 1.0
        self.get_logger().info(
            f"prediction ready: {len(curve.indentation_m)} steps to "
            f"{curve.indentation_m[-1] * 1e3:.2f} mm, {curve.force_n[-1]:.2f} N, "
            f"output {curve.output_v[-1]:.3f} V ({curve.nodes} nodes, {curve.seconds:.1f} s)")
        try:
            static = Calibration.from_prediction_curve(curve)
            calibration: Calibration | RateCalibration = static
            if terms:
                static.source = f"fem:{curve.digest}+prony"
                calibration = RateCalibration(static, terms)
        except (PhysicsError, SensingError) as exc:  # e.g. an output that never grows
            self.get_logger().error(f"no calibration curve: {exc}")
            return
        if isinstance(calibration, RateCalibration):
            self.get_logger().info(f"calibration curve with the physics' rate terms, a "
                                   f"simulation's assumption: {calibration.describe()}")
        self._calibration = calibration
        if self._publisher is not None and self._publisher.is_activated:
            self._publish_curve()

    def _compute_array(self, params: PhysicsParams, cache_dir: str | None) -> None:
        def progress(fraction: float, message: str) -> None:
            self.get_logger().info(f"array grid {fraction:4.0%}: {message}",
                                   throttle_duration_sec=2.0)

        try:
            folder = Path(cache_dir) if cache_dir else None
            grid = load_or_compute_grid(params, folder, progress)
            # torque columns for a layout with off-centre windows (centred ones cannot
            # observe a torque)
            wrench_set = load_or_compute_wrench_set(params, folder, progress) \
                if off_centre(params) else None
            calibration, report = fit_grid(grid, degree=ARRAY_DEGREE) if wrench_set is None \
                else fit_wrench(grid, wrench_set, degree=ARRAY_DEGREE)
        except (PhysicsError, SensingError) as exc:
            self.get_logger().error(f"array calibration failed: {exc}")
            return
        self._array = calibration
        rmse = report["held_out_rmse_n"]
        self.get_logger().info(
            f"array calibration ready: {', '.join(grid.faces)}, {report['points']} grid "
            f"points, held-out rmse x {rmse['x'] * 1e3:.1f} mN, y {rmse['y'] * 1e3:.1f} mN, "
            f"z {rmse['z'] * 1e3:.1f} mN ({calibration.source}); observes "
            f"{', '.join(calibration.observed)}"
            + ("" if wrench_set is not None else
               " (centred windows cannot observe a torque: forces only)"))
        publisher = self._array_publisher
        if publisher is not None and publisher.is_activated:
            self._publish_array()

    def _publish_array(self) -> None:
        assert self._array is not None and self._array_publisher is not None
        msg = array_calibration_msg.to_msg(self._array)
        msg.header.stamp = self.get_clock().now().to_msg()
        self._array_publisher.publish(msg)

    def _publish_curve(self) -> None:
        assert self._calibration is not None and self._publisher is not None
        msg = calibration_curve_msg.to_msg(self._calibration)
        msg.header.stamp = self.get_clock().now().to_msg()
        self._publisher.publish(msg)

    def _on_predict(self, request: PredictOutput.Request,
                    response: PredictOutput.Response) -> PredictOutput.Response:
        curve = self._curve
        if curve is None:
            response.success = False
            response.message = (self._failure if self._failure is not None
                                else f"not ready, {self._progress:.0%} done")
            return response
        try:
            points = curve.at(list(request.indentation))
        except OutOfRangeError as exc:
            response.success = False
            response.message = str(exc)
            return response
        response.force = points.force_n.tolist()
        response.distance = points.distance_m.tolist()
        response.voltage = points.voltage_v.tolist()
        response.output = points.output_v.tolist()
        response.success = True
        response.message = f"fem:{curve.digest}"
        return response


def main(args: list[str] | None = None) -> int:
    return run_lifecycle_node(ModelNode, args)


if __name__ == "__main__":
    sys.exit(main())
