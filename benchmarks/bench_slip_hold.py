"""The adaptive hold against a fixed one, offline: the pure hold in closed loop with the
mock's own world at the control tick, no ROS, so it is fast and repeatable.

What runs (as the mock does it, without its threads): ``sim.gripper_world.GripperWorld``
on the FEM skin with a ``sim.held_object.HeldObject`` (the FEM's tangential stiffness,
the silicone's rate effect, slipping off the skins past half their width), driven by
``sim.motor_model.MotorModel`` in current-based position mode at the gripper's defaults
(stop velocity 6 rad/s, 0.6 A); the world steps at 1 ms. Each 10 ms control tick the hold
(``control.slip_hold.SlipHold``, at the gripper node's defaults) gets the means of the
forces since the last tick, ``DELAY_S`` old (the driver and the topic; ``--delay-ms``
for a loaded machine's, figures printed only), each 1 kHz sample
with the shear fingertip's white noise (docs/gripper.md: 38.9 mN of Ft and 57.0 mN of Fn
at 10 Hz); its goal reaches the servo at once.

The scenario is the slip study's (``analysis.slip.signature.Scenario``): the object is
gripped at the starting force, lifted (its weight eased on over 0.3 s), held for
``HOLD_S`` while the hold learns, then its load doubles over 100 ms. The starting force
keeps the weight (``START_OVER_LEAST`` x its least grip at the kinetic friction) but not
the doubled load, so a fixed hold at it slips.

Figures per object and in sum: the friction learned against the true ones, the slip (all
of it, and from the doubling on), the peak grip from the doubling on over the least grip
that holds the doubled load (``least_grip_n`` at the static friction), from the slip's
onset after the doubling to the grip rising (``RISE_N`` over its level then; negative: it
rose first), whether it fell; and the same object under a fixed hold at the starting force.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_slip_hold.py [--objects N] [--delay-ms D]
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tactile_sensor"))

from results import Figure, write_results

from tactile_sensor.analysis.slip.fem import indentation_for
from tactile_sensor.analysis.slip.signature import Scenario, least_grip_n
from tactile_sensor.control.geometry import GripperGeometry
from tactile_sensor.control.grasp import GraspConfig
from tactile_sensor.control.slip_hold import SHEAR_FINGERTIP_NOISE, SlipHold, SlipHoldConfig
from tactile_sensor.hardware.xm430_table import RAD_PER_PULSE
from tactile_sensor.physics.params import PhysicsParams
from tactile_sensor.physics.viscoelastic import RateDependentForce
from tactile_sensor.sim.drivetrain import DEFAULT_DRIVETRAIN, Drivetrain
from tactile_sensor.sim.gripper_world import GripperWorld
from tactile_sensor.sim.held_object import HeldObject, ObjectSpec
from tactile_sensor.sim.motor_model import MotorCommand, MotorModel
from tactile_sensor.sim.skin_response import default_skin
from tactile_sensor.sim.skin_shear import load_or_compute_stiffness

MASSES_KG = (0.05, 0.1, 0.2, 0.3)
STATIC_FRICTION = (0.3, 0.5, 0.7, 1.0)
KINETIC_SHARE = (1.0, 0.8)
#: World step [s] and the control tick [s] (the gripper's control_rate, 100 Hz).
WORLD_STEP_S = 1e-3
TICK_S = 0.01
#: The tactile forces reach the hold this late: the ADC frame, the driver, the topic [s].
DELAY_S = 0.005
#: The settle that leaves the grasp (``Loop._settled_goal``): rounds of a close from this
#: far open [rad], each this long [s].
SETTLE_ROUNDS = 8
SETTLE_FROM_RAD = 0.02
SETTLE_S = 0.3
#: Rod (the object's size across the fingers) [m].
ROD_M = 0.020
#: Gripped before the lift [s]; held after the lift before the doubling [s]; after it [s].
GRIPPED_S = 0.5
HOLD_S = 3.0
AFTER_S = 1.5
#: The starting force over the least grip that keeps the weight at the kinetic friction.
START_OVER_LEAST = 1.25
#: The gripper's max_grasp_force: the adaptive hold's ceiling [N].
CEILING_N = 10.0
#: The grip has risen once it is this far above its level at the onset [N].
RISE_N = 0.05
#: Goal figures (docs/gripper.md, "The adaptive hold").
SLIP_GOAL_MM = 2.0
GRIP_GOAL = 1.5
LATENCY_GOAL_MS = 30.0


@dataclass(frozen=True)
class Run:
    """One object under one hold: what the world's ground truth says of it."""

    friction: float | None
    slip_mm: float
    slip_after_doubling_mm: float
    peak_after_doubling_n: float
    least_doubled_n: float
    onset_to_rise_ms: float | None
    #: From the load's doubling starting to the grip rising [ms] (None: it did not rise).
    doubling_to_rise_ms: float | None
    dropped: bool

    @property
    def grip_ratio(self) -> float:
        return self.peak_after_doubling_n / self.least_doubled_n


