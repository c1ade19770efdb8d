"""Mock hardware node: the devices on pseudo-terminals plus the rig's ground truth.

One world per process, shared by every mock device in it, so the tactile signal, the
servo and the reference instruments agree:

- ``world: bench`` — the paper's compression rig with a three-axis stage and gauge. The
  mock ADC streams the module's signal; ``~/stage/joint_states`` (``stage_z``, ``stage_x``,
  ``stage_y``: indentation [m], positive into the sensor, and the probe's lateral
  displacement along +x and +y [m]) and ``~/gauge/wrench`` (``force.x/y/z`` [N], the probe's
  force on the skin, +z pressing in, with the viscoelastic rate effect) are published at
  the gauge rate with the sample times. When the physics parameter ``modules`` names
  several faces, the skin is the FEM array grid (``sim/array_world.py``) and ADC channel i
  carries the i-th face; ``protocol.shear`` > 0 runs the shear sweep. ``protocol.tilt``
  or ``protocol.twist`` > 0 runs the wrench protocol on the six-axis bench
  (``sim/wrench_world.py``): the stage adds ``stage_rx``, ``stage_ry``, ``stage_rz``
  [rad] and the gauge torque.x/y/z [N m] (the probe's torque on the skin about its centre,
  with the rate effect). The protocol
  (config/protocols.yaml) starts ``protocol.start_delay`` s after start-up, or on
  ``~/start``.
- ``world: bend`` — a soft finger bending at its joint (sim/bend_world.py, the FEM of
  physics/bend.py through nodes/bend_physics.py): the mock ADC streams its modules
  (``bend.modules``, channel i the i-th: joint, tip), ``~/joint_states`` carries the true
  joint angle ``finger_joint`` [rad] and ``~/tip/wrench`` the fingertip's contact force
  (force.z [N], into the pad), both at ``truth_rate`` with the sample times. The protocol's
  bends (``protocol.angle``, ``protocol.frequencies``, ``protocol.cycles``,
  ``protocol.tip_force``) or ``bend.actuation_profile`` drive it, started as the bench's.
- ``world: gripper`` — the soft gripper: an emulated XM430 moves the fingers, the rod
  indents the fingertip skin, the mock ADC streams finger A's modules, and
  ``~/ground_truth`` carries finger A's true skin force. With ``modules`` naming several
  faces finger A's skin is the FEM array grid: its modules read the press and the object's
  shear of the skin along the fingers (configuration ``gripper_shear``). With
  ``object.mass_kg`` > 0 the rod is an object that can slip along the fingers
  (sim/held_object.py): its skin force along them is force.x of ``~/ground_truth`` and
  ``~/object/joint_states`` carries its travel and slip; the emulator's control FIFO lifts
  it (``object lift``).
"""

from __future__ import annotations

import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger

from tactile_sensor.nodes.lifecycle_main import run_plain_node
from tactile_sensor.nodes.parameters import (
    ParameterError,
    ParamSpec,
    declare_parameters,
    read_parameters,
)
from tactile_sensor.nodes.physics_parameters import physics_from_values, physics_specs
from tactile_sensor.nodes.reading_cdr import JointStateCdr, WrenchCdr
from tactile_sensor.physics.detector import DetectorState, headroom_ratio
from tactile_sensor.physics.errors import PhysicsError
from tactile_sensor.physics.prediction import load_or_compute_curve
from tactile_sensor.physics.viscoelastic import RateDependentForce
from tactile_sensor.sensing.blind import SATURATION_V
from tactile_sensor.sim.adc_device import AdcNoise, MockAdcDevice
from tactile_sensor.sim.ambient_light import (
    SCENARIOS,
    LightScene,
    LitSource,
    parse_steps,
    scenario_scene,
)
from tactile_sensor.sim.array_world import ArrayBenchWorld, ArraySkin
from tactile_sensor.sim.bench_world import BenchRun, BenchWorld
from tactile_sensor.sim.drivetrain import DEFAULT_DRIVETRAIN as DRIVETRAIN
from tactile_sensor.sim.drivetrain import Drivetrain, DrivetrainError
from tactile_sensor.sim.errors import SimError
from tactile_sensor.sim.held_object import ObjectSpec, object_from_values
from tactile_sensor.sim.profiles import MAX_ROTATION_RAD, MAX_SHEAR_M, LoadProfile, array_profile
from tactile_sensor.sim.rig_refusals import RigSettings, rig_refusal
from tactile_sensor.sim.skin_response import TabulatedSkin
from tactile_sensor.sim.wrench_world import WrenchBenchWorld, WrenchSkin

