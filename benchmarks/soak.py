"""Soak: the bench and gripper configurations for N minutes at 1 kHz under scheduled faults.

Every node runs in its own process, as under ``ros2 launch`` (bench in namespace
/soak_bench, gripper in /soak_gripper, one ROS domain): the mock ADC (``tactile-sensor mock
adc --control``) and the XM430 emulator with its gripper world and ADC (``mock xm430
--control --adc-link``) on pseudo-terminals; per configuration a model, a driver
(``autostart``), the gripper node (``auto_reboot``), and the bench's recorder splitting its
bag every ``--split`` seconds. This process grasps and releases through the gripper's
actions in a loop and injects, on the schedule of ``analysis/soak.py``:

* adc_unplug: ``unplug 2`` to the mock ADC. Detected when the bench driver's /diagnostics
  says the connection is not ``connected``; recovered when it says ``connected`` again
  with more frames than before the pull. The time between pull and recovery is the window
  in which lost frames are explained.
* servo_overload: ``fault overload`` to the XM430 emulator (latches the Overload bit,
  torque off). Detected when the gripper's diagnostics go ERROR; recovered when they go OK
  after the node's ``auto_reboot`` rebooted the servo.
* cpu_burner: a busy process for 10 s. Nothing to detect (the system only gets less CPU);
  recovery is the time after the burner ends until the bench driver's backlog is empty.
* model_restart: SIGTERM to the bench model process (its clean lifecycle shutdown) and a
  new process. Detected when the old one has exited; recovered when the new one's latched
  ``calibration_curve`` reaches this process.
* recording_split: the recorder's ``max_bag_duration``. Detected when the next storage
  file appears; its "recovery" is the recorder's loss goal (every message in some file).

Readings lost are counted by sequence number, never by rate: the device counts frames it
generated while plugged in, the driver's reader counts frames parsed and those missing in
the sequence, the driver counts readings published (/diagnostics); the bag is read back.
RSS growth is the Theil-Sen slope of VmRSS samples after a warm-up (start-up allocation,
caches and the first GC cycles are not a leak), each process sampled every 5 s.

    python benchmarks/soak.py --minutes 5 [--json soak.json] [--keep DIR]

Run with ``scripts/env.sh`` sourced. ROS domain: $ROS_DOMAIN_ID (default 216); discovery
stays on localhost. Exits 1 when a goal fails.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

SOURCE = Path(__file__).resolve().parents[1] / "tactile_sensor"
sys.path.insert(0, str(SOURCE))
sys.path.insert(0, str(Path(__file__).resolve().parent))  # results.py, also when imported

from results import RESULTS, Figure, write_results  # noqa: E402

from tactile_sensor.analysis.soak import (  # noqa: E402
    SPLIT_KIND,
    LossSnapshot,
    ScheduledFault,
    account_losses,
    evaluate_goals,
    fault_schedule,
    growth_per_hour,
    parse_device_stats,
)
from tactile_sensor.configurations import BENCH, GRIPPER  # noqa: E402

BENCH_NS, GRIPPER_NS = "/soak_bench", "/soak_gripper"
ADC_RATE_HZ = 1000.0
SAMPLE_PERIOD_S = 5.0
WAIT_S = 90.0  # the most any condition may take before it counts as failed
TEARDOWN_S = 20.0  # this process's own ROS teardown, after the figures are written
FRAME_BYTES = 11  # one-channel frame (docs/serial-frame.md)
# What a cable pull can swallow: the device's host buffer and the pseudo-terminal's.
LINK_CAPACITY_FRAMES = (65536 + 20000) // FRAME_BYTES
GRASP_FORCE_N = 2.0
SELF = "soak (this process)"


def say(text: str) -> None:
    print(text, flush=True)


class Proc:
    """One child process with its log; remembers every pid it ran as."""

    def __init__(self, name: str, argv: list[str], folder: Path, env: dict[str, str]) -> None:
        self.name, self.argv, self.env = name, argv, env
        self.log_path = folder / f"{name}.log"
        self.proc: subprocess.Popen[bytes] | None = None
        self.pids: list[int] = []
        self.exit_codes: list[int | None] = []

    def start(self) -> None:
        with self.log_path.open("ab") as log:
            self.proc = subprocess.Popen(self.argv, env=self.env, stdout=log,
                                         stderr=subprocess.STDOUT, start_new_session=True)
        self.pids.append(self.proc.pid)

    @property
    def pid(self) -> int:
        assert self.proc is not None
        return self.proc.pid

    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def log(self) -> str:
        return self.log_path.read_text(errors="replace") if self.log_path.exists() else ""

    def stop(self, sig: int = signal.SIGINT, timeout_s: float = 30.0) -> int | None:
        if self.proc is None:
            return None
        if self.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(self.proc.pid, sig)
            try:
                self.proc.wait(timeout_s)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait(10)
        self.exit_codes.append(self.proc.returncode)
        return self.proc.returncode


def wait_until(condition: Callable[[], Any], timeout_s: float = WAIT_S,
               period_s: float = 0.05) -> Any:
    """The condition's first true value, or None after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while True:
        value = condition()
        if value or time.monotonic() > deadline:
            return value or None
        time.sleep(period_s)