def objects() -> list[Scenario]:
    """The study's objects, each gripped at its starting force."""
    out = []
    for m in MASSES_KG:
        for mu in STATIC_FRICTION:
            for share in KINETIC_SHARE:
                s = Scenario(m, mu, mu * share, 1.0, hold_s=HOLD_S, after_s=AFTER_S)
                start = START_OVER_LEAST * least_grip_n(s.weight_n, s.friction_kinetic)
                out.append(replace(s, grip_n=start))
    return out


class Loop:
    """The world, the motor and (for the adaptive hold) the hold, one world step at a time."""

    def __init__(self, scenario: Scenario, adaptive: bool, seed: int,
                 delay_s: float = DELAY_S,
                 drivetrain: Drivetrain | None = DEFAULT_DRIVETRAIN) -> None:
        params = PhysicsParams()
        self.delay_s = delay_s
        self.geometry = GripperGeometry()
        self.config = GraspConfig()
        skin = default_skin()
        spec = ObjectSpec(scenario.mass_kg, scenario.friction_static,
                          scenario.friction_kinetic, scenario.load())
        held = HeldObject(spec, load_or_compute_stiffness(params),
                          lambda: RateDependentForce.from_params(params),
                          reach_m=0.5 * params.width)
        self.world = GripperWorld(skin, self.geometry, rod_diameter_m=ROD_M, held=held)
        depth = indentation_for(skin, scenario.grip_n)
        start = self.geometry.position_rad(ROD_M - 2.0 * depth)
        # as a grasp leaves it: at rest on the position loop's closing edge, whose lead the
        # settle read (control/hold.py) and hands to the adaptive hold
        goal = self._settled_goal(skin, start, drivetrain)
        self.motor = MotorModel(start, self.world.load_torque_nm, drivetrain=drivetrain)
        self.command = self._command(goal)
        self.rng = np.random.default_rng(seed)
        self.hold = (SlipHold(self._hold_config(), scenario.grip_n, start, goal - start)
                     if adaptive else None)
        #: (time, Fn, Ft) of each world step, true.
        self.samples: list[tuple[float, float, float]] = []

    def _settled_goal(self, skin: Any, start_rad: float,
                      drivetrain: Drivetrain | None) -> float:
        """The goal at which the output, closing onto the skins, rests at ``start_rad``:
        a settle's corrections from the closing side, on a servo and skins of their own."""
        world = GripperWorld(skin, self.geometry, rod_diameter_m=ROD_M)
        goal = start_rad
        for _ in range(SETTLE_ROUNDS):
            motor = MotorModel(start_rad - SETTLE_FROM_RAD, world.load_torque_nm,
                               drivetrain=drivetrain)
            for _ in range(round(SETTLE_S / WORLD_STEP_S)):
                state = motor.step(WORLD_STEP_S, self._command(goal))
            error = start_rad - state.position_rad
            if abs(error) < 0.1 * RAD_PER_PULSE:
                break
            goal += error
        return goal

    def _hold_config(self) -> SlipHoldConfig:
        per_rad = self.config.skin_stiffness_n_per_m * self.geometry.pitch_radius_m
        return SlipHoldConfig(SHEAR_FINGERTIP_NOISE, ceiling_n=CEILING_N,
                              newton_per_rad=per_rad,
                              closed_position_rad=self.geometry.closed_position_rad,
                              control_rate_hz=1.0 / TICK_S)

    def _command(self, goal_rad: float) -> MotorCommand:
        return MotorCommand(True, goal_rad, self.config.stop_velocity_rad_s, 0.0,
                            self.config.hold_current_a)

    def step(self, t_s: float) -> None:
        state = self.motor.step(WORLD_STEP_S, self.command)
        sample = self.world.update(t_s, state.position_rad)
        shear = sample.held.force_a_n if sample.held is not None else 0.0
        self.samples.append((t_s, sample.force_a_n, shear))

    def tick(self, t_s: float, since: int) -> int:
        """The hold's tick at ``t_s`` on the samples from index ``since`` up to ``DELAY_S``
        ago; the index it read up to."""
        upto = since
        while (upto < len(self.samples)
               and self.samples[upto][0] <= t_s - self.delay_s + 1e-9):
            upto += 1
        if self.hold is None or upto == since:
            return upto
        part = np.asarray(self.samples[since:upto])
        n = upto - since
        root = math.sqrt(0.5 / WORLD_STEP_S / n)
        noise = self.rng.standard_normal(3) * root
        fn = float(part[:, 1].mean()) + SHEAR_FINGERTIP_NOISE.normal_density * noise[0]
        fx = float(part[:, 2].mean()) + SHEAR_FINGERTIP_NOISE.shear_density * noise[1]
        fy = SHEAR_FINGERTIP_NOISE.shear_density * noise[2]
        state = self.motor.state
        step = self.hold.update(t_s, fn, fx, fy, state.position_rad,
                                abs(state.velocity_rad_s) > 1e-6)
        if step.goal_rad is not None:
            self.command = self._command(step.goal_rad)
        return upto


