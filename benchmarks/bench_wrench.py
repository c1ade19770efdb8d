"""The six-axis wrench's accuracy goals: ``bringup wrench --protocol wrench`` recorded and
analysed with the default settings.

Runs the wrench protocol (press, shear, tilt about x and y, twist about z, then combined
moves) on mock hardware through ``tactile-sensor bringup wrench``, then ``tactile-sensor
analyze`` on the bag, and prints the driver's error per component against the six-component
gauge beside the goals: torque rmse <= 10 % of its range on each of Tx, Ty and Tz, force
within 10 / 10 / 5 % (x / y / z), and the torque bandwidth (the driver's
``torque_cutoff_hz``) at least 10 Hz. A component the layout does not observe is printed as
such and fails its goal.

    python benchmarks/bench_wrench.py [--protocol wrench] [--config extra.yaml] [--keep DIR]

Run with ``scripts/env.sh`` sourced. ROS domain: $ROS_DOMAIN_ID (default 218).
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

import yaml
from results import Figure, write_results

ROOT = Path(__file__).resolve().parents[1]
FORCE_GOALS_PCT = {"x": 10.0, "y": 10.0, "z": 5.0}
TORQUE_GOAL_PCT = 10.0
BANDWIDTH_GOAL_HZ = 10.0


def torque_cutoff_hz(extra: Path | None) -> float:
    """The driver's torque bandwidth as the configuration sets it (the extra file wins)."""
    value = None
    for path in (ROOT / "tactile_sensor" / "config" / "wrench.yaml", extra):
        if path is None:
            continue
        for key, node in (yaml.safe_load(path.read_text()) or {}).items():
            params = (node or {}).get("ros__parameters", {})
            if key.endswith("driver") and "torque_cutoff_hz" in params:
                value = float(params["torque_cutoff_hz"])
    if value is None:
        raise SystemExit("bench_wrench: no torque_cutoff_hz in config/wrench.yaml; the "
                         "wrench configuration must set the torque's bandwidth.")
    return value


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--protocol", default="wrench",
                        help="wrench protocol with overrides, e.g. wrench:twist=0.1")
    parser.add_argument("--config", type=Path, default=None,
                        help="extra ROS parameter file for the run (e.g. another "
                             "torque_cutoff_hz)")
    parser.add_argument("--keep", type=Path, default=None,
                        help="folder to keep the bag and the analysis in (default: temporary)")
    args = parser.parse_args()
    os.environ.setdefault("ROS_DOMAIN_ID", "218")
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    work = args.keep or Path(tempfile.mkdtemp(prefix="bench_wrench_"))
    work.mkdir(parents=True, exist_ok=True)
    bag, out = work / "bag", work / "analysis"
    command = ["tactile-sensor", "bringup", "wrench", "--protocol", args.protocol,
               "--record", str(bag), "--port", f"adc_port={work / 'adc'}"]
    if args.config is not None:
        command += ["--config", str(args.config)]
    t0 = time.monotonic()
    run = subprocess.run(command)
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
    print(f"wrench run ({args.protocol}): bringup {t1 - t0:.0f} s, analysis {t2 - t1:.1f} s, "
          f"load average {os.getloadavg()[0]:.1f}")
    figures = [Figure("bringup", round(t1 - t0, 1), "s"),
               Figure("analysis", round(t2 - t1, 1), "s")]
    met = True
    goals = [("force", "n", "N", axis, FORCE_GOALS_PCT[axis]) for axis in "xyz"]
    goals += [("torque", "nm", "N m", axis, TORQUE_GOAL_PCT) for axis in "xyz"]
    for kind, key, unit, axis, goal in goals:
        rmse = (mt.get(f"{kind}_rmse_{key}") or {}).get(axis)
        span = (mt.get(f"{kind}_range_{key}") or {}).get(axis)
        name = f"{kind[0].upper()}{axis}"
        if rmse is None or not span:
            met = False
            print(f"  {name}: not estimated (goal <= {goal:g} % of range: NOT met)")
            figures.append(Figure(f"{name} rmse", None, "% of range", f"<= {goal:g} %",
                                  False))
            continue
        pct = 100 * rmse / span
        ok = pct <= goal
        met &= ok
        print(f"  {name}: rmse {rmse:.4g} {unit} over a {span:.4g} {unit} range = "
              f"{pct:.2f} % (goal <= {goal:g} %: {'met' if ok else 'NOT met'})")
        figures.append(Figure(f"{name} rmse", round(pct, 3), "% of range", f"<= {goal:g} %",
                              ok))
    cutoff = torque_cutoff_hz(args.config)
    ok = cutoff >= BANDWIDTH_GOAL_HZ
    met &= ok
    print(f"  torque bandwidth (driver torque_cutoff_hz): {cutoff:g} Hz (goal >= "
          f"{BANDWIDTH_GOAL_HZ:g} Hz: {'met' if ok else 'NOT met'})")
    figures.append(Figure("torque bandwidth", cutoff, "Hz", f">= {BANDWIDTH_GOAL_HZ:g}", ok))
    print(f"  figures and report: {out}")
    print("goals " + ("met" if met else "NOT met"))
    write_results("bench_wrench", figures, notes=f"Protocol {args.protocol} on mock hardware "
                  f"through `tactile-sensor bringup wrench`; load average "
                  f"{os.getloadavg()[0]:.1f} at the end.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
