"""Driver node over ROS at 1 kHz: end-to-end latency and CPU use, optionally side by side
with the driver of another commit.

Starts the mock ADC (1 kHz, its own process) and the driver node (its own process), and
subscribes here. Latency = reception time - the reading's stamp, which is the sample's
device time mapped to the host clock (so it includes serial transfer, framing, the signal
chain, publishing and DDS delivery, less the smallest transfer delay, which the clock
mapping absorbs). Two reception times are reported: the middleware's (DDS hands the
message to this subscriber; MessageInfo.received_timestamp) and this Python callback's
(adds rclpy's executor, which for any Python subscriber at 1 kHz is the slowest link).
CPU = the driver process's user+system time over the window, in % of one core.

The driver runs with a static calibration file, then with the same curve and two rate
terms (calibration across speeds: the Prony estimator on every sample), then (``all``)
with those terms and play (two branches and the direction tracker, file version 3).
``--model modulation`` runs the static file on a stock module and on a modulated one
(protocol 3: an emitter-on and an emitter-off sample per period, the same ADC sample
rate, so half as many readings; docs/ambient.md) and compares the driver's CPU.

``--floor`` measures instead what one rclpy publish of ~/reading costs at this rate, in
this process with a subscriber in another (the limit of rclpy and the middleware, which no
driver code can go below): a message object built per sample as b36bc06 did, a message
object reused, and the bytes the driver publishes now (nodes/reading_cdr.py).

``--mock-floor`` reads the mock ADC with a bare poll/read loop in this process instead (no
driver, no ROS) and reports how late its frames arrive against the earliest one, the
same measure as the latency above: the mock's own pacing jitter, which every driver's
latency includes. It also reports the loop's own CPU per frame (wake-up, read, parse): with
``--floor``'s publish cost, the least any driver publishing both topics can use.

``--compare REV`` runs the driver of commit REV (its sources unpacked by ``git archive``,
this checkout's interfaces and mock ADC) and this checkout's, one after the other, for
``--rounds`` rounds whose order alternates, and prints a before/after table: on a shared
machine only figures measured in one run compare. The figures go to
``build/benchmarks/results/bench_driver.json``.

    python benchmarks/bench_driver.py [--seconds 20] [--model static|rate|play|both|all]
                                      [--compare REV] [--rounds 2]
    python benchmarks/bench_driver.py --floor [--seconds 20]
    python benchmarks/bench_driver.py --mock-floor [--seconds 20]
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import struct
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import rclpy
from node_processes import interrupt, isolate_ros
from rclpy.executors import SingleThreadedExecutor
from results import Figure, write_results
from side_by_side import (
    MOCK,
    WARM_UP_S,
    CompareError,
    Variant,
    cpu_seconds,
    load_average,
    variants,
)

from tactile_sensor.nodes.background_spin import BackgroundSpin
from tactile_sensor.nodes.reading_cdr import ReadingCdr
from tactile_sensor.nodes.ros_session import ros_session
from tactile_sensor_interfaces.msg import TactileReading

ROOT = Path(__file__).resolve().parents[1]
CPU_RATIO_GOAL = 0.37  # at most 0.37 x b36bc06's CPU, static calibration
P99_GOAL_MS = 1.0  # sample -> subscriber (DDS), static calibration
RATE_OVERHEAD_GOAL = 10.0  # rate-aware (with play) at most +10 % CPU over static
MODULATION_CPU_GOAL = 1.2  # a modulated module at most 1.2 x a stock one's driver CPU


@dataclass
class Run:
    """One driver run: CPU [s] over ``span_s``, latencies [s] (middleware, callback)."""

    cpu_s: float
    span_s: float
    latencies: np.ndarray
    load: tuple[float, float]  # 1-minute load average at start and end


@dataclass
class Totals:
    """All rounds of one (variant, model)."""

    runs: list[Run]

    @property
    def cpu_percent(self) -> float:
        return 100 * sum(r.cpu_s for r in self.runs) / sum(r.span_s for r in self.runs)

    @property
    def round_percents(self) -> list[float]:
        return [100 * r.cpu_s / r.span_s for r in self.runs]

    def latency_ms(self, column: int) -> tuple[float, float, float]:
        """(median, p99, max) [ms] over every reading of every round."""
        lat = np.concatenate([r.latencies[:, column] for r in self.runs]) * 1e3
        return float(np.median(lat)), float(np.percentile(lat, 99)), float(lat.max())

    @property
    def received_per_s(self) -> float:
        return sum(len(r.latencies) for r in self.runs) / sum(r.span_s for r in self.runs)

    @property
    def cpu_per_reading_us(self) -> float:
        """CPU per reading received: fair where a starved driver fell behind the device."""
        return 1e6 * sum(r.cpu_s for r in self.runs) / max(
            1, sum(len(r.latencies) for r in self.runs))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0,
                        help="measuring window per run [s]")
    parser.add_argument("--rate", type=float, default=1000.0)
    parser.add_argument("--model", choices=("static", "rate", "play", "both", "all",
                                            "modulated", "modulation"),
                        default="both", help="both: static and rate; all: and play; "
                        "modulation: static on a stock and on a modulated module")
    parser.add_argument("--compare", metavar="REV",
                        help="also run the driver of commit REV, alternating with this one")
    parser.add_argument("--rounds", type=int, default=None,
                        help="runs of each driver (default 2 with --compare, else 1)")
    parser.add_argument("--floor", action="store_true",
                        help="measure one rclpy publish of ~/reading in isolation instead")
    parser.add_argument("--mock-floor", action="store_true",
                        help="measure the mock ADC's own arrival jitter instead")
    args = parser.parse_args()
    if args.floor:
        return publish_floor(args)
    if args.mock_floor:
        return mock_floor(args)
    rounds = args.rounds if args.rounds is not None else (2 if args.compare else 1)
    if rounds < 1:
        parser.error(f"--rounds must be at least 1, got {rounds}")
    isolate_ros(150 + os.getpid() % 50)
    models = {"both": ("static", "rate"), "all": ("static", "rate", "play"),
              "modulation": ("static", "modulated")}.get(args.model, (args.model,))
    try:
        with variants(args.compare) as drivers:
            totals = run_all(args, drivers, models, rounds)
    except CompareError as exc:
        print(f"bench_driver: {exc}", file=sys.stderr)
        return 2
    if totals is None:
        return 1
    figures = report(args, drivers, models, rounds, totals)
    path = write_results("bench_driver", figures, notes=(
        f"{rounds} round(s) of {args.seconds:g} s per driver and calibration, order "
        "alternating; latency from the middleware's reception time; CPU in % of one core"))
    print(f"figures written to {path.relative_to(ROOT)}")
    return 0


def run_all(args: argparse.Namespace, drivers: list[Variant], models: tuple[str, ...],
            rounds: int) -> dict[tuple[str, str], Totals] | None:
    """Every (calibration, driver) pair once a round, the order reversed every other round:
    run one model after the other and the later one measured 39 % more CPU (rate-aware
    against static, the same driver), alone 4 %."""
    totals: dict[tuple[str, str], Totals] = {}
    pairs = [(model, driver) for model in models for driver in drivers]
    for r in range(rounds):
        for model, driver in (pairs if r % 2 == 0 else pairs[::-1]):
            run = measure(args, model, driver)
            if run is None:
                return None
            totals.setdefault((driver.label, model), Totals([])).runs.append(run)
            print(f"  round {r + 1}, {driver.label}, {model}: CPU "
                  f"{100 * run.cpu_s / run.span_s:.1f} %, p99 "
                  f"{np.percentile(run.latencies[:, 0], 99) * 1e3:.2f} ms "
                  f"(load average {run.load[0]:.1f} -> {run.load[1]:.1f})", flush=True)
    return totals


def report(args: argparse.Namespace, drivers: list[Variant], models: tuple[str, ...],
           rounds: int, totals: dict[tuple[str, str], Totals]) -> list[Figure]:
    """Print the before/after table and return its figures."""
    loads = [x for t in totals.values() for r in t.runs for x in r.load]
    print(f"\ndriver at {args.rate:g} Hz, {rounds} round(s) x {args.seconds:g} s per driver "
          f"and calibration (load average {min(loads):.1f} .. {max(loads):.1f} on "
          f"{os.cpu_count()} cores)")
    print(f"  {'driver':22s} {'calibration':11s} {'CPU % of one core':28s} "
          f"{'DDS latency median / p99 / max [ms]':37s} callback p99 [ms]  "
          "CPU per reading [us]")
    figures: list[Figure] = []
    for model in models:
        for driver in drivers:
            t = totals[(driver.label, model)]
            med, p99, worst = t.latency_ms(0)
            cb_p99 = t.latency_ms(1)[1]
            each = ", ".join(f"{p:.1f}" for p in t.round_percents)
            print(f"  {driver.label:22s} {model:11s} {t.cpu_percent:5.1f} ({each})"
                  f"{'':{max(0, 21 - len(each))}s} {med:6.2f} / {p99:6.2f} / {worst:6.2f}"
                  f"{'':16s} {cb_p99:6.2f}{'':13s} {t.cpu_per_reading_us:6.1f}")
            name = f"{driver.label}, {model}"
            p99_goal = f"<= {P99_GOAL_MS:g} ms" if (model == "static"
                                                   and driver is drivers[-1]) else ""
            figures += [
                Figure(f"driver CPU, {name}", round(t.cpu_percent, 2), "% of one core"),
                Figure(f"latency median, {name}", round(med, 3), "ms"),
                Figure(f"latency p99, {name}", round(p99, 3), "ms", p99_goal),
                Figure(f"latency max, {name}", round(worst, 3), "ms"),
                Figure(f"callback latency p99, {name}", round(cb_p99, 3), "ms"),
                Figure(f"readings received, {name}", round(t.received_per_s, 1), "1/s"),
                Figure(f"driver CPU per reading received, {name}",
                       round(t.cpu_per_reading_us, 1), "us"),
            ]
    if len(drivers) == 2:
        before, after = drivers
        for model in models:
            a, b = totals[(after.label, model)], totals[(before.label, model)]
            ratio = a.cpu_percent / b.cpu_percent
            per_reading = a.cpu_per_reading_us / b.cpu_per_reading_us
            goal = f"<= {CPU_RATIO_GOAL:g}" if model == "static" else ""
            print(f"  CPU {after.label} / {before.label}, {model}: {ratio:.2f}"
                  + (f" (goal {goal})" if goal else "")
                  + f"; per reading received: {per_reading:.2f}")
            figures += [Figure(f"CPU ratio {after.label} / {before.label}, {model}",
                               round(ratio, 3), "", goal),
                        Figure(f"CPU per reading ratio {after.label} / {before.label}, "
                               f"{model}", round(per_reading, 3), "", goal)]
    for driver in drivers:
        static = totals.get((driver.label, "static"))
        for model, name in (("rate", "rate-aware"), ("play", "rate-aware with play")):
            other = totals.get((driver.label, model))
            if static is None or other is None:
                continue
            extra = 100 * (other.cpu_percent / static.cpu_percent - 1)
            print(f"  {driver.label}: {name} against static: {other.cpu_percent:.1f} % vs "
                  f"{static.cpu_percent:.1f} % of one core ({extra:+.1f} %; goal: at most "
                  f"+{RATE_OVERHEAD_GOAL:g} %)")
            figures.append(Figure(f"CPU over static, {driver.label}, {name}", round(extra, 1),
                                  "%", f"<= +{RATE_OVERHEAD_GOAL:g} %"))
    for driver in drivers:
        stock = totals.get((driver.label, "static"))
        modulated = totals.get((driver.label, "modulated"))
        if stock is None or modulated is None:
            continue
        ratio = modulated.cpu_percent / stock.cpu_percent
        print(f"  {driver.label}: modulated module against stock: {modulated.cpu_percent:.1f} "
              f"% vs {stock.cpu_percent:.1f} % of one core ({ratio:.2f} x; goal: at most "
              f"{MODULATION_CPU_GOAL:g} x); per reading received "
              f"{modulated.cpu_per_reading_us / stock.cpu_per_reading_us:.2f} x")
        figures.append(Figure(f"CPU modulated / stock module, {driver.label}",
                              round(ratio, 3), "", f"<= {MODULATION_CPU_GOAL:g}"))
    figures.append(Figure("load average during the run", f"{min(loads):.1f} .. "
                          f"{max(loads):.1f}", f"on {os.cpu_count()} cores"))
    return figures


def write_inputs(tmp: Path, model: str) -> None:
    """The mock's skin table and the driver's calibration file for ``model``."""
    d = np.linspace(0, 0.003, 31)
    (tmp / "skin.json").write_text(json.dumps({"indentation_m": d.tolist(),
                                               "force_n": (7 * d / 0.003).tolist(),
                                               "voltage_v": (3.0 - 0.5 * d / 0.003).tolist()}))
    calibration = {"format": "tactile_sensor/calibration", "version": 1, "source": "bench",
                   "output_v": (0.5 * d / 0.003).tolist(), "force_n": (7 * d / 0.003).tolist()}
    if model in ("rate", "play"):  # the simulation's own terms (config/physics.yaml)
        calibration.update(version=2, rate_terms=[{"g": 0.05, "tau_s": 0.1},
                                                  {"g": 0.04, "tau_s": 1.5}])
    if model == "play":  # a half-gap like the mock's play makes, a band like the fit's
        calibration.update(version=3, play={"half_gap_n": (0.1 * d / 0.003).tolist(),
                                            "band_v": 0.05, "smoothing_hz": 10.0})
    (tmp / "cal.json").write_text(json.dumps(calibration))


def measure(args: argparse.Namespace, model: str, variant: Variant) -> Run | None:
    """One run of ``variant``'s driver with a static or a rate-aware file."""
    tmp = Path(tempfile.mkdtemp(prefix="bench_driver_"))
    write_inputs(tmp, model)
    py = sys.executable
    # a modulated module sends an on and an off sample per period: the same ADC rate
    periods = args.rate / 2 if model == "modulated" else args.rate
    driver = subprocess.Popen(
        [py, "-m", "tactile_sensor.nodes.driver", "--ros-args", "-r", "__node:=driver",
         "-p", f"port:={tmp / 'adc'}", "-p", "calibration_source:=file",
         "-p", f"calibration_file:={tmp / 'cal.json'}", "-p", "autostart:=true",
         "-p", f"sample_rate:={periods}"], env=variant.env(), stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL)
    mock = subprocess.Popen(
        [py, "-m", "tactile_sensor.cli", "mock", "adc", "--link", str(tmp / "adc"),
         "--rate", str(periods), "--skin-table", str(tmp / "skin.json"), "--loop",
         "--profile", "ramp:depth=0.003,speed=0.003,cycles=1,rest=0.5",
         *(["--protocol", "3"] if model == "modulated" else [])],
        env=MOCK.env(), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    latencies: list[tuple[float, float]] = []  # (middleware, callback) [s]
    lock = threading.Lock()

    def record(cdr: bytes, info: dict) -> None:
        now = time.time_ns()
        sec, nanosec = struct.unpack_from("<iI", cdr, 4)  # CDR header, then header.stamp
        stamp = sec * 1_000_000_000 + nanosec
        with lock:
            latencies.append(((info["received_timestamp"] - stamp) * 1e-9,
                              (now - stamp) * 1e-9))

    def on_reading(cdr: bytes, info: dict) -> None:
        record(cdr, info)
        with subscription.handle:  # drain what else waits: one executor round per message
            for _ in range(256):   # would measure rclpy, not the driver
                item = subscription.handle.take_message(TactileReading, True)
                if item is None:
                    break
                record(*item)

    try:
        with ros_session():
            node = rclpy.create_node("bench_driver_listener")
            subscription = node.create_subscription(TactileReading, "/driver/reading",
                                                    on_reading, 1000, raw=True)
            executor = SingleThreadedExecutor()
            executor.add_node(node)
            spin = BackgroundSpin(executor)
            deadline = time.monotonic() + WARM_UP_S
            while len(latencies) < 2000 and time.monotonic() < deadline:
                time.sleep(0.1)
            if len(latencies) < 2000:
                print(f"{variant.label}'s driver produced no data within {WARM_UP_S:g} s",
                      file=sys.stderr)
                return None
            with lock:
                latencies.clear()
            load0 = load_average()
            cpu0, t0 = cpu_seconds(driver.pid), time.monotonic()
            time.sleep(args.seconds)
            cpu1, t1 = cpu_seconds(driver.pid), time.monotonic()
            with lock:
                both = np.array(latencies)
            spin.stop()
            node.destroy_node()
    finally:
        interrupt(mock, driver, timeout_s=5)
    return Run(cpu1 - cpu0, t1 - t0, both, (load0, load_average()))


SUBSCRIBER = """
import rclpy
from tactile_sensor.nodes.ros_session import ros_session
from tactile_sensor_interfaces.msg import TactileReading
with ros_session():
    node = rclpy.create_node("bench_publish_floor_listener")
    node.create_subscription(TactileReading, "/bench_publish_floor/reading", lambda m: None,
                             1000, raw=True)
    try:
        rclpy.spin(node)
    except Exception:
        pass
"""


def publish_floor(args: argparse.Namespace) -> int:
    """CPU of this thread per publish of ~/reading at ``args.rate``, less the pacing's."""
    from rclpy.time import Time

    n = max(100, int(args.seconds * args.rate / 4))
    cdr = ReadingCdr("tactile_sensor")
    reused = TactileReading(voltage=2.0, output=0.25, force=3.5, contact=True)
    reused.header.frame_id = "tactile_sensor"

    def built(k: int) -> TactileReading:  # as b36bc06's driver, per sample
        msg = TactileReading(voltage=2.0, output=0.25, force=3.5, contact=True)
        msg.header.stamp = Time(nanoseconds=time.time_ns()).to_msg()
        msg.header.frame_id = "tactile_sensor"
        return msg

    listener = subprocess.Popen([sys.executable, "-c", SUBSCRIBER], env=dict(os.environ),
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        with ros_session():
            node = rclpy.create_node("bench_publish_floor")
            pub = node.create_publisher(TactileReading, "/bench_publish_floor/reading", 10_000)
            deadline = time.monotonic() + WARM_UP_S
            while pub.get_subscription_count() < 1 and time.monotonic() < deadline:
                time.sleep(0.05)
            if pub.get_subscription_count() < 1:
                print("the listener did not connect within 60 s", file=sys.stderr)
                return 1
            cases = {
                "pacing only": lambda k: None,
                "message built per sample": lambda k: pub.publish(built(k)),
                "message reused": lambda k: pub.publish(reused),
                "bytes (driver now)": lambda k: pub.publish(
                    cdr.encode(time.time_ns(), 2.0, 0.25, 3.5, True)),
            }
            cost = {name: paced_cpu_us(fn, n, 1.0 / args.rate) for name, fn in cases.items()}
            node.destroy_node()
    finally:
        listener.terminate()
        try:
            listener.wait(10)
        except subprocess.TimeoutExpired:  # a middleware teardown that hangs
            listener.kill()
            listener.wait()
    base = cost.pop("pacing only")
    print(f"rclpy publish of ~/reading at {args.rate:g} Hz, one subscriber in another "
          f"process, {n} publishes each (load average {load_average():.1f}); CPU of the "
          f"publishing thread per publish, less the pacing's ({base:.1f} us):")
    figures = []
    for name, us in cost.items():
        print(f"  {name:26s} {us - base:6.1f} us")
        figures.append(Figure(f"publish ~/reading, {name}", round(us - base, 2), "us"))
    figures.append(Figure("load average during the run", round(load_average(), 1),
                          f"on {os.cpu_count()} cores"))
    path = write_results("bench_driver_publish_floor", figures, notes=(
        "thread CPU per publish at the driver's rate with one raw subscriber in another "
        "process, less the cost of the pacing loop alone"))
    print(f"figures written to {path.relative_to(ROOT)}")
    return 0


def mock_floor(args: argparse.Namespace) -> int:
    """Arrival delay of the mock's frames read by a bare loop [ms], as the driver's
    latency is computed: host time of the read less device time, less the smallest."""
    import select

    import serial

    from tactile_sensor.hardware.adc_frame import Frame, FrameParser

    tmp = Path(tempfile.mkdtemp(prefix="bench_mock_floor_"))
    write_inputs(tmp, "static")
    mock = subprocess.Popen(
        [sys.executable, "-m", "tactile_sensor.cli", "mock", "adc", "--link",
         str(tmp / "adc"), "--rate", str(args.rate), "--skin-table", str(tmp / "skin.json"),
         "--loop", "--profile", "ramp:depth=0.003,speed=0.003,cycles=1,rest=0.5"],
        env=MOCK.env(), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    arrivals: list[tuple[int, int]] = []  # (device time [us], host time [ns])
    try:
        deadline = time.monotonic() + WARM_UP_S
        while not (tmp / "adc").exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        port = serial.serial_for_url(str(tmp / "adc"), baudrate=1_000_000, timeout=0.05)
        poll = select.poll()
        poll.register(port.fd, select.POLLIN)
        parser = FrameParser()
        start = time.monotonic()
        warm_up_until = start + 2.0  # what waited in the port before it was opened
        cpu_from: float | None = None  # this process's CPU time when the window opened
        window_from = warm_up_until
        while time.monotonic() < warm_up_until + args.seconds:
            if poll.poll(50):
                data = os.read(port.fd, 1 << 16)
                now = time.time_ns()
                if time.monotonic() > warm_up_until:
                    if cpu_from is None:
                        cpu_from, window_from = time.process_time(), time.monotonic()
                    arrivals += [(f.t_us, now) for f in parser.feed(data) if type(f) is Frame]
                else:
                    parser.feed(data)
        cpu_s = time.process_time() - (cpu_from or 0.0)
        window_s = time.monotonic() - window_from
        port.close()
    finally:
        mock.send_signal(signal.SIGINT)
        mock.wait(10)
    device_us = np.unwrap(np.array([a[0] for a in arrivals], dtype=float), period=2.0**32)
    offset_ns = np.array([a[1] for a in arrivals], dtype=float) - device_us * 1e3
    late_ms = (offset_ns - offset_ns.min()) * 1e-6
    med, p99, worst = np.median(late_ms), np.percentile(late_ms, 99), late_ms.max()
    print(f"mock ADC at {args.rate:g} Hz read by a bare poll/read loop for {args.seconds:g} s "
          f"({len(arrivals)} frames, load average {load_average():.1f}): arrival after the "
          f"earliest frame's delay: median {med:.2f} ms, p99 {p99:.2f} ms, max {worst:.2f} ms")
    # the reading side's floor: one wake-up, read and parse per frame (the device sends each
    # frame as it samples it, so a latency bound of 1 ms leaves no room to batch them)
    read_us = cpu_s / max(len(arrivals), 1) * 1e6
    print(f"the loop's own CPU: {100 * cpu_s / window_s:.1f} % of one core, {read_us:.0f} us "
          "per frame (wake-up, read, parse)")
    figures = [Figure("mock arrival delay median", round(float(med), 3), "ms"),
               Figure("mock arrival delay p99", round(float(p99), 3), "ms"),
               Figure("mock arrival delay max", round(float(worst), 3), "ms"),
               Figure("bare read loop CPU", round(100 * cpu_s / window_s, 1),
                      "% of one core"),
               Figure("bare read loop CPU per frame", round(read_us, 1), "us"),
               Figure("load average during the run", round(load_average(), 1),
                      f"on {os.cpu_count()} cores")]
    path = write_results("bench_driver_mock_floor", figures, notes=(
        "the mock ADC's frames read without a driver: its pacing jitter, which every "
        "driver latency above includes"))
    print(f"figures written to {path.relative_to(ROOT)}")
    return 0


def paced_cpu_us(fn: Callable[[int], object], n: int, period_s: float) -> float:
    """This thread's CPU per call of ``fn`` [µs], called every ``period_s`` (cold, as in
    the driver: a tight loop keeps caches warm and measures a third of it)."""
    next_at = time.monotonic()
    cpu0 = time.thread_time()
    for k in range(n):
        next_at += period_s
        delay = next_at - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        fn(k)
    return (time.thread_time() - cpu0) / n * 1e6


if __name__ == "__main__":
    sys.exit(main())
