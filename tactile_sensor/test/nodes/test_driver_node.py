"""Mock photoreflector (own process) -> driver node (own process) -> this test, over ROS.

The mock streams a press from a skin table the test chooses, and the driver calibrates
with the matching calibration file, so the true force at every instant is known here.
"""

from __future__ import annotations

import json
import math
import signal
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from driver_listener import DriverListener, start_driver
from geometry_msgs.msg import WrenchStamped
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64

from tactile_sensor.configurations import config_dir
from tactile_sensor.hardware.adc_frame import crc16, encode_frame
from tactile_sensor.nodes import calibration_curve_msg
from tactile_sensor.physics.params import PhysicsParams
from tactile_sensor.sensing.calibration import Calibration
from tactile_sensor.sensing.rate_calibration import RateCalibration, RateTerm
from tactile_sensor.sim import firmware_host
from tactile_sensor.sim.firmware_host import PICO, UNO, HostFirmware
from tactile_sensor.sim.profiles import parse_profile
from tactile_sensor.sim.pty_link import PtyLink
from tactile_sensor_interfaces.msg import CalibrationCorrection, CalibrationCurve, TactileReading

FULL_SCALE_N = 7.0
DEPTH_M = 0.003
PROFILE = "ramp:depth=0.003,speed=0.001,cycles=1,hold=0.5,rest=2"
REST_V = 3.0
SPAN_V = 0.5  # module output at full scale: the paper's 0.07 V/N x 7 N
# Upper bound of a wait on a condition a busy machine may be slow to reach.
PATIENCE_S = 60.0


def skin_table() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    d = np.linspace(0.0, DEPTH_M, 61)
    force = FULL_SCALE_N * (d / DEPTH_M) ** 1.3
    voltage = REST_V - SPAN_V * (d / DEPTH_M)
    return d, force, voltage


@pytest.fixture
def files(tmp_path: Path) -> dict[str, Path]:
    d, force, voltage = skin_table()
    table = tmp_path / "skin.json"
    table.write_text(json.dumps({"indentation_m": d.tolist(), "force_n": force.tolist(),
                                 "voltage_v": voltage.tolist()}))
    calibration = tmp_path / "calibration.json"
    Calibration.from_curve((REST_V - voltage).tolist(), force.tolist(), "test").to_file(
        calibration)
    return {"table": table, "calibration": calibration, "link": tmp_path / "adc",
            "control": tmp_path / "adc.ctl"}


