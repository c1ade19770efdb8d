"""Contact and hold of the gripper's Grasp, and of current-limited grasping, on the mock.

The Grasp runs as the gripper node runs it: the node's default parameters, its goal runner
(control/goal_runner.py) and servo link, a control loop sampling the servo at
``control_rate``, and the XM430 emulator driving the gripper world (rod fixed between the
fingers). The tactile force is the world's finger-A force as the driver publishes it: every
1 kHz sample carries the paper's white noise (31.5 dB dynamic range after a 9-point mean:
sim/adc_device.py's σ at the ADC over the paper's 0.07 V/N sensitivity), goes through the
driver's default filter (causal Savitzky–Golay, 40 samples) and reaches the node after
``TRANSPORT_DELAY_S`` in the batches the node takes at once.

Current-limited grasping is the gripper without touch as ros2_control users run the XM430:
current-based position mode, the goal position beyond the object, Goal Current set to the
current whose torque (the datasheet's torque constant) balances the target force on both
fingers through the pinion.

Figures, per target force (ground truth = the world's finger-A force):
- peak true force over the grasp, against target × 1.10 + 0.05 N;
- true force 0.5 s after contact (first touch), within ±5 % of the target;
- true force when the grasp answered (what the caller then holds), within ±5 %;
- whether the result said "settled".
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from tactile_sensor.control.actions import accept_grasp, settings_from_parameters
from tactile_sensor.control.goal_runner import GoalLink, GoalRunner, GoalSlot, RunnerTiming
from tactile_sensor.control.servo_link import ServoLink
from tactile_sensor.control.tactile_force import TactileForce
from tactile_sensor.hardware.errors import CommunicationTimeout, CorruptPacket
from tactile_sensor.hardware.xm430 import Xm430Client
from tactile_sensor.nodes.gripper_parameters import SPECS
from tactile_sensor.sensing.filters import make_filter
from tactile_sensor.sim.adc_device import PAPER_SENSITIVITY_V_PER_N, white_noise_for_dynamic_range
from tactile_sensor.sim.drivetrain import DEFAULT_DRIVETRAIN, Drivetrain
from tactile_sensor.sim.gripper_world import GripperWorld
from tactile_sensor.sim.motor_model import TORQUE_CONSTANT_NM_PER_A
from tactile_sensor.sim.xm430_emulator import Xm430Emulator

TARGETS_N = (1.0, 1.5, 3.0, 5.0)
#: Driver → node: the ADC frame, the driver's processing and the topic (as bench_gripper).
TRANSPORT_DELAY_S = 0.005
SAMPLE_RATE_HZ = 1000.0
#: White noise of one tactile sample [N]: the ADC's σ over the paper's sensitivity.
NOISE_N = white_noise_for_dynamic_range() / PAPER_SENSITIVITY_V_PER_N
#: The node takes all waiting messages at once (nodes/gripper.py); this often.
DELIVERY_PERIOD_S = 0.002
#: Fingers open this far before each grasp (rod 20 mm: 5 mm to travel per finger) [m].
START_OPENING_M = 0.030
ROD_M = 0.020
#: "Contact" is the first true force above this [N].
TOUCH_N = 0.02
HOLD_AFTER_S = 0.5
BAUD = 1_000_000


def contact_goal_n(target_n: float) -> float:
    return target_n * 1.10 + 0.05


@dataclass(frozen=True)
class Grasp:
    """One grasp's ground truth."""

    peak_n: float
    held_n: float
    settled: bool
    message: str
    #: The true force when the grasp answered (the hold a caller gets; NaN: unknown).
    answered_n: float = math.nan


class Background:
    """A daemon thread running ``_run`` while ``_running``, for the span of a ``with``."""

    def __init__(self) -> None:
        self._running = True
        self.thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        raise NotImplementedError

    def __enter__(self) -> Background:
        self.thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._running = False
        self.thread.join()


class TactileFeed(Background):
    """Finger A's true force → noise → the driver's filter → the node's TactileForce."""

    def __init__(self, world: GripperWorld, t0: float, forces: TactileForce,
                 seed: int) -> None:
        super().__init__()
        self.world, self.t0, self.forces = world, t0, forces
        self.rng = np.random.default_rng(seed)
        self.filter = make_filter("savgol", SAMPLE_RATE_HZ)
        self._next = time.monotonic()
        self._pending: list[tuple[float, float]] = []

    def _run(self) -> None:
        period = 1.0 / SAMPLE_RATE_HZ
        while self._running:
            now = time.monotonic()
            while self._next <= now:
                true = self.world.force_at(self._next - self.t0)
                sensed = self.filter.update(true + NOISE_N * self.rng.standard_normal())
                self._pending.append((self._next, sensed))
                self._next += period
            due = [p for p in self._pending if p[0] <= now - TRANSPORT_DELAY_S]
            if due:
                self._pending = self._pending[len(due):]
                wall_offset = time.time() - now
                values = [f for _, f in due]
                self.forces.add(values[-1], due[-1][0] + wall_offset, float(sum(values)),
                                len(values), due[0][0] + wall_offset)
            time.sleep(DELIVERY_PERIOD_S)


