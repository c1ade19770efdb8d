"""One soak: both configurations brought up as separate processes, the scheduled faults
injected and each one's detection and recovery timed, then the losses, the recording and
the processes' growth summarised."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from soak_accounting import (
    SPLIT_KIND,
    LossSnapshot,
    ScheduledFault,
    account_losses,
    evaluate_goals,
    growth_per_hour,
    parse_device_stats,
)
from soak_monitor import (
    BENCH_NS,
    DRIVER_DIAG,
    GRIPPER_DIAG,
    GRIPPER_DRIVER_DIAG,
    GRIPPER_NS,
    GraspLoop,
    Monitor,
    Report,
)
from soak_processes import SELF, Proc, Sampler, node_argv, say, wait_until, write_fifo

from tactile_sensor.configurations import BENCH, GRIPPER

SOURCE = Path(__file__).resolve().parents[1] / "tactile_sensor"
ADC_RATE_HZ = 1000.0
FRAME_BYTES = 11  # one-channel frame (docs/serial-frame.md)
# What a cable pull can swallow: the device's host buffer and the pseudo-terminal's.
LINK_CAPACITY_FRAMES = (65536 + 20000) // FRAME_BYTES


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


def fault_line(f: FaultResult) -> str:
    det = "-" if f.detected_after_s is None else f"{f.detected_after_s:.2f} s"
    rec = "NOT RECOVERED" if f.recovered_after_s is None else f"{f.recovered_after_s:.2f} s"
    return f"detected after {det}, recovered after {rec} ({f.note})"


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
        # the gripper listens to the live force only (its readings go out while a
        # self-check or a recorder listens): its driver streams once frames arrive
        self._expect(lambda: any(int(r.values.get("frames", 0)) > 0
                                 for r in self.monitor.history(GRIPPER_DRIVER_DIAG)),
                     "the gripper's driver received no ADC frame", "gripper_driver")

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
            say(f"  {result.at_s:6.1f} s {fault.kind}: " + fault_line(result))
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
