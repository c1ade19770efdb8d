"""The gripper stack on a busy robot: idle and grasping CPU per node, the age of the live
force, what the recording loses and how grasps fare beside two busy loops, side by side
with another commit.

Each version's stack (mock hardware, model, driver at 1 kHz, gripper) runs two ways, one
after the other:

* separate processes: ``ros2 launch tactile_sensor gripper.launch.py protocol:=idle``
  where ``ros2`` is on PATH; without it (the PyPI-wheels setup) the same node modules with
  the same parameter files, remappings and ports, one process each (stack_processes.py);
  the table says which ran;
* one process: ``tactile-sensor bringup gripper --protocol idle`` (and any process it
  starts itself).

Once the stack serves grasps, through its topics, actions and /proc only:

1. idle CPU over ``--seconds`` per process (utime + stime, in cores) and per thread (the
   per-thread idle profile, printed after the table), with no subscriber of this process;
2. the age of ``/driver/wrench`` here (receipt by this process's callback - header stamp;
   p50, p99, max) on the quiet machine;
3. CPU while grasping: a few 1.5 N grasps, each opening first;
4. the project's recorder (its own process) records ``/driver/reading``; two busy loops
   (``python3 -c 'while True: pass'``) start; the age is taken for a window, then 20
   grasps at 1.5 N run beside the loops (tactile_stale aborts counted; the hold judged
   within 5 % on the mock's ground truth 0.5 s after the first touch, as grasp_hold.py);
5. the loops stop: the time until the age's p99 over 0.25 s windows stays under 10 ms;
   the recorder stops and the bag's readings are counted against the ADC's sequence
   (stamp steps in ADC periods, stack_figures.py).

    python benchmarks/bench_stack.py [--compare 549bc19|REV|none] [--quick] [--seconds 10]

``--quick``: 3 s windows, one grasp while quiet and 5 beside the loops (a smoke test).
Figures: build/benchmarks/results/bench_stack.json (the per-thread profile as its series).
On a shared machine only figures measured in one run compare.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import yaml
from bench_recording_loss import read_stamps
from grasp_hold import Grasp, summarise
from node_processes import isolate_ros
from results import ROOT, Figure, write_results
from side_by_side import MOCK, CompareError, Variant, load_average, variants
from stack_figures import (
    AgeSummary,
    Goal,
    Loss,
    Row,
    age_summary,
    cores,
    hold_goal,
    missing_samples,
    recovery_s,
    render_table,
)
from stack_processes import (
    BRING_UP_S,
    Child,
    Stack,
    StackError,
    launch_available,
    snapshot,
    start,
    stop,
    wait_until,
)

TARGET_N = 1.5
BUSY_LOOPS = 2
BUSY = [sys.executable, "-c", "while True: pass"]
LAUNCH_SELF = "ros2 launch itself"
GOALS = {
    "gripper idle": Goal("<=", 0.05),
    "driver idle": Goal("<=", 0.10),
    "stack idle": Goal("<=", 0.35),
    "busy p99": Goal("<=", 20.0),
    "busy max": Goal("<=", 100.0),
    "recovery": Goal("<=", 1.0),
    "missing": Goal("<=", 0),
    "stale": Goal("<=", 0),
}


@dataclass
class Plan:
    idle_s: float
    age_s: float
    quiet_grasps: int
    busy_grasps: int
    recovery_span_s: float
    settle_s: float

    @classmethod
    def of(cls, args: argparse.Namespace) -> Plan:
        if args.quick:
            return cls(args.seconds or 3.0, args.seconds or 3.0, 1, 5, 2.0, 1.0)
        return cls(args.seconds or 10.0, args.seconds or 10.0, 3, 20, 5.0, 3.0)


@dataclass
class Run:
    """What one version's stack measured one way (empty where it failed: ``error``)."""

    error: str = ""
    idle: dict[str, float] = field(default_factory=dict)  # process -> cores
    threads: dict[tuple[str, str], float] = field(default_factory=dict)
    grasping: dict[str, float] = field(default_factory=dict)
    quiet: AgeSummary | None = None
    busy: AgeSummary | None = None
    busy_dds: AgeSummary | None = None
    recovery: float | None = None
    recovery_span_s: float = 0.0
    loss: Loss | None = None
    reading_type: str = ""
    driver_lost: int | None = None
    grasps: list[Grasp] = field(default_factory=list)
    load: tuple[float, float] = (0.0, 0.0)


