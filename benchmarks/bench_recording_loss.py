"""Where recorded readings get lost: one short bench protocol under extra CPU load.

Runs ``tactile-sensor bringup bench --record`` in this process (the same
``BringupRunner``), with ``--burners`` busy-loop processes competing for the CPU, and
counts each ADC frame along the chain:

    written   the mock ADC accepted it into the host's serial buffers
    parsed    the driver's reader decoded it (frames the sequence numbers say are missing
              are counted as dropped)
    published the driver published a reading for it
    recorded  the bag holds that reading

and the same for the gauge (published by the mock rig, recorded in the bag). Loss is
counted inside the recorded window (first to last recorded stamp, so start-up and
shut-down edges, which no press falls into, are not loss): the readings missing between
consecutive stamps, and the gaps ``tactile-sensor analyze`` would report (a stamp step
more than 20 times the median). While the protocol runs it also prints, every few
seconds, how far each stage trails: bytes waiting in the device, frames written but
not parsed, readings published but not yet recorded.

    python benchmarks/bench_recording_loss.py [--protocol compression] [--burners 1]

Run from /work/main with ``scripts/env.sh`` sourced. ROS domain: $ROS_DOMAIN_ID (default
177).
"""

from __future__ import annotations

import argparse
import os
import struct
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
from node_processes import isolate_ros
from recorded_run import add_protocol_argument
from results import Figure, write_results

SOURCE = Path(__file__).resolve().parents[1] / "tactile_sensor"
sys.path.insert(0, str(SOURCE))

GAP_FACTOR = 20.0  # as analysis/alignment.py


def stream_loss(stamps_ns: np.ndarray) -> tuple[int, int, float]:
    """(missing messages, gaps > 20x the median step, longest step [s]) of one stream."""
    if stamps_ns.size < 3:
        return 0, 0, 0.0
    steps = np.diff(np.sort(stamps_ns))
    median = float(np.median(steps))
    missing = int(np.clip(np.rint(steps / median) - 1, 0, None).sum())
    return missing, int(np.sum(steps > GAP_FACTOR * median)), float(steps.max()) * 1e-9


def read_stamps(bag: Path) -> dict[str, np.ndarray]:
    """Header stamps [ns] per stamped data topic, straight from the CDR (the header comes
    first: after the 4-byte encapsulation, int32 sec and uint32 nanosec)."""
    from rosbags.highlevel import AnyReader

    out: dict[str, list[int]] = {}
    with AnyReader([bag]) as reader:
        wanted = [c for c in reader.connections
                  if c.topic not in ("/diagnostics", "/calibration_curve")]
        for connection, _, raw in reader.messages(connections=wanted):
            sec, nanosec = struct.unpack_from("<iI", raw, 4)
            out.setdefault(connection.topic, []).append(sec * 10**9 + nanosec)
    return {topic: np.array(s, dtype=np.int64) for topic, s in out.items()}


def make_runner(bag: Path, adc_link: Path, protocol: str) -> Any:
    from tactile_sensor.configurations import BENCH
    from tactile_sensor.nodes.bringup import protocol_parameters
    from tactile_sensor.nodes.bringup_runner import BringupRunner

    class ProbedRunner(BringupRunner):
        """Takes every stage's counters as the nodes go down: the reader's before the
        driver is cleaned up, the publish counts after it stopped publishing."""

        def __init__(self, *args: Any, **kwargs: Any) -> None:
            super().__init__(*args, **kwargs)
            self.final: dict[str, Any] = {}
            self.threads: dict[str, float] = {}

        def _lifecycle_down(self) -> None:
            self.final = snapshot(self)
            self.threads.update(thread_cpu_s())
            super()._lifecycle_down()

        def _destroy_nodes(self) -> None:
            after = snapshot(self)
            self.final.update({k: after[k] for k in ("published", "gauge_published")
                               if k in after})
            super()._destroy_nodes()

    return ProbedRunner(BENCH, ports={"adc_port": str(adc_link)},
                        protocol=protocol_parameters("bench", protocol), namespace="",
                        use_mock=True, extra_config=None, record=bag)


def snapshot(runner: Any) -> dict[str, Any]:
    """Counters of every stage now (missing nodes or readers give zeros)."""
    bench, driver, recorder = (runner.nodes.get(n) for n in ("bench", "driver", "recorder"))
    out: dict[str, Any] = {}
    if bench is not None:
        stats = bench.adc.stats()
        out.update(written=stats.frames_written, generated=stats.frames_generated,
                   device_lost=stats.frames_generated - stats.frames_written
                   - stats.frames_dropped - stats.frames_unplugged,
                   backlog=bench.adc.backlog_bytes, gauge_published=bench.gauge_published)
    reader = getattr(driver, "_reader", None)
    if reader is not None:
        stats = reader.stats()
        out.update(parsed=stats.frames, seq_dropped=stats.dropped_frames,
                   queued=stats.backlog, queued_peak=stats.backlog_peak,
                   overflowed=stats.backlog_dropped)
    if driver is not None:
        out.update(published=driver.published_readings)
    if recorder is not None:
        out.update(recorded=recorder.counts.get("/driver/reading", 0),
                   gauge_recorded=recorder.counts.get("/bench/gauge/wrench", 0),
                   bag_pending=recorder.pending)
    return out