def node_argv(spec_name: str, configuration: Any, namespace: str, *extra: str,
              params_file: Path | None = None) -> list[str]:
    """``python -m <node module> --ros-args`` as the launch file gives it, in a namespace
    (``params_file`` after the configuration's: its node sections beat theirs, a global
    ``-p`` would not)."""
    from tactile_sensor.nodes.bringup_runner import node_arguments

    spec = next(s for s in configuration.nodes if s.name == spec_name)
    return [sys.executable, "-m", spec.module, *node_arguments(spec, params_file),
            "-r", f"__ns:={namespace}", "-p", "autostart:=true", *extra]


# -- the monitor: diagnostics, calibration, grasp actions, in this process ---------------------

@dataclass
class Report:
    t_s: float
    level: int
    message: str
    values: dict[str, str]


class Monitor:
    def __init__(self, t0: float) -> None:
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.executors import MultiThreadedExecutor
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

        from tactile_sensor.nodes.action_client import RaceFreeActionClient as ActionClient
        from tactile_sensor_interfaces.action import Grasp, Release
        from tactile_sensor_interfaces.msg import CalibrationCurve

        self.t0 = t0
        rclpy.init()
        self.node = rclpy.create_node("soak_monitor")
        self.lock = threading.Lock()
        self.reports: dict[str, list[Report]] = {}
        self.calibrations: list[float] = []
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                             reliability=ReliabilityPolicy.RELIABLE)
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self._on_diag, 100)
        self.node.create_subscription(CalibrationCurve, f"{BENCH_NS}/calibration_curve",
                                      self._on_calibration, latched)
        self.grasp = ActionClient(self.node, Grasp, f"{GRIPPER_NS}/gripper/grasp")
        self.release = ActionClient(self.node, Release, f"{GRIPPER_NS}/gripper/release")
        self.Grasp, self.Release = Grasp, Release
        self.executor = MultiThreadedExecutor(num_threads=2)
        self.executor.add_node(self.node)
        self.spinning = threading.Event()
        self.spinning.set()
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _spin(self) -> None:
        # spin_once in a loop, so close() can stop it before the node and context go (a
        # thread left in spin() when they do aborts the interpreter at exit)
        while self.spinning.is_set():
            self.executor.spin_once(timeout_sec=0.05)

    def now(self) -> float:
        return time.monotonic() - self.t0

    def _on_diag(self, msg: Any) -> None:
        t = self.now()
        with self.lock:
            for status in msg.status:
                self.reports.setdefault(status.name, []).append(Report(
                    t, int.from_bytes(status.level, "little") if isinstance(status.level, bytes)
                    else int(status.level), status.message,
                    {kv.key: kv.value for kv in status.values}))

    def _on_calibration(self, msg: Any) -> None:
        with self.lock:
            self.calibrations.append(self.now())

    def history(self, name: str) -> list[Report]:
        with self.lock:
            return list(self.reports.get(name, []))

    def first(self, name: str, after_s: float, test: Callable[[Report], bool],
              timeout_s: float = WAIT_S) -> Report | None:
        return wait_until(lambda: next((r for r in self.history(name)
                                        if r.t_s > after_s and test(r)), None), timeout_s)

    def call(self, client: Any, goal: Any, timeout_s: float) -> Any:
        """Send a goal and wait for its result; None when it was rejected or took too long."""
        if not client.wait_for_server(timeout_sec=timeout_s):
            return None
        sent = client.send_goal_async(goal)
        if not wait_until(sent.done, timeout_s) or not sent.result().accepted:
            return None
        result = sent.result().get_result_async()
        return result.result().result if wait_until(result.done, timeout_s) else None

    def close(self, timeout_s: float = TEARDOWN_S) -> bool:
        """Stop spinning and tear the node down; False when the teardown did not end in
        ``timeout_s``. On Kilted, Fast DDS 3.2 can deadlock destroying a publisher (its
        event thread and a receive thread each waiting on the other), which would hang the
        benchmark after its run; the caller then exits without waiting for it."""
        import rclpy

        def teardown() -> None:
            self.spinning.clear()
            self.thread.join(5.0)
            self.executor.shutdown(timeout_sec=2.0)
            self.grasp.destroy()  # destroy_node() leaves action clients to the collector
            self.release.destroy()
            self.node.destroy_node()
            rclpy.try_shutdown()

        worker = threading.Thread(target=teardown, daemon=True)
        worker.start()
        worker.join(timeout_s)
        return not worker.is_alive()