def stack_total(per_process: dict[str, float]) -> float | None:
    values = [v for k, v in per_process.items() if k != LAUNCH_SELF]
    return sum(values) if values else None


def adc_period_ns(variant: Variant) -> float:
    """The mock ADC's sample period in this version's gripper configuration [ns]."""
    text = (variant.source / "config" / "gripper.yaml").read_text()
    rate = yaml.safe_load(text)["/**/gripper_world"]["ros__parameters"]["adc_rate"]
    return 1e9 / float(rate)


def recording_loss(bag: Path, period_ns: float) -> tuple[Loss | None, str]:
    from rosbags.highlevel import AnyReader, AnyReaderError

    if not bag.exists():
        return None, "no bag written"
    try:
        with AnyReader([bag]) as reader:
            types = {c.topic: c.msgtype for c in reader.connections}
    except (AnyReaderError, FileNotFoundError) as exc:  # a folder without metadata
        return None, f"no readable bag ({exc})"
    stamps = read_stamps(bag).get("/driver/reading")
    if stamps is None:
        return None, types.get("/driver/reading", "not recorded")
    return missing_samples(stamps, period_ns), types["/driver/reading"]


def measure(way: str, variant: Variant, plan: Plan) -> Run:
    """Bring the stack up, measure every phase, take it down (busy loops always ended)."""
    from stack_probe import Ages, Probe

    run = Run(load=(load_average(), 0.0))
    folder = Path(tempfile.mkdtemp(prefix=f"bench_stack_{way}_"))
    stack = Stack(way, variant, folder)
    probe = Probe()
    ages: Ages | None = None
    extra: list[Child] = []
    loops: list[subprocess.Popen] = []  # type: ignore[type-arg]
    try:
        stack.start()

        def up() -> bool:
            stack.check_alive()
            return probe.ready()
        if not wait_until(up, BRING_UP_S):
            raise StackError(f"the stack was not ready within {BRING_UP_S:g} s (driver "
                             f"streaming, servo OK, actions served); logs in {folder}")
        time.sleep(plan.settle_s)
        pids = stack.processes()
        s0 = snapshot(pids)
        time.sleep(plan.idle_s)
        s1 = snapshot(pids)
        run.idle = cores(s0.processes, s1.processes, s1.at - s0.at)
        run.threads = cores(s0.threads, s1.threads, s1.at - s0.at)
        say(f"    idle: {fmt_cpu(run.idle)}")

        ages = Ages()
        time.sleep(1.0)
        t0 = time.time()
        time.sleep(plan.age_s)
        run.quiet = age_summary(ages.between(t0, time.time())[1])
        say(f"    age quiet: p99 {run.quiet.p99_ms:.1f} ms ({run.quiet.count} messages)")

        probe.watch_truth()
        g0 = snapshot(pids)
        for _ in range(plan.quiet_grasps):
            probe.grasp_once(TARGET_N)
        g1 = snapshot(pids)
        run.grasping = cores(g0.processes, g1.processes, g1.at - g0.at)
        say(f"    grasping: {fmt_cpu(run.grasping)}")
        probe.open()

        bag = folder / "bag"
        listeners = probe.driver_value("reading_subscribers") or 0
        recorder = start("recorder", [
            sys.executable, "-m", "tactile_sensor.nodes.recorder", "--ros-args",
            "-r", "__node:=bench_stack_recorder", "-p", f"path:={bag}",
            "-p", 'topics:=["/driver/reading"]'], folder, MOCK.env())
        extra.append(recorder)
        if not wait_until(lambda: "Recording /driver/reading" in recorder.log.read_text(
                errors="replace") and (probe.driver_value("reading_subscribers") or 0)
                > listeners, 60.0):
            raise StackError(f"the recorder did not subscribe to /driver/reading within "
                             f"60 s; {recorder.log} ends: {recorder.tail()}")
        lost0 = driver_lost(probe)
        loops = [subprocess.Popen(BUSY) for _ in range(BUSY_LOOPS)]
        busy_from = time.time()
        time.sleep(plan.age_s)
        for k in range(plan.busy_grasps):
            stack.check_alive()
            run.grasps.append(probe.grasp_once(TARGET_N))
            g = run.grasps[-1]
            say(f"    grasp {k + 1}/{plan.busy_grasps} beside the loops: true force "
                f"{g.held_n:.3f} N 0.5 s after the touch, peak {g.peak_n:.2f} N; {g.message}")
        probe.open()
        busy_to = time.time()
        for loop in loops:
            loop.kill()
            loop.wait()
        loops = []
        time.sleep(plan.recovery_span_s + 0.5)
        times, age, dds = ages.between(busy_from, busy_to)
        run.busy, run.busy_dds = age_summary(age), age_summary(dds)
        times, age, _ = ages.between(busy_to, busy_to + plan.recovery_span_s)
        run.recovery = recovery_s(times, age, busy_to, plan.recovery_span_s)
        run.recovery_span_s = plan.recovery_span_s
        lost1 = driver_lost(probe)
        run.driver_lost = None if lost0 is None or lost1 is None else lost1 - lost0
        stop([recorder])
        extra.remove(recorder)
        run.loss, run.reading_type = recording_loss(bag, adc_period_ns(variant))
        say(f"    beside the loops: age p99 {run.busy.p99_ms:.1f} ms, max "
            f"{run.busy.max_ms:.1f} ms; recovery {run.recovery}; recording "
            f"{run.loss}")
    except StackError as exc:
        run.error = str(exc)
        say(f"    FAILED: {exc}")
    finally:
        for loop in loops:
            loop.kill()
            loop.wait()
        stop(extra)
        if ages is not None:
            ages.close()
        probe.close()
        stack.stop()
        run.load = (run.load[0], load_average())
    return run


