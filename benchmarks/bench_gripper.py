"""Gripper control-loop figures on the XM430 emulator.

1. Control-loop rate with ``Xm430Client.read_state`` (one Sync Read) at 1 Mbps and 4 Mbps,
   emulator in its own process (as a real servo is), Return Delay Time 250 (factory, 500 us)
   and 0.
2. Force overshoot past the grasp target at 5, 10 and 20 mm/s finger speed: the grasp state
   machine, the client, the emulator and the gripper world in ONE process; the tactile force
   is the world's finger-A skin force seen through a 9-point moving average at 1 kHz plus a
   transport delay (ADC frame + driver + topic), as the driver would publish it.

Run: python benchmarks/bench_gripper.py [--quick]
"""

from __future__ import annotations

import argparse
import contextlib
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tactile_sensor"))

from grasp_hold import (  # noqa: E402
    DRIVETRAINS,
    TARGETS_N,
    Bench,
    contact_goal_n,
    open_bench,
    print_misses,
    print_table,
    run_grasps,
    summarise,
)
from results import Figure, write_results  # noqa: E402

from tactile_sensor.control.grasp import (  # noqa: E402
    GraspConfig,
    GraspController,
    GraspRequest,
    ReleaseController,
)
from tactile_sensor.hardware.errors import CommunicationTimeout  # noqa: E402
from tactile_sensor.hardware.xm430 import Xm430Client  # noqa: E402
from tactile_sensor.hardware.xm430_table import OperatingMode  # noqa: E402
from tactile_sensor.sim.gripper_world import GripperWorld  # noqa: E402
from tactile_sensor.sim.skin_response import TabulatedSkin  # noqa: E402
from tactile_sensor.sim.xm430_emulator import Xm430Emulator  # noqa: E402

TRANSPORT_DELAY_S = 0.005
AVERAGE_POINTS = 9
TARGET_FORCE_N = 3.0
#: The grasp whose force and opening the results keep (with slow-down, as configured).
TRACE_SPEED_M_S = 0.010


def skin() -> tuple[TabulatedSkin, str]:
    try:
        from tactile_sensor.physics.params import PhysicsParams
        from tactile_sensor.physics.prediction import load_or_compute_curve
    except ImportError:
        # Stand-in shaped like the paper's Fig. 7(a): stiffening below 0.5 mm, ~7 N at 3 mm.
        d = np.linspace(0.0, 0.003, 61)
        force = 7.0 * (0.75 * d / 0.003 + 0.25 * (d / 0.003) ** 2)
        volts = 2.0 - 0.07 * force
        return TabulatedSkin(d, force, volts, thickness_m=0.005), "paper-shaped stand-in"
    curve = load_or_compute_curve(PhysicsParams())
    return TabulatedSkin.from_prediction_curve(curve), "physics PredictionCurve"