class Listener(DriverListener):
    """Collects the driver's topics in a background executor."""

    def __init__(self) -> None:
        self.readings: list[tuple[float, TactileReading]] = []
        self.wrenches: list[tuple[float, float]] = []
        self.diagnostics: list[tuple[float, DiagnosticStatus]] = []
        super().__init__("driver_listener")

    def subscribe(self) -> None:
        # As deep as the driver's queues (SAMPLE_QUEUE_DEPTH): 10 s of samples wait for a
        # listener that a busy machine starves.
        self.node.create_subscription(TactileReading, "/driver/reading",
                                      lambda m: self.readings.append((time.monotonic(), m)),
                                      10_000)
        self.node.create_subscription(
            WrenchStamped, "/driver/wrench",
            lambda m: self.wrenches.append((_stamp(m), m.wrench.force.z)), 10_000)
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self._on_diag, 100)

    def _on_diag(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            if "tactile ADC" in status.name:
                self.diagnostics.append((time.monotonic(), status))

    def await_driver(self) -> bool:
        """This listener has discovered the driver's sample topics, so it receives from
        their first message on (discovery beside a busy core once took longer than the
        mock's rest before its press, and the press's start was never received)."""
        return self.wait_for(lambda: all(
            self.node.count_publishers(t) > 0 for t in ("/driver/reading", "/driver/wrench")),
            PATIENCE_S)


def _stamp(msg) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


@pytest.fixture
def ros(ros_domain):
    with Listener.listening() as listener:
        yield listener


def start_mock(spawn, files: dict[str, Path], profile: str = PROFILE, *extra: str):
    child = spawn("mock", "adc", "--link", str(files["link"]), "--profile", profile,
                  "--skin-table", str(files["table"]), "--control", str(files["control"]),
                  "--seed", "1", *extra, module="tactile_sensor.cli")
    assert child.wait_for_output("mock adc:", 20), child.output()
    return child


def test_force_tracks_a_3mm_press_and_contact_has_hysteresis(spawn, ros, files):
    driver = start_driver(spawn, files["link"], files["calibration"],
                          "-p", "contact_on_force:=1.0", "-p", "contact_off_force:=0.5")
    assert driver.wait_for_output("active", 30), driver.output()
    assert ros.await_driver(), driver.output()
    mock = start_mock(spawn, files)
    duration = parse_profile(PROFILE).duration_s
    assert ros.wait_for(lambda: len(ros.wrenches) > 100, PATIENCE_S), driver.output()
    first = ros.wrenches[0][0]
    assert ros.wait_for(lambda: ros.wrenches[-1][0] - first > duration - 1.0,
                        PATIENCE_S)
    mock.stop()

    # one copy: the listener still appends what the driver had queued (two reads of the
    # live list once differed by one message)
    wrenches = list(ros.wrenches)
    stamps = np.array([s for s, _ in wrenches])
    force = np.array([f for _, f in wrenches])
    # Ground truth on the mock's clock; the driver's stamps share it up to an unknown
    # start offset, found as the shift that best aligns the two (searched over 1 s).
    d, table_force, _ = skin_table()
    profile = parse_profile(PROFILE)

    def truth(shift: float) -> np.ndarray:
        return np.interp(profile.indentation(stamps - shift), d, table_force)

    shifts = stamps[0] - np.linspace(0.0, 4.0, 801)
    errors = [np.sqrt(np.mean((force - truth(s)) ** 2)) for s in shifts]
    best = shifts[int(np.argmin(errors))]
    residual = force - truth(best)
    rmse, worst = float(np.sqrt(np.mean(residual**2))), float(np.max(np.abs(residual)))
    # Stated tolerance: RMSE within 5 % of full scale, every sample within 15 %.
    print(f"force vs truth: rmse {rmse:.3f} N, worst {worst:.3f} N, shift {stamps[0] - best:.3f} s")
    assert rmse < 0.05 * FULL_SCALE_N, (rmse, worst)
    assert worst < 0.15 * FULL_SCALE_N, (rmse, worst)
    assert force.max() == pytest.approx(FULL_SCALE_N, rel=0.1)

    contact = [(m.force, m.contact) for _, m in ros.readings if m.force == m.force]
    changes = [(f, c) for (f, c), (_, prev) in zip(contact[1:], contact[:-1], strict=True)
               if c != prev]
    assert [c for _, c in changes] == [True, False], changes
    on_force, off_force = changes[0][0], changes[1][0]
    assert on_force >= 1.0 - 0.3 and off_force <= 0.5 + 0.3
    assert on_force > off_force
    # following at rest by default; a stock module's optical gain cannot be measured
    status = ros.diagnostics[-1][1]
    assert _value(status, "rest_retares").isdigit(), status.values
    assert _value(status, "optical_gain").startswith("not measured"), status.values


def test_a_rate_aware_file_runs_its_model_on_every_sample(spawn, ros, files, tmp_path):
    """calibration_source: file with rate terms: the published force is the rate-aware one
    (the pure estimator replayed over the published outputs and stamps gives it back), above
    the static curve while loading, and the diagnostics name the model."""
    static = Calibration.from_file(files["calibration"])
    rate = RateCalibration(static, [RateTerm(g=0.4, tau_s=0.5)])
    rate_file = tmp_path / "rate_calibration.json"
    rate.to_file(rate_file)
    driver = start_driver(spawn, files["link"], rate_file)
    assert driver.wait_for_output("active", PATIENCE_S), driver.output()
    assert "rate-aware (1 term(s): g=0.4 tau=0.5 s)" in driver.output()
    # A 5 s rest first: the driver tares and this test hears tared readings before the press,
    # so the replay below starts where the driver's terms were at rest too.
    start_mock(spawn, files, "ramp:depth=0.003,speed=0.003,cycles=1,hold=1,rest=5")
    assert ros.wait_for(lambda: any(m.output == m.output for _, m in ros.readings), PATIENCE_S)
    assert ros.wait_for(lambda: any(m.force > 5.0 for _, m in ros.readings[-50:]), PATIENCE_S)
    assert ros.wait_for(lambda: all(m.force < 0.5 for _, m in ros.readings[-50:]), PATIENCE_S)
    assert ros.wait_for(lambda: any(
        _value(s, "calibration_model").startswith("rate-aware") for _, s in ros.diagnostics),
        PATIENCE_S)
    readings = [m for _, m in ros.readings if m.output == m.output]  # tared
    assert readings[0].force < 0.2  # heard from the rest on, not from inside the press
    stamps = np.array([_stamp(m) for m in readings])
    output = np.array([m.output for m in readings])
    force = np.array([m.force for m in readings])
    assert np.all(np.diff(stamps) > 0)  # every sample, in order (none lost between them)
    # The driver steps on the device's clock, 1 kHz exactly here (sim/adc_device.py). The
    # stamps are host times whose offset estimate (sensing/device_clock.py) steps down by
    # part of a period whenever a frame arrives with less delay than any before, as on a
    # busy machine (a replay on the raw stamps drifted 0.013 N from the driver's), so the
    # replay steps on the stamps' differences rounded to whole sample periods.
    period_s = 1e-3
    steps = np.maximum(1.0, np.rint(np.diff(stamps) / period_s))
    device_s = stamps[0] + period_s * np.concatenate(([0.0], np.cumsum(steps)))
    estimator = rate.estimator()
    replayed = np.array([estimator.update(v, t)[0] for v, t in zip(output, device_s,
                                                                     strict=True)])
    # The terms restart at the tare, at rest (no force, nothing to relax), just before the
    # first tared reading: compare from 1 s in, where any start-up difference has decayed.
    # The replay cannot be sample-exact on a busy machine (a reading this test's subscription
    # missed is bridged as a straight line; the period grid above is a reconstruction): it
    # has stayed within 0.013 N, against the up to 1.4 N the term adds while loading, which
    # the checks below measure.
    # A gap of many readings (this listener starved beside a busy core: 196 in a row, once)
    # bridges more of the driver's noise, and the replay strayed 0.026 N: readings within
    # 3 tau (1.5 s) after a gap of more than 10 are not judged, and at least 2 s of readings
    # are, 0.2 s of them pressing (above 1 N, where the term is at work).
    settled = stamps > stamps[0] + 1.0
    after_gap = np.zeros(stamps.size, dtype=bool)
    for gap_end in stamps[1:][steps > 10]:
        after_gap |= (stamps >= gap_end) & (stamps < gap_end + 1.5)
    judged = settled & ~after_gap
    static_force = np.array([static.evaluate(v)[0] for v in output])
    peak = int(np.argmax(static_force))
    rise = int(np.argmax(static_force > 1.0))
    pressing = static_force > 1.0
    assert judged.sum() > 2000 and (judged & pressing).sum() > 200, (
        judged.sum(), (judged & pressing).sum(), np.unique(steps))
    error = np.abs(force - replayed)[judged]
    worst = int(np.argmax(error))
    assert error[worst] < 0.02, (
        f"published force {error[worst]:.4f} N off the replay at "
        f"{stamps[judged][worst] - stamps[0]:.3f} s; stamp steps {np.unique(steps)}")
    # Loading: from 1 N on the rise to the peak (7 N/s for 1 s). The term then carries
    # g * rate * tau * (1 - exp(-t / tau)), up to 1.4 N; the static curve carries none.
    # The rise was heard, in time (about 0.86 s) and in readings (a listener starved on a
    # busy machine drops some of the 1 kHz stream: once 68 of about 860 were left).
    assert stamps[peak] - stamps[rise] > 0.5 and peak - rise >= 30, (
        stamps[peak] - stamps[rise], peak - rise)
    excess = force[rise:peak] - static_force[rise:peak]
    assert np.median(excess) > 0.5, np.median(excess)


def test_the_model_nodes_prony_terms_make_the_driver_rate_aware(spawn, ros, files):
    """calibration_source: model and the model's calibration_rate_terms: the latched curve
    carries physics' prony_g/prony_tau and /diagnostics name the rate-aware model; a curve
    with unpaired rate terms before it is ignored with one sentence. The driver latches the
    full scale of the curve it uses (none before it has one) for the gripper's ceiling."""
    driver = spawn("--ros-args", "-r", "__node:=driver", "-p", f"port:={files['link']}",
                   "-p", "calibration_source:=model", "-p", "autostart:=true",
                   module="tactile_sensor.nodes.driver")
    assert driver.wait_for_output("active", PATIENCE_S), driver.output()
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                         reliability=ReliabilityPolicy.RELIABLE)
    bad = ros.node.create_publisher(CalibrationCurve, "/calibration_curve", latched)
    bad.publish(CalibrationCurve(output=[0.0, 0.5], force=[0.0, 7.0], source="test:unpaired",
                                 rate_g=[0.05, 0.04], rate_tau=[0.1]))
    assert driver.wait_for_output("ignoring calibration curve: test:unpaired: the curve has 2 "
                                  "rate moduli (rate_g) but 1 relaxation times", PATIENCE_S), \
        driver.output()
    assert ros.wait_for(lambda: ros.diagnostics, PATIENCE_S)
    assert _value(ros.diagnostics[-1][1], "calibration_model") == "none"
    assert _value(ros.diagnostics[-1][1], "full_scale_force_n") == "none"
    # `bad` lives on with the node: destroying it while the listener's thread spins raced
    # that thread's wait set (rclpy took the destroyed publisher's event handler and the
    # thread died with "cannot use Destroyable because destruction was requested").
    full_scales: list[float] = []
    ros.node.create_subscription(Float64, "/driver/full_scale_force",
                                 lambda m: full_scales.append(m.data), latched)

    curves: list[CalibrationCurve] = []
    ros.node.create_subscription(CalibrationCurve, "/calibration_curve", curves.append, latched)
    model = spawn("--ros-args", "-r", "__node:=model",
                  "--params-file", str(config_dir() / "physics.yaml"),
                  "-p", "calibration_rate_terms:=true", "-p", "autostart:=true",
                  module="tactile_sensor.nodes.model")
    physics = PhysicsParams()
    assert ros.wait_for(lambda: any(m.source.endswith("+prony") for m in curves), 120), \
        model.output()
    curve = next(m for m in curves if m.source.endswith("+prony"))
    assert curve.source == f"fem:{physics.digest()}+prony"
    assert list(curve.rate_g) == list(physics.prony_g)
    assert list(curve.rate_tau) == list(physics.prony_tau)
    described = calibration_curve_msg.from_msg(curve).describe()
    assert described == "rate-aware (2 term(s): g=0.05 tau=0.1 s, g=0.04 tau=1.5 s)"
    assert ros.wait_for(lambda: _value(ros.diagnostics[-1][1], "calibration_model")
                        == described, PATIENCE_S), driver.output()
    assert _value(ros.diagnostics[-1][1], "full_scale_force_n") == f"{curve.force[-1]:.4g}"
    assert ros.wait_for(lambda: full_scales, PATIENCE_S)
    assert full_scales == [curve.force[-1]]  # nothing for the curve it ignored
    assert f"calibration from {curve.source} ({len(curve.output)} points, {described})" \
        in driver.output()
    assert "simulation's assumption" in model.output()

    # a self-check's correction, found after the model's curve, applies over it (rate
    # terms kept); one stamped before the curve in use is ignored in one sentence
    correction = ros.node.create_publisher(CalibrationCorrection, "/calibration_correction",
                                           latched)
    found = CalibrationCorrection(source="test:found", optical_gain=0.8, stiffness=1.15)
    found.header.stamp = ros.node.get_clock().now().to_msg()
    correction.publish(found)
    assert ros.wait_for(lambda: len(full_scales) > 1, PATIENCE_S), driver.output()
    assert full_scales[-1] == pytest.approx(1.15 * curve.force[-1])
    assert f"calibration from {curve.source} corrected by test:found (optical gain 0.8000, " \
        f"stiffness 1.1500, {described})" in driver.output()
    stale = CalibrationCorrection(source="test:stale", optical_gain=0.7, stiffness=1.3)
    stale.header.stamp = curve.header.stamp
    correction.publish(stale)
    assert driver.wait_for_output("the correction test:stale is older than the one in use",
                                  PATIENCE_S), driver.output()