def thread_cpu_s() -> dict[str, float]:
    """CPU seconds used so far by each live thread of this process, by thread name."""
    tick = os.sysconf("SC_CLK_TCK")
    out: dict[str, float] = {}
    for thread in threading.enumerate():
        try:
            stat = Path(f"/proc/self/task/{thread.native_id}/stat").read_text()
        except OSError:
            continue
        fields = stat.rsplit(")", 1)[1].split()
        name = thread.name.split(":")[0].rstrip("_0123456789-")
        out[name] = out.get(name, 0.0) + (int(fields[11]) + int(fields[12])) / tick
    return out


def monitor(runner: Any, stop: threading.Event, period_s: float) -> None:
    start = time.monotonic()
    while not stop.wait(period_s):
        runner.threads.update(thread_cpu_s())
        s = snapshot(runner)
        if "written" not in s or "parsed" not in s:
            continue
        print(f"  t={time.monotonic() - start:5.1f} s  device backlog {s['backlog']:6d} B  "
              f"unparsed {s['written'] - s['parsed']:5d}  "
              f"parsed, not yet published {s.get('queued', 0):6d}  "
              f"unrecorded {s.get('published', 0) - s.get('recorded', 0):6d} "
              f"(bag queue {s.get('bag_pending', 0)})", flush=True)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_protocol_argument(parser, "compression", "repeatability:cycles=3", "bench")
    parser.add_argument("--burners", type=int, default=1,
                        help="busy-loop processes started alongside (default 1)")
    parser.add_argument("--monitor", type=float, default=2.0,
                        help="print the stages' backlog every this many seconds (0 = never)")
    args = parser.parse_args()
    isolate_ros(177)
    tmp = Path(tempfile.mkdtemp(prefix="bench_recording_loss_"))
    bag = tmp / "bag"
    burners = [subprocess.Popen([sys.executable, "-c", "while True: pass"])
               for _ in range(args.burners)]
    stop = threading.Event()
    try:
        runner = make_runner(bag, tmp / "adc", args.protocol)
        original = runner._create_nodes

        def create_and_watch() -> None:
            original()
            if args.monitor > 0:
                threading.Thread(target=monitor, args=(runner, stop, args.monitor),
                                 daemon=True).start()

        runner._create_nodes = create_and_watch
        cpu0 = time.process_time()
        wall0 = time.monotonic()
        code = runner.run(None)
        cpu_s, wall_s = time.process_time() - cpu0, time.monotonic() - wall0
    finally:
        stop.set()
        for burner in burners:
            burner.kill()
            burner.wait()
    final = runner.final
    stamps = read_stamps(bag)
    print(f"\nprotocol {args.protocol} with {args.burners} burner(s) on {os.cpu_count()} "
          f"cores: exit {code}, {wall_s:.1f} s wall, bringup CPU {cpu_s:.1f} s "
          f"({cpu_s / wall_s:.2f} cores)")
    figures = [Figure("wall time", wall_s, "s"), Figure("bringup CPU", cpu_s / wall_s, "cores"),
               Figure("ADC frames generated", final.get("generated", 0)),
               Figure("ADC frames lost in the device", final.get("device_lost", 0)),
               Figure("frames missing by sequence at the driver", final.get("seq_dropped", 0)),
               Figure("frames dropped with a full driver backlog", final.get("overflowed", 0))]
    print(f"ADC frames  generated {final.get('generated', 0)}  written {final.get('written', 0)}"
          f"  lost in the device (host buffer full) {final.get('device_lost', 0)}")
    print(f"driver      parsed {final.get('parsed', 0)}  missing by sequence "
          f"{final.get('seq_dropped', 0)}  dropped with a full backlog "
          f"{final.get('overflowed', 0)}  published {final.get('published', 0)}  "
          f"(backlog peak {final.get('queued_peak', 0)} samples)")
    for topic, published in (("/driver/reading", final.get("published", 0)),
                             ("/bench/gauge/wrench", final.get("gauge_published", 0))):
        s = stamps.get(topic, np.array([], dtype=np.int64))
        missing, gaps, longest = stream_loss(s)
        expected = s.size + missing
        share = 100.0 * missing / expected if expected else 0.0
        print(f"{topic:20s} published {published}  recorded {s.size}  missing inside "
              f"the recording {missing} ({share:.3f} %)  gaps {gaps}  longest step "
              f"{longest * 1e3:.1f} ms")
        figures += [Figure(f"{topic} missing inside the recording", share, "%"),
                    Figure(f"{topic} gaps", gaps),
                    Figure(f"{topic} longest step", longest * 1e3, "ms")]
    written = max(final.get("generated", 0), 1)
    print(f"stages: device overflow {final.get('device_lost', 0)} frames, sequence gaps seen "
          f"by the driver {final.get('seq_dropped', 0)}, driver backlog overflow "
          f"{final.get('overflowed', 0)} (of {written} generated; the first two count the "
          "same frames)")
    threads = sorted(runner.threads.items(), key=lambda kv: -kv[1])
    print("CPU by thread [s]: " + ", ".join(f"{name} {cpu:.1f}" for name, cpu in threads))
    print(f"bag: {bag}")
    write_results("recording_loss", figures, notes=f"Protocol {args.protocol} with "
                  f"{args.burners} busy-loop process(es) on {os.cpu_count()} cores; exit {code}.")
    return code


if __name__ == "__main__":
    sys.exit(main())