def wait_for(path: Path, timeout_s: float = 10.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not path.exists():
        if time.monotonic() > deadline:
            raise RuntimeError(f"emulator did not create {path}")
        time.sleep(0.02)


def loop_rate(baud: int, return_delay: int, seconds: float) -> tuple[float, int]:
    with tempfile.TemporaryDirectory() as tmp:
        link = Path(tmp) / "xm430"
        env = dict(os.environ, PYTHONPATH=str(ROOT / "tactile_sensor"))
        proc = subprocess.Popen(
            [sys.executable, "-m", "tactile_sensor.sim.xm430_emulator", "--link", str(link),
             "--baud", str(baud), "--no-world"], env=env, stderr=subprocess.DEVNULL)
        try:
            wait_for(link)
            with Xm430Client(str(link), baud, 1, timeout_s=0.2) as client:
                client.write_item("Return Delay Time", return_delay)
                n, lost, t0 = 0, 0, time.perf_counter()
                while time.perf_counter() - t0 < seconds:
                    try:
                        client.read_state()
                        n += 1
                    except CommunicationTimeout:
                        lost += 1
                return n / (time.perf_counter() - t0), lost
        finally:
            proc.terminate()
            proc.wait(timeout=5)


class SensedForce:
    """Finger-A force as the tactile topic would deliver it: moving average + delay."""

    def __init__(self, world: GripperWorld, t0: float) -> None:
        self.world, self.t0 = world, t0

    def __call__(self, now: float) -> tuple[float, float]:
        t_world = now - self.t0 - TRANSPORT_DELAY_S
        samples = [self.world.force_at(t_world - k * 1e-3) for k in range(AVERAGE_POINTS)]
        return float(np.mean(samples)), now - TRANSPORT_DELAY_S


def open_fully(client: Xm430Client, config: GraspConfig) -> None:
    release = ReleaseController(config)
    now = time.monotonic()
    step = release.start(config.geometry.open_opening_m, 0.05, 5.0, now, client.read_state())
    cmd = step.command
    client.command_position(cmd.goal_position_rad, cmd.profile_velocity_rad_s,
                            goal_current_a=cmd.goal_current_a)
    while not step.finished:
        step = release.tick(time.monotonic(), client.read_state())


def grasp_once(client: Xm430Client, world: GripperWorld, emulator_t0: float,
               config: GraspConfig, speed_m_s: float
               ) -> tuple[float, float, float, dict[str, list[float]]]:
    """Overshoot, held force and loop rate of one grasp, and its trace as the controller
    saw it (time from the goal, sensed force, opening) for the docs' figure."""
    sensed = SensedForce(world, emulator_t0)
    trace: dict[str, list[float]] = {"t_s": [], "force_n": [], "opening_m": []}
    controller = GraspController(config)
    start = time.monotonic()
    state = client.read_state()
    step = controller.start(GraspRequest(TARGET_FORCE_N, speed_m_s, 10.0), start, state)
    ticks = 0
    while True:
        cmd = step.command
        if cmd is not None:
            client.command_position(cmd.goal_position_rad, cmd.profile_velocity_rad_s,
                                    goal_current_a=cmd.goal_current_a)
        if step.finished:
            break
        try:
            state = client.read_state()
        except CommunicationTimeout:
            continue  # a loaded machine can starve the emulator thread; try again
        now = time.monotonic()
        force, stamp = sensed(now)
        step = controller.tick(now, force, stamp, state)
        ticks += 1
        trace["t_s"].append(now - start)
        trace["force_n"].append(force)
        trace["opening_m"].append(config.geometry.opening_m(state.position_rad))
    end = time.monotonic()
    time.sleep(0.3)  # hold and let everything settle
    t_start, t_end = start - emulator_t0, time.monotonic() - emulator_t0
    forces = [world.force_at(t) for t in np.arange(t_start, t_end, 1e-3)]
    if step.outcome is None or step.outcome.value != "contact":
        raise RuntimeError(f"grasp at {speed_m_s} m/s ended with {step.outcome}: "
                           f"{step.message}")
    return max(forces) - TARGET_FORCE_N, forces[-1], ticks / (end - start), trace


HOLD_NOTES = ("Contact and hold on the XM430 emulator and the gripper world with the gripper "
              "node's default parameters; tactile force with the paper's noise through the "
              "driver's default filter; a one-core busy loop beside the run.")


@contextlib.contextmanager
def busy_core() -> Iterator[None]:
    """A one-core busy loop beside the run (the goal's load)."""
    proc = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        yield
    finally:
        proc.terminate()
        proc.wait(timeout=5)


def contact_and_hold(grasps: int, drivetrain: str = "default",
                     targets: tuple[float, ...] = TARGETS_N) -> list[Figure]:
    """The contact and hold tables of the Grasp and of current-limited grasping."""
    figures: list[Figure] = []
    world = GripperWorld(skin()[0], rod_diameter_m=0.020)
    print(f"drivetrain: {drivetrain} ({DRIVETRAINS[drivetrain]})")
    with tempfile.TemporaryDirectory() as tmp:
        emulator, client = open_bench(Path(tmp) / "xm430", world, DRIVETRAINS[drivetrain])
        try:
            bench = Bench(world, emulator, client)
            for label, grasp in (("tactile Grasp (node defaults)", bench.tactile_grasp),
                                 ("current-limited (current-based position mode)",
                                  lambda target, k: bench.current_limited_grasp(target))):
                load = os.getloadavg()[0]
                runs = run_grasps(bench, grasp, targets, grasps)
                rows = [summarise(t, g) for t, g in runs.items()]
                print_table(f"{label}, {grasps} grasps per target; true force (load average "
                            f"{load:.1f} -> {os.getloadavg()[0]:.1f} on {os.cpu_count()} "
                            "cores)", rows)
                for target, run in runs.items():
                    print_misses(target, run)
                for r in rows:
                    figures += [
                        Figure(f"{label}: peak true force at {r.target_n:g} N", r.peak_max_n,
                               "N", f"<= {contact_goal_n(r.target_n):.2f} N", r.contact_met),
                        Figure(f"{label}: worst hold error 0.5 s after contact at "
                               f"{r.target_n:g} N", r.held_worst_error * 100, "%"),
                        Figure(f"{label}: grasps within 5 % and settled at {r.target_n:g} N",
                               f"{r.settled}/{r.count}", "",
                               ">= 19 of 20", r.hold_met),
                        Figure(f"{label}: grasps within 5 % when they answered at "
                               f"{r.target_n:g} N", f"{r.within_answered}/{r.count}", "")]
        finally:
            client.close()
            emulator.stop()
    return figures


def main() -> int:
    sys.setswitchinterval(5e-4)  # emulator thread and control loop share the GIL
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true",
                    help="shorter rate measurement and 3 grasps per target")
    ap.add_argument("--grasps", type=int, default=0,
                    help="grasps per target force (default 20; 3 with --quick)")
    ap.add_argument("--tables-only", action="store_true",
                    help="only the contact and hold tables")
    ap.add_argument("--drivetrain", choices=tuple(DRIVETRAINS), default="default",
                    help="the emulated servo's drivetrain for the tables (grasp_hold.py)")
    ap.add_argument("--targets", type=float, nargs="+", default=list(TARGETS_N),
                    help="target forces of the tables [N]")
    args = ap.parse_args()
    seconds = 1.0 if args.quick else 3.0
    grasps = args.grasps or (3 if args.quick else 20)
    figures: list[Figure] = []
    with busy_core():
        figures += contact_and_hold(grasps, args.drivetrain, tuple(args.targets))
    if args.tables_only:
        suffix = "" if args.drivetrain == "default" else "_" + args.drivetrain.replace("-", "_")
        write_results("gripper_hold" + suffix, figures,
                      notes=f"{HOLD_NOTES} Drivetrain: {args.drivetrain} (grasp_hold.py).")
        return 0

    print("\ncontrol-loop rate, read_state() = one Sync Read, emulator in its own process")
    for baud in (1_000_000, 4_000_000):
        for delay in (250, 0):
            rate, lost = loop_rate(baud, delay, seconds)
            print(f"  {baud / 1e6:.0f} Mbps, Return Delay Time {delay:3d} "
                  f"({delay * 2:3d} us): {rate:6.0f} Hz  ({lost} timeouts)")
            figures.append(Figure(f"control-loop rate at {baud / 1e6:.0f} Mbps, Return Delay "
                                  f"{delay * 2} us", rate, "Hz"))

    skin_model, source = skin()
    print(f"\ngrasp overshoot past {TARGET_FORCE_N} N (skin: {source}; tactile: "
          f"{AVERAGE_POINTS}-point moving average at 1 kHz + {TRANSPORT_DELAY_S * 1e3:.0f} ms"
          " transport; one process, 1 Mbps, Return Delay 0)")
    world = GripperWorld(skin_model, rod_diameter_m=0.020)
    traces: dict[float, dict[str, list[float]]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        link = Path(tmp) / "xm430"
        with Xm430Emulator(link, baudrate=1_000_000, world=world) as emulator:
            t0 = emulator._t0
            with Xm430Client(str(link), 1_000_000, 1, timeout_s=0.2) as client:
                client.write_item("Return Delay Time", 0)
                client.set_operating_mode(OperatingMode.CURRENT_BASED_POSITION)
                client.set_torque(True)
                for label, fraction in (("slow-down from 50 % of target", 0.5),
                                        ("no slow-down", 1.0)):
                    config = GraspConfig(slowdown_from_fraction=fraction)
                    print(f"  {label}:")
                    for speed in (0.005, 0.010, 0.020):
                        open_fully(client, config)
                        over, final, rate, trace = grasp_once(client, world, t0, config,
                                                              speed)
                        traces.setdefault(speed, trace)  # the first: with slow-down
                        print(f"    {speed * 1e3:4.0f} mm/s: overshoot {over:+.2f} N "
                              f"(held {final:.2f} N), loop {rate:.0f} Hz")
                        figures.append(Figure(f"overshoot at {speed * 1e3:.0f} mm/s, {label}",
                                              over, "N"))
    write_results("gripper", figures, series=traces[TRACE_SPEED_M_S],
                  notes=f"Grasp to {TARGET_FORCE_N:g} N on the XM430 emulator"
                  f" (skin: {source}); tactile force through a {AVERAGE_POINTS}-point "
                  f"moving average at 1 kHz and {TRANSPORT_DELAY_S * 1e3:.0f} ms transport.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