def test_tare_succeeds_at_rest_and_is_refused_while_pressing(spawn, ros, files):
    driver = start_driver(spawn, files["link"], files["calibration"],
                          "-p", "auto_tare:=false")
    assert driver.wait_for_output("active", 30), driver.output()
    # The tare at rest must fall into the mock's first rest (device time): 10 s of it, of
    # which the test needs ~1 s when idle (3 s were missed beside a busy loop: 'not at
    # rest, moved 77 mV'). The mock has no command to start the press on cue.
    start_mock(spawn, files, "ramp:depth=0.003,speed=0.001,cycles=3,hold=0,rest=10")
    assert ros.wait_for(lambda: len(ros.readings) > 800, PATIENCE_S)
    assert all(m.output != m.output for _, m in ros.readings[:50])  # NaN before any tare
    at_rest = ros.call_tare()
    assert at_rest.success, at_rest.message
    assert "baseline" in at_rest.message
    # Asked while pressing, past the toe (past 0.25 V the output moves about 0.1 V per 0.5 s
    # at 1 mm/s, over the tare's 50 mV bound; at 0.1 V the toe had moved only 24.8 mV). A
    # busy core holds this listener's readings, and each call, back by seconds (fresh-clone
    # runs: answered at rest three presses in a row), so the tare is asked again and again
    # until the press is over, on each of the three presses. Pressing is judged on the
    # voltage, which a tare that happened to find the press's turn at rest does not move.
    rest_v = float(np.mean([m.voltage for _, m in ros.readings[:50]]))

    def displaced_v(index: int = -1) -> float:
        return abs(ros.readings[index][1].voltage - rest_v)

    def pressed_past_the_toe(cursor: list[int]) -> bool:
        end = len(ros.readings)
        found = any(displaced_v(i) > 0.25 for i in range(cursor[0], end))
        cursor[0] = end
        return found

    refused = None
    for _ in range(3):
        cursor = [len(ros.readings)]
        assert ros.wait_for(lambda cursor=cursor: pressed_past_the_toe(cursor), PATIENCE_S)
        while refused is None and displaced_v() > 0.05:
            answer = ros.call_tare()
            if not answer.success:
                refused = answer
        if refused is not None:
            break
    assert refused is not None, "every tare asked during three presses was answered at rest"
    assert "rest" in refused.message.lower(), refused.message