DRIVER_DIAG = f"{BENCH_NS}/driver: tactile ADC"
GRIPPER_DIAG = f"{GRIPPER_NS}/gripper: XM430"
GRIPPER_DRIVER_DIAG = f"{GRIPPER_NS}/driver: tactile ADC"


class GraspLoop:
    """Release, grasp the rod, again and again, through the gripper's actions."""

    def __init__(self, monitor: Monitor) -> None:
        self.monitor = monitor
        self.attempted = self.succeeded = 0
        self.outcomes: dict[str, int] = {}
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        m = self.monitor
        while not self.stop.is_set():
            m.call(m.release, m.Release.Goal(opening=0.0), 30.0)
            if self.stop.is_set():
                break
            result = m.call(m.grasp, m.Grasp.Goal(target_force=GRASP_FORCE_N), 30.0)
            self.attempted += 1
            # the outcome without its figures: "contact", "tactile_stale", ...
            outcome = ("no result" if result is None
                       else (result.message or "?").split(":")[0])
            self.outcomes[outcome] = self.outcomes.get(outcome, 0) + 1
            if result is not None and result.contact_detected:
                self.succeeded += 1
            else:
                self.stop.wait(0.5)  # e.g. a servo being rebooted: do not spin


# -- /proc sampling -------------------------------------------------------------------------------