def driver_lost(probe: object) -> int | None:
    """Frames the driver says it lost so far (missing by sequence + a full backlog)."""
    dropped = probe.driver_value("frames_dropped")  # type: ignore[attr-defined]
    overflowed = probe.driver_value("frames_overflowed")  # type: ignore[attr-defined]
    return None if dropped is None or overflowed is None else dropped + overflowed


def say(text: str) -> None:
    print(text, flush=True)


def fmt_cpu(per_process: dict[str, float]) -> str:
    return ", ".join(f"{k} {v:.3f}" for k, v in per_process.items())


WAY_TITLES = {
    "launch": "separate processes: ros2 launch tactile_sensor gripper.launch.py",
    "processes": "separate processes as gripper.launch.py starts them (no `ros2 launch` "
                 "here: the same node modules, parameter files, remappings and ports, "
                 "one process each, autostart)",
    "bringup": "one process: tactile-sensor bringup gripper --protocol idle",
}
WAY_SHORT = {"launch": "ros2 launch", "processes": "separate processes",
             "bringup": "in-process bringup"}


def rows_of(way: str, runs: list[Run], plan: Plan) -> list[Row]:
    """The table's rows for one way, one value per version."""
    def each(get: object) -> tuple[object, ...]:
        return tuple(None if r.error else get(r) for r in runs)  # type: ignore[operator]

    names = list(dict.fromkeys(n for r in runs for n in (*r.idle, *r.grasping)))
    apart = way != "bringup"
    rows: list[Row] = []
    for phase, key in (("idle", "idle"), ("grasping", "grasping")):
        for name in names:
            goal = (GOALS.get(f"{name} idle") if phase == "idle" and apart else None)
            rows.append(Row(f"CPU {phase}, {name}", "cores",
                            each(lambda r, n=name, k=key: getattr(r, k).get(n)), goal))
        rows.append(Row(f"CPU {phase}, whole stack incl. mock", "cores",
                        each(lambda r, k=key: stack_total(getattr(r, k))),
                        GOALS["stack idle"] if phase == "idle" else None))
    for label, attr, goals in (("quiet", "quiet", (None, None)),
                               (f"beside {BUSY_LOOPS} busy loops", "busy",
                                (GOALS["busy p99"], GOALS["busy max"]))):
        rows += [Row(f"/driver/wrench age {label}, p50", "ms",
                     each(lambda r, a=attr: getattr(r, a).p50_ms), digits=1),
                 Row(f"/driver/wrench age {label}, p99", "ms",
                     each(lambda r, a=attr: getattr(r, a).p99_ms), goals[0], digits=1),
                 Row(f"/driver/wrench age {label}, max", "ms",
                     each(lambda r, a=attr: getattr(r, a).max_ms), goals[1], digits=1)]
    rows += [
        Row("/driver/wrench age beside the loops, middleware receipt, p99", "ms",
            each(lambda r: r.busy_dds.p99_ms), digits=1),
        Row("after the loads stop: until p99 over 0.25 s stays < 10 ms", "s",
            each(lambda r: r.recovery if r.recovery is not None
                 else f"> {r.recovery_span_s:g}"), GOALS["recovery"], digits=2),
        Row("/driver/reading recorded beside the loops", "samples",
            each(lambda r: r.loss.recorded if r.loss else r.reading_type)),
        Row("  missing against the ADC's sequence", "samples",
            each(lambda r: r.loss.missing if r.loss else None), GOALS["missing"]),
        Row("  frames the driver reports lost", "frames", each(lambda r: r.driver_lost)),
        Row(f"grasps at {TARGET_N:g} N beside the loops: tactile_stale", f"of "
            f"{plan.busy_grasps}", each(lambda r: sum("tactile_stale" in g.message
                                                      for g in r.grasps)), GOALS["stale"]),
        Row("  true force within 5 % 0.5 s after touch", f"of {plan.busy_grasps}",
            each(lambda r: summarise(TARGET_N, r.grasps).within if r.grasps else 0),
            Goal(">=", hold_goal(plan.busy_grasps))),
        Row("  settled and within 5 %", f"of {plan.busy_grasps}",
            each(lambda r: summarise(TARGET_N, r.grasps).settled if r.grasps else 0)),
        Row("  true force within 5 % when the grasp answered", f"of {plan.busy_grasps}",
            each(lambda r: summarise(TARGET_N, r.grasps).within_answered if r.grasps
                 else 0)),
        Row("load average (1 min) at start, end", "", tuple(
            f"{r.load[0]:.1f}, {r.load[1]:.1f}" for r in runs)),
    ]
    return rows