def test_garbage_is_rejected_and_unplug_is_survived(spawn, ros, files):
    driver = start_driver(spawn, files["link"], files["calibration"])
    assert driver.wait_for_output("active", 30), driver.output()
    start_mock(spawn, files, "ramp:depth=0.001,speed=0.001,cycles=1,hold=0,rest=1", "--loop")
    assert ros.wait_for(lambda: len(ros.wrenches) > 500, PATIENCE_S)
    control = files["control"]
    for _ in range(10):
        control.write_text("garbage 10000\n")
        time.sleep(0.05)
    # the garbage reached the driver (was: sleep 1 s and hope), then 1 s of readings after
    crc_seen = ros.wait_for(lambda: any(
        int(_value(s, "crc_errors")) + int(_value(s, "bytes_discarded")) > 0
        for _, s in ros.diagnostics), PATIENCE_S)
    assert crc_seen
    seen = len(ros.readings)
    assert ros.wait_for(lambda: len(ros.readings) > seen + 250, PATIENCE_S)
    # No bad frame accepted: every reading after the garbage is a plausible voltage.
    voltages = np.array([m.voltage for _, m in ros.readings])
    assert voltages.min() > REST_V - SPAN_V - 0.3 and voltages.max() < REST_V + 0.3

    control.write_text("unplug 1.5\n")
    unplugged_at = time.monotonic()
    assert ros.wait_for(lambda: any(s.level == DiagnosticStatus.ERROR and t >= unplugged_at
                                    for t, s in ros.diagnostics), PATIENCE_S)
    error = next(s for t, s in ros.diagnostics
                 if s.level == DiagnosticStatus.ERROR and t >= unplugged_at)
    # reported from the failed read / missing port (both say "unplugged"), not from the
    # 1 s silence timeout: how fast is a benchmark's business, not a bound a busy machine
    # can break (was: < 0.5 s by the time the test process received it)
    assert "unplugged" in error.message, error.message
    back = len(ros.readings)
    assert ros.wait_for(lambda: len(ros.readings) > back + 100, PATIENCE_S)
    assert driver.proc.poll() is None  # no restart


