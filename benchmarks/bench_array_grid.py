"""Array calibration grid: compute time on this machine (goal <= 5 min on 2 cores, progress
shown), the fit's held-out error per axis, and the default single-module sweep beside it
(it must not get slower).

Runs the default four-module grid cold (no cache) with ``--workers`` processes (default: 1
and 2, one after the other), then fits it. Say whether the machine was busy: the load
average is printed before and after.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_array_grid.py [--workers 2] [--quiet]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tactile_sensor"))

from tactile_sensor.physics.array_grid import compute_grid
from tactile_sensor.physics.array_report import fit_grid, summary
from tactile_sensor.physics.params import PhysicsParams
from tactile_sensor.physics.prediction import compute_curve


def load() -> str:
    one, five, _ = os.getloadavg()
    return f"load average {one:.1f} (1 min), {five:.1f} (5 min) on {os.cpu_count()} cores"


class Ticker:
    """Progress lines at most every 2 s, with the elapsed time."""

    def __init__(self) -> None:
        self.start = time.perf_counter()
        self.last = -10.0

    def __call__(self, fraction: float, message: str) -> None:
        now = time.perf_counter() - self.start
        if now - self.last > 2.0 or fraction >= 1.0:
            self.last = now
            print(f"  {now:6.1f} s [{100 * fraction:5.1f}%] {message}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--degree", type=int, default=3)
    parser.add_argument("--quiet", action="store_true", help="no per-step progress")
    args = parser.parse_args()
    print(load(), flush=True)
    start = time.perf_counter()
    curve = compute_curve(PhysicsParams())
    print(f"default single-module sweep (extrapolated): {time.perf_counter() - start:.2f} s, "
          f"force {curve.force_n[-1]:.4f} N, output {curve.output_v[-1]:.4f} V", flush=True)
    params = PhysicsParams(modules="front,back,left,right")
    for workers in args.workers:
        start = time.perf_counter()
        grid = compute_grid(params, None if args.quiet else Ticker(), workers)
        seconds = time.perf_counter() - start
        print(f"grid with {workers} worker(s): {seconds:.1f} s for {grid.paths} paths, "
              f"{grid.indentation_m.size} points (goal <= 300 s); {load()}", flush=True)
    _, report = fit_grid(grid, args.degree)
    print(summary(report, params, "off (benchmark)"))


if __name__ == "__main__":
    main()