def proc_sample(pid: int) -> tuple[float, int] | None:
    """(VmRSS [MB], open file descriptors) of a live process, None when it is gone."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
        fds = len(os.listdir(f"/proc/{pid}/fd"))
    except (FileNotFoundError, ProcessLookupError, PermissionError):
        return None
    match = re.search(r"^VmRSS:\s+(\d+) kB", status, re.M)
    return (int(match.group(1)) / 1024.0 if match else math.nan), fds


@dataclass
class Series:
    name: str
    pid: int
    samples: list[tuple[float, float, int]] = field(default_factory=list)  # (t, MB, fds)


class Sampler:
    def __init__(self, processes: Callable[[], dict[str, int]], monitor: Monitor) -> None:
        self.processes, self.monitor = processes, monitor
        self.series: dict[tuple[str, int], Series] = {}
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)

    def sample_once(self) -> None:
        t = self.monitor.now()
        for name, pid in self.processes().items():
            got = proc_sample(pid)
            if got is not None:
                self.series.setdefault((name, pid), Series(name, pid)).samples.append(
                    (t, *got))

    def _run(self) -> None:
        while not self.stop.wait(SAMPLE_PERIOD_S):
            self.sample_once()


# -- faults ---------------------------------------------------------------------------------------

@dataclass
class FaultResult:
    kind: str
    at_s: float
    detected_after_s: float | None
    recovered_after_s: float | None
    note: str = ""

    @property
    def recovered(self) -> bool:
        return self.recovered_after_s is not None


def write_fifo(path: Path, line: str) -> None:
    fd = os.open(path, os.O_WRONLY | os.O_NONBLOCK)
    try:
        os.write(fd, (line + "\n").encode())
    finally:
        os.close(fd)


class Soak:
    def __init__(self, folder: Path, minutes: float, split_s: float,
                 schedule: list[ScheduledFault], bring_up_timeout_s: float = 180.0) -> None:
        self.folder, self.minutes, self.split_s = folder, minutes, split_s
        self.schedule, self.bring_up_timeout_s = schedule, bring_up_timeout_s
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(SOURCE), env.get("PYTHONPATH")]))
        self.env = env
        self.bag = folder / "bag"
        f = folder
        self.adc_link, self.adc_ctl = f / "bench_adc", f / "bench_adc.ctl"
        self.servo_link, self.servo_ctl = f / "xm430", f / "xm430.ctl"
        self.gripper_adc = f / "gripper_adc"
        self.gripper_params = f / "soak_gripper.yaml"
        self.gripper_params.write_text(  # the overload fault's recovery
            "/**/gripper:\n  ros__parameters:\n    auto_reboot: true\n")
        topics = [f"{BENCH_NS}/driver/reading", f"{BENCH_NS}/driver/wrench"]
        self.reading_topic = topics[0]
        types = [f"{topics[0]}=tactile_sensor_interfaces/msg/TactileReading",
                 f"{topics[1]}=geometry_msgs/msg/WrenchStamped"]
        py = sys.executable
        self.procs = {
            "bench_adc": Proc("bench_adc", [
                py, "-m", "tactile_sensor.sim.adc_device", "--link", str(self.adc_link),
                "--rate", f"{ADC_RATE_HZ:g}", "--profile", "repeatability", "--loop",
                "--control", str(self.adc_ctl)], f, env),
            "bench_model": Proc("bench_model", node_argv("model", BENCH, BENCH_NS), f, env),
            "bench_driver": Proc("bench_driver", node_argv(
                "driver", BENCH, BENCH_NS, "-p", f"port:={self.adc_link}"), f, env),
            "recorder": Proc("recorder", [
                py, "-m", "tactile_sensor.nodes.recorder", "--ros-args",
                "-r", f"__ns:={BENCH_NS}", "-p", f"path:={self.bag}",
                "-p", f"topics:={json.dumps(topics)}",
                "-p", f"topic_types:={json.dumps(types)}",
                "-p", f"max_bag_duration:={split_s:g}"], f, env),
            "xm430": Proc("xm430", [
                py, "-m", "tactile_sensor.sim.xm430_emulator", "--link", str(self.servo_link),
                "--baud", "1000000", "--control", str(self.servo_ctl),
                "--adc-link", str(self.gripper_adc)], f, env),
            "gripper_model": Proc("gripper_model", node_argv("model", GRIPPER, GRIPPER_NS),
                                  f, env),
            "gripper_driver": Proc("gripper_driver", node_argv(
                "driver", GRIPPER, GRIPPER_NS, "-p", f"port:={self.gripper_adc}"), f, env),
            "gripper": Proc("gripper", node_argv(
                "gripper", GRIPPER, GRIPPER_NS, "-p", f"port:={self.servo_link}",
                params_file=self.gripper_params), f, env),
        }
        self.t0 = time.monotonic()
        self.wall_minus_monitor_s = time.time() - (time.monotonic() - self.t0)
        self.monitor = Monitor(self.t0)
        self.sampler = Sampler(self._pids, self.monitor)
        self.grasps = GraspLoop(self.monitor)
        self.faults: list[FaultResult] = []
        self.windows: list[tuple[float, float]] = []
        self.split_files: dict[str, float] = {}
        self.run_start_s = 0.0

    def _pids(self) -> dict[str, int]:
        pids = {name: p.pid for name, p in self.procs.items() if p.alive()}
        pids[SELF] = os.getpid()
        return pids

    # -- bring-up ---------------------------------------------------------------------------
    def bring_up(self) -> None:
        """Every node up and working, each step waiting for its condition."""
        p = self.procs
        for name in ("bench_model", "gripper_model", "recorder", "xm430"):
            p[name].start()
        self._expect(lambda: f"Recording {self.reading_topic}" in p["recorder"].log(),
                     "the recorder did not subscribe", "recorder")
        self._expect(lambda: self.servo_link.exists() and self.gripper_adc.exists(),
                     "the XM430 emulator did not create its links", "xm430")
        p["bench_driver"].start()  # before the ADC: it sees the very first frame
        p["gripper_driver"].start()
        p["gripper"].start()
        self._expect(lambda: self.monitor.calibrations, "no calibration from the bench model",
                     "bench_model")
        self._expect(lambda: "calibration from" in p["bench_driver"].log(),
                     "the bench driver got no calibration", "bench_driver")
        # The recorder hears only what is published after its subscriptions match the
        # driver's publishers: on a loaded machine that took 0.8 s past the driver's start,
        # and the first ~800 readings were lost to it. The driver counts its matches.
        self._expect(lambda: any(
            int(r.values.get("reading_subscribers", 0)) >= 1
            and int(r.values.get("wrench_subscribers", 0)) >= 1
            for r in self.monitor.history(DRIVER_DIAG)),
            "the recorder's subscriptions did not match the bench driver", "recorder")
        p["bench_adc"].start()
        self._expect(lambda: any(int(r.values.get("readings_published", 0)) > 0
                                 for r in self.monitor.history(DRIVER_DIAG)),
                     "the bench driver published no reading", "bench_driver")
        self._expect(lambda: any(r.level == 0 for r in self.monitor.history(GRIPPER_DIAG)),
                     "the gripper is not ready", "gripper")
        self._expect(lambda: any(int(r.values.get("readings_published", 0)) > 0
                                 for r in self.monitor.history(GRIPPER_DRIVER_DIAG)),
                     "the gripper's driver published no reading", "gripper_driver")

    def _expect(self, condition: Callable[[], Any], failure: str, name: str) -> None:
        if not wait_until(condition, self.bring_up_timeout_s):
            tail = self.procs[name].log()[-2000:]
            raise RuntimeError(f"{failure}; {self.procs[name].log_path} ends:\n{tail}")

    # -- faults -----------------------------------------------------------------------------
    def inject(self, fault: ScheduledFault) -> FaultResult:
        m = self.monitor
        at = m.now()
        if fault.kind == "adc_unplug":
            before = self._last(DRIVER_DIAG)
            frames = int(before.values.get("frames", 0)) if before else 0
            write_fifo(self.adc_ctl, f"unplug {fault.duration_s:g}")
            det = m.first(DRIVER_DIAG, at, lambda r: r.values.get("connection") != "connected")
            rec = det and m.first(DRIVER_DIAG, det.t_s, lambda r: (
                r.values.get("connection") == "connected"
                and int(r.values.get("frames", 0)) > frames))
            self.windows.append((at, rec.t_s if rec else math.inf))
            return self._result(fault, at, det, rec, f"unplugged {fault.duration_s:g} s")
        if fault.kind == "servo_overload":
            pid = self.procs["gripper"].pid
            write_fifo(self.servo_ctl, "fault overload")
            det = m.first(GRIPPER_DIAG, at, lambda r: r.level == 2
                          and "hardware error" in r.message)
            rec = det and m.first(GRIPPER_DIAG, det.t_s, lambda r: r.level == 0)
            same = self.procs["gripper"].alive() and self.procs["gripper"].pid == pid
            return self._result(fault, at, det, rec if same else None,
                                "auto_reboot" + ("" if same else "; the gripper process died"))
        if fault.kind == "cpu_burner":
            burner = subprocess.Popen([sys.executable, "-c", "while True: pass"])
            try:
                time.sleep(fault.duration_s)
            finally:  # never leave a busy loop behind (Ctrl-C, an error)
                burner.kill()
                burner.wait()
            end = m.now()
            rec = m.first(DRIVER_DIAG, end, lambda r: r.values.get("frames_backlog") == "0")
            peak = max((int(r.values.get("frames_backlog", 0))
                        for r in m.history(DRIVER_DIAG) if at <= r.t_s <= end), default=0)
            result = FaultResult(fault.kind, at, None,
                                 None if rec is None else rec.t_s - end,
                                 f"busy process {fault.duration_s:g} s; driver backlog peak "
                                 f"{peak} frames; recovery = backlog empty after it ended")
            return result
        assert fault.kind == "model_restart", fault.kind  # FAULT_KINDS holds no other
        model = self.procs["bench_model"]
        seen = len(m.calibrations)
        model.stop(signal.SIGTERM)
        exited = m.now()
        model.start()
        rec = wait_until(lambda: len(m.calibrations) > seen)
        return FaultResult(fault.kind, at, exited - at,
                           None if rec is None else m.calibrations[seen] - at,
                           f"SIGTERM (exit {model.exit_codes[-1]}), new process; "
                           "recovered = its calibration_curve received")

    def _last(self, name: str) -> Report | None:
        history = self.monitor.history(name)
        return history[-1] if history else None

    @staticmethod
    def _result(fault: ScheduledFault, at: float, det: Report | None, rec: Report | None,
                note: str) -> FaultResult:
        return FaultResult(fault.kind, at, None if det is None else det.t_s - at,
                           None if rec is None else rec.t_s - at, note)

    def _watch_splits(self, stop: threading.Event) -> None:
        while not stop.wait(0.2):
            for path in sorted(self.bag.glob("*.mcap")):
                self.split_files.setdefault(path.name, self.monitor.now())

    # -- the run ----------------------------------------------------------------------------
    def run(self) -> dict[str, Any]:
        run_s = self.minutes * 60.0
        schedule = self.schedule
        say(f"soak: {self.minutes:g} min, ADC {ADC_RATE_HZ:g} Hz, bag split every "
            f"{self.split_s:g} s; bringing up {len(self.procs)} processes in {self.folder}")
        watch_stop = threading.Event()
        watcher = threading.Thread(target=self._watch_splits, args=(watch_stop,), daemon=True)
        watcher.start()  # before the recorder starts: its first file's creation is seen
        self.bring_up()
        self.run_start_s = self.monitor.now()
        say(f"soak: up after {self.run_start_s:.1f} s; faults at "
            + ", ".join(f"{self.run_start_s + f.at_s:.0f} s {f.kind}" for f in schedule)
            + " (times since the benchmark started)")
        self.sampler.sample_once()
        self.sampler.thread.start()
        self.grasps.thread.start()
        for fault in schedule:
            delay = self.run_start_s + fault.at_s - self.monitor.now()
            if delay > 0:
                time.sleep(delay)
            result = self.inject(fault)
            self.faults.append(result)
            say(f"  {result.at_s:6.1f} s {fault.kind}: " + _fault_line(result))
        delay = self.run_start_s + run_s - self.monitor.now()
        if delay > 0:
            time.sleep(delay)
        self.sampler.sample_once()
        self.sampler.stop.set()
        return self.wind_down(watch_stop)

    def wind_down(self, watch_stop: threading.Event) -> dict[str, Any]:
        """Stop the sources first and let the pipeline drain, so every count is final."""
        m, p = self.monitor, self.procs
        self.grasps.stop.set()
        self.grasps.thread.join(60.0)
        stopped_at = m.now()
        p["bench_adc"].stop(signal.SIGTERM)
        device = parse_device_stats(p["bench_adc"].log())

        def drained() -> Report | None:
            history = [r for r in m.history(DRIVER_DIAG) if r.t_s > stopped_at
                       and r.values.get("connection") != "connected"]
            if len(history) >= 2 and history[-1].values.get("frames_backlog") == "0" and (
                    history[-1].values.get("readings_published")
                    == history[-2].values.get("readings_published")):
                return history[-1]
            return None

        final = wait_until(drained)
        if final is None:
            raise RuntimeError("the bench driver did not report its final counts")
        # The recorder can still be behind the driver on a busy machine, and stopping it then
        # cut off what it had not yet taken (886 readings once). Its chunks reach the disk
        # every 0.5 s: stop it once they hold every published reading, or once they stopped
        # growing for 5 s (a real loss, which the goal then reports).
        wait_until(RecorderCatchUp(self.bag, self.reading_topic,
                                   int(final.values["readings_published"])), period_s=0.5)
        codes = {"recorder": p["recorder"].stop(signal.SIGINT, 60.0)}
        watch_stop.set()
        for name in ("gripper", "gripper_driver", "gripper_model", "bench_driver",
                     "bench_model", "xm430"):
            codes[name] = p[name].stop(signal.SIGINT if name != "xm430" else signal.SIGTERM)
        recorded, files, first_ns = count_bag(self.bag, self.reading_topic)
        # the recorder splits by message time: due k x max_bag_duration after the first
        first_s = first_ns * 1e-9 - self.wall_minus_monitor_s
        splits = self._split_faults(files, first_s)
        return self.summarise(device, final, recorded, files, splits, codes)

    def _split_faults(self, files: list[str], first: float) -> list[FaultResult]:
        """Each split: detected when its file appeared, relative to when it was due (the
        bag's first message + k x max_bag_duration, both in this process's clock)."""
        seen = sorted(self.split_files.items(), key=lambda kv: kv[1])
        out = []
        for k, (name, t) in enumerate(seen[1:], start=1):
            due = first + k * self.split_s
            out.append(FaultResult(SPLIT_KIND, due, t - due,
                                   t - due if name in files else None,
                                   f"{name}; recovered = it holds messages in the bag"))
        return out

    def summarise(self, device: dict[str, int], final: Report, recorded: int,
                  files: list[str], splits: list[FaultResult],
                  codes: dict[str, int | None]) -> dict[str, Any]:
        values = final.values
        sent = device["frames_generated"] - device["frames_unplugged"] - device[
            "frames_dropped"]
        received = int(values["frames"])
        published = int(values["readings_published"])
        snapshots = [LossSnapshot(r.t_s, int(r.values.get("frames_dropped", 0))
                                  + int(r.values.get("frames_overflowed", 0)))
                     for r in self.monitor.history(DRIVER_DIAG) if "frames" in r.values]
        loss = account_losses(sent, received, published, snapshots, self.windows,
                              LINK_CAPACITY_FRAMES)
        self.faults.extend(splits)
        restarted = [n for n, proc in self.procs.items()
                     if n != "bench_model" and len(proc.pids) > 1]
        unrecovered = [f"{f.kind} at {f.at_s:.0f} s" for f in self.faults if not f.recovered]
        unrecovered += [f"{n} restarted" for n in restarted]
        run_s = self.minutes * 60.0
        warmup_s = min(60.0, 0.25 * run_s)  # after each process's first sample
        processes = []
        growth: dict[str, float] = {}
        for series in self.sampler.series.values():
            s = series.samples
            label = f"{series.name} (pid {series.pid})"
            after = s[0][0] + warmup_s
            rss_h = growth_per_hour([(t, mb) for t, mb, _ in s], after)
            fd_h = growth_per_hour([(t, float(fd)) for t, _, fd in s], after)
            if series.name != SELF:  # it keeps every report it receives, by design
                growth[label] = rss_h
            processes.append({"process": label, "samples": len(s),
                              "rss_start_mb": s[0][1], "rss_end_mb": s[-1][1],
                              "fds_start": s[0][2], "fds_end": s[-1][2],
                              "rss_growth_mb_per_h": rss_h, "fd_growth_per_h": fd_h,
                              "samples_t_s_rss_mb_fds": s})
        gripper_final = self._last(GRIPPER_DRIVER_DIAG)
        goals = evaluate_goals(loss, recorded, published, unrecovered, growth)
        return {
            "minutes": self.minutes, "adc_rate_hz": ADC_RATE_HZ, "bag_split_s": self.split_s,
            "bring_up_s": self.run_start_s,
            "device": device,
            "bench_driver": {k: values.get(k) for k in (
                "frames", "frames_dropped", "frames_overflowed", "sequence_gaps",
                "reconnections", "readings_published")},
            "gripper_driver": gripper_final.values if gripper_final else {},
            "loss": asdict(loss), "unplugged_windows_s": self.windows,
            "recorded": recorded, "bag_files": files,
            "faults": [asdict(f) for f in self.faults],
            "processes": processes, "rss_warmup_s": warmup_s,
            "grasps": {"attempted": self.grasps.attempted, "succeeded": self.grasps.succeeded,
                       "outcomes": self.grasps.outcomes},
            "exit_codes": codes,
            "goals": [asdict(g) for g in goals],
        }

    def close(self) -> bool:
        """Stop everything; False when this process's own ROS teardown hung."""
        self.grasps.stop.set()
        self.sampler.stop.set()
        for proc in self.procs.values():
            if proc.alive():
                proc.stop(signal.SIGKILL, 10.0)
        return self.monitor.close()