def _value(status: DiagnosticStatus, key: str) -> str:
    return next((kv.value for kv in status.values if kv.key == key), "0")


@pytest.mark.parametrize(("parameter", "value"), [
    ("adc_bits", "17"), ("filter_type", "kalman"), ("contact_off_force", "2.0"),
    ("baud_rate", "'fast'"), ("gain_warn_bound", "1.5"),
])
def test_a_bad_parameter_fails_configure_naming_it(spawn, ros_domain, files, parameter, value):
    driver = start_driver(spawn, files["link"], files["calibration"],
                          "-p", f"{parameter}:={value}")
    assert driver.wait_for_output("configure transition failed", 30), driver.output()
    assert f"'{parameter}'" in driver.output()
    assert "Traceback" not in driver.output()
    assert driver.proc.poll() is None  # still running, can be reconfigured


def test_a_missing_calibration_file_fails_configure_with_the_path(spawn, ros_domain, files,
                                                                     tmp_path):
    driver = start_driver(spawn, files["link"], tmp_path / "nope.json")
    assert driver.wait_for_output("configure transition failed", 30), driver.output()
    assert "nope.json" in driver.output()
    assert "Traceback" not in driver.output()


# -- the real firmware (compiled for this computer) in the loop ----------------------------

needs_gxx = pytest.mark.skipif(firmware_host.compiler() is None,
                               reason="no g++ on this computer (apt-get install g++)")


