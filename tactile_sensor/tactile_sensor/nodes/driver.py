"""Driver node: photoreflector ADC on a serial port -> calibrated contact force.

Wiring only: parameters, the reader (hardware/), the signal chain (sensing/), topics,
the tare service and diagnostics. The calibration in use is the base one (a file, or the
model's latched ``calibration_curve``) under the latest correction the gripper's
self-check latched on ``calibration_correction`` (sensing/calibration_correction.py: their
stamps, not the order they come in, decide). The reader's thread reads the port, and the same thread
runs each chunk's samples through the chain and publishes them as pre-serialised CDR
(nodes/reading_cdr.py): no executor and no thread hand-off between the serial port and
the force topic, while the reader's drain thread keeps the port emptied if publishing is
starved. ADC frames lost anyway (sequence gaps, a full backlog) are counted in /diagnostics and
logged as a warning. The ADC's resolution and reference come from the device's info
frame unless configured (sensing/adc_settings.py); a contradiction is a diagnostics ERROR
and no force is published.
"""

from __future__ import annotations

import sys
import time
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.lifecycle import State, TransitionCallbackReturn
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

from tactile_sensor.hardware.adc_frame import DeviceInfo
from tactile_sensor.hardware.adc_reader import AdcStreamReader, ConnectionState
from tactile_sensor.hardware.adc_samples import SampleBatch
from tactile_sensor.hardware.errors import HardwareError
from tactile_sensor.nodes import (
    array_calibration_msg,
    calibration_correction_msg,
    calibration_curve_msg,
)
from tactile_sensor.nodes.diagnostics_msg import diagnostic_array
from tactile_sensor.nodes.driver_parameters import SPEC_BY_NAME, SPECS
from tactile_sensor.nodes.guarded_lifecycle import GuardedLifecycleNode
from tactile_sensor.nodes.lifecycle_main import run_lifecycle_node
from tactile_sensor.nodes.parameters import (
    ParameterError,
    declare_parameters,
    read_parameters,
)
from tactile_sensor.nodes.reading_cdr import JointStateCdr, ReadingCdr, WrenchCdr
from tactile_sensor.sensing.adc_health import FrameRate, LossCounter, adc_health
from tactile_sensor.sensing.adc_settings import AdcSettings, resolve_adc
from tactile_sensor.sensing.array_chain import (
    ArrayChain,
    ArrayReading,
    build_chain,
    parse_modules,
)
from tactile_sensor.sensing.bend_chain import (
    BendChain,
    BendReading,
    bend_health,
    parse_bend_modules,
)
from tactile_sensor.sensing.calibration_correction import CorrectedCalibration
from tactile_sensor.sensing.chain import Reading, SignalChain
from tactile_sensor.sensing.chain_parameters import (
    RUNTIME_PARAMETERS,
    chain_config,
    configure_only_refusal,
    publish_period_ns,
    with_runtime_changes,
)
from tactile_sensor.sensing.device_clock import DeviceClock
from tactile_sensor.sensing.errors import SensingError, TareError
from tactile_sensor.sensing.live_force import LiveSelector
from tactile_sensor.sensing.modulation import modulation_of
from tactile_sensor.sensing.rate_calibration import describe_model
from tactile_sensor_interfaces.msg import ArrayCalibration as ArrayCalibrationMsg
from tactile_sensor_interfaces.msg import (
    CalibrationCorrection,
    CalibrationCurve,
    TactileReading,
)

#: Readings a reliable subscriber may fall behind before the publisher's KEEP_LAST history
#: drops them unacknowledged: 10 s at 1 kHz, as deep as the recorder's own queue. With 100
#: the recorder lost 34-247 readings at a time while a model process started beside it,
#: with 2000 it lost 2,691 after a CPU burner left 2,433 frames to publish at once
#: (benchmarks/soak.py).
SAMPLE_QUEUE_DEPTH = 10_000
CALIBRATION_QOS = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                             reliability=ReliabilityPolicy.RELIABLE)



