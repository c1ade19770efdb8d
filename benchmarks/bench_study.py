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

import json
import math
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

SOURCE = Path(__file__).resolve().parents[1] / "tactile_sensor"
sys.path.insert(0, str(SOURCE))

from tactile_sensor.physics.study import DesignRow, run_study  # noqa: E402
from tactile_sensor.physics.study_spec import load_spec  # noqa: E402

DEFAULT_SPEC = SOURCE / "config" / "studies" / "window_placement.yaml"
START_LIMIT_S = 120.0


def wait_for(condition: Callable[[], bool], what: str, procs: list[subprocess.Popen]) -> None:
    end = time.monotonic() + START_LIMIT_S
    while not condition():
        if any(p.poll() is not None for p in procs):
            raise SystemExit(f"a cluster process exited while waiting for {what}")
        if time.monotonic() > end:
            raise SystemExit(f"no {what} after {START_LIMIT_S:.0f} s")
        time.sleep(0.1)


def start_cluster(folder: Path) -> tuple[str, list[subprocess.Popen]]:
    """A scheduler and two one-thread workers on 127.0.0.1, as the README starts them."""
    from distributed import Client

    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(SOURCE), os.environ.get("PYTHONPATH", "")]), "OMP_NUM_THREADS": "1",
        "OPENBLAS_NUM_THREADS": "1"}
    file = folder / "scheduler.json"
    procs = [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler",
                               "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                               "--scheduler-file", str(file)], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    wait_for(lambda: file.is_file() and file.stat().st_size > 0, "scheduler file", procs)
    for name in ("w1", "w2"):
        procs.append(subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_worker", "--scheduler-file", str(file),
             "--nthreads", "1", "--nworkers", "1", "--name", name, "--no-dashboard",
             "--local-directory", str(folder / name)],
            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
    address = json.loads(file.read_text())["address"]
    with Client(address, timeout="60s") as client:
        wait_for(lambda: len(client.scheduler_info()["workers"]) >= 2, "2 workers", procs)
    return address, procs


def stop(procs: list[subprocess.Popen]) -> None:
    for p in reversed(procs):
        p.terminate()
    for p in reversed(procs):
        try:
            p.wait(timeout=30)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


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


def main() -> int:
    spec = load_spec(Path(sys.argv[1]) if len(sys.argv) > 1 else DEFAULT_SPEC)
    print(f"study '{spec.name}': {len(spec.designs()) + 1} designs (the paper's included), "
          f"{os.cpu_count()} cores", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        _, one = timed("1 local worker", spec=spec, workers=1, cache_dir=root / "one")
        _, two = timed("2 local workers", spec=spec, workers=2, cache_dir=root / "two")
        address, procs = start_cluster(root)
        try:
            _, remote = timed("loopback cluster (2)", spec=spec, scheduler=address,
                              cache_dir=root / "remote")
        finally:
            stop(procs)
    workers = {r.worker for r in remote if r.ok}
    agree = same(one, two) and same(one, remote)
    print(f"rows agree on every path: {agree}; loopback workers used: {len(workers)}")
    return 0 if agree and len(workers) == 2 else 1


if __name__ == "__main__":
    sys.exit(main())