def run(scenario: Scenario, adaptive: bool, seed: int, delay_s: float = DELAY_S) -> Run:
    loop = Loop(scenario, adaptive, seed, delay_s)
    world = loop.world
    lift_at = GRIPPED_S
    double_at = lift_at + scenario.double_at_s
    end = lift_at + scenario.duration_s
    steps = round(end / WORLD_STEP_S)
    per_tick = round(TICK_S / WORLD_STEP_S)
    read = 0
    slip_at_double = onset = grip_at_onset = rise = None
    for i in range(1, steps + 1):
        t = i * WORLD_STEP_S
        if i == round(lift_at / WORLD_STEP_S):
            world.lift()
        before = world.held.state.slip_m if world.held is not None else 0.0
        loop.step(t)
        held = world.held
        assert held is not None
        if t >= double_at:
            if slip_at_double is None:
                slip_at_double = before
                grip_at_onset = loop.samples[-1][1]
            if onset is None and (held.state.slip_m != before
                                  or not all(c.stuck for c in held.contacts)):
                onset = t
            if rise is None and grip_at_onset is not None \
                    and loop.samples[-1][1] > grip_at_onset + RISE_N:
                rise = t
        if i % per_tick == 0:
            read = loop.tick(t, read)
    held = world.held
    assert held is not None
    times = np.asarray([s[0] for s in loop.samples])
    grips = np.asarray([s[1] for s in loop.samples])
    slip = held.state.slip_m
    return Run(loop.hold.friction if loop.hold is not None else None, abs(slip) * 1e3,
               abs(slip - (slip_at_double or 0.0)) * 1e3,
               float(grips[times >= double_at].max()),
               least_grip_n(2.0 * scenario.weight_n, scenario.friction_static),
               None if onset is None or rise is None else (rise - onset) * 1e3,
               None if rise is None else (rise - double_at) * 1e3, held.dropped)


def floor_ratio(s: Scenario) -> float:
    """The least a hold at the exact kinetic friction keeps after the doubling (the doubled
    load's shear plus the detector's least margin, 2 k sigma_m at 20 Hz) over the least grip
    for the doubled load: the noise's limit on the peak-grip goal."""
    threshold = SHEAR_FINGERTIP_NOISE.threshold_n(s.friction_kinetic, 20.0)
    return ((s.weight_n + 2.0 * threshold) / s.friction_kinetic
            / least_grip_n(2.0 * s.weight_n, s.friction_static))


def table(scenarios: list[Scenario], results: list[tuple[Run, Run]]) -> None:
    print(f"{'mass':>5} {'mu_s':>5} {'mu_k':>5} {'start':>6} | {'learned':>7} "
          f"{'slip':>6} {'slip2x':>6} {'peak':>6} {'least':>6} {'ratio':>5} {'rise':>6} "
          f"{'drop':>4} {'floor':>5} | fixed: {'slip':>6} {'drop':>4}")
    for s, (a, f) in zip(scenarios, results, strict=True):
        learned = "-" if a.friction is None else f"{a.friction:.3f}"
        rise = "-" if a.onset_to_rise_ms is None else f"{a.onset_to_rise_ms:.0f}"
        print(f"{s.mass_kg * 1e3:5.0f} {s.friction_static:5.2f} {s.friction_kinetic:5.2f} "
              f"{s.grip_n:6.2f} | {learned:>7} {a.slip_mm:6.2f} "
              f"{a.slip_after_doubling_mm:6.2f} {a.peak_after_doubling_n:6.2f} "
              f"{a.least_doubled_n:6.2f} {a.grip_ratio:5.2f} {rise:>6} "
              f"{'yes' if a.dropped else 'no':>4} {floor_ratio(s):5.2f} | fixed: {f.slip_mm:6.2f} "
              f"{'yes' if f.dropped else 'no':>4}")


