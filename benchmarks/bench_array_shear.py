"""The array's accuracy goal: ``bringup array --protocol shear`` recorded and analysed.

Runs the full shear protocol (press 3 mm at 1 mm/s, probe out 6 mm and back along eight
directions, release; 104 s) on mock hardware through ``tactile-sensor bringup array``, then
``tactile-sensor analyze`` on the bag, and prints the driver's force error per axis against
the three-axis gauge beside the goals: rmse x and y <= 10 % of their range, z <= 5 %.

    python benchmarks/bench_array_shear.py [--protocol shear] [--keep DIR]

Run with ``scripts/env.sh`` sourced. ROS domain: $ROS_DOMAIN_ID (default 217).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from results import Figure, write_results

GOALS_PCT = {"x": 10.0, "y": 10.0, "z": 5.0}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--protocol", default="shear",
                        help="array protocol with overrides, e.g. shear:shear_directions=4")
    parser.add_argument("--keep", type=Path, default=None,
                        help="folder to keep the bag and the analysis in (default: temporary)")
    args = parser.parse_args()
    os.environ.setdefault("ROS_DOMAIN_ID", "217")
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    work = args.keep or Path(tempfile.mkdtemp(prefix="bench_array_shear_"))
    work.mkdir(parents=True, exist_ok=True)
    bag, out = work / "bag", work / "analysis"
    t0 = time.monotonic()
    run = subprocess.run(["tactile-sensor", "bringup", "array", "--protocol", args.protocol,
                          "--record", str(bag), "--port", f"adc_port={work / 'adc'}"])
    if run.returncode != 0:
        print(f"bringup failed with status {run.returncode}", file=sys.stderr)
        return 1
    t1 = time.monotonic()
    analysis = subprocess.run(["tactile-sensor", "analyze", str(bag), "--out", str(out),
                               "--quiet"])
    if analysis.returncode != 0:
        print(f"analysis failed with status {analysis.returncode}", file=sys.stderr)
        return 1
    t2 = time.monotonic()
    mt = json.loads((out / "metrics.json").read_text())
    array = mt["array"]
    print(f"array shear run ({args.protocol}): bringup {t1 - t0:.0f} s, analysis "
          f"{t2 - t1:.1f} s, {array['samples']} samples at {array['sample_rate_hz']:.0f} Hz, "
          f"load average {os.getloadavg()[0]:.1f}")
    met = True
    figures = [Figure("bringup", t1 - t0, "s"), Figure("analysis", t2 - t1, "s")]
    for axis in "xyz":
        rmse, span = mt["force_rmse_n"][axis], mt["force_range_n"][axis]
        pct = 100 * rmse / span if span else float("nan")
        ok = pct <= GOALS_PCT[axis]
        met &= ok
        print(f"  F{axis}: rmse {rmse:.3f} N over a {span:.2f} N range = {pct:.2f} % "
              f"(goal <= {GOALS_PCT[axis]:g} %: {'met' if ok else 'NOT met'})")
        figures.append(Figure(f"F{axis} rmse", pct, "% of range", f"<= {GOALS_PCT[axis]:g} %",
                              ok))
    shear = array.get("shear_direction")
    if shear:
        print(f"  shear direction where |F_lateral| >= {shear['threshold_n']:.2f} N: median "
              f"|error| {shear['median_abs_deg']:.1f} deg, rmse {shear['rmse_deg']:.1f} deg, "
              f"max {shear['max_abs_deg']:.1f} deg over {shear['samples']} samples")
        figures += [Figure("shear direction median |error|", shear["median_abs_deg"], "deg"),
                    Figure("shear direction max |error|", shear["max_abs_deg"], "deg")]
    sens = array.get("sensitivity_matrix")
    if sens:
        print("  sensitivity matrix [V/N] (rows: modules; columns: Fx, Fy, Fz):")
        for face, row in zip(sens["faces"], sens["values_v_per_n"], strict=True):
            print(f"    {face:6s} " + "  ".join("    n/a" if v is None else f"{v:+.4f}"
                                           for v in row))
    print(f"  figures and report: {out}")
    print("goals " + ("met" if met else "NOT met"))
    write_results("array_shear", figures, notes=f"Protocol {args.protocol} on mock hardware "
                  f"through `tactile-sensor bringup array`, {array['samples']} samples; load "
                  f"average {os.getloadavg()[0]:.1f} at the end.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
