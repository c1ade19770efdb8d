"""What the tactile effort limit buys: GripperCommand closes on the rod with max_effort 1, 2
and 4 N, beside a position-only close (max_effort 0) into the rod under the current limit.

Processes as on the robot: the mock gripper world (emulated XM430 + photoreflector, 20 mm
rod), then ``ros2 launch tactile_sensor gripper.launch.py use_mock_hardware:=false`` (model,
driver, gripper) against it; this process is the action client, as MoveIt would be. Every
trial starts fully open (60 mm) and closes toward the closed limit at the default speed
(config/gripper.yaml: 10 mm/s per finger).

Per condition (median over the trials):

* goal -> at rest: goal sent until the fingers stop (the first ``~/joint_states`` sample,
  by stamp, from which on the opening stays within 0.05 mm);
* goal -> result: until the action's answer (a tactile stop adds the force settling,
  ``settle_time``; a position-only stall adds ``stall_timeout`` at rest);
* peak force: the largest true finger force (``/gripper_world/ground_truth``) during the goal;
  overshoot = peak - max_effort; held = the true force 0.2-0.5 s after the result;
* result effort and opening: what the action answered (the tactile force it measured).

Run: . scripts/env.sh && python benchmarks/bench_gripper_command.py [--trials 3]
     [--plot gripper_command.png]   (ROS_DOMAIN_ID defaults to 122)
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml
from results import Figure, without_ros2, write_results

from tactile_sensor.analysis.finger_rest import rest_onset
from tactile_sensor.nodes.background_spin import BackgroundSpin
from tactile_sensor.nodes.ros_session import ros_session

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tactile_sensor"))

CONDITIONS = (1.0, 2.0, 4.0, 0.0)  # max_effort [N]; 0 = position only


def spawn(argv: list[str], log: Path, env: dict[str, str]) -> subprocess.Popen:
    return subprocess.Popen(argv, stdout=log.open("wb"), stderr=subprocess.STDOUT, env=env,
                            start_new_session=True)


def stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGINT)
        try:
            proc.wait(15)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(5)


def wait_until(condition, timeout_s: float, what: str, poll_s: float = 0.05) -> None:  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            raise RuntimeError(f"timed out waiting for {what}")
        time.sleep(poll_s)


class TrialFailed(RuntimeError):
    """A goal that did not succeed (a starved emulator, a lost servo): counted, not used."""


class Recorder:
    """The client node: topics recorded with their stamps, the GripperCommand client."""

    def __init__(self, rclpy) -> None:  # type: ignore[no-untyped-def]
        from action_msgs.msg import GoalStatus
        from control_msgs.action import GripperCommand
        from geometry_msgs.msg import WrenchStamped
        from sensor_msgs.msg import JointState

        from tactile_sensor.nodes.action_client import RaceFreeActionClient as ActionClient

        self.GripperCommand = GripperCommand
        self.succeeded = GoalStatus.STATUS_SUCCEEDED
        self.node = rclpy.create_node("gripper_command_bench")
        self.action = ActionClient(self.node, GripperCommand, "/gripper/gripper_cmd")
        self.truth: list[tuple[float, float]] = []
        self.tactile: list[tuple[float, float]] = []
        self.opening: list[tuple[float, float]] = []
        self.node.create_subscription(WrenchStamped, "/gripper_world/ground_truth",
                                      lambda m: self.truth.append(_sample(m)), 1000)
        self.node.create_subscription(WrenchStamped, "/driver/wrench",
                                      lambda m: self.tactile.append(_sample(m)), 1000)
        self.node.create_subscription(
            JointState, "/gripper/joint_states",
            lambda m: self.opening.append((_stamp(m), m.position[0])), 1000)
        self.executor = rclpy.executors.MultiThreadedExecutor(num_threads=2)
        self.executor.add_node(self.node)
        self.spin = BackgroundSpin(self.executor)

    def run(self, position: float, max_effort: float):  # type: ignore[no-untyped-def]
        goal = self.GripperCommand.Goal()
        goal.command.position, goal.command.max_effort = position, max_effort
        sent = time.time()
        future = self.action.send_goal_async(goal)
        wait_until(future.done, 10, "the goal's acceptance", 0.002)
        handle = future.result()
        if not handle.accepted:
            raise RuntimeError(f"goal {position} m, {max_effort} N rejected")
        result = handle.get_result_async()
        wait_until(result.done, 30, "the goal's result", 0.002)
        answer = result.result()
        if answer.status != self.succeeded:
            raise TrialFailed(f"goal {position} m, {max_effort} N ended with status "
                              f"{answer.status} ({answer.result})")
        return sent, time.time(), answer.result

    def close(self) -> None:
        self.spin.stop()
        self.action.destroy()  # destroy_node() leaves action clients to the garbage collector
        self.node.destroy_node()


def _stamp(msg) -> float:  # type: ignore[no-untyped-def]
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def _sample(msg) -> tuple[float, float]:  # type: ignore[no-untyped-def]
    return _stamp(msg), msg.wrench.force.z


def trial(rec: Recorder, max_effort: float, closed: float, open_: float) -> dict[str, float]:
    rec.run(open_, 0.0)
    time.sleep(0.3)
    sent, answered, result = rec.run(closed, max_effort)
    end = answered + 0.5
    # the subscriptions lag on a loaded machine: wait until the window is in
    wait_until(lambda: rec.truth[-1][0] > end and rec.opening[-1][0] > end, 5,
               "ground truth and joint states after the result")
    truth = [(t, f) for t, f in rec.truth if sent <= t <= end]
    held = [f for t, f in truth if t >= answered + 0.2]
    peak = max(f for _, f in truth)
    return {"rest": rest_onset(rec.opening, sent, end) - sent,
            "result": answered - sent, "peak": peak,
            "overshoot": peak - max_effort if max_effort else float("nan"),
            "held": float(np.mean(held)) if held else float("nan"),
            "effort": result.effort, "opening": result.position,
            "stalled": float(result.stalled), "sent": sent, "end": end}


def plot(path: Path, rec: Recorder, traces: dict[float, dict[str, float]]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (force_ax, opening_ax) = plt.subplots(2, 1, sharex=True, figsize=(8, 6))
    for max_effort, run in traces.items():
        label = f"max_effort {max_effort:g} N" if max_effort else "position only"
        truth = np.array([(t - run["sent"], f) for t, f in rec.truth
                          if run["sent"] <= t <= run["end"]])
        opening = np.array([(t - run["sent"], o * 1e3) for t, o in rec.opening
                            if run["sent"] <= t <= run["end"]])
        force_ax.plot(truth[:, 0], truth[:, 1], label=label)
        opening_ax.plot(opening[:, 0], opening[:, 1], label=label)
        if not max_effort:  # off the scale of the limits: say how far
            force_ax.annotate(f"position only: {truth[:, 1].max():.1f} N", xy=(0.02, 0.9),
                              xycoords="axes fraction")
        else:
            force_ax.axhline(max_effort, color="grey", linewidth=0.5, linestyle=":")
    limits = [m for m in traces if m]
    force_ax.set_ylim(0.0, 1.5 * max(limits, default=5.0))
    force_ax.set_ylabel("true finger force [N]")
    force_ax.legend(loc="center left")
    opening_ax.set_ylabel("opening [mm]")
    opening_ax.set_xlabel("time since the goal [s]")
    fig.suptitle("GripperCommand into the 20 mm rod: tactile limit vs position only")
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=3, help="closes per condition")
    ap.add_argument("--plot", type=Path, default=None, help="PNG of one close per condition")
    args = ap.parse_args()
    cannot = without_ros2("bench_gripper_command", " (or use benchmarks/bench_gripper_cancel.py, "
                                                   "which runs without it)")
    if cannot is not None:
        return cannot

    import rclpy

    from tactile_sensor.configurations import config_dir

    os.environ.setdefault("ROS_DOMAIN_ID", "122")
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(ROOT / "tactile_sensor"), os.environ.get("PYTHONPATH", "")]),
        PYTHONUNBUFFERED="1")
    config = config_dir()
    shared = yaml.safe_load((config / "gripper.yaml").read_text())["/**"]["ros__parameters"]
    closed, open_ = shared["geometry.closed_opening"], shared["geometry.open_opening"]
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        adc, servo = tmp / "adc", tmp / "xm430"
        overrides = tmp / "overrides.yaml"
        overrides.write_text(yaml.safe_dump({"/**/gripper_world": {"ros__parameters": {
            "adc_link": str(adc), "servo_link": str(servo), "seed": 3}}}))
        mock = spawn([sys.executable, "-m", "tactile_sensor.nodes.mock_hardware", "--ros-args",
                      "-r", "__node:=gripper_world",
                      "--params-file", str(config / "physics.yaml"),
                      "--params-file", str(config / "gripper.yaml"),
                      "--params-file", str(overrides)], tmp / "mock.log", env)
        launch = None
        try:
            wait_until(lambda: "mock gripper ready" in (tmp / "mock.log").read_text(), 300,
                       "the mock gripper world")
            launch = spawn(["ros2", "launch", "tactile_sensor", "gripper.launch.py",
                            "use_mock_hardware:=false", f"adc_port:={adc}",
                            f"servo_port:={servo}"], tmp / "launch.log", env)
            with ros_session():
                rec = Recorder(rclpy)
                try:
                    if not rec.action.wait_for_server(timeout_sec=120):
                        raise RuntimeError("no /gripper/gripper_cmd server")
                    wait_until(lambda: rec.opening and rec.tactile, 120, "the gripper and "
                               "the driver to be active")
                    time.sleep(1.0)
                    return measure(args, rec, closed, open_, tmp / "launch.log")
                finally:
                    rec.close()
        except RuntimeError as exc:
            for name in ("mock.log", "launch.log"):
                if (tmp / name).exists():
                    sys.stderr.write(f"--- {name}\n{(tmp / name).read_text()[-4000:]}\n")
            print(f"benchmark failed: {exc}", file=sys.stderr)
            return 1
        finally:
            if launch is not None:
                stop(launch)
            stop(mock)


def measure(args: argparse.Namespace, rec: Recorder, closed: float, open_: float,
            log: Path) -> int:
    print(f"GripperCommand from {open_ * 1e3:.0f} mm toward {closed * 1e3:.0f} mm into the "
          f"20 mm rod at the default speed, {args.trials} trials per condition", flush=True)
    runs: dict[float, list[dict[str, float]]] = {}
    for max_effort in CONDITIONS:
        runs[max_effort] = []
        for k in range(args.trials):
            try:
                runs[max_effort].append(trial(rec, max_effort, closed, open_))
                outcome = "done"
            except TrialFailed as exc:
                why = [line for line in log.read_text().splitlines() if "aborted" in line]
                outcome = f"FAILED, left out: {exc}; {why[-1] if why else ''}"
            print(f"  max_effort {max_effort:g} N: trial {k + 1}/{args.trials} {outcome}",
                  flush=True)
    rec.run(open_, 0.0)
    runs = {m: trials for m, trials in runs.items() if trials}
    header = (f"{'max_effort':>14} {'n':>2} {'goal->rest':>11} {'goal->result':>13} {'peak':>7} "
              f"{'overshoot':>10} {'held':>7} {'result effort':>14} {'opening':>8}")
    print("\n" + header + "\n" + " " * 18 + f"{'[s]':>11} {'[s]':>13} {'[N]':>7} {'[N]':>10} "
          f"{'[N]':>7} {'[N]':>14} {'[mm]':>8}")
    for max_effort, trials in runs.items():
        def med(key: str, trials: list[dict[str, float]] = trials) -> float:
            return float(np.median([t[key] for t in trials]))
        name = f"{max_effort:g} N" if max_effort else "0 (position)"
        overshoot = f"{med('overshoot'):+10.2f}" if max_effort else f"{'-':>10}"
        print(f"{name:>14} {len(trials):2d} {med('rest'):11.2f} {med('result'):13.2f} "
              f"{med('peak'):7.2f} "
              f"{overshoot} {med('held'):7.2f} {med('effort'):14.2f} "
              f"{med('opening') * 1e3:8.1f}")
    if args.plot is not None:
        plot(args.plot, rec, {m: trials[-1] for m, trials in runs.items()})
        print(f"\nplot: {args.plot}")
    figures = []
    for max_effort, trials in runs.items():
        name = f"max_effort {max_effort:g} N" if max_effort else "position only"
        for key, label, unit, scale in (("rest", "goal -> at rest", "s", 1.0),
                                        ("result", "goal -> result", "s", 1.0),
                                        ("peak", "peak force", "N", 1.0),
                                        ("held", "held force", "N", 1.0),
                                        ("opening", "result opening", "mm", 1e3)):
            figures.append(Figure(f"{name}: {label}",
                                  float(np.median([t[key] for t in trials])) * scale, unit))
    write_results("gripper_command", figures, notes=f"Median of {args.trials} closes per "
                  "condition into the 20 mm rod, launched with `ros2 launch`.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
