"""Soak: the bench and gripper configurations for N minutes at 1 kHz under scheduled faults.

Every node runs in its own process, as under ``ros2 launch`` (bench in namespace
/soak_bench, gripper in /soak_gripper, one ROS domain): the mock ADC (``tactile-sensor mock
adc --control``) and the XM430 emulator with its gripper world and ADC (``mock xm430
--control --adc-link``) on pseudo-terminals; per configuration a model, a driver
(``autostart``), the gripper node (``auto_reboot``), and the bench's recorder splitting its
bag every ``--split`` seconds. This process grasps and releases through the gripper's
actions in a loop and injects, on the schedule of ``soak_accounting.py``:

* adc_unplug: ``unplug 2`` to the mock ADC. Detected when the bench driver's /diagnostics
  says the connection is not ``connected``; recovered when it says ``connected`` again
  with more frames than before the pull. The time between pull and recovery is the window
  in which lost frames are explained.
* servo_overload: ``fault overload`` to the XM430 emulator (latches the Overload bit,
  torque off). Detected when the gripper's diagnostics go ERROR; recovered when they go OK
  after the node's ``auto_reboot`` rebooted the servo.
* cpu_burner: a busy process for 10 s. Nothing to detect (the system only gets less CPU);
  recovery is the time after the burner ends until the bench driver's backlog is empty.
* model_restart: SIGTERM to the bench model process (its clean lifecycle shutdown) and a
  new process. Detected when the old one has exited; recovered when the new one's latched
  ``calibration_curve`` reaches this process.
* recording_split: the recorder's ``max_bag_duration``. Detected when the next storage
  file appears; its "recovery" is the recorder's loss goal (every message in some file).

Readings lost are counted by sequence number, never by rate: the device counts frames it
generated while plugged in, the driver's reader counts frames parsed and those missing in
the sequence, the driver counts readings published (/diagnostics); the bag is read back.
RSS growth is the Theil-Sen slope of VmRSS samples after a warm-up (start-up allocation,
caches and the first GC cycles are not a leak), each process sampled every 5 s.

    python benchmarks/soak.py --minutes 5 [--json soak.json] [--keep DIR]

Run with ``scripts/env.sh`` sourced. ROS domain: $ROS_DOMAIN_ID (default 216); discovery
stays on localhost. Exits 1 when a goal fails.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import sys
import tempfile
from pathlib import Path
from typing import Any

SOURCE = Path(__file__).resolve().parents[1] / "tactile_sensor"
sys.path.insert(0, str(SOURCE))
sys.path.insert(0, str(Path(__file__).resolve().parent))  # the soak's modules, also when imported

from results import RESULTS, Figure, write_results  # noqa: E402
from soak_accounting import fault_schedule  # noqa: E402
from soak_monitor import TEARDOWN_S  # noqa: E402
from soak_processes import SELF, say  # noqa: E402
from soak_report import print_report  # noqa: E402
from soak_run import ADC_RATE_HZ, Soak  # noqa: E402


def report_figures(r: dict[str, Any]) -> list[Figure]:
    """The summary's figures for the results file: losses, each fault kind's slowest
    detection and recovery, the worst RSS growth, grasps and every goal."""
    loss = r["loss"]
    figures = [Figure("readings lost outside the unplugged windows", loss["lost_outside"]),
               Figure("readings lost in the unplugged windows", loss["lost_in_windows"]),
               Figure("readings recorded", r["recorded"], f"of {loss['published']} published")]
    for kind in sorted({f["kind"] for f in r["faults"]}):
        of_kind = [f for f in r["faults"] if f["kind"] == kind]
        for key, label in (("detected_after_s", "detection"), ("recovered_after_s", "recovery")):
            values = [f[key] for f in of_kind if f[key] is not None]
            figures.append(Figure(f"{kind}: slowest {label} of {len(of_kind)}",
                                  max(values) if len(values) == len(of_kind) else None, "s"))
    judged = [p["rss_growth_mb_per_h"] for p in r["processes"] if SELF not in p["process"]
              and math.isfinite(p["rss_growth_mb_per_h"])]
    figures.append(Figure("worst RSS growth", max(judged) if judged else None, "MB/h"))
    grasps = r["grasps"]
    figures.append(Figure("grasps succeeded", grasps["succeeded"], f"of {grasps['attempted']}"))
    figures += [Figure(g["name"], "PASS" if g["passed"] else "FAIL", "", g["detail"], g["passed"])
                for g in r["goals"]]
    return figures


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--minutes", type=float, default=5.0)
    parser.add_argument("--json", type=Path, default=None, help="write the figures here")
    parser.add_argument("--split", type=float, default=None,
                        help="recorder max_bag_duration [s] (default: a third of the run)")
    parser.add_argument("--keep", type=Path, default=None,
                        help="work folder to keep (logs, bag); default: a temporary one")
    parser.add_argument("--results", type=Path, default=RESULTS,
                        help="folder for soak.json, the summary's figures (default "
                             "build/benchmarks/results)")
    parser.add_argument("--bring-up-timeout", type=float, default=180.0,
                        help="seconds each bring-up step may take (default %(default)g)")
    args = parser.parse_args(argv)
    os.environ.setdefault("ROS_DOMAIN_ID", "216")
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    split_s = args.split or max(10.0, args.minutes * 60.0 / 3.0)
    run_s = args.minutes * 60.0
    try:
        # inject() waits for each fault's recovery before the schedule goes on, so the
        # spacing spreads the faults over the run; 10 s leaves room for the slowest (the
        # 10 s busy process) and makes one of each fit in a minute
        schedule = fault_schedule(run_s, spacing_s=min(30.0, max(10.0, run_s / 12)))
    except ValueError as exc:
        print(f"soak: --minutes {args.minutes:g}: {exc}", file=sys.stderr)
        return 2
    if args.keep is not None and args.keep.exists():
        print(f"soak: --keep {args.keep} already exists; give a new folder (the soak writes its "
              "bag and logs there and would mix them with another run's).", file=sys.stderr)
        return 2
    with contextlib.ExitStack() as stack:
        if args.keep is not None:
            args.keep.mkdir(parents=True, exist_ok=False)
            folder = args.keep
        else:
            folder = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="soak_")))
        soak = Soak(folder, args.minutes, split_s, schedule, args.bring_up_timeout)
        code = 1
        try:
            report = soak.run()
            # the figures first: nothing after the run may cost them
            print_report(report)
            if args.json is not None:
                args.json.write_text(json.dumps(report, indent=2, default=str))
            write_results("soak", report_figures(report), directory=args.results,
                          argv=sys.argv if argv is None else [sys.argv[0], *argv],
                          notes=f"Bench and gripper configurations for {args.minutes:g} min at "
                                f"{ADC_RATE_HZ:g} Hz under scheduled faults.")
            code = 0 if all(g["passed"] for g in report["goals"]) else 1
        except RuntimeError as exc:  # a node did not come up or report: say which, where
            say(f"soak: {exc}")
        finally:
            if not soak.close():
                say(f"soak: this process's ROS teardown did not end within {TEARDOWN_S:g} s "
                    "(a DDS deadlock); exiting without it, the figures above are complete.")
                sys.stdout.flush()
                sys.stderr.flush()
                os._exit(code)
    return code


if __name__ == "__main__":
    sys.exit(main())