def thread_profile(way: str, labels: list[str], runs: list[Run]) -> tuple[str, dict]:  # type: ignore[type-arg]
    """The per-thread idle profile as text and as series columns."""
    lines = [f"per-thread idle CPU [cores], {WAY_SHORT[way]}:"]
    series: dict[str, list[object]] = {"way": [], "version": [], "process": [], "thread": [],
                                       "idle_cores": []}
    for label, run in zip(labels, runs, strict=True):
        if run.error:
            lines.append(f"  {label}: failed ({run.error})")
            continue
        for process in run.idle:
            threads = sorted(((t, c) for (p, t), c in run.threads.items() if p == process),
                             key=lambda tc: -tc[1])
            shown = [f"{t} {c:.3f}" for t, c in threads if c >= 0.0005][:12]
            rest = sum(c for t, c in threads[len(shown):])
            lines.append(f"  {label}, {process} ({run.idle[process]:.3f}, {len(threads)} "
                         f"threads): {', '.join(shown) or 'none above 0.0005'}"
                         + (f", the other {len(threads) - len(shown)} {rest:.3f}"
                            if len(threads) > len(shown) else ""))
            for t, c in threads:
                for key, value in (("way", WAY_SHORT[way]), ("version", label),
                                   ("process", process), ("thread", t),
                                   ("idle_cores", round(c, 4))):
                    series[key].append(value)
    return "\n".join(lines), series