class ControlLoop(Background):
    """The node's timer: sample the servo every control period."""

    def __init__(self, servo: ServoLink) -> None:
        self.servo = servo
        super().__init__()

    def _run(self) -> None:
        next_at = time.monotonic()
        while self._running:
            self.servo.poll()
            next_at += self.servo.period_s
            time.sleep(max(0.0, next_at - time.monotonic()))


def defaults() -> dict:
    return {spec.name: spec.default for spec in SPECS}


class Bench:
    """The emulator, the world and a client, shared by every grasp of a run."""

    def __init__(self, world: GripperWorld, emulator: Xm430Emulator,
                 client: Xm430Client) -> None:
        self.world, self.emulator, self.client = world, emulator, client
        self.values = defaults()
        self.settings = settings_from_parameters(self.values)
        self.geometry = self.settings.config.geometry

    def world_time(self) -> float:
        return time.monotonic() - self.emulator._t0

    def open_to(self, opening_m: float) -> None:
        link = ServoLink(self.client, self.settings.config, period_s=0.01)
        goal_rad = self.geometry.position_rad(opening_m)
        link.retrying(lambda: self.client.command_position(
            goal_rad, 3.0,
            goal_current_a=self.settings.config.closing_current_a))
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline:
            try:
                state = self.client.read_state()
            except (CommunicationTimeout, CorruptPacket):
                continue  # the busy loop can starve the emulator's thread; read again
            # through the drivetrain's friction the output rests short of its goal (its
            # P loop's error: ~17 pulses, 0.7 mm of opening); the profile has arrived
            arrived = abs(state.trajectory_position_rad - goal_rad) < 1e-3
            if arrived and not state.moving and abs(
                    self.geometry.opening_m(state.position_rad) - opening_m) < 2e-3:
                return
            time.sleep(0.01)
        raise RuntimeError(f"the fingers did not open to {opening_m * 1e3:.0f} mm")

    def truth(self, t_start: float, hold_for_s: float) -> tuple[float, float]:
        """(peak, force ``hold_for_s`` after the first touch; NaN without a touch) of the
        true force since ``t_start`` (world time); waits until that instant has passed."""
        give_up_at = self.world_time() + 3.0
        touch: float | None = None
        while True:
            now = self.world_time()
            times = np.arange(t_start, now - 2e-3, 1e-3)
            forces = np.array([self.world.force_at(t) for t in times])
            above = np.nonzero(forces > TOUCH_N)[0]
            if touch is None and above.size:
                touch = float(times[above[0]])
            if touch is not None and now - 2e-3 > touch + hold_for_s:
                return float(forces.max()), self.world.force_at(touch + hold_for_s)
            if touch is None and now > give_up_at:
                return float(forces.max(initial=0.0)), math.nan
            time.sleep(0.05)

    def goal_runner(self) -> tuple[ServoLink, TactileForce, GoalRunner, GoalLink]:
        """The gripper node's goal runner on this bench's servo, with the node's settings,
        and a link for goals nobody cancels."""
        values, settings = self.values, self.settings
        period = 1.0 / values["control_rate"]
        servo = ServoLink(self.client, settings.config, period_s=period,
                          retries=values["comm_retries"])
        forces = TactileForce()
        runner = GoalRunner(servo, forces, GoalSlot(),
                            RunnerTiming(period, 1.0 / values["feedback_rate"],
                                         values["settle_time"]),
                            on_hardware_error=lambda bits: None, log_error=print)
        return servo, forces, runner, GoalLink(object(), lambda: False, lambda fields: None)

    def tactile_grasp(self, target_n: float, seed: int) -> Grasp:
        settings = self.settings
        servo, forces, runner, link = self.goal_runner()
        goal = SimpleNamespace(target_force=target_n, closing_speed=0.0, timeout=0.0)
        t_start = self.world_time()
        with TactileFeed(self.world, self.emulator._t0, forces, seed), ControlLoop(servo):
            servo.await_sample(1.0)
            finish = runner.run(link, lambda: accept_grasp(goal, settings))
            answered_s = self.world_time()
            peak, held = self.truth(t_start, HOLD_AFTER_S)
        if not math.isfinite(held):
            print(f"    no touch: {finish.message}")
        return Grasp(peak, held, "settled at" in finish.message, finish.message,
                     self.world.force_at(answered_s) if math.isfinite(held) else math.nan)

    def current_limited_grasp(self, target_n: float) -> Grasp:
        """Goal Current for the target, goal position at the closed limit."""
        current_a = 2.0 * target_n * self.geometry.pitch_radius_m / TORQUE_CONSTANT_NM_PER_A
        speed = self.geometry.finger_speed_to_rad_s(self.values["default_closing_speed"])
        t_start = self.world_time()
        ServoLink(self.client, self.settings.config, period_s=0.01).retrying(
            lambda: self.client.command_position(self.geometry.closed_position_rad, speed,
                                                 goal_current_a=current_a))
        peak, held = self.truth(t_start, HOLD_AFTER_S)
        return Grasp(peak, held, True, f"goal current {current_a:.3f} A", held)


