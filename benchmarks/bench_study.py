"""Study benchmark: one design study's wall time with 1 and 2 local workers and on a loopback
Dask cluster (``dask scheduler`` + two ``dask worker`` processes on 127.0.0.1).

Every run starts from an empty cache, so each solves every design; the rows of all three
must agree (the same FEM on every path), and the loopback run must have used both workers.
Prints the seconds per run, designs per minute and the load average beside them: on a
shared 2-core machine the second worker only helps when a core is idle.

    python benchmarks/bench_study.py [SPEC]   (default: config/studies/window_placement.yaml)

Run with ``scripts/env.sh`` sourced.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time
from pathlib import Path

SOURCE = Path(__file__).resolve().parents[1] / "tactile_sensor"
sys.path.insert(0, str(SOURCE))

from results import Figure, write_results  # noqa: E402

from tactile_sensor.studies.cluster import loopback_cluster  # noqa: E402
from tactile_sensor.studies.run import DesignRow, metric_value, run_study  # noqa: E402
from tactile_sensor.studies.spec import StudySpecError, load_spec  # noqa: E402

DEFAULT_SPEC = SOURCE / "config" / "studies" / "window_placement.yaml"


def timed(label: str, **kwargs: object) -> tuple[float, list[DesignRow]]:
    start = time.perf_counter()
    rows = run_study(**kwargs)  # type: ignore[arg-type]
    seconds = time.perf_counter() - start
    failed = sum(not r.ok for r in rows)
    print(f"{label:>24}: {seconds:7.1f} s for {len(rows)} designs ({failed} error rows), "
          f"{60 * len(rows) / seconds:5.1f} designs/min, load average "
          f"{os.getloadavg()[0]:.1f}", flush=True)
    return seconds, rows


def same(a: list[DesignRow], b: list[DesignRow]) -> bool:
    return all(x.values == y.values and x.error == y.error and all(
        math.isclose(x.metrics[k], v, rel_tol=1e-9) for k, v in y.metrics.items())
        for x, y in zip(a, b, strict=True))


def study_series(rows: list[DesignRow], columns: tuple[str, ...]) -> dict[str, list[object]]:
    """Each design's name, error and metrics (the paper's first): the study's Pareto plot
    is drawn from them again on the design-studies page."""
    series: dict[str, list[object]] = {"design": [r.design for r in rows],
                                       "error": [r.error for r in rows]}
    for column in columns:
        series[column] = [metric_value(r, column) for r in rows]
    return series


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("spec", nargs="?", type=Path, default=DEFAULT_SPEC,
                        help="study spec (default: config/studies/window_placement.yaml)")
    path = parser.parse_args().spec
    try:
        spec = load_spec(path)
    except StudySpecError as exc:
        print(exc, file=sys.stderr)
        return 2
    print(f"study '{spec.name}': {len(spec.designs()) + 1} designs (the paper's included), "
          f"{os.cpu_count()} cores", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        s1, one = timed("1 local worker", spec=spec, workers=1, cache_dir=root / "one")
        s2, two = timed("2 local workers", spec=spec, workers=2, cache_dir=root / "two")
        with loopback_cluster(root, workers=2) as address:
            s3, remote = timed("loopback cluster (2)", spec=spec, scheduler=address,
                               cache_dir=root / "remote")
    workers = {r.worker for r in remote if r.ok}
    agree = same(one, two) and same(one, remote)
    print(f"rows agree on every path: {agree}; loopback workers used: {len(workers)}")
    # the spec file's name: a study's own name is prose (spaces, commas), not a file name
    write_results(f"study_{path.stem}", [
        Figure("1 local worker", s1, "s"), Figure("2 local workers", s2, "s"),
        Figure("loopback cluster (2 workers)", s3, "s"),
        Figure("rows agree on every path", agree, "", "yes", agree),
        Figure("loopback workers used", len(workers), "", "2", len(workers) == 2)],
        notes=f"Study '{spec.name}', {len(one)} designs, each run from an empty cache; load "
              f"average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores at the end.",
        series=study_series(one, spec.columns))
    return 0 if agree and len(workers) == 2 else 1


if __name__ == "__main__":
    sys.exit(main())