def figures_of(sections: list[tuple[str, list[Row]]], labels: list[str]) -> list[Figure]:
    out: list[Figure] = []
    for way, rows in sections:
        for row in rows:
            for label, value in zip(labels, row.values, strict=True):
                numeric = isinstance(value, int | float) and not isinstance(value, bool)
                met = row.goal.met(float(value)) if row.goal and numeric else None
                if row.goal and isinstance(value, str):
                    met = False  # e.g. "> 5": not recovered within the span
                out.append(Figure(f"{WAY_SHORT[way]}: {row.name.strip()}, {label}",
                                  round(value, 4) if isinstance(value, float) else value,
                                  row.unit, row.goal.text if row.goal else "", met))
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--compare", default="549bc19", metavar="REV",
                        help="the commit to run beside this checkout (default 549bc19); "
                             "'none': this checkout alone")
    parser.add_argument("--quick", action="store_true",
                        help="3 s windows, 1 + 5 grasps: a smoke test")
    parser.add_argument("--seconds", type=float, default=None,
                        help="idle CPU and age windows [s] (default 10; 3 with --quick)")
    args = parser.parse_args()
    if args.seconds is not None and not args.seconds > 0:
        parser.error(f"--seconds must be > 0, got {args.seconds:g}")
    plan = Plan.of(args)
    isolate_ros(229)
    compare = None if args.compare.lower() == "none" else args.compare
    first = "launch" if launch_available() else "processes"
    if first == "processes":
        say("bench_stack: `ros2 launch` is not on PATH (PyPI-wheels setup); the separate-"
            "process part starts the launch file's nodes itself, one process each.")
    from tactile_sensor.nodes.ros_session import ros_session

    results: dict[str, list[Run]] = {}
    try:
        with variants(compare) as versions, ros_session():
            labels = [v.label for v in versions]
            for k, way in enumerate((first, "bringup")):
                order = versions if k % 2 == 0 else versions[::-1]
                by_label: dict[str, Run] = {}
                for variant in order:
                    say(f"== {WAY_SHORT[way]}, {variant.label}")
                    by_label[variant.label] = measure(way, variant, plan)
                results[way] = [by_label[label] for label in labels]
    except (CompareError, StackError) as exc:
        print(f"bench_stack: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("bench_stack: interrupted; the processes it started are stopped.",
              file=sys.stderr)
        return 130
    sections = [(way, rows_of(way, runs, plan)) for way, runs in results.items()]
    print()
    print(render_table(labels, [(WAY_TITLES[w], rows) for w, rows in sections]))
    series: dict[str, list[object]] = {}
    for way, runs in results.items():
        text, columns = thread_profile(way, labels, runs)
        print("\n" + text)
        for key, values in columns.items():
            series.setdefault(key, []).extend(values)
    failed = [f"{WAY_SHORT[w]}, {label}: {r.error}" for w, runs in results.items()
              for label, r in zip(labels, runs, strict=True) if r.error]
    for line in failed:
        print(f"not measured: {line}")
    print(f"\n{os.cpu_count()} cores; the busy loops: {BUSY_LOOPS} x "
          "`python3 -c 'while True: pass'`; ages as this process's callback receives them")
    path = write_results("bench_stack", figures_of(sections, labels), series=series, notes=(
        f"{WAY_SHORT[first]} and in-process bringup, each version in turn; idle window "
        f"{plan.idle_s:g} s, ages {plan.age_s:g} s quiet and over the busy phase, "
        f"{plan.quiet_grasps} grasp(s) quiet, {plan.busy_grasps} beside {BUSY_LOOPS} busy "
        "loops; CPU in cores (utime + stime); the series holds the per-thread idle "
        "profile"))
    print(f"figures written to {path.relative_to(ROOT)}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