@pytest.fixture(scope="session")
def firmware_builds(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    out = tmp_path_factory.getbasetemp() / "firmware-build"
    return {board.name: firmware_host.build(board, out) for board in (UNO, PICO)}


def _steady_force(ros, volts: float, device: HostFirmware) -> float:
    """Median force of 100 readings from 100 samples after the driver first saw ``volts``
    (synchronised on the data, not the clock: a starved driver may lag the device)."""
    device.set_voltage(volts)
    start = len(ros.readings)

    def first_at_level() -> int | None:
        return next((i for i, (_, m) in enumerate(ros.readings[start:], start)
                     if abs(m.voltage - volts) < 0.01), None)

    assert ros.wait_for(lambda: first_at_level() is not None, PATIENCE_S)
    first = first_at_level()
    assert ros.wait_for(lambda: len(ros.readings) > first + 200, PATIENCE_S)
    return float(np.median([m.force for _, m in ros.readings[first + 100:first + 200]]))


@needs_gxx
def test_a_10_and_a_12_bit_board_give_the_same_force_with_nothing_configured(
        spawn, ros, files, firmware_builds):
    # The user swaps an Uno (10 bit, 5 V) for a Pico (12 bit, 3.3 V) under a running driver.
    pressed_v, rest_v = REST_V - 0.3, REST_V
    _, force, voltage = skin_table()
    truth = float(np.interp(pressed_v, voltage[::-1], force[::-1]))
    driver = start_driver(spawn, files["link"], files["calibration"])
    assert driver.wait_for_output("active", 30), driver.output()
    forces = {}
    for board in (UNO, PICO):
        with HostFirmware(firmware_builds[board.name], files["link"], board) as device:
            device.set_voltage(rest_v)
            name = "avr" if board is UNO else "rp2040"
            assert ros.wait_for(lambda n=name: any(
                n in _value(s, "device") for _, s in ros.diagnostics[-3:]), 10)
            # Press only once the driver has tared on this board (force is NaN before): on
            # a quiet machine the press otherwise lands inside the first tare window.
            seen = len(ros.readings)
            assert ros.wait_for(lambda s=seen: any(
                math.isfinite(m.force) and abs(m.voltage - rest_v) < 0.01
                for _, m in ros.readings[s:]), 10)
            forces[board.name] = _steady_force(ros, pressed_v, device)
            assert _steady_force(ros, rest_v, device) == pytest.approx(0.0, abs=0.05)
    print(f"force for a {rest_v - pressed_v:.1f} V press: {forces}, truth {truth:.3f} N")
    # 1 code of the 10-bit board (4.9 mV) is 0.08 N on this curve
    assert forces["uno"] == pytest.approx(truth, abs=0.15)
    assert forces["pico"] == pytest.approx(truth, abs=0.15)
    assert abs(forces["uno"] - forces["pico"]) < 0.15
    assert driver.output().count("ADC device: protocol 2") == 2
    assert "rp2040, 12 bit, 3.3 V" in driver.output()


@needs_gxx
def test_a_configuration_the_device_contradicts_is_an_error_and_no_force(
        spawn, ros, files, firmware_builds):
    with HostFirmware(firmware_builds["uno"], files["link"], UNO) as device:
        device.set_voltage(REST_V)
        driver = start_driver(spawn, files["link"], files["calibration"],
                              "-p", "adc_bits:=12")
        assert driver.wait_for_output("active", 30), driver.output()
        assert ros.wait_for(lambda: any(s.level == DiagnosticStatus.ERROR
                                        for _, s in ros.diagnostics), 10)
        time.sleep(1.0)
    error = next(s for _, s in ros.diagnostics if s.level == DiagnosticStatus.ERROR)
    assert error.message.startswith("adc_bits is configured as 12 bit but the device sends "
                                    "10-bit codes: no force is published")
    assert _value(error, "device").startswith("protocol 2, avr, 10 bit, 5 V")
    assert ros.wrenches == [] and ros.readings == []
    assert driver.output().count("adc_bits is configured as 12 bit") == 1  # logged once
    assert "Traceback" not in driver.output()


def test_a_version_1_device_works_with_one_warning(spawn, ros, files):
    driver = start_driver(spawn, files["link"], files["calibration"],
                          "-p", "adc_bits:=12", "-p", "reference_voltage:=5.0")
    assert driver.wait_for_output("active", 30), driver.output()
    start_mock(spawn, files, "ramp:depth=0.001,speed=0.001,cycles=1,hold=0,rest=1",
               "--protocol", "1", "--loop")
    assert ros.wait_for(lambda: len(ros.wrenches) > 500, PATIENCE_S), driver.output()
    files["control"].write_text("unplug 0.5\n")  # a reconnection: the same device again
    # reconnected (was: sleep 0.6 s, which a busy machine can end before the unplug)
    assert ros.wait_for(lambda: driver.output().count("ADC connected: receiving frames")
                        >= 2, PATIENCE_S), driver.output()
    count = len(ros.wrenches)
    assert ros.wait_for(lambda: len(ros.wrenches) > count + 500, PATIENCE_S)
    log = driver.output()
    assert log.count("does not state its resolution: using the configured 12 bit and 5 V") == 1
    assert "[WARN]" in log.split("does not state its resolution")[0].rsplit("\n", 1)[-1]


def test_a_device_whose_info_is_unusable_is_a_warning_that_says_why(spawn, ros, files):
    # Version-2 data frames, but the info frame (good CRC) states a 0-bit ADC.
    bad = b"\xa5\x5a\x20\x09" + bytes([0, 1, 0x88, 0x13, 0xE8, 3, 0, 0, 0])
    bad += crc16(bad[2:]).to_bytes(2, "little")
    stop = threading.Event()
    with PtyLink(files["link"]) as link:

        def device() -> None:
            k = 0
            while not stop.is_set():
                link.write_all(bad + b"".join(encode_frame(k + i, (k + i) * 1000, [500])
                                              for i in range(50)))
                k += 50
                time.sleep(0.05)

        thread = threading.Thread(target=device, daemon=True)
        thread.start()
        driver = start_driver(spawn, files["link"], files["calibration"])
        assert driver.wait_for_output("active", 30), driver.output()
        try:
            assert ros.wait_for(lambda: any(
                "waiting for the device's info frame" in s.message
                and "its last was unusable: adc_bits 0 is not 1..16" in s.message
                for _, s in ros.diagnostics), 10), [s.message for _, s in ros.diagnostics]
        finally:
            stop.set()
            thread.join(2.0)
    warn = next(s for _, s in ros.diagnostics if "unusable" in s.message)
    assert warn.level == DiagnosticStatus.WARN
    assert ros.wrenches == [] and ros.readings == []


def test_a_frame_id_set_while_running_names_every_later_reading(spawn, ros, files):
    """The messages are serialised from a template per frame id: a new one takes effect."""
    driver = start_driver(spawn, files["link"], files["calibration"])
    assert driver.wait_for_output("active", PATIENCE_S), driver.output()
    start_mock(spawn, files)
    assert ros.wait_for(lambda: len(ros.readings) > 200, PATIENCE_S)
    assert ros.readings[-1][1].header.frame_id == "tactile_sensor"
    client = ros.node.create_client(SetParameters, "/driver/set_parameters")
    assert client.wait_for_service(timeout_sec=PATIENCE_S)
    future = client.call_async(SetParameters.Request(parameters=[
        Parameter("frame_id", value="left_fingertip").to_parameter_msg()]))
    assert ros.wait_for(future.done, PATIENCE_S)
    assert future.result().results[0].successful
    # Samples stamped 0.3 s after the answer (this listener may still be reading older
    # ones; stamps are the device's time mapped to this clock).
    set_at = time.time()
    assert ros.wait_for(lambda: _stamp(ros.readings[-1][1]) > set_at + 0.3, PATIENCE_S)
    later = [m for _, m in list(ros.readings) if _stamp(m) > set_at + 0.3]
    assert later and {m.header.frame_id for m in later} == {"left_fingertip"}


def test_a_driver_behind_its_adc_skips_the_live_force_to_the_newest_and_records_every_sample(
        spawn, ros, files):
    """A driver stopped for a while (as a starved process is) finds a second of frames
    waiting: ~/reading still carries every one of them, ~/wrench only the newest (within
    live_window), and /diagnostics counts what the live topic skipped."""
    driver = start_driver(spawn, files["link"], files["calibration"])
    assert driver.wait_for_output("active", 30), driver.output()
    assert ros.await_driver(), driver.output()
    start_mock(spawn, files)
    assert ros.wait_for(lambda: len(ros.wrenches) > 500, PATIENCE_S), driver.output()
    driver.send_signal(signal.SIGSTOP)
    try:
        # the frames pile up in the pseudo-terminal while the driver cannot run
        stopped_at = ros.readings[-1][1].header.stamp
        time.sleep(1.0)
    finally:
        driver.send_signal(signal.SIGCONT)
    stopped_s = stopped_at.sec + stopped_at.nanosec * 1e-9
    assert ros.wait_for(lambda: _reading_stamps(ros)[-1] > stopped_s + 2.0, PATIENCE_S)
    assert ros.wait_for(lambda: any(int(_value(s, "wrench_skipped")) > 0
                                    for _, s in list(ros.diagnostics)), PATIENCE_S)

    readings = _reading_stamps(ros)
    gaps = np.diff(readings[readings > stopped_s - 0.5])
    assert gaps.max() < 0.0025, f"the record lost samples: a gap of {gaps.max():.4f} s"
    wrench = np.array([s for s, _ in list(ros.wrenches)])
    # the stopped second's readings waited as one block: the live topic carried only its
    # newest live_window (10 ms), so its stamps jump where the record's do not
    live_gaps = np.diff(wrench[wrench > stopped_s - 0.5])
    assert live_gaps.max() > 0.5, f"the live force replayed the backlog: {live_gaps.max():.4f} s"


def _reading_stamps(ros) -> np.ndarray:
    return np.array([_stamp(m) for _, m in list(ros.readings)])