def _fault_line(f: FaultResult) -> str:
    det = "-" if f.detected_after_s is None else f"{f.detected_after_s:.2f} s"
    rec = "NOT RECOVERED" if f.recovered_after_s is None else f"{f.recovered_after_s:.2f} s"
    return f"detected after {det}, recovered after {rec} ({f.note})"


class RecorderCatchUp:
    """A wait condition: the recording's files on disk hold ``published`` messages on
    ``topic``, or their count has not grown for ``still_s``. Split files other than the newest
    are closed, so each is read once."""

    def __init__(self, bag: Path, topic: str, published: int, still_s: float = 5.0) -> None:
        self.bag, self.topic, self.published, self.still_s = bag, topic, published, still_s
        self._closed: dict[Path, int] = {}
        self._count, self._grew_at = -1, time.monotonic()

    def _in_file(self, file: Path) -> int:
        from tactile_sensor.recording.recovery import read_mcap

        content = read_mcap(file)
        wanted = {i for i, t in enumerate(content.topics) if t.name == self.topic}
        return sum(1 for index, _, _ in content.messages if index in wanted)

    def __call__(self) -> bool:
        files = sorted(self.bag.glob("*.mcap"), key=lambda f: int(f.stem.rsplit("_", 1)[-1]))
        for file in files[:-1]:
            if file not in self._closed:
                self._closed[file] = self._in_file(file)
        count = sum(self._closed.values()) + (self._in_file(files[-1]) if files else 0)
        if count > self._count:
            self._count, self._grew_at = count, time.monotonic()
        return count >= self.published or time.monotonic() - self._grew_at > self.still_s


