"""Cancel -> fingers stopped, over ROS across processes, with a per-stage breakdown.

Three processes, as in the integration test and on the robot:

* the XM430 emulator (1 Mbps, factory Return Delay Time) -- records its motor's ground truth
  (output position every model step) and when each Goal Position write arrives;
* the ``gripper`` node (config/gripper.yaml: 100 Hz control loop) -- run through a wrapper
  that only time-stamps ``_on_cancel`` and the stop write (no behaviour change);
* this client: publishes a 0 N tactile force on ``tactile_wrench`` at the driver's rate (so
  the grasp never finds contact and the node is as busy as with the driver), sends a grasp
  at 10 mm/s, cancels it after a random 0.4..0.9 s and reopens; N times.

Stages (all on CLOCK_MONOTONIC, shared by the processes; ROS stamps converted):

1. cancel sent (client) -> ``_on_cancel`` entered (node): DDS + the node's executor;
2. -> stop write acknowledged by the servo (node);
3. -> the emulated output is within one encoder pulse of where it comes to rest, for good
   (ground truth);
4. -> first ``~/joint_states`` sample showing the rest opening (±0.05 mm), by its header stamp
   (the time the servo was read) and by the time it reached the client.

Run: python benchmarks/bench_gripper_cancel.py [--trials 20] [--force-rate 250]
(needs the built workspace: ``. scripts/env.sh``; ROS_DOMAIN_ID defaults to 121).
A/B switches for the node: BENCH_SWITCH_INTERVAL=0.005 (Python's default GIL switch
interval), BENCH_READ_FIRST=1 (the stop reads the servo first: two transactions instead of
one write).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from node_processes import interrupt
from results import Figure, write_results

from tactile_sensor.nodes.background_spin import BackgroundSpin
from tactile_sensor.nodes.ros_session import ros_session

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tactile_sensor"))

RAD_PER_PULSE = 2.0 * math.pi / 4096
OPENING_TOLERANCE_M = 5e-5
FINGER_SPEED_M_S = 0.01


def emit(kind: str, **values: float) -> None:
    print(json.dumps({"kind": kind, **values}), flush=True)


# -- the emulator process ----------------------------------------------------------------------


def run_emulator(link: str) -> int:
    """An XM430 emulator that writes its ground truth to stdout as JSON lines."""
    from tactile_sensor.sim.xm430_emulator import Xm430Emulator

    samples: list[tuple[float, float]] = []
    goals: list[tuple[float, float]] = []

    class Recording(Xm430Emulator):
        def _publish_motor(self) -> None:
            super()._publish_motor()
            samples.append((self._clock(), self.motor.state.position_rad))

        def _apply(self, values: dict[str, int], now: float):  # type: ignore[override]
            if "Goal Position" in values:
                goals.append((now, values["Goal Position"] * RAD_PER_PULSE))
            return super()._apply(values, now)

    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    with Recording(link, baudrate=1_000_000):
        emit("ready")
        stop.wait()
    # only what the analysis needs: thin the samples to changes of position
    thinned, last = [], None
    for t, p in samples:
        if p != last:
            thinned.append((t, p))
            last = p
    if samples:
        thinned.append(samples[-1])
    print(json.dumps({"kind": "truth", "samples": thinned, "goals": goals}), flush=True)
    return 0


# -- the node process --------------------------------------------------------------------------


def run_node(ros_args: list[str]) -> int:
    """The gripper node, with time stamps around cancel handling and Goal Position writes."""
    from tactile_sensor.hardware.xm430 import Xm430Client
    from tactile_sensor.nodes import gripper

    on_cancel = gripper.GripperNode._on_cancel
    write_items = Xm430Client.write_items
    read_state = Xm430Client.read_state
    local = threading.local()

    def timed_cancel(self, goal_handle):  # type: ignore[no-untyped-def]
        emit("cancel_enter", t=time.monotonic())
        local.inside = True
        try:
            return on_cancel(self, goal_handle)
        finally:
            local.inside = False

    def timed_read(self):  # type: ignore[no-untyped-def]
        start = time.monotonic()
        state = read_state(self)
        if getattr(local, "inside", False):
            emit("cancel_read", t0=start, t1=time.monotonic())
        return state

    def timed_write(self, values, **kwargs):  # type: ignore[no-untyped-def]
        start = time.monotonic()
        write_items(self, values, **kwargs)
        if "Goal Position" in values:
            emit("write", t0=start, t1=time.monotonic(),
                 goal=values["Goal Position"] * RAD_PER_PULSE)

    gripper.GripperNode._on_cancel = timed_cancel  # type: ignore[method-assign]
    Xm430Client.write_items = timed_write  # type: ignore[method-assign]
    Xm430Client.read_state = timed_read  # type: ignore[method-assign]
    if os.environ.get("BENCH_READ_FIRST"):  # A/B: the stop reads the servo first
        stop = gripper.GripperNode._stop

        def read_first(self, goal_handle):  # type: ignore[no-untyped-def]
            self._sample = None
            return stop(self, goal_handle)
        gripper.GripperNode._stop = read_first  # type: ignore[method-assign]
    if os.environ.get("BENCH_SWITCH_INTERVAL"):  # A/B the node's GIL switch interval
        gripper.SWITCH_INTERVAL_S = float(os.environ["BENCH_SWITCH_INTERVAL"])
    gripper.main(ros_args)
    return 0


# -- the client (this process) -----------------------------------------------------------------


class Reader(threading.Thread):
    """JSON lines from a child's stdout."""

    def __init__(self, proc: subprocess.Popen) -> None:
        super().__init__(daemon=True)
        self.proc, self.events, self.lines = proc, [], []
        self.start()

    def run(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.append(line)
            if line.startswith("{"):
                self.events.append(json.loads(line))

    def wait_for(self, kind: str, timeout_s: float) -> bool:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if any(e["kind"] == kind for e in self.events):
                return True
            if self.proc.poll() is not None:
                time.sleep(0.2)
                return any(e["kind"] == kind for e in self.events)
            time.sleep(0.05)
        return False


def stats(values: list[float]) -> str:
    import numpy as np

    a = np.asarray(values) * 1e3
    if a.size == 0:
        return "no data"
    return (f"median {np.median(a):6.1f}  p90 {np.percentile(a, 90):6.1f}  "
            f"max {a.max():6.1f}  min {a.min():6.1f} ms")


def wait_future(future, timeout_s: float):  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout_s
    while not future.done():
        if time.monotonic() > deadline:
            raise RuntimeError("timed out waiting for the gripper node")
        time.sleep(0.002)
    return future.result()


def client_main(args: argparse.Namespace) -> int:
    import rclpy
    from geometry_msgs.msg import WrenchStamped
    from rclpy.executors import MultiThreadedExecutor
    from sensor_msgs.msg import JointState

    from tactile_sensor.configurations import config_dir
    from tactile_sensor.nodes.action_client import RaceFreeActionClient as ActionClient
    from tactile_sensor_interfaces.action import Grasp, Release

    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(ROOT / "tactile_sensor"), os.environ.get("PYTHONPATH", "")]))
    env.setdefault("ROS_DOMAIN_ID", "121")
    os.environ["ROS_DOMAIN_ID"] = env["ROS_DOMAIN_ID"]
    me = str(Path(__file__).resolve())
    with tempfile.TemporaryDirectory() as tmp:
        link = str(Path(tmp) / "xm430")
        emulator = subprocess.Popen([sys.executable, me, "--emulator", link], env=env,
                                    stdout=subprocess.PIPE, text=True)
        emu = Reader(emulator)
        if not emu.wait_for("ready", 30):
            print("the emulator did not start:\n" + "".join(emu.lines), file=sys.stderr)
            return 1
        node = subprocess.Popen(
            [sys.executable, me, "--node", "--ros-args", "-r", "__node:=gripper",
             "--params-file", str(config_dir() / "gripper.yaml"),
             "-p", f"port:={link}", "-p", "autostart:=true"],
            env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        gripper = Reader(node)
        try:
            with ros_session():
                return measure(args, gripper, emulator, emu, rclpy, WrenchStamped,
                               ActionClient, MultiThreadedExecutor, JointState, Grasp,
                               Release)
        finally:
            interrupt(node, timeout_s=10)
            if emulator.poll() is None:
                emulator.terminate()
                emulator.wait(10)


def measure(args, gripper, emulator, emu, rclpy, WrenchStamped, ActionClient,
            MultiThreadedExecutor, JointState, Grasp, Release) -> int:  # type: ignore[no-untyped-def]
    client = rclpy.create_node("cancel_bench")
    grasp = ActionClient(client, Grasp, "/gripper/grasp")
    release = ActionClient(client, Release, "/gripper/release")
    wall_minus_mono = time.time() - time.monotonic()
    joints: list[tuple[float, float, float]] = []  # (stamp as monotonic, received, opening)

    def on_joint(msg: JointState) -> None:
        stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9 - wall_minus_mono
        joints.append((stamp, time.monotonic(), msg.position[0]))

    client.create_subscription(JointState, "/gripper/joint_states", on_joint, 1000)
    force_pub = client.create_publisher(WrenchStamped, "tactile_wrench", 100)
    stop = threading.Event()

    def publish_force() -> None:
        period = 1.0 / args.force_rate
        due = time.monotonic()
        while not stop.is_set():
            msg = WrenchStamped()
            msg.header.stamp = client.get_clock().now().to_msg()
            force_pub.publish(msg)
            due += period
            time.sleep(max(0.0, due - time.monotonic()))

    executor = MultiThreadedExecutor(num_threads=2)
    executor.add_node(client)
    spin = BackgroundSpin(executor)
    threading.Thread(target=publish_force, daemon=True).start()
    try:
        if not (grasp.wait_for_server(timeout_sec=30) and release.wait_for_server(
                timeout_sec=30)):
            print("the gripper node did not come up:\n" + "".join(gripper.lines),
                  file=sys.stderr)
            return 1
        deadline = time.monotonic() + 30
        while not any("active" in line for line in gripper.lines):
            if time.monotonic() > deadline or gripper.proc.poll() is not None:
                print("the gripper node did not activate:\n" + "".join(gripper.lines),
                      file=sys.stderr)
                return 1
            time.sleep(0.05)
        time.sleep(0.5)
        rng = random.Random(1)
        cancels: list[float] = []
        print(f"{args.trials} cancels at {FINGER_SPEED_M_S * 1e3:.0f} mm/s finger speed, "
              f"tactile force at {args.force_rate:.0f} Hz", flush=True)
        for trial in range(args.trials):
            handle = wait_future(release.send_goal_async(Release.Goal(opening=0.0)), 10)
            wait_future(handle.get_result_async(), 20)
            handle = wait_future(grasp.send_goal_async(Grasp.Goal(
                target_force=1.5, closing_speed=FINGER_SPEED_M_S, timeout=10.0)), 10)
            time.sleep(rng.uniform(0.4, 0.9))
            sent = time.monotonic()
            response = wait_future(handle.cancel_goal_async(), 5)
            result = wait_future(handle.get_result_async(), 5).result
            if not response.goals_canceling or "cancel" not in result.message:
                print(f"  trial {trial}: not canceled ({result.message})", flush=True)
                continue
            cancels.append(sent)
            time.sleep(0.3)
        stop.set()
    finally:
        stop.set()
        spin.stop()
        grasp.destroy()  # destroy_node() leaves action clients to the garbage collector
        release.destroy()
        client.destroy_node()
    emulator.send_signal(signal.SIGTERM)
    emulator.wait(30)
    time.sleep(0.3)
    if not cancels:
        print("no cancel measured; the gripper node said:\n" + "".join(gripper.lines[-30:]),
              file=sys.stderr)
        return 1
    truth = next(e for e in emu.events if e["kind"] == "truth")
    report(cancels, gripper.events, truth, joints)
    return 0


def report(cancels: list[float], node_events: list[dict], truth: dict,
           joints: list[tuple[float, float, float]]) -> None:
    from tactile_sensor.control.geometry import GripperGeometry

    geometry = GripperGeometry()
    enters = sorted(e["t"] for e in node_events if e["kind"] == "cancel_enter")
    writes = sorted((e["t0"], e["t1"]) for e in node_events if e["kind"] == "write")
    reads = sorted((e["t0"], e["t1"]) for e in node_events if e["kind"] == "cancel_read")
    samples = truth["samples"]
    goals = sorted(g[0] for g in truth["goals"])
    stages: dict[str, list[float]] = {k: [] for k in (
        "sent -> _on_cancel entered", "entered -> read started", "read in cancel",
        "entered -> stop write started",
        "stop write started -> acknowledged", "sent -> stop goal reached the servo",
        "sent -> output stopped (ground truth)", "stop goal at servo -> output stopped",
        "sent -> joint_states stamp shows stop", "sent -> joint_states received")}
    for sent in cancels:
        enter = next((t for t in enters if t >= sent), math.nan)
        write = next(((a, b) for a, b in writes if a >= enter), (math.nan, math.nan))
        read = next(((a, b) for a, b in reads if enter <= a <= write[0]),
                    (math.nan, math.nan))
        goal_at = next((t for t in goals if t >= sent), math.nan)
        window = [(t, p) for t, p in samples if sent - 0.05 <= t <= sent + 0.3]
        if not window:
            continue
        rest = window[-1][1]
        stopped = sent
        for t, p in window:
            if abs(p - rest) > RAD_PER_PULSE and t > sent:
                stopped = t
        # the first sample after the last one that was still off the rest position
        later = [t for t, _ in window if t > stopped]
        stopped = later[0] if later and stopped > sent else stopped
        rest_opening = geometry.opening_m(rest)
        shown = next(((s, r) for s, r, o in joints if s >= sent
                      and abs(o - rest_opening) <= OPENING_TOLERANCE_M), (math.nan, math.nan))
        for key, value in zip(stages, (
                enter - sent, read[0] - enter, read[1] - read[0], write[0] - enter,
                write[1] - write[0], goal_at - sent,
                stopped - sent, stopped - goal_at, shown[0] - sent, shown[1] - sent),
                strict=True):
            if math.isfinite(value):
                stages[key].append(value)
    one_write = len(cancels) - len(stages["read in cancel"])
    print(f"\n{len(cancels)} cancels measured (CLOCK_MONOTONIC across processes); "
          f"{one_write} stopped with one write from the last sample, the rest read first:")
    for key, values in stages.items():
        print(f"  {key:40s} {stats(values)}")
    import numpy as np

    figures = [Figure(f"{key}: {label}", float(fn(values)) * 1e3, "ms")
               for key, values in stages.items() if values
               for label, fn in (("median", np.median), ("p90", lambda v: np.percentile(v, 90)),
                                 ("max", np.max))]
    variant = ", ".join(f"{k}={os.environ[k]}" for k in ("BENCH_SWITCH_INTERVAL",
                                                         "BENCH_READ_FIRST") if k in os.environ)
    write_results("gripper_cancel", figures, notes=f"{len(cancels)} cancels at "
                  f"{FINGER_SPEED_M_S * 1e3:.0f} mm/s finger speed; {one_write} stopped with "
                  "one write" + (f"; node variant {variant}" if variant else "") + ".")


def main() -> int:
    if len(sys.argv) > 2 and sys.argv[1] == "--emulator":
        return run_emulator(sys.argv[2])
    if len(sys.argv) > 1 and sys.argv[1] == "--node":
        return run_node(sys.argv[2:])
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=20, help="number of cancels")
    ap.add_argument("--force-rate", type=float, default=250.0,
                    help="tactile force publishing rate [Hz] (driver: 250)")
    return client_main(ap.parse_args())


if __name__ == "__main__":
    sys.exit(main())