SPECS = [
    ParamSpec("world", "bench", "which rig to simulate", choices=("bench", "gripper", "bend")),
    ParamSpec("adc_link", "/tmp/tactile_sensor/adc", "path of the mock ADC's serial device"),
    ParamSpec("adc_rate", 1000.0, "mock ADC sample rate [Hz] (paper: 1 kHz)", minimum=1.0,
              maximum=200_000.0),
    ParamSpec("adc_protocol", 2, "serial protocol of the mock ADC: 2 = one code per channel, "
              "3 = a modulated module (emitter on and off codes per channel; use adc_rate "
              "500), 1 = an old device that states nothing", minimum=1, maximum=3),
    ParamSpec("noise.white", -1.0, "white noise sigma [V] before quantisation; < 0 = the "
              "value that gives the paper's 31.5 dB with the 9-point average", maximum=10.0),
    ParamSpec("noise.drift", 0.001, "ambient-light drift sigma [V]", minimum=0.0,
              maximum=10.0),
    ParamSpec("noise.drift_tau", 120.0, "ambient-light drift correlation time [s]",
              minimum=0.0, exclusive_minimum=True),
    ParamSpec("ambient.dc_ratio", 0.0, "steady ambient photocurrent as a ratio of the "
              "emitter's at rest [1] (0 = the paper's dark room; docs/ambient.md)",
              minimum=0.0),
    ParamSpec("ambient.flicker_ratio", 0.0, "mean photocurrent of a lamp on the mains, "
              "flickering fully at ambient.flicker_hz, as a ratio of the emitter's at rest "
              "[1]", minimum=0.0),
    ParamSpec("ambient.flicker_hz", 100.0, "lamp flicker frequency [Hz]: twice the mains, "
              "100 or 120; below the ADC's Nyquist rate", exclusive_minimum=True,
              minimum=0.0),
    ParamSpec("ambient.steps", [], "ambient light switching: 'time:ratio' entries, from "
              "time [s] on the level changes by ratio [1]; seconds after the protocol starts "
              "(bench) or start-up (gripper); a shadow or a slow daylight change is a "
              "series of them"),
    ParamSpec("temperature.delta_k", 0.0, "module temperature above the calibration's [K]: "
              "the emitter's intensity, the detector's gain and dark current follow",
              minimum=-60.0, maximum=60.0),
    ParamSpec("emitter.output_ratio", 1.0, "emitter output as a fraction of a new one's [1] "
              "(ageing)", minimum=0.0, maximum=1.5),
    ParamSpec("skin.stiffness_ratio", 1.0, "skin stiffness against the FEM's [1] (all "
              "Mooney-Rivlin moduli scaled; single-module skins)", minimum=0.2, maximum=5.0),
    ParamSpec("seed", -1, "random seed of the noise; < 0 = different every run"),
    ParamSpec("cache_dir", "", "prediction cache folder; empty = default"),
    # bench
    ParamSpec("gauge_rate", 1000.0, "stage and gauge sampling rate [Hz] (paper: 1 kHz); the "
              "samples go out in 5 ms bursts, each stamped with its own time",
              minimum=1.0, maximum=10_000.0),
    ParamSpec("protocol.name", "compression", "protocol name (for the log and the bag)"),
    ParamSpec("protocol.depth", 0.003, "indentation at the bottom of each stroke [m]",
              minimum=0.0, maximum=0.02),
    ParamSpec("protocol.speeds", [0.001], "probe speeds [m/s], run in order"),
    ParamSpec("protocol.cycles", 1, "load/unload cycles per speed", minimum=1,
              maximum=100_000),
    ParamSpec("protocol.hold", 0.0, "hold at depth between loading and unloading [s]",
              minimum=0.0),
    ParamSpec("protocol.rest", 1.0, "rest before the first and after each cycle [s]",
              minimum=0.0),
    ParamSpec("protocol.shear", 0.0, "lateral amplitude of the shear sweep [m] (module "
              "arrays only: set the physics parameter modules); 0 = press only", minimum=0.0,
              maximum=MAX_SHEAR_M),
    ParamSpec("protocol.shear_directions", 8, "directions of the shear sweep: 4 = +x, -x, "
              "+y, -y; 8 = then the diagonals +x+y, -x-y, -x+y, +x-y", minimum=4, maximum=8,
              check=lambda n: None if n in (4, 8) else "give 4 or 8."),
    ParamSpec("protocol.tilt", 0.0, "largest probe tilt about x and y of the wrench protocol "
              "[rad] (needs >= 6 modules); 0 with twist 0 = no wrench protocol", minimum=0.0,
              maximum=MAX_ROTATION_RAD),
    ParamSpec("protocol.twist", 0.0, "largest probe twist about z of the wrench protocol [rad]",
              minimum=0.0, maximum=MAX_ROTATION_RAD),
    ParamSpec("protocol.angular_speed", 0.05, "tilt and twist speed of the wrench protocol "
              "[rad/s]", minimum=1e-4, maximum=1.0),
    ParamSpec("protocol.scenario", "", "light of the ambient protocol: dark, office, "
              "sunlight or shadow (sim/ambient_light.py, docs/ambient.md); '' = the ambient.* "
              "parameters alone", choices=("", *SCENARIOS)),
    ParamSpec("protocol.start_delay", 5.0, "start the protocol this long after start-up "
              "[s] (time for the driver to tare); < 0 = wait for ~/start"),
    # bend
    ParamSpec("bend.modules", "joint,tip", "the finger's modules, ADC channel i the i-th: "
              "joint (clipped over the joint) and tip (at the fingertip); a layout without "
              "joint is refused"),
    ParamSpec("bend.actuation_profile", [], "the finger's tendon tension itself in place of "
              "the protocol's bends: 'seconds:newtons' points [s:N], linear in between, "
              "seconds after the protocol starts; finite and >= 0; [] = the protocol's bends"),
    ParamSpec("protocol.angle", 1.5708, "joint angle at the top of each bend [rad] (bend "
              "world)", minimum=0.0, exclusive_minimum=True, maximum=3.1416),
    ParamSpec("protocol.frequencies", [0.5], "bend rates [Hz], run in order, protocol.cycles "
              "raised-cosine bends each (bend world)"),
    ParamSpec("protocol.tip_force", 0.0, "fingertip contact [N]: > 0 runs each rate's bends "
              "again while a contact rises to it and falls back (bend world)", minimum=0.0,
              maximum=10.0),
    ParamSpec("truth_rate", 1000.0, "rate of the bend world's ~/joint_states and ~/tip/wrench "
              "[Hz]", minimum=1.0, maximum=10_000.0),
    # gripper
    ParamSpec("servo_link", "/tmp/tactile_sensor/xm430", "path of the emulated XM430"),
    ParamSpec("servo_control", "", "FIFO accepting the emulator's fault-injection commands "
              "('fault overload', 'no-response on', ...; see tactile-sensor mock xm430 "
              "--help); empty = none"),
    ParamSpec("servo_id", 1, "Dynamixel id of the emulated servo", minimum=0, maximum=252),
    ParamSpec("servo_baud_rate", 1_000_000, "baud rate [bit/s] the emulator models",
              minimum=9600, maximum=4_500_000),
    ParamSpec("geometry.pitch_radius", 0.014, "pinion pitch radius [m]", minimum=0.0,
              exclusive_minimum=True),
    ParamSpec("geometry.open_opening", 0.060, "finger opening at the open end [m]",
              minimum=0.0, exclusive_minimum=True),
    ParamSpec("geometry.closed_opening", 0.002, "finger opening at the closed end [m]",
              minimum=0.0),
    # the servo's drivetrain at its output (sim/drivetrain.py gives each source)
    ParamSpec("drivetrain.torque_offset_nm", DRIVETRAIN.torque_offset_nm, "torque the "
              "motor loses before it turns anything [N m] (XM430-W350 performance graph's "
              "intercept, 0.22 N m, at the W210's 212.6:1 gear)"),
    ParamSpec("drivetrain.coulomb_friction_nm", DRIVETRAIN.coulomb_friction_nm, "Coulomb "
              "friction [N m] (Dynamixel MX-64, Duclusaud et al. 2024, model M4)"),
    ParamSpec("drivetrain.stribeck_friction_nm", DRIVETRAIN.stribeck_friction_nm, "extra "
              "friction at rest [N m] (MX-64, M4)"),
    ParamSpec("drivetrain.stribeck_velocity_rad_s", DRIVETRAIN.stribeck_velocity_rad_s,
              "speed over which the friction at rest falls off [rad/s] (> 0; MX-64, M4)"),
    ParamSpec("drivetrain.viscous_friction_nm_s", DRIVETRAIN.viscous_friction_nm_s,
              "viscous friction [N m s/rad] (MX-64, M4)"),
    ParamSpec("drivetrain.load_friction_ratio", DRIVETRAIN.load_friction_ratio, "friction "
              "at rest per N m the gears transmit [1] (< 1; MX-64, M4)"),
    ParamSpec("drivetrain.backlash_rad", DRIVETRAIN.backlash_rad, "play between the "
              "servo's output and the racks [rad] (X-series e-manual: 15 arcmin); below the "
              "rod's clearance"),
    ParamSpec("drivetrain.guide_friction_n", DRIVETRAIN.guide_friction_n, "friction of "
              "each finger's linear guide and rack [N] (ball carriage, coefficient 0.003 "
              "on the finger's weight)"),
    ParamSpec("drivetrain.ideal", False, "an ideal servo instead (torque = current x the "
              "datasheet's constant, no play): the drivetrain.* values are not used"),
    ParamSpec("rod.diameter", 0.020, "diameter of the rod between the fingers [m]; 0 = none",
              minimum=0.0),
    ParamSpec("rod.offset", 0.0, "rod centre offset from the gripper axis [m]"),
    ParamSpec("object.mass_kg", 0.0, "mass [kg] of an object held between the fingers in "
              "place of the fixed rod (its size and place are the rod's); 0 = none", minimum=0.0,
              maximum=100.0),
    ParamSpec("object.friction_static", 0.5, "static friction coefficient of the object on "
              "each skin [1] (> 0)"),
    ParamSpec("object.friction_kinetic", 0.5, "kinetic friction coefficient of the object "
              "on each skin [1] (> 0, <= object.friction_static)"),
    ParamSpec("object.load_profile", [], "pull on the object along the fingers, toward "
              "their tips: 'time:newtons' entries [s:N], seconds after the lift (`object "
              "lift` on servo_control), linear in between; added to its weight once lifted"),
    ParamSpec("ground_truth_rate", 200.0, "rate of ~/ground_truth [Hz]", minimum=1.0,
              maximum=2000.0),
]