def run_grasps(bench: Bench, grasp: Callable[[float, int], Grasp], targets: tuple[float, ...],
               count: int) -> dict[float, list[Grasp]]:
    out: dict[float, list[Grasp]] = {}
    for target in targets:
        out[target] = []
        for k in range(count):
            bench.open_to(START_OPENING_M)
            out[target].append(grasp(target, k))
    bench.open_to(START_OPENING_M)
    return out


@dataclass(frozen=True)
class Row:
    target_n: float
    peak_max_n: float
    contact_met: bool
    held_mean_n: float
    held_worst_error: float
    within: int
    settled: int
    count: int
    #: Grasps whose true force when they answered was within ±5 %.
    within_answered: int = 0

    @property
    def hold_met(self) -> bool:
        return self.within >= self.count - self.count // 20 and self.settled >= self.within


def summarise(target: float, grasps: list[Grasp]) -> Row:
    peaks = [g.peak_n for g in grasps]
    # a grasp that never touched holds nothing: -100 %
    errors = [((g.held_n if math.isfinite(g.held_n) else 0.0) - target) / target
              for g in grasps]
    within = sum(abs(e) <= 0.05 for e in errors)
    settled = sum(g.settled and abs(e) <= 0.05 for g, e in zip(grasps, errors, strict=True))
    answered = sum(abs(g.answered_n - target) <= 0.05 * target for g in grasps)
    return Row(target, max(peaks), max(peaks) <= contact_goal_n(target),
               float(np.mean([g.held_n if math.isfinite(g.held_n) else 0.0
                              for g in grasps])),
               max(errors, key=abs), within, settled, len(grasps), answered)


def print_misses(target: float, grasps: list[Grasp]) -> None:
    """The grasps that missed the hold, with their answers (what a user would read)."""
    for g in grasps:
        if not (abs(g.held_n - target) <= 0.05 * target and g.settled):
            print(f"    {target:g} N: held {g.held_n:.3f} N at 0.5 s, {g.answered_n:.3f} N "
                  f"at the answer, peak {g.peak_n:.2f} N: {g.message}")


def print_table(title: str, rows: list[Row]) -> None:
    print(title)
    print("  target   peak max  (goal)     held mean  worst err  within±5%  settled&within"
          "  at answer")
    for r in rows:
        print(f"  {r.target_n:4.1f} N   {r.peak_max_n:5.2f} N  (≤{contact_goal_n(r.target_n):4.2f})"
              f" {'met ' if r.contact_met else 'FAIL'}  {r.held_mean_n:5.2f} N  "
              f"{r.held_worst_error * 100:+6.1f} %   {r.within:2d}/{r.count}      "
              f"{r.settled:2d}/{r.count} {'met' if r.hold_met else 'FAIL'}     "
              f"{r.within_answered:2d}/{r.count}")


#: The drivetrains a run can take (sim/drivetrain.py): the mock's default (the XM430-W210
#: from its sources), one held out from every choice of the hold's design (the other
#: servo Duclusaud et al. identified in the MX class, the MX-106 (M4, Rhoban/bam
#: params/mx106/m4.json: no Coulomb term, Stribeck 0.105 N m at 1.62 rad/s, viscous
#: 0.051 N m s/rad, load-dependent 0.222 + 0.009), the W350 graph's torque offset at the
#: output unscaled (0.22 N m), guide friction at the carriage's upper coefficient on a
#: 1 N finger), and the datasheet's ideal servo.
DRIVETRAINS: dict[str, Drivetrain | None] = {
    "default": DEFAULT_DRIVETRAIN,
    "held-out": Drivetrain(torque_offset_nm=0.22, coulomb_friction_nm=0.0,
                           stribeck_friction_nm=0.105, stribeck_velocity_rad_s=1.62,
                           viscous_friction_nm_s=0.051, load_friction_ratio=0.231,
                           backlash_rad=DEFAULT_DRIVETRAIN.backlash_rad,
                           guide_friction_n=0.003),
    "ideal": None,
}


def open_bench(link: Path, world: GripperWorld, drivetrain: Drivetrain | None = (
        DEFAULT_DRIVETRAIN)) -> tuple[Xm430Emulator, Xm430Client]:
    emulator = Xm430Emulator(link, baudrate=BAUD, world=world, drivetrain=drivetrain).start()
    client = Xm430Client(str(link), BAUD, 1, timeout_s=0.2)
    client.connect()
    bench_values = defaults()
    servo = ServoLink(client, settings_from_parameters(bench_values).config, period_s=0.01)
    servo.prepare(bench_values["current_limit"])
    client.set_torque(True)
    return emulator, client


