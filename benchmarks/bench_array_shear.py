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
import sys
from typing import Any

from node_processes import isolate_ros
from recorded_run import (
    add_keep_argument,
    add_protocol_argument,
    axis_shares,
    bring_up_and_analyse,
    report_array_run,
)
from results import Figure

GOALS_PCT = {"x": 10.0, "y": 10.0, "z": 5.0}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_protocol_argument(parser, "shear", "shear:shear_directions=4", "array")
    add_keep_argument(parser)
    args = parser.parse_args()
    isolate_ros(217)
    run = bring_up_and_analyse("array", args.protocol, args.keep)
    if run is None:
        return 1
    mt = run.metrics
    array = mt["array"]
    figures = run.timing_figures(f", {array['samples']} samples at "
                                 f"{array['sample_rate_hz']:.0f} Hz")
    figures += axis_shares(mt, "force", GOALS_PCT)
    figures += shear_figures(array)
    report_array_run("array_shear", run, figures, f", {array['samples']} samples")
    return 0


def shear_figures(array: dict[str, Any]) -> list[Figure]:
    """The shear direction's error, printed with the sensitivity matrix beside it."""
    figures = []
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
    return figures


if __name__ == "__main__":
    sys.exit(main())