#: The object along the fingers (+ toward their tips) [m]: its travel since the lift (the
#: skins' deflection included) and its slip over the skins (without it).
OBJECT_JOINTS = ("object_position", "object_slip")

#: On shutdown the devices stay until their clients closed them, at most this long [s].
RELEASE_WAIT_S = 3.0


class MockHardwareError(Exception):
    """The mock rig cannot start; the message names the parameter or file to fix."""


class ProtocolSource:
    """The ADC's voltage source: the world at rest until the protocol starts, then its run.

    The ADC asks in device seconds; the protocol starts at a device time set by
    :meth:`start`, so the gauge (stamped in host time from the same instant) and the
    module stay aligned to the ADC's clock.
    """

    def __init__(self, world: BenchRun) -> None:
        self.world = world
        self._start_device_s: float | None = None
        #: Bumped at each start: the ADC samples ahead of time and must sample again.
        self.revision = 0

    @property
    def start_device_s(self) -> float | None:
        return self._start_device_s

    @start_device_s.setter
    def start_device_s(self, value: float | None) -> None:
        self._start_device_s = value
        self.revision += 1

    def __call__(self, t: Any) -> Any:
        start = self._start_device_s
        if start is None:
            return self.world.module_voltages(np.zeros_like(np.asarray(t, float)))
        return self.world.module_voltages(np.maximum(np.asarray(t, float) - start, 0.0))


