"""A configuration brought up on mock hardware, recorded and analysed, as a user would:
``tactile-sensor bringup <configuration> --protocol P --record BAG`` and then
``tactile-sensor analyze BAG``, each timed. Accuracy benchmarks judge the analysis's
metrics against their goals.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from results import Figure, write_results


def add_protocol_argument(parser: argparse.ArgumentParser, default: str, example: str,
                          kind: str) -> None:
    """``--protocol``, as ``tactile-sensor bringup`` takes it."""
    parser.add_argument("--protocol", default=default,
                        help=f"{kind} protocol as for bringup, e.g. {example}")


def add_keep_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--keep", type=Path, default=None,
                        help="folder to keep the bag and the analysis in (default: temporary)")


@dataclass(frozen=True)
class RecordedRun:
    """What the analysis measured (its ``metrics.json``), where it wrote its report, and how
    long bring-up and analysis took [s]."""

    configuration: str
    protocol: str
    metrics: dict[str, Any]
    out: Path
    bringup_s: float
    analysis_s: float

    def timing_figures(self, detail: str = "") -> list[Figure]:
        """Bring-up and analysis time, printed with what else the machine was doing."""
        print(f"{self.configuration} run ({self.protocol}): bringup {self.bringup_s:.0f} s, "
              f"analysis {self.analysis_s:.1f} s{detail}, load average "
              f"{os.getloadavg()[0]:.1f}")
        return [Figure("bringup", round(self.bringup_s, 1), "s"),
                Figure("analysis", round(self.analysis_s, 1), "s")]

    def notes(self, detail: str = "") -> str:
        """How the figures were measured, for the results file."""
        return (f"Protocol {self.protocol} on mock hardware through `tactile-sensor bringup "
                f"{self.configuration}`{detail}; load average {os.getloadavg()[0]:.1f} at "
                "the end.")


def bring_up_and_analyse(configuration: str, protocol: str, keep: Path | None,
                         extra: list[str] | None = None) -> RecordedRun | None:
    """Run the protocol and analyse its bag in ``keep`` (or a temporary folder); None, with
    the failing step said on stderr, when either command fails."""
    work = keep or Path(tempfile.mkdtemp(prefix=f"bench_{configuration}_"))
    work.mkdir(parents=True, exist_ok=True)
    bag, out = work / "bag", work / "analysis"
    t0 = time.monotonic()
    run = subprocess.run(["tactile-sensor", "bringup", configuration, "--protocol", protocol,
                          "--record", str(bag), "--port", f"adc_port={work / 'adc'}",
                          *(extra or [])])
    if run.returncode != 0:
        print(f"bringup failed with status {run.returncode}", file=sys.stderr)
        return None
    t1 = time.monotonic()
    analysis = subprocess.run(["tactile-sensor", "analyze", str(bag), "--out", str(out),
                               "--quiet"])
    if analysis.returncode != 0:
        print(f"analysis failed with status {analysis.returncode}", file=sys.stderr)
        return None
    metrics = json.loads((out / "metrics.json").read_text())
    return RecordedRun(configuration, protocol, metrics, out, t1 - t0, time.monotonic() - t1)


def array_series(run: RecordedRun) -> dict[str, Any]:
    """The aligned signals the analysis's array figures are drawn from, read again from the
    run's bag: the results file keeps them (decimated) for the docs' figures."""
    from tactile_sensor.analysis.array.analysis import analyse_array, detect
    from tactile_sensor.analysis.bag_reader import read_recording
    from tactile_sensor.analysis.characterise import Topics

    recording = read_recording(str(run.out.parent / "bag"), Topics().specs())
    sig = analyse_array(recording, detect(recording) or "an array configuration").signals
    series: dict[str, Any] = {"t_s": sig.t_s, "estimate_n": sig.estimate_n,
                              "reference_n": sig.reference_n}
    if sig.estimate_torque_nm is not None and sig.reference_torque_nm is not None:
        series |= {"estimate_torque_nm": sig.estimate_torque_nm,
                   "reference_torque_nm": sig.reference_torque_nm}
    return series


def share_of_range(name: str, rmse: float | None, span: float | None, unit: str,
                   goal_pct: float) -> Figure:
    """An error as a share of the range it was measured over, judged against its goal and
    printed; a component not estimated fails its goal."""
    goal = f"<= {goal_pct:g} %"
    if rmse is None or not span:
        print(f"  {name}: not estimated (goal {goal} of range: NOT met)")
        return Figure(f"{name} rmse", None, "% of range", goal, False)
    pct = 100 * rmse / span
    ok = pct <= goal_pct
    print(f"  {name}: rmse {rmse:.4g} {unit} over a {span:.4g} {unit} range = {pct:.2f} % "
          f"(goal {goal}: {'met' if ok else 'NOT met'})")
    return Figure(f"{name} rmse", round(pct, 3), "% of range", goal, ok)


#: (metrics key suffix, unit) of each kind of component the analysis scores per axis.
_COMPONENTS = {"force": ("n", "N"), "torque": ("nm", "N m")}


def axis_shares(metrics: dict[str, Any], kind: str, goals_pct: dict[str, float]
                ) -> list[Figure]:
    """The rmse of each axis of ``kind`` ("force" or "torque") against the gauge as a share
    of its range, judged against that axis's goal [%] and printed, x, y then z."""
    key, unit = _COMPONENTS[kind]
    rmse = metrics.get(f"{kind}_rmse_{key}") or {}
    span = metrics.get(f"{kind}_range_{key}") or {}
    return [share_of_range(f"{kind[0].upper()}{axis}", rmse.get(axis), span.get(axis), unit,
                           goals_pct[axis]) for axis in "xyz"]


def goals_line(figures: list[Figure], out: Path) -> None:
    """Where the report is, and whether every judged figure met its goal."""
    print(f"  figures and report: {out}")
    print("goals " + ("met" if all(f.met is not False for f in figures) else "NOT met"))


def report_array_run(name: str, run: RecordedRun, figures: list[Figure],
                     detail: str = "") -> None:
    """Whether every goal was met and where the report is, then the results file ``name``
    with the array's signals; ``detail`` goes into its notes."""
    goals_line(figures, run.out)
    write_results(name, figures, series=array_series(run), notes=run.notes(detail))