def summary(scenarios: list[Scenario], results: list[tuple[Run, Run]]) -> list[Figure]:
    adaptive = [a for a, _ in results]
    fixed = [f for _, f in results]
    learned = [(a.friction / s.friction_kinetic) for s, a in zip(scenarios, adaptive,
                                                                 strict=True)
               if a.friction is not None]
    reachable = [a for a in adaptive if a.least_doubled_n <= CEILING_N]
    held = [a for a in reachable if not a.dropped]
    latencies = np.asarray([a.onset_to_rise_ms for a in reachable
                            if a.onset_to_rise_ms is not None])
    ratios = np.asarray([a.grip_ratio for a in held])
    starts = np.asarray([a.doubling_to_rise_ms for a in held
                         if a.doubling_to_rise_ms is not None])
    slips = np.asarray([a.slip_mm for a in reachable])
    p95 = float(np.percentile(latencies, 95)) if latencies.size else math.nan
    figures = [
        Figure("objects", len(scenarios)),
        Figure("objects whose doubled load the ceiling can hold", len(reachable)),
        Figure("adaptive: friction learned", len(learned)),
        Figure("adaptive: learned / kinetic friction, min",
               min(learned) if learned else math.nan),
        Figure("adaptive: learned / kinetic friction, median",
               float(np.median(learned)) if learned else math.nan),
        Figure("adaptive: learned / kinetic friction, max",
               max(learned) if learned else math.nan),
        Figure("adaptive: dropped", sum(a.dropped for a in reachable), "",
               "0", not any(a.dropped for a in reachable)),
        Figure("adaptive: slip, max", float(slips.max()) if slips.size else math.nan, "mm",
               f"<= {SLIP_GOAL_MM:g} mm", bool(slips.size and slips.max() <= SLIP_GOAL_MM)),
        Figure("adaptive: objects slipping <= 2 mm", int(np.sum(slips <= SLIP_GOAL_MM))),
        Figure("adaptive: peak grip / least for the doubled load, median",
               float(np.median(ratios)) if ratios.size else math.nan),
        Figure("adaptive: peak grip / least for the doubled load, max",
               float(ratios.max()) if ratios.size else math.nan, "",
               f"<= {GRIP_GOAL:g}", bool(ratios.size and ratios.max() <= GRIP_GOAL)),
        Figure("adaptive: objects held at <= 1.5 x least", int(np.sum(ratios <= GRIP_GOAL))),
        Figure("objects the noise lets a hold keep at <= 1.5 x least",
               sum(floor_ratio(s) <= GRIP_GOAL for s in scenarios)),
        Figure("adaptive: onset to grip rising, p95", p95, "ms",
               f"<= {LATENCY_GOAL_MS:g} ms", bool(p95 <= LATENCY_GOAL_MS)),
        Figure("adaptive: slips after the doubling timed", int(latencies.size)),
        Figure("adaptive: doubling starting to grip rising, median",
               float(np.median(starts)) if starts.size else math.nan, "ms"),
        Figure("fixed at the starting force: dropped", sum(f.dropped for f in fixed)),
        Figure("fixed at the starting force: slip > 2 mm",
               sum(f.slip_mm > SLIP_GOAL_MM for f in fixed)),
    ]
    for fig in figures:
        value = fig.value if not isinstance(fig.value, float) else f"{fig.value:.3g}"
        goal = f" (goal {fig.goal}: {'met' if fig.met else 'not met'})" if fig.goal else ""
        print(f"  {fig.name}: {value} {fig.unit}{goal}")
    return figures


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--objects", type=int, default=0,
                        help="run only the first N objects (0: all 32)")
    parser.add_argument("--delay-ms", type=float, default=DELAY_S * 1e3,
                        help="how late the forces reach the hold [ms] (default "
                        f"{DELAY_S * 1e3:g}; another value prints its figures only)")
    args = parser.parse_args()
    if not 0.0 <= args.delay_ms < 1000.0:
        parser.error(f"--delay-ms {args.delay_ms:g} must be in [0, 1000) ms")
    delay_s = args.delay_ms * 1e-3
    scenarios = objects()[:args.objects or None]
    results = []
    for i, s in enumerate(scenarios):
        results.append((run(s, True, i, delay_s), run(s, False, i, delay_s)))
    table(scenarios, results)
    figures = summary(scenarios, results)
    if delay_s != DELAY_S:
        return
    rows: dict[str, Any] = {
        "mass_kg": [s.mass_kg for s in scenarios],
        "friction_static": [s.friction_static for s in scenarios],
        "friction_kinetic": [s.friction_kinetic for s in scenarios],
        "learned": [a.friction for a, _ in results],
        "slip_mm": [a.slip_mm for a, _ in results],
        "grip_ratio": [a.grip_ratio for a, _ in results],
        "fixed_slip_mm": [f.slip_mm for _, f in results]}
    write_results("slip_hold", figures, series=rows,
                  notes=f"Objects lifted, held {HOLD_S:g} s, load doubled over 100 ms; "
                  f"starting force {START_OVER_LEAST:g} x the weight's least grip at mu_k.")


if __name__ == "__main__":
    main()