def count_bag(path: Path, topic: str) -> tuple[int, list[str], int]:
    """Messages on ``topic`` in every storage file of the bag, the files, and the bag's
    first reception stamp [ns, system clock]."""
    from tactile_sensor.analysis.bag_reader import open_reader

    reader = open_reader(path)  # every storage file metadata.yaml lists
    try:
        connections = [c for c in reader.connections if c.topic == topic]
        count = sum(1 for _ in reader.messages(connections=connections))
        first_ns = reader.start_time
    finally:
        reader.close()
    return count, sorted(p.name for p in path.glob("*.mcap")), first_ns


def print_report(r: dict[str, Any]) -> None:
    d, loss = r["device"], r["loss"]
    say(f"\nsoak {r['minutes']:g} min at {r['adc_rate_hz']:g} Hz (bring-up "
        f"{r['bring_up_s']:.1f} s)")
    say(f"bench ADC: {d['frames_generated']:,} frames generated, {d['frames_unplugged']:,} "
        f"while unplugged ({d['unplugs']} pulls), {loss['sent']:,} sent plugged in, "
        f"{d['bytes_lost']:,} bytes lost to a full host buffer")
    b = r["bench_driver"]
    say(f"bench driver: {int(b['frames']):,} frames received, {b['frames_dropped']} missing "
        f"in the sequence, {b['frames_overflowed']} overflowed, {b['reconnections']} "
        f"connections; {loss['published']:,} readings published")
    say(f"readings lost: {loss['lost_total']:,} = {loss['lost_in_windows']:,} in the "
        f"unplugged windows + {loss['lost_outside']:,} outside")
    g = r["gripper_driver"]
    if g:
        say(f"gripper driver: {int(g.get('frames', 0)):,} frames, "
            f"{g.get('frames_dropped')} missing, {g.get('frames_overflowed')} overflowed, "
            f"{int(g.get('readings_published', 0)):,} readings published (250 Hz)")
    say(f"recorder: {r['recorded']:,} readings in {len(r['bag_files'])} file(s) "
        f"({', '.join(r['bag_files'])}) of {loss['published']:,} published")
    say("faults (at: since the benchmark started; detection and recovery: from the "
        "injection, for a split from when it was due):")
    for f in r["faults"]:
        say(f"  {f['at_s']:6.1f} s {f['kind']:<16} " + _fault_line(FaultResult(**f)))
    say(f"processes (RSS growth: Theil-Sen slope of samples every {SAMPLE_PERIOD_S:g} s "
        f"from {r['rss_warmup_s']:.0f} s after each process's first one; this process "
        "keeps every report, so it is listed but not judged):")
    say(f"  {'process':<34} {'RSS MB start':>12} {'end':>7} {'MB/h':>8} {'fds':>9} {'fd/h':>7}")
    for p in r["processes"]:
        say(f"  {p['process']:<34} {p['rss_start_mb']:12.1f} {p['rss_end_mb']:7.1f} "
            f"{p['rss_growth_mb_per_h']:+8.2f} {p['fds_start']:>4}->{p['fds_end']:<4} "
            f"{p['fd_growth_per_h']:+7.1f}")
    gr = r["grasps"]
    say(f"grasps: {gr['succeeded']} of {gr['attempted']} succeeded ({gr['outcomes']})")
    say(f"exit codes: {r['exit_codes']}")
    for goal in r["goals"]:
        say(f"{'PASS' if goal['passed'] else 'FAIL'}  {goal['name']}: {goal['detail']}")