class DriverNode(GuardedLifecycleNode):
    def __init__(self, node_name: str = "driver", **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        declare_parameters(self, SPECS)
        self.add_on_set_parameters_callback(self._check_runtime_change)
        self.add_post_set_parameters_callback(self._apply_runtime_change)
        self._values: dict[str, Any] = {}
        self._faces: list[str] = []  # of the modules, [] with one module
        self._chain: SignalChain | ArrayChain | BendChain | None = None
        self._reader: AdcStreamReader | None = None
        self._clock_map = DeviceClock()
        self._publish_every_ns = 0
        self._next_publish_ns = 0
        self._frame_rate = FrameRate()
        self._cdr: tuple[ReadingCdr, WrenchCdr] | None = None  # swapped whole: frame_id
        self.published_readings = 0  # ~/reading messages published since construction
        self.published_until_ns = 0  # stamp of the newest reading (sent where heard)
        self._loss = LossCounter()  # ADC frames lost, as last logged
        self._adc: AdcSettings | None = None  # decided on the device's info, per connection
        self._info_logged: DeviceInfo | None = None
        self._wrench_pub = self._reading_pub = self._diag_pub = None
        self._tare_srv = self._calibration_sub = self._diag_timer = None
        self._correction_sub: Any = None
        self._full_scale_pub: Any = None
        self._joint_pub: Any = None  # a bending finger's joint angle
        self._joint_cdr: JointStateCdr | None = None
        self._out_of_range_reported = 0  # angles beyond the calibration, as last reported
        self._calibrations = CorrectedCalibration()
        self._live = LiveSelector()
        self._active_since: float | None = None  # time.monotonic() of the last activation

    @property
    def ready(self) -> bool:
        """Forces are flowing: tared and calibrated."""
        chain = self._chain
        return chain is not None and chain.tared and chain.calibration is not None

    # -- lifecycle -------------------------------------------------------------------------
    def on_configure(self, state: State) -> TransitionCallbackReturn:
        try:
            values = read_parameters(self, SPECS)
            modules = parse_modules(values["modules"])
            bend = parse_bend_modules(values["bend_modules"]) if values["bend_modules"] else ()
            if bend and modules:
                raise SensingError("Parameters 'modules' and 'bend_modules' both name modules; "
                                   "a finger's go in bend_modules alone, so leave modules "
                                   "empty.")
            chain: SignalChain | ArrayChain | BendChain
            if bend:
                chain = BendChain(chain_config(values), bend, bend_calibration(values, bend))
            else:
                chain = build_chain(chain_config(values), modules, values["calibration_file"]
                                    if values["calibration_source"] == "file" else None,
                                    values["torque_cutoff_hz"])
            reader = AdcStreamReader(values["port"], on_batch=self._on_batch,
                                     on_state=self._on_state, baudrate=values["baud_rate"],
                                     backlog=values["reader_backlog"],
                                     on_info=self._on_info,
                                     read_period_s=values["read_period"])
        except (ParameterError, SensingError, HardwareError) as exc:
            self.get_logger().error(f"configure failed: {exc}")
            return TransitionCallbackReturn.FAILURE
        self._values, self._chain, self._reader = values, chain, reader
        self._faces = [m.face for m in modules] or [m.place for m in bend if len(bend) > 1]
        self._clock_map = DeviceClock()
        self._loss = LossCounter()
        self._live = LiveSelector(values["live_window"])
        self._adc = self._info_logged = None
        self._publish_every_ns = publish_period_ns(values)
        self._cdr = _encoders(values["frame_id"], self._faces)
        self._out_of_range_reported = 0
        if bend:
            self._joint_cdr = JointStateCdr(values["frame_id"], (values["joint_name"],))
            self._joint_pub = self.create_lifecycle_publisher(JointState, "~/joint_states",
                                                              SAMPLE_QUEUE_DEPTH)
        self._wrench_pub = self.create_lifecycle_publisher(WrenchStamped, "~/wrench",
                                                             SAMPLE_QUEUE_DEPTH)
        self._reading_pub = self.create_lifecycle_publisher(TactileReading, "~/reading",
                                                              SAMPLE_QUEUE_DEPTH)
        self._diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._tare_srv = self.create_service(Trigger, "~/tare", self._on_tare)
        self._full_scale_pub = self.create_publisher(Float64, "~/full_scale_force",
                                                     CALIBRATION_QOS)
        self._publish_full_scale()
        if bend:
            pass  # calibrated from the FEM (or its file) above
        elif values["calibration_source"] == "model" and modules:
            self._calibration_sub = self.create_subscription(
                ArrayCalibrationMsg, "array_calibration", self._on_array_calibration,
                CALIBRATION_QOS)
        elif values["calibration_source"] == "model":
            self._calibration_sub = self.create_subscription(
                CalibrationCurve, "calibration_curve", self._on_calibration, CALIBRATION_QOS)
        if not modules and not bend:
            self._calibrations = CorrectedCalibration(chain.calibration)
            self._correction_sub = self.create_subscription(
                CalibrationCorrection, "calibration_correction", self._on_correction,
                CALIBRATION_QOS)
        self._diag_timer = self.create_timer(values["diagnostics_period"],
                                             self._publish_diagnostics)
        self.get_logger().info(
            f"configured: {values['port']} at {values['baud_rate']} bit/s, filter "
            f"{values['filter_type']}, calibration from {values['calibration_source']}"
            + (f" ({chain.calibration.describe()})" if isinstance(chain, BendChain)
               and chain.calibration else f" ({describe_model(chain.calibration)})"
               if chain.calibration else "")
            + (f", modules {values['modules']}" if modules else ""))
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: State) -> TransitionCallbackReturn:
        result = super().on_activate(state)
        assert self._reader is not None
        self._reader.start()
        self._active_since = time.monotonic()
        return result

    def no_frame_for(self) -> tuple[float, str] | None:
        """(seconds active without a single ADC frame, the reader's reason) while none came
        yet; None once one came or while inactive. A bringup fails on it in seconds."""
        reader, since = self._reader, self._active_since
        if reader is None or since is None or reader.stats().frames:
            return None
        return time.monotonic() - since, reader.reason

    def on_deactivate(self, state: State) -> TransitionCallbackReturn:
        self._active_since = None
        if self._reader is not None:
            self._reader.stop()
            discarded = self._reader.stats().discarded_at_stop
            if discarded:
                self.get_logger().info(f"stopped with {discarded} ADC sample(s) read but not "
                                       "yet processed; they were not published")
        return super().on_deactivate(state)

    def on_cleanup(self, state: State) -> TransitionCallbackReturn:
        self._teardown()
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: State) -> TransitionCallbackReturn:
        self._teardown()
        return TransitionCallbackReturn.SUCCESS

    def _teardown(self) -> None:
        if self._reader is not None:
            self._reader.stop()
        for timer in (self._diag_timer,):
            if timer is not None:
                self.destroy_timer(timer)
        if self._tare_srv is not None:
            self.destroy_service(self._tare_srv)
        for sub in (self._calibration_sub, self._correction_sub):
            if sub is not None:
                self.destroy_subscription(sub)
        self._correction_sub = None
        for pub in (self._wrench_pub, self._reading_pub, self._joint_pub):
            if pub is not None:
                self.destroy_lifecycle_publisher(pub)
        self._joint_pub = self._joint_cdr = None
        for plain in (self._diag_pub, self._full_scale_pub):
            if plain is not None:
                self.destroy_publisher(plain)
        self._full_scale_pub = None
        self._reader = self._chain = None
        self._wrench_pub = self._reading_pub = self._diag_pub = None
        self._tare_srv = self._calibration_sub = self._diag_timer = None

    # -- ros2 param set while configured -------------------------------------------------------
    def _check_runtime_change(self, params: list[Parameter]) -> SetParametersResult:
        if self._chain is None:  # unconfigured: every parameter is read on configure
            return SetParametersResult(successful=True)
        refusal = configure_only_refusal([p.name for p in params], SPEC_BY_NAME,
                                         self.get_fully_qualified_name())
        if refusal is not None:
            return SetParametersResult(successful=False, reason=refusal)
        try:
            self._runtime_values(params)
        except (ParameterError, SensingError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _runtime_values(self, params: list[Parameter]) -> dict[str, Any]:
        return with_runtime_changes(self._values, {p.name: p.value for p in params},
                                    lambda name, value: SPEC_BY_NAME[name].validate(value))

    def _apply_runtime_change(self, params: list[Parameter]) -> None:
        chain = self._chain
        changed = [p for p in params if p.name in RUNTIME_PARAMETERS]
        if chain is None or not changed:
            return
        values = self._runtime_values(changed)
        chain.reconfigure(chain_config(values))
        self._publish_every_ns = publish_period_ns(values)
        if values["frame_id"] != self._values["frame_id"]:
            self._cdr = _encoders(values["frame_id"], self._faces)
        self._values = values
        self.get_logger().info("changed while running: " + ", ".join(
            f"{p.name} = {values[p.name]}" for p in changed))

    # -- data path (reader thread) -----------------------------------------------------------
    def _on_batch(self, batch: SampleBatch) -> None:
        chain, adc = self._chain, self._adc
        if chain is None or adc is None or not adc.usable:
            return  # the device contradicts the configuration: no force (diagnostics ERROR)
        try:
            readings = chain.process_batch(batch)
        except SensingError as exc:
            self.get_logger().error(str(exc), throttle_duration_sec=5.0)
            return
        stamp, epoch, every = self._clock_map.stamp_ns, batch.epoch, self._publish_every_ns
        stamps = [stamp(epoch, r.device_time_us, r.host_time_ns) for r in readings]
        due: list[int] = []  # the readings ~/wrench may carry, at publish_rate
        for i, stamp_ns in enumerate(stamps):
            if stamp_ns >= self._next_publish_ns:
                self._next_publish_ns = stamp_ns + every
                due.append(i)
        if not stamps:
            return
        self.published_until_ns = stamps[-1]
        # Only what someone listens to is encoded and sent: an idle gripper stack has no
        # recorder, and 1,000 ~/reading messages a second nobody takes cost the driver
        # more than its signal chain.
        reading_pub, wrench_pub = self._reading_pub, self._wrench_pub
        record = reading_pub is not None and reading_pub.get_subscription_count() > 0
        joint_pub, joint_cdr = self._joint_pub, self._joint_cdr
        if joint_pub is not None and joint_cdr is not None and \
                joint_pub.get_subscription_count() > 0:  # the angle: every published sample
            for i in due:
                joint_pub.publish(joint_cdr.encode(stamps[i], (readings[i].angle_rad,)))
        live: set[int] = set()
        if wrench_pub is not None and wrench_pub.get_subscription_count() > 0:
            reader = self._reader
            first = self._live.first_live([stamps[i] for i in due],
                                          reader is not None and reader.samples_waiting > 0)
            live = set(due[first:])
        if record:  # the record: every sample, whatever publish_rate paces ~/wrench at
            for i, (reading, stamp_ns) in enumerate(zip(readings, stamps, strict=True)):
                self._publish(reading, stamp_ns, True, i in live)
        elif live:
            for i in due:
                self._publish(readings[i], stamps[i], False, i in live)

    def _publish(self, reading: Reading | ArrayReading | BendReading, stamp_ns: int,
                 record: bool, live: bool) -> None:
        """On ~/reading when ``record`` (someone records), on ~/wrench when ``live`` and the
        reading has a force."""
        encoders, reading_pub, wrench_pub = self._cdr, self._reading_pub, self._wrench_pub
        if encoders is None:
            return
        force = reading.force_n
        message = wrench = None
        if type(reading) is BendReading:  # the tip force, NaN where it is not observed
            if record:
                message = encoders[0].encode(stamp_ns, reading.voltage_v, reading.output_v,
                                             force, reading.contact,
                                             *((reading.voltages_v, reading.outputs_v)
                                               if len(reading.voltages_v) > 1 else ()))
            if live and reading.angle_rad == reading.angle_rad:
                wrench = encoders[1].encode(stamp_ns, 0.0, 0.0, force)
        elif type(reading) is ArrayReading:
            if record:
                message = encoders[0].encode(stamp_ns, reading.voltage_v, reading.output_v,
                                             force, reading.contact, reading.voltages_v,
                                             reading.outputs_v)
            if live and force == force:  # not NaN
                wrench = encoders[1].encode(stamp_ns, reading.force_x_n, reading.force_y_n,
                                            force, reading.torque_x_nm, reading.torque_y_nm,
                                            reading.torque_z_nm)
        else:
            if record:
                message = encoders[0].encode(stamp_ns, reading.voltage_v, reading.output_v,
                                             force, reading.contact)
            if live and force == force:
                wrench = encoders[1].encode(stamp_ns, 0.0, 0.0, force)
        if message is not None and reading_pub is not None:
            reading_pub.publish(message)
            self.published_readings += 1
        if wrench is not None and wrench_pub is not None:
            wrench_pub.publish(wrench)

    def _on_info(self, info: DeviceInfo) -> None:
        """The device said what its codes mean (before its first sample, on each connection)."""
        values = self._values
        chain = self._chain
        if chain is None:
            return
        adc = resolve_adc(info, values["adc_bits"] or None, values["reference_voltage"] or None,
                          chain.top_channel, values["sample_rate"])
        if adc.conversion is not None:
            chain.set_conversion(adc.conversion)
        try:  # channel 0 is sampled first after each switch: the least settled
            chain.set_modulation(modulation_of(info, 0))
        except SensingError as exc:
            self.get_logger().error(f"The device's modulation cannot be read: {exc}")
        self._adc = adc
        if info != self._info_logged:  # once per device, not once per reconnection
            self._info_logged = info
            log = self.get_logger()
            log.info(f"ADC device: {info.summary()}; counts -> volts {adc.source.value}")
            if not adc.usable:
                log.error(adc.problem)
            elif adc.problem:
                log.warning(adc.problem)
        self._publish_diagnostics()

    def _on_state(self, state: ConnectionState, reason: str) -> None:
        log = self.get_logger()
        if state is ConnectionState.DISCONNECTED:
            log.error(f"ADC disconnected: {reason}")
        else:
            log.info(f"ADC {state.value}: {reason}")
        if state is ConnectionState.CONNECTED and self._chain is not None:
            self._chain.reset()
        self._publish_diagnostics()

    # -- services and subscriptions ----------------------------------------------------------
    def _on_tare(self, request: Trigger.Request, response: Trigger.Response
                 ) -> Trigger.Response:
        if self._chain is None:
            response.success, response.message = False, "driver is not configured"
            return response
        try:
            result = self._chain.tare()
        except TareError as exc:
            response.success, response.message = False, str(exc)
            return response
        response.success, response.message = True, result.describe()
        self.get_logger().info(f"tared: {response.message}")
        return response

    def _on_calibration(self, msg: CalibrationCurve) -> None:
        if self._chain is None:
            return
        try:
            calibration = calibration_curve_msg.from_msg(msg)
        except SensingError as exc:
            self.get_logger().error(f"ignoring calibration curve: {exc}")
            return
        changed, note = self._calibrations.set_base(
            calibration, msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9)
        if note:
            self.get_logger().warning(note)
        if changed:
            self._use_calibration(f"{len(msg.output)} points")

    def _on_correction(self, msg: CalibrationCorrection) -> None:
        if self._chain is None:
            return
        try:
            correction = calibration_correction_msg.from_msg(msg)
        except SensingError as exc:
            self.get_logger().error(f"ignoring calibration correction: {exc}")
            return
        changed, note = self._calibrations.set_correction(correction)
        if note:
            self.get_logger().warning(note)
        elif self._calibrations.base is None:
            self.get_logger().info(f"correction {correction.source} waits for a calibration")
        if changed:
            self._use_calibration(f"optical gain {correction.optical_gain:.4f}, stiffness "
                                  f"{correction.stiffness:.4f}")

    def _use_calibration(self, what: str) -> None:
        """Put the base calibration under its correction into the chain, and say so."""
        chain, calibration = self._chain, self._calibrations.effective
        if chain is None or calibration is None:
            return
        chain.set_calibration(calibration)
        self._publish_full_scale()
        self.get_logger().info(f"calibration from {calibration.source} "
                               f"({what}, {describe_model(calibration)})")

    def _on_array_calibration(self, msg: ArrayCalibrationMsg) -> None:
        chain = self._chain
        if not isinstance(chain, ArrayChain):
            return
        try:
            chain.set_calibration(array_calibration_msg.from_msg(msg))
        except SensingError as exc:
            self.get_logger().error(f"ignoring array calibration: {exc}")
            return
        self._publish_full_scale()
        cal = chain.calibration
        unseen = cal.unobserved_reason() if cal is not None else ""
        self.get_logger().info(f"array calibration from {chain.calibration_source} "
                               f"({', '.join(chain.faces)}; observes "
                               f"{', '.join(cal.observed) if cal else 'nothing'})"
                               + (f"; NaN for {unseen}" if unseen else ""))
        self._publish_diagnostics()

    def _publish_full_scale(self) -> None:
        """Latch the most force the calibration reports [N], the gripper's force ceiling."""
        chain, pub = self._chain, self._full_scale_pub
        if chain is not None and chain.calibration is not None and pub is not None:
            pub.publish(Float64(data=float(chain.calibration.full_scale_force_n)))

    # -- diagnostics ---------------------------------------------------------------------------
    def _publish_diagnostics(self) -> None:
        reader, chain, pub = self._reader, self._chain, self._diag_pub
        if reader is None or chain is None or pub is None:
            return
        stats = reader.stats()
        rate = self._frame_rate.update(stats.frames)
        lost_now, warning = self._loss.update(stats)
        if warning is not None:
            self.get_logger().warning(warning)
        subscribers = {"reading": self._reading_pub.get_subscription_count(),
                       "wrench": self._wrench_pub.get_subscription_count()}
        health = adc_health(stats, self._adc, chain, rate, lost_now,  # type: ignore[arg-type]
                            self.published_readings, subscribers, self._live.skipped)
        if isinstance(chain, BendChain):
            health = bend_health(health, chain, self._out_of_range_reported)
            self._out_of_range_reported = chain.out_of_range
        pub.publish(diagnostic_array(f"{self.get_fully_qualified_name()}: tactile ADC",
                                     str(self._values["port"]), health,
                                     self.get_clock().now().to_msg()))


def bend_calibration(values: dict[str, Any], modules: Any) -> Any:
    """A finger's calibration: its file (calibration_source file), or fitted on the FEM's
    table for these modules (nodes/bend_physics.py, cached)."""
    from tactile_sensor.sensing.bend_calibration import BendCalibration

    if values["calibration_source"] == "file":
        return BendCalibration.from_file(values["calibration_file"])
    from tactile_sensor.nodes.bend_physics import fem_bend_calibration

    return fem_bend_calibration(tuple(m.place for m in modules), values["bend_cache_dir"] or None)


def _encoders(frame_id: str, faces: list[str]) -> tuple[ReadingCdr, WrenchCdr]:
    """~/reading's and ~/wrench's byte layouts for this frame and these faces."""
    return ReadingCdr(frame_id, faces), WrenchCdr(frame_id)


def main(args: list[str] | None = None) -> int:
    return run_lifecycle_node(DriverNode, args)


if __name__ == "__main__":
    sys.exit(main())
