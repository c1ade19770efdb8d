"""A real Dask cluster on 127.0.0.1: ``dask scheduler`` and one-thread ``dask worker``
processes started from their command-line entry points, as the README starts them on
machines of their own.

Why here: the cluster test and the study benchmark must exercise the same path a user's
cluster takes (a scheduler address, workers in other processes that import this package),
not a LocalCluster in disguise.
"""

from __future__ import annotations

import contextlib
import json
import os
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

from tactile_sensor.physics.batch import BatchError

#: The folder holding the package, which workers must be able to import.
SOURCE = Path(__file__).resolve().parents[2]
START_LIMIT_S = 120.0  # guards against a hang only; the start is awaited as a condition


def _wait(condition: Callable[[], bool], what: str, procs: list[subprocess.Popen]) -> None:
    end = time.monotonic() + START_LIMIT_S
    while not condition():
        dead = [" ".join(map(str, p.args)) for p in procs if p.poll() is not None]
        if dead:
            raise BatchError(f"a Dask process exited while waiting for {what}: {dead[0]}; "
                             "check that dask and distributed are installed (make setup).")
        if time.monotonic() > end:
            raise BatchError(f"no {what} after {START_LIMIT_S:.0f} s; the machine may be "
                             "overloaded, or a firewall blocks 127.0.0.1.")
        time.sleep(0.1)


@contextlib.contextmanager
def loopback_cluster(folder: Path, workers: int = 2) -> Iterator[str]:
    """Yield the scheduler's address once ``workers`` workers have joined; stop them all on
    leaving."""
    from distributed import Client

    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(SOURCE), os.environ.get("PYTHONPATH", "")]), "OMP_NUM_THREADS": "1",
        "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    file = folder / "scheduler.json"
    procs = [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler",
                               "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                               "--scheduler-file", str(file)], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        _wait(lambda: file.is_file() and file.stat().st_size > 0, "the scheduler file", procs)
        for k in range(workers):
            name = f"w{k + 1}"
            procs.append(subprocess.Popen(
                [sys.executable, "-m", "distributed.cli.dask_worker", "--scheduler-file",
                 str(file), "--nthreads", "1", "--nworkers", "1", "--name", name,
                 "--no-dashboard", "--local-directory", str(folder / name)],
                env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        address = json.loads(file.read_text())["address"]
        with Client(address, timeout="60s") as client:
            _wait(lambda: len(client.scheduler_info()["workers"]) >= workers,
                  f"{workers} workers", procs)
        yield address
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in reversed(procs):
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