#: How far ahead [s] the stage and gauge are evaluated, in one call.
GAUGE_BLOCK_S = 0.05
#: The gauge publishes its samples in bursts this long [s], each stamped with its own time,
#: as a USB gauge delivers them: waking a thread every millisecond costs more than the work.
GAUGE_BURST_S = 0.005
#: The stage's joints: indentation (+ into the skin), lateral probe displacement along +x, +y.
STAGE_JOINTS = ("stage_z", "stage_x", "stage_y")
#: The six-axis stage adds the probe's tilt about x and y and twist about z [rad].
WRENCH_STAGE_JOINTS = (*STAGE_JOINTS, "stage_rx", "stage_ry", "stage_rz")


def stage_and_gauge(world: BenchRun, t: float
                    ) -> tuple[list[float], tuple[float, ...]]:
    """Stage positions (d, sx, sy [m], and rx, ry, rz [rad] on the six-axis bench) and gauge
    (Fx, Fy, Fz [N], then Tx, Ty, Tz [N m] on the six-axis bench) at protocol time t; a
    single-module bench has no lateral axis (0)."""
    stage, gauge = stage_and_gauge_block(world, np.array([t], dtype=float))
    return stage[0].tolist(), tuple(gauge[0].tolist())


def stage_and_gauge_block(world: BenchRun, t: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray]:
    """``stage_and_gauge`` at every time of ``t`` in one call: shapes (n, 3 or 6) each."""
    return world.stage_and_gauge(t)


