"""Analysis time for a 100-cycle 1 kHz recording against rosbags' own read + deserialize.

Usage: python benchmarks/bench_analysis.py [--cycles 100] [--rate 1000]
       [--storage sqlite3 mcap] [--keep DIR]
Goal: full analysis (read, decode, metrics, calibration fit, figures, report) within
1.5x of the baseline, which reads the same three topics with rosbags and runs
deserialize_cdr on every message.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tactile_sensor"))

from results import Figure, write_results
from rosbags.rosbag2 import Reader

from tactile_sensor.analysis import cli
from tactile_sensor.analysis.characterise import Options, analyse_bag
from tactile_sensor.analysis.plots import compression_ramps
from tactile_sensor.analysis.synthetic import (
    BagTopics,
    PressProtocol,
    SensorTruth,
    press_signals,
    write_press_bag,
    writer_typestore,
)


def baseline_s(bag: Path) -> tuple[float, int]:
    """rosbags alone: read the three topics and deserialize every message."""
    store = writer_typestore()
    topics = BagTopics()
    wanted = {topics.reading, topics.reference, topics.position}
    start = time.perf_counter()
    n = 0
    with Reader(bag) as reader:
        conns = [c for c in reader.connections if c.topic in wanted]
        deserialize = store.deserialize_cdr
        for conn, _, raw in reader.messages(connections=conns):
            deserialize(raw, conn.msgtype)
            n += 1
    return time.perf_counter() - start, n


def analysis_s(bag: Path, out: Path) -> float:
    start = time.perf_counter()
    code = cli.main([str(bag), "--out", str(out), "--fit-calibration", "--prediction",
                     "none", "--quiet"])
    if code != 0:
        raise SystemExit(f"analysis failed with exit code {code}")
    return time.perf_counter() - start


def compression_series(bag: Path) -> dict[str, np.ndarray]:
    """The compression curve the analysis draws (Fig. 7a), for the bench page's figure:
    both ramps in one set of columns, ``unloading`` telling them apart."""
    ramps = compression_ramps(analyse_bag(str(bag), Options()))
    (load_m, load_n), (unload_m, unload_n) = ramps["load"], ramps["unload"]
    return {"indentation_m": np.concatenate([load_m, unload_m]),
            "force_n": np.concatenate([load_n, unload_n]),
            "unloading": np.concatenate([np.zeros(load_m.size), np.ones(unload_m.size)])}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cycles", type=int, default=100)
    p.add_argument("--rate", type=float, default=1000.0)
    p.add_argument("--storage", nargs="+", default=["sqlite3", "mcap"])
    p.add_argument("--keep", type=Path, help="write/reuse bags in this directory")
    args = p.parse_args()
    protocol = PressProtocol(speeds_mm_s=(1.0,), cycles=(args.cycles,), rate_hz=args.rate)
    with contextlib.ExitStack() as stack:
        root = args.keep or Path(stack.enter_context(tempfile.TemporaryDirectory()))
        root.mkdir(parents=True, exist_ok=True)
        signals = None
        figures: list[Figure] = []
        print(f"{args.cycles} cycles at 1 mm/s, 3 mm, {args.rate:g} Hz, three topics")
        for storage in args.storage:
            bag = root / f"press_{args.cycles}_{int(args.rate)}_{storage}"
            if not bag.exists():
                if signals is None:
                    signals = press_signals(protocol, SensorTruth(), seed=0)
                t = time.perf_counter()
                write_press_bag(bag, signals, storage)
                print(f"  wrote {storage} bag in {time.perf_counter() - t:.1f} s")
            base, n = baseline_s(bag)
            full = analysis_s(bag, root / f"out_{storage}")
            print(f"{storage:8s} messages {n:9d}  rosbags read+deserialize {base:7.2f} s  "
                  f"analysis {full:7.2f} s  ratio {full / base:5.2f}x (goal <= 1.5x)")
            figures += [Figure(f"{storage}: messages", n),
                        Figure(f"{storage}: rosbags read + deserialize", base, "s"),
                        Figure(f"{storage}: full analysis", full, "s"),
                        Figure(f"{storage}: analysis / baseline", full / base, "x", "<= 1.5",
                               full / base <= 1.5)]
        series = compression_series(bag)
    write_results("analysis", figures, series=series,
                  notes=f"{args.cycles} cycles at 1 mm/s to 3 mm, {args.rate:g} Hz, three "
                  "topics; the baseline reads the same topics with rosbags and deserializes "
                  "every message.")


if __name__ == "__main__":
    main()
