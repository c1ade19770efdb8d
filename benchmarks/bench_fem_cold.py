"""Cold FEM sweep: ``tactile-sensor model sweep --json F`` in a new process with an empty cache.

This is what a user pays the first time a parameter set is asked for: process start,
imports, both meshes of the extrapolated sweep, the optics and the JSON. Each run is a new
Python process with ``XDG_CACHE_HOME`` pointing at a fresh empty folder (the prediction
cache lives in ``$XDG_CACHE_HOME/tactile_sensor``), so no run reuses another's sweep.

``--compare REV`` runs the same command for this checkout and for commit REV (exported with
``git archive`` into a temporary folder and run with ``PYTHONPATH`` at its source),
alternating the two so that the load of a shared machine hits both alike, and prints each
one's median wall and CPU time (user + sys of the child), the ratio new / REV, and the
largest difference between the two curves. Absolute times do not carry between machines;
the ratio side by side does. Figures go to
``build/benchmarks/results/fem_cold.json``.

    python benchmarks/bench_fem_cold.py --compare b36bc06 --repeat 5
    python -X importtime ... (``--importtime`` prints the slowest imports of one cold run)
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from results import ROOT, Figure, write_results

GOAL_RATIO = 0.5
SOURCE = "tactile_sensor"  # the ament_python package's folder: PYTHONPATH for a checkout
COMPARED = ("force_n", "bulge_m", "output_v")


@dataclass
class Candidate:
    """One checkout's source folder and what its runs measured."""

    label: str
    source: Path
    wall_s: list[float] = field(default_factory=list)
    cpu_s: list[float] = field(default_factory=list)
    curve: dict | None = None


def cold_run(source: Path, workdir: Path, importtime: bool = False
             ) -> tuple[float, float, dict, str]:
    """(wall [s], child CPU [s], the sweep's JSON, stderr) of one cold sweep."""
    cache = Path(tempfile.mkdtemp(prefix="cache-", dir=workdir))
    out = cache / "sweep.json"
    env = dict(os.environ, XDG_CACHE_HOME=str(cache), MPLBACKEND="Agg",
               PYTHONPATH=os.pathsep.join(filter(None, [str(source),
                                                       os.environ.get("PYTHONPATH")])))
    cmd = [sys.executable, *(["-X", "importtime"] if importtime else []),
           "-m", "tactile_sensor.cli", "model", "sweep", "--json", str(out), "--quiet"]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"the cold sweep of {source} failed ({proc.returncode}): "
                         f"{proc.stderr.strip()[-500:]}")
    if "cache           miss" not in proc.stdout:
        raise SystemExit(f"the sweep of {source} was not cold: {proc.stdout.strip()}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, json.loads(out.read_text()), proc.stderr


def export(rev: str, workdir: Path) -> Path:
    """The package source of commit ``rev``, exported into ``workdir``."""
    target = workdir / f"rev-{rev}"
    target.mkdir()
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev, SOURCE],
                             capture_output=True, check=False)
    if archive.returncode != 0:
        raise SystemExit(f"git cannot export {rev!r}: "
                         f"{archive.stderr.decode(errors='replace').strip()}; name a commit "
                         "of this repository.")
    subprocess.run(["tar", "-x", "-C", str(target)], input=archive.stdout, check=True)
    return target / SOURCE


def slowest_imports(stderr: str, top: int = 12) -> list[tuple[float, str]]:
    """The outermost imports with the largest cumulative time [s] from ``-X importtime``
    (what the process imported by itself, each with everything it pulled in)."""
    rows = []
    for line in stderr.splitlines():
        if not line.startswith("import time:"):
            continue
        parts = line[len("import time:"):].split("|")
        if len(parts) != 3 or not parts[1].strip().isdigit():
            continue
        name = parts[2]
        if len(name) - len(name.lstrip()) == 1:                # nesting level 0
            rows.append((int(parts[1]) * 1e-6, name.strip()))
    return sorted(rows, reverse=True)[:top]


def largest_difference(new: dict, old: dict) -> float:
    """Largest |new - old| / max|old| over the compared arrays of two curves."""
    worst = 0.0
    for name in COMPARED:
        a, b = new[name], old[name]
        scale = max(abs(x) for x in b) or 1.0
        worst = max(worst, max(abs(x - y) for x, y in zip(a, b, strict=True)) / scale)
    return worst


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--compare", metavar="REV", help="commit to run side by side with this "
                    "checkout (e.g. b36bc06)")
    ap.add_argument("--repeat", type=int, default=5, help="cold runs per checkout")
    ap.add_argument("--importtime", action="store_true",
                    help="also print the slowest imports of one cold run per checkout")
    ap.add_argument("--no-write", action="store_true", help="do not write the results file")
    args = ap.parse_args()
    if args.repeat < 1:
        raise SystemExit("--repeat must be at least 1.")
    load = os.getloadavg()
    print(f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} on {os.cpu_count()} cores",
          flush=True)
    with tempfile.TemporaryDirectory(prefix="bench-fem-cold-") as tmp:
        workdir = Path(tmp)
        candidates = [Candidate("this checkout", ROOT / SOURCE)]
        if args.compare:
            candidates.append(Candidate(args.compare, export(args.compare, workdir)))
        if args.importtime:
            for c in candidates:
                *_, stderr = cold_run(c.source, workdir, importtime=True)
                print(f"{c.label}: slowest imports (cumulative) "
                      + ", ".join(f"{name} {s:.2f} s" for s, name in slowest_imports(stderr)))
        for n in range(args.repeat):
            order = candidates if n % 2 == 0 else candidates[::-1]
            for c in order:
                wall, cpu, c.curve, _ = cold_run(c.source, workdir)
                c.wall_s.append(wall)
                c.cpu_s.append(cpu)
                print(f"  run {n + 1}/{args.repeat} {c.label}: wall {wall:.2f} s, "
                      f"CPU {cpu:.2f} s", flush=True)
    figures = []
    for c in candidates:
        key = "new" if c is candidates[0] else "rev"
        wall, cpu = statistics.median(c.wall_s), statistics.median(c.cpu_s)
        print(f"{c.label}: median wall {wall:.2f} s (min {min(c.wall_s):.2f}), median CPU "
              f"{cpu:.2f} s (min {min(c.cpu_s):.2f}) over {len(c.wall_s)} cold runs")
        figures += [Figure(f"{key}_wall_median", round(wall, 3), "s"),
                    Figure(f"{key}_cpu_median", round(cpu, 3), "s")]
    if args.compare:
        new, old = candidates
        ratio = statistics.median(new.wall_s) / statistics.median(old.wall_s)
        cpu_ratio = statistics.median(new.cpu_s) / statistics.median(old.cpu_s)
        diff = largest_difference(new.curve, old.curve)
        print(f"wall ratio {ratio:.3f} (goal <= {GOAL_RATIO}), CPU ratio {cpu_ratio:.3f}; "
              f"curves differ by at most {diff:.2e} of their range ({', '.join(COMPARED)})")
        figures += [Figure("wall_ratio", round(ratio, 3), "1", f"<= {GOAL_RATIO}"),
                    Figure("cpu_ratio", round(cpu_ratio, 3), "1"),
                    Figure("curve_difference", float(f"{diff:.3g}"), "1")]
    load = os.getloadavg()
    print(f"load average now {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    if not args.no_write:
        note = (f"baseline {args.compare}; " if args.compare else "") + \
            f"load average at the end {load[0]:.2f}"
        print(f"results: {write_results('fem_cold', figures, notes=note)}")


if __name__ == "__main__":
    main()