class MockHardwareNode(Node):
    def __init__(self, node_name: str = "mock_hardware", **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        # Before anything can refuse: a node whose set-up raised is still destroyed by the
        # context's shutdown (Kilted's rclpy destroys every node it made), and closing the
        # devices must find nothing to close instead of failing (the context stayed up).
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self.emulator = None
        specs = physics_specs() + SPECS
        declare_parameters(self, specs)
        try:
            values = read_parameters(self, specs)
            physics = physics_from_values(values)
            noise = AdcNoise(drift_v=values["noise.drift"],
                             drift_tau_s=values["noise.drift_tau"],
                             **({"white_v": values["noise.white"]}
                                if values["noise.white"] >= 0 else {}))
            self.scene = LightScene(values["ambient.dc_ratio"], values["ambient.flicker_ratio"],
                                    values["ambient.flicker_hz"],
                                    parse_steps(values["ambient.steps"]),
                                    sample_rate_hz=values["adc_rate"])
            self.detector = DetectorState(values["temperature.delta_k"],
                                          values["emitter.output_ratio"])
            self.object_spec: ObjectSpec | None = object_from_values(
                values["object.mass_kg"], values["object.friction_static"],
                values["object.friction_kinetic"], values["object.load_profile"])
        except (ParameterError, PhysicsError, SimError) as exc:
            raise MockHardwareError(str(exc)) from None
        self.values = values
        self.faces: tuple[str, ...] = physics.module_faces
        rig = RigSettings(
            values["world"], len(self.faces), values["protocol.shear"], values["protocol.tilt"],
            values["protocol.twist"], values["skin.stiffness_ratio"],
            self.object_spec is not None, values["rod.diameter"], values["protocol.scenario"],
            self.scene.is_dark)
        if (refusal := rig_refusal(rig)) is not None:
            raise MockHardwareError(refusal)
        array, wrench = rig.array, rig.wrench
        cache = Path(values["cache_dir"]) if values["cache_dir"] else None
        skin: Any
        try:
            if values["world"] == "bend":  # the finger's own FEM (nodes/bend_physics.py)
                skin = held = None
            elif array:
                self.get_logger().info(
                    f"loading the array skin ({', '.join(self.faces)}; a first run computes "
                    "the FEM grid)")
                skin = (WrenchSkin if wrench else ArraySkin).from_params(
                    physics, cache, self._grid_progress)
            else:
                self.get_logger().info(
                    "loading the skin model (a first run computes the FEM sweep)")
                self.curve = load_or_compute_curve(physics, cache, self._progress)
                skin = TabulatedSkin.from_prediction_curve(self.curve)
            held = self._held_object(physics, cache)
        except (PhysicsError, SimError) as exc:
            raise MockHardwareError(str(exc)) from None
        seed = values["seed"] if values["seed"] >= 0 else None
        self.source: Any
        try:
            if values["world"] == "bend":
                self._build_bend(physics, cache)
            elif values["world"] == "bench":
                self._build_bench(skin, physics)
            elif array:  # finger A's modules from the grid, the fingers' forces as it reads
                self._build_gripper(skin.press_skin(), held, skin)
            else:
                self._build_gripper(skin, held)
            for path in self._links():
                Path(path).parent.mkdir(parents=True, exist_ok=True)
            faces = self.world.faces  # the ADC samples every module the world has
            self.adc = MockAdcDevice(values["adc_link"], self._lit(self.source, physics),
                                     rate_hz=values["adc_rate"], noise=noise, seed=seed,
                                     channels=len(faces), protocol=values["adc_protocol"])
            self.adc.start()
            if self.emulator is not None:
                self.emulator.start()
        except (SimError, OSError, ValueError) as exc:
            self.close_devices()
            raise MockHardwareError(f"Cannot start the mock devices: {exc}") from None
        self.get_logger().info(
            f"mock {values['world']} ready: ADC at {values['adc_link']}"
            + (f" ({len(faces)} channels: {', '.join(faces)})" if len(faces) > 1 else "")
            + (f", XM430 at {values['servo_link']}" if self.emulator is not None else ""))

    def _lit(self, source: Any, physics: Any) -> LitSource:
        """The world's voltages as the module outputs them under the scene's light, at its
        temperature and with its emitter's age."""
        v, supply = self.values, physics.supply_voltage
        rest = np.asarray(self.world.module_voltages(np.zeros(1)), dtype=float)[0]
        if v["protocol.scenario"]:
            room = min(headroom_ratio(float(r), supply, self.detector, SATURATION_V)
                       for r in rest)
            self.scene = scenario_scene(v["protocol.scenario"], room, v["adc_rate"])
            self.get_logger().info(f"ambient scenario '{v['protocol.scenario']}': {self.scene}")
        return LitSource(source, self.scene, self.detector, rest, supply)

    def _links(self) -> list[str]:
        return [self.values["adc_link"]] + (
            [self.values["servo_link"]] if self.emulator is not None else [])

    def _progress(self, fraction: float, message: str) -> None:
        self.get_logger().info(f"FEM sweep {fraction:4.0%}: {message}",
                               throttle_duration_sec=2.0)

    def _grid_progress(self, fraction: float, message: str) -> None:
        self.get_logger().info(f"FEM array grid {fraction:4.0%}: {message}",
                               throttle_duration_sec=2.0)

    # -- bench ---------------------------------------------------------------------------------
    def _build_bench(self, skin: TabulatedSkin | ArraySkin | WrenchSkin, physics: Any) -> None:
        v = self.values
        rate = RateDependentForce.from_params(physics)
        self.world: BenchRun
        if isinstance(skin, ArraySkin | WrenchSkin):
            profile = array_profile(depth_m=v["protocol.depth"],
                                    speeds_m_s=tuple(v["protocol.speeds"]),
                                    cycles=v["protocol.cycles"], hold_s=v["protocol.hold"],
                                    rest_s=v["protocol.rest"], shear_m=v["protocol.shear"],
                                    shear_directions=v["protocol.shear_directions"],
                                    tilt_rad=v["protocol.tilt"], twist_rad=v["protocol.twist"],
                                    angular_speed_rad_s=v["protocol.angular_speed"])
            world = WrenchBenchWorld if isinstance(skin, WrenchSkin) else ArrayBenchWorld
            self.world = world(profile, skin, rate,  # type: ignore[arg-type]
                               output_play_m=physics.output_play)
        else:
            profile = LoadProfile(depth_m=v["protocol.depth"],
                                  speeds_m_s=tuple(v["protocol.speeds"]),
                                  cycles=v["protocol.cycles"], hold_s=v["protocol.hold"],
                                  rest_s=v["protocol.rest"])
            self.world = BenchWorld(profile, skin, rate, output_play_m=physics.output_play,
                                    faces=physics.module_faces,
                                    stiffness_ratio=v["skin.stiffness_ratio"])
        self.source = ProtocolSource(self.world)
        self._start_host_ns: int | None = None
        self.published_until_ns = 0  # host time of the last stage/gauge sample published
        self.gauge_published = 0  # gauge samples published (the stage publishes as many)
        self._stage_pub = self.create_publisher(JointState, "~/stage/joint_states", 1000)
        self._gauge_pub = self.create_publisher(WrenchStamped, "~/gauge/wrench", 1000)
        self._truth_joints = WRENCH_STAGE_JOINTS
        self._truth_frame = "force_gauge"
        self._start_services(v["gauge_rate"])

    def _start_services(self, rate_hz: float) -> None:
        """~/start, the protocol's delayed start and the ground truth's thread."""
        self.create_service(Trigger, "~/start", self._on_start)
        delay = self.values["protocol.start_delay"]
        if delay >= 0:
            self._delay_timer = self.create_timer(delay, self._start_after_delay)
        thread = threading.Thread(target=self._publish_gauge, args=(rate_hz,),
                                  name="bench-gauge", daemon=True)
        self._threads.append(thread)
        thread.start()

    @property
    def protocol_duration_s(self) -> float:
        return self.world.duration_s

    @property
    def protocol_start_ns(self) -> int | None:
        """Host time [ns] at which the protocol started (None before)."""
        return self._start_host_ns

    @property
    def protocol_elapsed_s(self) -> float | None:
        if self._start_host_ns is None:
            return None
        return (time.time_ns() - self._start_host_ns) * 1e-9

    def start_protocol(self) -> bool:
        """Start the protocol now; False when it already runs."""
        if self._start_host_ns is not None:
            return False
        self.source.start_device_s = self.adc.elapsed_s
        self._start_host_ns = time.time_ns()
        self.get_logger().info(
            f"protocol '{self.values['protocol.name']}' started "
            f"({self.world.duration_s:.1f} s)")
        return True

    def _start_after_delay(self) -> None:
        self.destroy_timer(self._delay_timer)
        self.start_protocol()

    def _on_start(self, request: Trigger.Request, response: Trigger.Response
                  ) -> Trigger.Response:
        response.success = self.start_protocol()
        response.message = ("started" if response.success else "the protocol is already "
                            "running; restart the node to run it again")
        return response

    def _publish_gauge(self, rate_hz: float) -> None:
        """Stage and gauge at ``gauge_rate``, each sample stamped with its own time. The
        world is evaluated a block of samples at a time and both messages go out as CDR
        bytes (nodes/reading_cdr.py): one sample a millisecond leaves no room for per-sample
        numpy calls or message objects."""
        period_ns = int(1e9 / rate_hz)
        block = max(1, int(GAUGE_BLOCK_S * 1e9) // period_ns)
        burst_ns = max(period_ns, int(GAUGE_BURST_S * 1e9))
        stage: JointStateCdr | None = None
        gauge = WrenchCdr(self._truth_frame)
        first_ns, block_start, rows = 0, None, []  # the block: samples from first_ns on
        next_ns = time.time_ns()
        while not self._stop.is_set():
            now = time.time_ns()
            if now < next_ns + burst_ns - period_ns:
                self._stop.wait(min((next_ns + burst_ns - period_ns - now) * 1e-9, 0.01))
                continue
            start = self._start_host_ns
            while next_ns <= now and not self._stop.is_set():  # catch up after a stall
                i = (next_ns - first_ns) // period_ns
                if start != block_start or not 0 <= i < len(rows):
                    first_ns, block_start, i = next_ns, start, 0
                    times = next_ns + period_ns * np.arange(block)
                    t = (np.zeros(block) if start is None
                         else np.maximum(0.0, (times - start) * 1e-9))
                    positions, forces = stage_and_gauge_block(self.world, t)
                    rows = list(zip(positions.tolist(), forces.tolist(), strict=True))
                    joints = self._truth_joints[:positions.shape[1]]
                    if stage is None or stage.names != joints:
                        stage = JointStateCdr("", joints)
                position, f = rows[i]
                self._stage_pub.publish(stage.encode(next_ns, position))
                self._gauge_pub.publish(gauge.encode(next_ns, *f))
                self.published_until_ns = next_ns
                self.gauge_published += 1
                next_ns += period_ns

    # -- bend ----------------------------------------------------------------------------------
    def _build_bend(self, physics: Any, cache: Path | None) -> None:
        """The finger: its FEM response and actuator (nodes/bend_physics.py), the protocol's
        bends or the user's actuation; the true angle on ~/joint_states and the fingertip's
        contact on ~/tip/wrench, published at truth_rate as the bench's stage and gauge."""
        from tactile_sensor.nodes.bend_physics import bend_world
        from tactile_sensor.sim.bend_world import JOINT_NAME

        v = self.values
        self.get_logger().info("loading the finger's FEM (a first run computes it)")
        self.world = bend_world(v, cache, self._progress)  # type: ignore[assignment]
        self.source = ProtocolSource(self.world)  # type: ignore[arg-type]
        self._start_host_ns = None
        self.published_until_ns = 0
        self.gauge_published = 0
        self._stage_pub = self.create_publisher(JointState, "~/joint_states", 1000)
        self._gauge_pub = self.create_publisher(WrenchStamped, "~/tip/wrench", 1000)
        self._truth_joints = (JOINT_NAME,)
        self._truth_frame = "fingertip"
        self._start_services(v["truth_rate"])

    # -- gripper -------------------------------------------------------------------------------
    def _held_object(self, physics: Any, cache: Path | None) -> Any:
        """The object with mass, its skins' tangential stiffness from the FEM array grid of
        the gripper's skin (None: the fixed rod)."""
        if self.object_spec is None:
            return None
        from tactile_sensor.sim.held_object import HeldObject
        from tactile_sensor.sim.skin_shear import load_or_compute_stiffness

        self.get_logger().info("loading the skin's tangential stiffness (a first run "
                               "computes its FEM shear path)")
        stiffness = load_or_compute_stiffness(physics, cache, self._grid_progress).scaled(
            self.values["skin.stiffness_ratio"])
        # the fingers run along the skin block's x: it slips off past half its width
        return HeldObject(self.object_spec, stiffness,
                          lambda: RateDependentForce.from_params(physics),
                          reach_m=0.5 * physics.width)

    def _build_gripper(self, skin: TabulatedSkin, held: Any = None,
                       fingertip: ArraySkin | None = None) -> None:
        from tactile_sensor.control.geometry import GripperGeometry
        from tactile_sensor.sim.gripper_world import GripperWorld
        from tactile_sensor.sim.xm430_emulator import Xm430Emulator

        v = self.values
        try:
            geometry = GripperGeometry(pitch_radius_m=v["geometry.pitch_radius"],
                                       open_opening_m=v["geometry.open_opening"],
                                       closed_opening_m=v["geometry.closed_opening"])
        except ValueError as exc:
            raise MockHardwareError(f"Gripper geometry parameters are inconsistent: {exc}."
                                    ) from None
        self.world = GripperWorld(skin, geometry, rod_diameter_m=v["rod.diameter"] or None,
                                  rod_offset_m=v["rod.offset"],
                                  stiffness_ratio=v["skin.stiffness_ratio"], held=held,
                                  fingertip=fingertip)
        self.source = self.world.voltage_source
        try:
            drivetrain = None if v["drivetrain.ideal"] else Drivetrain.from_parameters(v)
            if drivetrain is not None:
                drivetrain.check_clearance(self.world.rod_clearance_rad)
        except DrivetrainError as exc:
            raise MockHardwareError(str(exc)) from None
        self.emulator = Xm430Emulator(v["servo_link"], servo_id=v["servo_id"],
                                      baudrate=v["servo_baud_rate"], world=self.world,
                                      control_path=v["servo_control"] or None,
                                      drivetrain=drivetrain)
        self._truth_pub = self.create_publisher(WrenchStamped, "~/ground_truth", 100)
        self._object_pub = None if held is None else self.create_publisher(
            JointState, "~/object/joint_states", 100)
        thread = threading.Thread(target=self._publish_truth_every,
                                  args=(1.0 / v["ground_truth_rate"],), name="ground-truth",
                                  daemon=True)
        self._threads.append(thread)
        thread.start()

    def _publish_truth_every(self, period_s: float) -> None:
        """The truth from its own thread, as the gauge's: a 200 Hz timer woke the
        executor of every node it shares 200 times a second (the in-process bringup's
        costliest idle wake-up after the gripper's)."""
        next_s = time.monotonic()
        while not self._stop.wait(max(0.0, next_s - time.monotonic())):
            next_s = max(next_s + period_s, time.monotonic() - period_s)
            if not self._publish_truth():  # nobody listens: look again in a while
                next_s = time.monotonic() + max(period_s, UNHEARD_TRUTH_CHECK_S)

    def _publish_truth(self) -> bool:
        """Publish the truth now; False when nobody subscribes (nothing built)."""
        if self._truth_pub.get_subscription_count() == 0 and (
                self._object_pub is None or self._object_pub.get_subscription_count() == 0):
            return False  # nobody checks against the truth: no message to build
        sample = self.world.latest
        msg = WrenchStamped()
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = "finger_a"
        msg.wrench.force.z = float(sample.force_a_n)
        held = sample.held
        if held is not None:
            msg.wrench.force.x = float(held.force_a_n)
        self._truth_pub.publish(msg)
        if held is not None and self._object_pub is not None:
            along = JointState()
            along.header = msg.header
            along.name = list(OBJECT_JOINTS)
            along.position = [held.position_m, held.slip_m]
            self._object_pub.publish(along)
        return True

    # -- shutdown ------------------------------------------------------------------------------
    def close_devices(self) -> None:
        """Stop the gauge thread, then the devices once their clients have closed them (at
        most ``RELEASE_WAIT_S``), so a client shutting down with us never sees its device
        vanish (idempotent)."""
        self._stop.set()
        for thread in self._threads:
            thread.join(timeout=5.0)  # before the publishers it uses are destroyed
        devices = [d for d in (getattr(self, "adc", None), self.emulator) if d is not None]
        deadline = time.monotonic() + RELEASE_WAIT_S
        for device in devices:
            device.link.wait_released(max(0.0, deadline - time.monotonic()))
        for device in devices:
            device.stop()

    def destroy_node(self) -> None:
        self.close_devices()
        super().destroy_node()


#: How often [s] the truth's thread looks for a listener while it has none: a subscriber's
#: first truth comes at most this late, and an unheard 200 Hz truth woke 200 times a second.
UNHEARD_TRUTH_CHECK_S = 0.1


def main(args: list[str] | None = None) -> int:
    sys.setswitchinterval(5e-4)  # several device threads must each answer within ~1 ms
    # the gauge thread stops before the context does
    return run_plain_node("mock_hardware", MockHardwareNode, (MockHardwareError,),
                          MockHardwareNode.close_devices, args, refused_code=2)


if __name__ == "__main__":
    sys.exit(main())