def report_figures(r: dict[str, Any]) -> list[Figure]:
    """The summary's figures for benchmarks/results: losses, each fault kind's slowest
    detection and recovery, the worst RSS growth, grasps and every goal."""
    loss = r["loss"]
    figures = [Figure("readings lost outside the unplugged windows", loss["lost_outside"]),
               Figure("readings lost in the unplugged windows", loss["lost_in_windows"]),
               Figure("readings recorded", r["recorded"], f"of {loss['published']} published")]
    for kind in sorted({f["kind"] for f in r["faults"]}):
        of_kind = [f for f in r["faults"] if f["kind"] == kind]
        for key, label in (("detected_after_s", "detection"), ("recovered_after_s", "recovery")):
            values = [f[key] for f in of_kind if f[key] is not None]
            figures.append(Figure(f"{kind}: slowest {label} of {len(of_kind)}",
                                  max(values) if len(values) == len(of_kind) else None, "s"))
    judged = [p["rss_growth_mb_per_h"] for p in r["processes"] if SELF not in p["process"]
              and math.isfinite(p["rss_growth_mb_per_h"])]
    figures.append(Figure("worst RSS growth", max(judged) if judged else None, "MB/h"))
    grasps = r["grasps"]
    figures.append(Figure("grasps succeeded", grasps["succeeded"], f"of {grasps['attempted']}"))
    figures += [Figure(g["name"], "PASS" if g["passed"] else "FAIL", "", g["detail"], g["passed"])
                for g in r["goals"]]
    return figures


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--minutes", type=float, default=5.0)
    parser.add_argument("--json", type=Path, default=None, help="write the figures here")
    parser.add_argument("--split", type=float, default=None,
                        help="recorder max_bag_duration [s] (default: a third of the run)")
    parser.add_argument("--keep", type=Path, default=None,
                        help="work folder to keep (logs, bag); default: a temporary one")
    parser.add_argument("--results", type=Path, default=RESULTS,
                        help="folder for soak.json, the summary's figures (default "
                             "benchmarks/results)")
    parser.add_argument("--bring-up-timeout", type=float, default=180.0,
                        help="seconds each bring-up step may take (default %(default)g)")
    args = parser.parse_args(argv)
    os.environ.setdefault("ROS_DOMAIN_ID", "216")
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    split_s = args.split or max(10.0, args.minutes * 60.0 / 3.0)
    run_s = args.minutes * 60.0
    try:
        # inject() waits for each fault's recovery before the schedule goes on, so the
        # spacing spreads the faults over the run; 10 s leaves room for the slowest (the
        # 10 s busy process) and makes one of each fit in a minute
        schedule = fault_schedule(run_s, spacing_s=min(30.0, max(10.0, run_s / 12)))
    except ValueError as exc:
        print(f"soak: --minutes {args.minutes:g}: {exc}", file=sys.stderr)
        return 2
    if args.keep is not None and args.keep.exists():
        print(f"soak: --keep {args.keep} already exists; give a new folder (the soak writes its "
              "bag and logs there and would mix them with another run's).", file=sys.stderr)
        return 2
    with contextlib.ExitStack() as stack:
        if args.keep is not None:
            args.keep.mkdir(parents=True, exist_ok=False)
            folder = args.keep
        else:
            folder = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="soak_")))
        soak = Soak(folder, args.minutes, split_s, schedule, args.bring_up_timeout)
        code = 1
        try:
            report = soak.run()
            # the figures first: nothing after the run may cost them
            print_report(report)
            if args.json is not None:
                args.json.write_text(json.dumps(report, indent=2, default=str))
            write_results("soak", report_figures(report), directory=args.results,
                          argv=sys.argv if argv is None else [sys.argv[0], *argv],
                          notes=f"Bench and gripper configurations for {args.minutes:g} min at "
                                f"{ADC_RATE_HZ:g} Hz under scheduled faults.")
            code = 0 if all(g["passed"] for g in report["goals"]) else 1
        except RuntimeError as exc:  # a node did not come up or report: say which, where
            say(f"soak: {exc}")
        finally:
            if not soak.close():
                say(f"soak: this process's ROS teardown did not end within {TEARDOWN_S:g} s "
                    "(a DDS deadlock); exiting without it, the figures above are complete.")
                sys.stdout.flush()
                sys.stderr.flush()
                os._exit(code)
    return code


if __name__ == "__main__":
    sys.exit(main())
