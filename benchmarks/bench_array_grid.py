"""Array calibration grid: compute time on this machine (goal <= 5 min on 2 cores, progress
shown), the fit's held-out error per axis, and the default single-module sweep beside it
(it must not get slower).

Runs the default four-module grid cold (no cache) with ``--workers`` processes (default: 1
and 2, one after the other), then fits it. Say whether the machine was busy: the load
average is printed before and after. Then (unless ``--no-off-grid``) a test between the
grid's directions: paths at 22.5 deg, which no grid direction or mirror image reaches, at
every shear level, against the calibration fitted on the whole grid.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_array_grid.py [--workers 2] [--quiet]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tactile_sensor"))

from results import Figure, write_results

from tactile_sensor.physics.array_grid import ArrayGrid, LoadPath, compute_grid, solve_path
from tactile_sensor.physics.array_report import fit_grid, summary
from tactile_sensor.physics.params import PhysicsParams
from tactile_sensor.physics.prediction import compute_curve, module_output
from tactile_sensor.sensing.array_calibration import ArrayCalibration


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
    parser.add_argument("--no-off-grid", action="store_true",
                        help="skip the test at 22.5 deg between the grid's directions")
    args = parser.parse_args()
    print(load(), flush=True)
    start = time.perf_counter()
    curve = compute_curve(PhysicsParams())
    sweep_s = time.perf_counter() - start
    print(f"default single-module sweep (extrapolated): {sweep_s:.2f} s, "
          f"force {curve.force_n[-1]:.4f} N, output {curve.output_v[-1]:.4f} V", flush=True)
    figures = [Figure("default single-module sweep", sweep_s, "s")]
    params = PhysicsParams(modules="front,back,left,right")
    for workers in args.workers:
        start = time.perf_counter()
        grid = compute_grid(params, None if args.quiet else Ticker(), workers)
        seconds = time.perf_counter() - start
        print(f"grid with {workers} worker(s): {seconds:.1f} s for {grid.paths} paths, "
              f"{grid.indentation_m.size} points (goal <= 300 s); {load()}", flush=True)
        figures.append(Figure(f"grid ({grid.paths} paths) with {workers} worker(s)", seconds,
                              "s", "<= 300 s", seconds <= 300))
    calibration, report = fit_grid(grid, args.degree)
    print(summary(report, params, "off (benchmark)"))
    figures += [Figure(f"held-out F{axis} rmse", report["held_out_rmse_percent_of_range"][axis],
                       "% of range") for axis in report["held_out_rmse_n"]]
    if not args.no_off_grid:
        figures += off_grid(params, calibration, grid)
    write_results("array_grid", figures, notes=f"Four-module grid computed cold; {load()} "
                  "at the end.")


def off_grid(params: PhysicsParams, calibration: ArrayCalibration, grid: ArrayGrid
             ) -> list[Figure]:
    """The calibration's error at 22.5 deg, halfway between two grid directions."""
    theta = np.radians(22.5)
    start = time.perf_counter()
    errors = []
    for level in range(1, params.array_shear_levels + 1):
        s = params.array_shear_ratio * level / params.array_shear_levels
        s *= params.max_indentation
        path = LoadPath(0, level, s * np.cos(theta), s * np.sin(theta))
        res = solve_path(params, path)
        outputs = np.stack([module_output(params, res["bulges_m"][f])[2]
                            for f in calibration.faces], axis=1)[1:]
        forces = np.stack([res["force_x_n"], res["force_y_n"], res["force_n"]], axis=1)[1:]
        errors.append(calibration.forces(outputs) - forces)
    error = np.concatenate(errors)
    span = np.ptp(grid.force_matrix(), axis=0)
    rmse = np.sqrt(np.mean(error**2, axis=0))
    print(f"off-grid direction 22.5 deg ({error.shape[0]} points, "
          f"{time.perf_counter() - start:.1f} s): " + ", ".join(
              f"{axis} rmse {r * 1e3:.1f} mN ({100 * r / w:.2f} % of range), max "
              f"{np.abs(e).max() * 1e3:.1f} mN"
              for axis, r, w, e in zip("xyz", rmse, span, error.T, strict=True)))
    return [Figure(f"off-grid (22.5 deg) F{axis} rmse", 100 * r / w, "% of range")
            for axis, r, w in zip("xyz", rmse, span, strict=True)]


if __name__ == "__main__":
    main()
